"""Every way out of ``trajopt play`` runs the confirmed stop sequence: SIGTERM, SIGHUP, SIGINT, a closed
terminal, the port vanishing, an exception in the streaming loop, a signal during the stop itself.

The signal cases run ``trajopt play`` as a real subprocess against the emulator (a pty served by this
process). Each signal is sent once the emulator has seen the playback stream moves (an event, not a
sleep); the trajectory is long (loops) so that it is still streaming whatever the load.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any, Iterator

import numpy as np
import pytest

pytest.importorskip("serial")

from trajopt.hardware import protocol as P  # noqa: E402
from trajopt.hardware.emulator import RoboClawEmulator  # noqa: E402
from trajopt.hardware.monitor import TrackingMonitor  # noqa: E402
from trajopt.hardware.playback import play_trajectory  # noqa: E402
from trajopt.hardware.signals import StopSignals, Terminated  # noqa: E402
from tests.test_hardware_faults import (  # noqa: E402
    DT,
    HUNG_TIMEOUT,
    MOVES,
    NAMES,
    at_step,
    cli,
    hooked_opener,
    smooth_u,
    stopped_after_last_move,
    tripod_config,
    tripod_toml,
)

ROOT = Path(__file__).resolve().parents[1]
DEADLINE = 120.0  # s: safety net only; every wait below ends on an event
STREAMING_STEP = 8  # the signal goes out once the emulator has seen this step's first move


@pytest.fixture
def emu() -> Iterator[RoboClawEmulator]:
    with RoboClawEmulator() as e:
        yield e


@pytest.fixture
def long_result(tmp_path: Path) -> str:
    """A result far longer than any test waits (it is played with --loops too): it is still streaming."""
    from trajopt.results.result import Result

    u = smooth_u(300, 0.004)
    res = Result(robot="tripod", task="walk", motor_names=NAMES, dt=DT, z=np.zeros(1), u=u, u_post=u,
                 target=np.zeros((0, 2)), com=np.zeros((0, 3)))
    return str(res.save(tmp_path / "gait.npz"))


@pytest.fixture
def safety_net() -> Iterator[list[int]]:
    """SIGTERM / SIGHUP handlers that only record, so that a failing in-process test cannot kill pytest."""
    caught: list[int] = []
    previous = {s: signal.signal(s, lambda signum, frame: caught.append(signum))
                for s in (signal.SIGTERM, signal.SIGHUP)}
    yield caught
    for s, handler in previous.items():
        signal.signal(s, handler)


def _default_dispositions() -> None:  # in the child: as from an interactive shell, whatever ran pytest
    for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT, signal.SIGUSR1, signal.SIGUSR2):
        signal.signal(s, signal.SIG_DFL)


def start_play(result: str, toml: str, log: Path, **streams: Any) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    code = "import sys; from trajopt.cli import main; sys.exit(main())"
    streams = {"stdout": subprocess.PIPE, "stderr": subprocess.PIPE, **streams}
    return subprocess.Popen([sys.executable, "-c", code, "play", result, "--hardware", toml, "--log", str(log),
                             "--loops", "20"], cwd=log.parent, env=env, preexec_fn=_default_dispositions,
                            text=True, **streams)


def when_streaming(emu: RoboClawEmulator) -> threading.Event:
    streaming = threading.Event()
    emu.after_packets(at_step(STREAMING_STEP), streaming.set)
    return streaming


def wait_for(event: threading.Event, proc: subprocess.Popen) -> None:
    if not event.wait(DEADLINE):
        proc.kill()
        out, err = proc.communicate()
        pytest.fail(f"the playback never streamed; exit {proc.returncode}; stderr:\n{err}")


def moves_after_the_signal(emu: RoboClawEmulator) -> int:
    return sum(c in MOVES for c in emu.commands()[at_step(STREAMING_STEP):])


@pytest.mark.parametrize("signum, code, said", [
    (signal.SIGTERM, 143, "terminated by SIGTERM"),
    (signal.SIGHUP, 129, "terminated by SIGHUP"),
    (signal.SIGINT, 130, "interrupted"),
    (signal.SIGQUIT, 131, "terminated by SIGQUIT"),      # Ctrl-\ (issue #40: it left the motors running)
    (signal.SIGUSR1, 138, "terminated by SIGUSR1"),
])
def test_signal_during_play_stops_every_motor(emu: RoboClawEmulator, tmp_path: Path, long_result: str,
                                              signum: int, code: int, said: str) -> None:
    streaming = when_streaming(emu)
    log = tmp_path / "p.csv"
    proc = start_play(long_result, tripod_toml(tmp_path, emu.port, timeout=1.0), log)
    wait_for(streaming, proc)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=DEADLINE)
    assert proc.returncode == code, err
    assert said in err and "motors confirmed stopped: front, back" in err and f"log kept at {log}" in err
    assert stopped_after_last_move(emu)  # duty 0 to both channels after the last move, both idle
    assert moves_after_the_signal(emu) < 20 * 300 - STREAMING_STEP  # it did stop early
    assert out == ""  # no summary: the playback did not finish


def test_sighup_after_the_terminal_closed_still_stops(emu: RoboClawEmulator, tmp_path: Path,
                                                      long_result: str) -> None:
    """SSH session gone: stdout / stderr are a pty whose master is closed (writes fail with EIO)."""
    streaming = when_streaming(emu)
    master, slave = os.openpty()
    proc = start_play(long_result, tripod_toml(tmp_path, emu.port, timeout=1.0), tmp_path / "p.csv",
                      stdout=slave, stderr=slave)
    os.close(slave)
    wait_for(streaming, proc)
    os.close(master)  # the terminal is gone: the progress lines can no longer be written
    gone = emu.commands().count(P.Cmd.READ_ENCODER_M1)
    proc.send_signal(signal.SIGHUP)
    assert proc.wait(timeout=DEADLINE) == 129
    assert stopped_after_last_move(emu)
    assert emu.commands().count(P.Cmd.READ_ENCODER_M1) > gone  # the stop was read back (confirmed)


def test_port_vanishing_under_a_running_play(emu: RoboClawEmulator, tmp_path: Path, long_result: str) -> None:
    streaming = when_streaming(emu)
    proc = start_play(long_result, tripod_toml(tmp_path, emu.port, timeout=0.2), tmp_path / "p.csv")
    wait_for(streaming, proc)
    emu.disconnect()  # the pty is closed: the USB cable was pulled
    out, err = proc.communicate(timeout=DEADLINE)
    assert proc.returncode == 3, err
    assert "stopping the motors" in err  # the stop was attempted ...
    assert "NOT confirmed stopped (cut their power): front (" in err and "; back (" in err  # ... and not confirmed


# --------------------------------------------------------------------------- in process
def test_exception_in_the_streaming_loop_runs_the_stop(emu: RoboClawEmulator, tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    from trajopt.results.result import Result

    check = TrackingMonitor.check

    def broken_check(self: TrackingMonitor, t: float, step: int, measured: Any) -> None:
        check(self, t, step, measured)
        if step == 10:
            raise RuntimeError("a bug in the streaming loop")

    monkeypatch.setattr(TrackingMonitor, "check", broken_check)
    u = smooth_u()
    res = Result(robot="tripod", task="walk", motor_names=NAMES, dt=DT, z=np.zeros(1), u=u, u_post=u,
                 target=np.zeros((0, 2)), com=np.zeros((0, 3)))
    result = str(res.save(tmp_path / "gait.npz"))
    code = cli(result, "--hardware", tripod_toml(tmp_path, emu.port), "--log", str(tmp_path / "p.csv"))
    err = capsys.readouterr().err
    assert code == 1, err
    assert "unexpected error (please report it): RuntimeError: a bug in the streaming loop" in err
    assert "motors confirmed stopped: front, back" in err and stopped_after_last_move(emu)
    assert sum(c in MOVES for c in emu.commands()) == 2 * 11  # steps 0..10, nothing after the exception


def test_exception_in_the_streaming_loop_with_a_hung_controller_exits_3(emu: RoboClawEmulator, tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch,
                                                                         capsys: pytest.CaptureFixture[str]
                                                                         ) -> None:
    from trajopt.results.result import Result

    def broken_check(self: TrackingMonitor, t: float, step: int, measured: Any) -> None:
        if step == 10:
            emu.hang()
            raise ValueError("not a user error: raised after the ports were opened")

    monkeypatch.setattr(TrackingMonitor, "check", broken_check)
    u = smooth_u()
    res = Result(robot="tripod", task="walk", motor_names=NAMES, dt=DT, z=np.zeros(1), u=u, u_post=u,
                 target=np.zeros((0, 2)), com=np.zeros((0, 3)))
    result = str(res.save(tmp_path / "gait.npz"))
    code = cli(result, "--hardware", tripod_toml(tmp_path, emu.port, timeout=HUNG_TIMEOUT),
               "--log", str(tmp_path / "p.csv"))
    err = capsys.readouterr().err
    assert code == 3, err  # not 2 ("nothing was sent"): the motors are not confirmed stopped
    assert "NOT confirmed stopped (cut their power): front (" in err


def test_sigterm_during_the_final_stop_is_held_then_raised(emu: RoboClawEmulator,
                                                           safety_net: list[int]) -> None:
    """The trajectory ended; SIGTERM arrives at the stop's first duty 0: the stop completes, then Terminated."""
    duties = {"M1": 0}

    def sigterm_at_the_stop(frame: bytes) -> None:
        if frame[1] == P.Cmd.DUTY_M1:
            duties["M1"] += 1
            if duties["M1"] == 2:  # the first was pre-flight's
                os.kill(os.getpid(), signal.SIGTERM)

    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    with pytest.raises(Terminated) as info:
        play_trajectory(smooth_u(10, 0.002), DT, NAMES, tripod_config(), port_override=emu.port,
                        open_port=hooked_opener(after=sigterm_at_the_stop))
    assert info.value.signum == signal.SIGTERM and safety_net == []
    report = info.value.stop_report  # type: ignore[attr-defined]
    assert report.all_confirmed and report.interruptions == ("SIGTERM",) and report.signals == (signal.SIGTERM,)
    assert stopped_after_last_move(emu) and emu.commands().count(P.Cmd.DUTY_M2) == 2  # both stopped
    assert {s: signal.getsignal(s) for s in before} == before  # the previous handlers are back


def test_sighup_during_playback_becomes_terminated_after_the_stop(emu: RoboClawEmulator,
                                                                  safety_net: list[int]) -> None:
    emu.after_packets(at_step(5), lambda: os.kill(os.getpid(), signal.SIGHUP))
    with pytest.raises(Terminated, match="terminated by SIGHUP") as info:
        play_trajectory(smooth_u(), DT, NAMES, tripod_config(), port_override=emu.port)
    assert safety_net == [] and info.value.stop_report.all_confirmed  # type: ignore[attr-defined]
    assert stopped_after_last_move(emu)


def test_ignored_signal_stays_ignored(emu: RoboClawEmulator) -> None:
    """Under nohup SIGHUP is ignored: the playback must not turn it back on."""
    previous = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        emu.after_packets(at_step(5), lambda: os.kill(os.getpid(), signal.SIGHUP))
        summary = play_trajectory(smooth_u(12, 0.002), DT, NAMES, tripod_config(), port_override=emu.port)
        assert summary.steps_sent == 12 and summary.stop is not None and summary.stop.all_confirmed
        assert signal.getsignal(signal.SIGHUP) == signal.SIG_IGN
    finally:
        signal.signal(signal.SIGHUP, previous)


def test_stop_signals_raise_until_holding_then_record(safety_net: list[int]) -> None:
    guard = StopSignals()
    with guard:
        with pytest.raises(Terminated):
            signal.raise_signal(signal.SIGTERM)
        guard.holding = True
        signal.raise_signal(signal.SIGTERM)
        signal.raise_signal(signal.SIGINT)
    assert guard.held == [signal.SIGTERM, signal.SIGINT] and safety_net == []


def test_every_catchable_signal_that_would_end_the_process_is_handled() -> None:
    """Issue #40: SIGQUIT, SIGUSR1 ... end a process by default: each must run the stop sequence;
    the signals whose default is to stop, continue or ignore the process are left alone, and so
    are the faults (SIGSEGV ...) a handler cannot recover from."""
    from trajopt.hardware.signals import STOP_SIGNALS
    ending = {"SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT", "SIGUSR1", "SIGUSR2", "SIGALRM", "SIGVTALRM", "SIGPROF",
              "SIGXCPU", "SIGIO", "SIGPWR", "SIGSTKFLT"}
    names = {signal.Signals(s).name for s in STOP_SIGNALS if s in signal.Signals._value2member_map_}
    assert ending & set(dir(signal)) <= names
    assert not names & {"SIGKILL", "SIGSTOP", "SIGTSTP", "SIGCONT", "SIGCHLD", "SIGWINCH", "SIGSEGV", "SIGBUS",
                        "SIGFPE", "SIGILL", "SIGABRT"}
    if hasattr(signal, "SIGRTMIN"):
        assert {signal.SIGRTMIN, signal.SIGRTMAX} <= set(STOP_SIGNALS)


def test_stop_signals_raise_sigquit_and_sigusr1_as_terminated() -> None:
    caught: list[int] = []
    previous = {s: signal.signal(s, lambda signum, frame: caught.append(signum))
                for s in (signal.SIGQUIT, signal.SIGUSR1)}
    try:
        with StopSignals():
            for s in (signal.SIGQUIT, signal.SIGUSR1):
                with pytest.raises(Terminated) as info:
                    signal.raise_signal(s)
                assert info.value.signum == s
        assert caught == []
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
