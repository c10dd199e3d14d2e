"""Fault injection on the hardware path: emulated controllers and a scripted device, both on ptys.

Faults are injected at a chosen packet of a playback (``RoboClawEmulator.after_packets``), Ctrl-C
as a real SIGINT or as a KeyboardInterrupt raised by a hook on the serial port.  What must hold
whatever happens: the stop is attempted on every motor, a stop is only called confirmed when it
was acknowledged by a reply matched to it and read back, and the exit code says when it was not.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import os
import re
import signal
import threading
import tty
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np
import pytest

serial = pytest.importorskip("serial")

from trajopt.hardware import protocol as P  # noqa: E402
from trajopt.cli.play import add_play_parser, run_play  # noqa: E402
from trajopt.hardware.config import EXAMPLE_TRIPOD, HardwareConfig, load_hardware_config  # noqa: E402
from trajopt.hardware.driver import WRITE_TIMEOUT, RoboClaw  # noqa: E402
from trajopt.hardware.emulator import RoboClawEmulator  # noqa: E402
from trajopt.hardware.errors import (  # noqa: E402
    PlaybackError,
    RoboClawConnectionError,
    RoboClawError,
    RoboClawTimeout,
    TrackingError,
)
from trajopt.hardware.monitor import TrackingMonitor  # noqa: E402
from trajopt.hardware.playback import play_trajectory  # noqa: E402
from trajopt.hardware.trajectory import iter_command_stream, plan_trajectory  # noqa: E402

DT = 0.033
NAMES = ["front", "back"]
MOVES = {P.Cmd.SPEED_ACCEL_DECEL_POSITION_M1, P.Cmd.SPEED_ACCEL_DECEL_POSITION_M2}
PREFLIGHT, PER_STEP = 5, 4  # firmware, battery, duty x2, reset; then 2 moves + 2 encoder reads per step


def at_step(step: int) -> int:
    """Number of the first packet of ``step`` (for ``after_packets``)."""
    return PREFLIGHT + PER_STEP * step + 1


def smooth_u(k: int = 60, amplitude: float = 0.01) -> np.ndarray:
    s = np.linspace(0.0, 1.0, k)
    return amplitude * np.stack([np.sin(np.pi * s) ** 2, 0.5 * (1 - np.cos(2 * np.pi * s))], axis=1)


#: Reply timeout [s] of the tests that are not about it: generous, so that a loaded machine cannot fail them.
REPLY_TIMEOUT = 1.0
#: Reply timeout [s] of the tests that wait out a controller that never answers (each wait costs one).
HUNG_TIMEOUT = 0.25


def tripod_config(**settings: Any) -> HardwareConfig:
    settings = {"timeout": REPLY_TIMEOUT, "retries": 2, **settings}
    return dataclasses.replace(load_hardware_config(EXAMPLE_TRIPOD), **settings)


def tripod_toml(tmp_path: Path, port: str, **settings: Any) -> str:
    """The shipped Tripod hardware file on ``port`` with some settings changed."""
    text = EXAMPLE_TRIPOD.read_text().replace("/dev/ttyACM0", port)
    for key, value in {"timeout": REPLY_TIMEOUT, "retries": 2, **settings}.items():
        line = f"{key} = {str(value).lower() if isinstance(value, bool) else value}"
        text, found = re.subn(rf"(?m)^{key} = .*$", line, text)
        if not found:
            text = text.replace("[settings]\n", f"[settings]\n{line}\n", 1)
    path = tmp_path / "hw.toml"
    path.write_text(text)
    return str(path)


def stopped_after_last_move(emu: RoboClawEmulator) -> bool:
    commands = emu.commands()
    last_move = max((i for i, c in enumerate(commands) if c in MOVES), default=-1)
    return {P.Cmd.DUTY_M1, P.Cmd.DUTY_M2} <= set(commands[last_move + 1:]) and \
        emu.snapshot().modes == ("idle", "idle")


@pytest.fixture
def emu() -> Iterator[RoboClawEmulator]:
    with RoboClawEmulator() as e:
        yield e


@pytest.fixture
def result_file(tmp_path: Path) -> str:
    """A real result file (trajopt.results is numpy-only)."""
    from trajopt.results.result import Result

    u = smooth_u()
    res = Result(robot="tripod", task="walk", motor_names=NAMES, dt=DT, z=np.zeros(1), u=u, u_post=u,
                 target=np.zeros((0, 2)), com=np.zeros((0, 3)))
    return str(res.save(tmp_path / "gait.npz"))


def cli(*argv: str) -> int:
    parser = argparse.ArgumentParser(prog="trajopt")
    add_play_parser(parser.add_subparsers(dest="command", required=True))
    return run_play(parser.parse_args(["play", *argv]))


class HookedSerial:
    """A pyserial port with hooks around each write (to raise or signal at a chosen packet)."""

    def __init__(self, ser: Any, before: Callable[[bytes], None] = lambda f: None,
                 after: Callable[[bytes], None] = lambda f: None) -> None:
        self._ser, self.before, self.after = ser, before, after

    def write(self, data: bytes) -> int | None:
        self.before(bytes(data))
        n = self._ser.write(data)
        self.after(bytes(data))
        return n

    @property
    def in_waiting(self) -> int:
        return self._ser.in_waiting

    def __getattr__(self, name: str) -> Any:
        return getattr(self._ser, name)


def hooked_opener(**hooks: Callable[[bytes], None]) -> Callable[[str, HardwareConfig], HookedSerial]:
    def open_port(port: str, config: HardwareConfig) -> HookedSerial:
        return HookedSerial(serial.Serial(port, timeout=config.timeout, write_timeout=WRITE_TIMEOUT), **hooks)
    return open_port


# --------------------------------------------------------------------------- transient faults: retried
TRANSIENT = {
    "lost request": lambda emu: emu.inject_no_reply(1),
    "lost reply": lambda emu: emu.inject_lost_reply(1),
    "late reply": lambda emu: emu.inject_late_reply(None),  # leaves with the next request: after the timeout
    "CRC error": lambda emu: emu.inject_bad_crc(1, command=P.Cmd.READ_ENCODER_M1),
    "partial reply": lambda emu: emu.inject_partial_reply(3, command=P.Cmd.READ_ENCODER_M2),
    "bad ACK": lambda emu: emu.inject_bad_ack(1),
}


@pytest.mark.parametrize("fault", list(TRANSIENT))
def test_transient_fault_is_retried_and_every_move_runs_in_order(emu: RoboClawEmulator, fault: str) -> None:
    emu.after_packets(at_step(5), lambda: TRANSIENT[fault](emu))
    u = smooth_u(16, 0.004)
    summary = play_trajectory(u, DT, NAMES, tripod_config(), port_override=emu.port)
    assert summary.steps_sent == 16 and summary.stop is not None and summary.stop.all_confirmed
    executed = [bytes((p.address, p.command)) + p.data for p in emu.received if p.command in MOVES and p.executed]
    once = [f for i, f in enumerate(executed) if i == 0 or f != executed[i - 1]]  # a retry re-runs a move
    plan = plan_trajectory(u, DT, NAMES, tripod_config().with_port_override(emu.port))
    assert once == [c.frame[:-2] for c in iter_command_stream(plan) if c.frame[1] in MOVES]
    assert emu.commands().count(P.Cmd.READ_MAIN_BATTERY) > 1  # the fault happened: a retry probed the line


# --------------------------------------------------------------------------- defect 1: the stop is reported as it was
def test_ctrl_c_with_hung_controller_says_motors_not_stopped(emu: RoboClawEmulator, tmp_path: Path,
                                                              result_file: str,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    emu.after_packets(at_step(10), lambda: (emu.hang(), os.kill(os.getpid(), signal.SIGINT)))
    code = cli(result_file, "--hardware", tripod_toml(tmp_path, emu.port, timeout=HUNG_TIMEOUT),
               "--log", str(tmp_path / "p.csv"))
    err = capsys.readouterr().err
    assert code == 3, err
    assert "interrupted" in err and "motors stopped" not in err and "confirmed stopped: " not in err
    assert "NOT confirmed stopped (cut their power): front (duty 0 not acknowledged: " in err
    assert "; back (duty 0 not acknowledged: " in err


def test_hung_controller_mid_play_is_reported_per_motor(emu: RoboClawEmulator) -> None:
    emu.after_packets(at_step(10), emu.hang)
    with pytest.raises(RoboClawTimeout) as info:
        play_trajectory(smooth_u(), DT, NAMES, tripod_config(timeout=HUNG_TIMEOUT), port_override=emu.port)
    report = info.value.stop_report  # type: ignore[attr-defined]
    assert not report.all_confirmed and [c.label for c in report.unconfirmed] == NAMES
    assert emu.snapshot().modes == ("position", "position")  # indeed not stopped: the report is true


@pytest.mark.parametrize("when", ["before", "after"])
def test_second_ctrl_c_during_the_stop_does_not_abort_it(emu: RoboClawEmulator, when: str) -> None:
    """KeyboardInterrupt raised just before / just after the stop's first duty 0 goes out.

    The first Ctrl-C comes at a chosen write of the stream (not after some sleeps: a loaded machine
    running late may not sleep at all)."""
    state = {"writes": 0, "stopping": False, "raised": 0}

    def first_ctrl_c(frame: bytes) -> None:
        state["writes"] += 1
        if state["writes"] == at_step(10):
            state["stopping"] = True
            raise KeyboardInterrupt

    def second_ctrl_c(frame: bytes) -> None:
        if state["stopping"] and frame[1] == P.Cmd.DUTY_M1 and not state["raised"]:
            state["raised"] += 1
            raise KeyboardInterrupt

    hooks: dict[str, Callable[[bytes], None]] = {"before": first_ctrl_c}
    if when == "before":
        hooks["before"] = lambda frame: (first_ctrl_c(frame), second_ctrl_c(frame))
    else:
        hooks["after"] = second_ctrl_c
    with pytest.raises(KeyboardInterrupt) as info:
        play_trajectory(smooth_u(), DT, NAMES, tripod_config(), port_override=emu.port,
                        open_port=hooked_opener(**hooks))
    assert state["raised"] == 1
    assert stopped_after_last_move(emu)
    report = info.value.stop_report  # type: ignore[attr-defined]
    assert report.all_confirmed and report.interruptions == ("Ctrl-C",)


def test_sigint_during_the_stop_is_held_until_it_ends(emu: RoboClawEmulator) -> None:
    state = {"writes": 0, "stopping": False, "signalled": 0}

    def first_ctrl_c(frame: bytes) -> None:  # at a chosen write of the stream, not after some sleeps
        state["writes"] += 1
        if state["writes"] == at_step(10):
            state["stopping"] = True
            os.kill(os.getpid(), signal.SIGINT)  # first Ctrl-C: raises KeyboardInterrupt here

    def ctrl_c(frame: bytes) -> None:
        if state["stopping"] and frame[1] in (P.Cmd.DUTY_M1, P.Cmd.DUTY_M2):
            state["signalled"] += 1
            os.kill(os.getpid(), signal.SIGINT)  # a Ctrl-C at each duty 0 of the stop

    before = signal.getsignal(signal.SIGINT)
    with pytest.raises(KeyboardInterrupt) as info:
        play_trajectory(smooth_u(), DT, NAMES, tripod_config(), port_override=emu.port,
                        open_port=hooked_opener(before=first_ctrl_c, after=ctrl_c))
    assert state["signalled"] == 2 and stopped_after_last_move(emu)
    report = info.value.stop_report  # type: ignore[attr-defined]
    assert report.all_confirmed and report.interruptions == ("Ctrl-C", "Ctrl-C")
    assert signal.getsignal(signal.SIGINT) is before


def test_one_ctrl_c_exits_130_with_motors_confirmed(emu: RoboClawEmulator, tmp_path: Path, result_file: str,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    emu.after_packets(at_step(10), lambda: os.kill(os.getpid(), signal.SIGINT))
    log = tmp_path / "p.csv"
    assert cli(result_file, "--hardware", tripod_toml(tmp_path, emu.port), "--log", str(log)) == 130
    err = capsys.readouterr().err
    assert "interrupted" in err and "motors confirmed stopped: front, back" in err and str(log) in err
    assert stopped_after_last_move(emu)


# --------------------------------------------------------------------------- a stop acknowledged is not yet confirmed
END = 16  # steps of the short playbacks below: the stop's first packet is at_step(END)


def test_stop_acknowledged_but_encoder_read_back_unanswered_is_not_confirmed(
        emu: RoboClawEmulator, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Every duty 0 of the stop is acknowledged, but M1's encoder never answers: front is not confirmed."""
    from trajopt.results.result import Result

    u = smooth_u(END, 0.004)
    result = str(Result(robot="tripod", task="walk", motor_names=NAMES, dt=DT, z=np.zeros(1), u=u, u_post=u,
                        target=np.zeros((0, 2)), com=np.zeros((0, 3))).save(tmp_path / "gait.npz"))
    emu.after_packets(at_step(END), lambda: emu.inject_no_reply(None, command=P.Cmd.READ_ENCODER_M1))
    code = cli(result, "--hardware", tripod_toml(tmp_path, emu.port, timeout=2 * HUNG_TIMEOUT),
               "--log", str(tmp_path / "p.csv"))
    err = capsys.readouterr().err
    assert code == 3, err
    assert "motors confirmed stopped: back;" in err
    assert "NOT confirmed stopped (cut their power): front (duty 0 acknowledged but the encoder could not be " \
           "read: " in err
    stop = emu.received[at_step(END) - 1:]
    assert stop[0].command == P.Cmd.DUTY_M1 and stop[0].answered  # the stop's duty 0 itself was acknowledged
    assert emu.snapshot().modes == ("idle", "idle")  # (indeed stopped: the report is conservative)


def test_motor_still_moving_after_an_acknowledged_stop_is_not_confirmed(emu: RoboClawEmulator) -> None:
    """back acknowledges every duty 0 but keeps turning: it must not be called stopped."""
    emu.after_packets(at_step(END), lambda: emu.run_away(2, 3000.0))
    summary = play_trajectory(smooth_u(END, 0.004), DT, NAMES, tripod_config(), port_override=emu.port)
    assert summary.stop is not None and not summary.stop.all_confirmed
    assert summary.stop.confirmed == ("front",)
    (back,) = summary.stop.unconfirmed
    assert back.label == "back" and back.detail.startswith("duty 0 acknowledged but the motor still moves (")
    stop = emu.received[at_step(END) - 1:]
    assert stop[0].command == P.Cmd.DUTY_M1 and all(p.answered for p in stop)  # every duty 0 acknowledged
    assert [p.command for p in stop].count(P.Cmd.DUTY_M2) == 2  # sent once more: still moving
    assert emu.snapshot().velocities[1] == 3000.0


def test_motor_still_moving_exits_3_naming_it(emu: RoboClawEmulator, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    from trajopt.results.result import Result

    u = smooth_u(END, 0.004)
    result = str(Result(robot="tripod", task="walk", motor_names=NAMES, dt=DT, z=np.zeros(1), u=u, u_post=u,
                        target=np.zeros((0, 2)), com=np.zeros((0, 3))).save(tmp_path / "gait.npz"))
    emu.after_packets(at_step(END), lambda: emu.run_away(1, -2500.0))
    code = cli(result, "--hardware", tripod_toml(tmp_path, emu.port), "--log", str(tmp_path / "p.csv"))
    err = capsys.readouterr().err
    assert code == 3, err
    assert "NOT confirmed stopped (cut their power): front (duty 0 acknowledged but the motor still moves" in err


# --------------------------------------------------------------------------- defect 2: replies matched to requests
def test_late_ack_is_not_taken_for_the_stop(emu: RoboClawEmulator, tmp_path: Path, result_file: str,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """A move's ACK arrives late; then every duty 0 to M1 is lost. The late 0xFF is no stop."""
    emu.after_packets(at_step(10), lambda: (emu.inject_late_reply(None),
                                            emu.inject_no_reply(None, command=P.Cmd.DUTY_M1)))
    code = cli(result_file, "--hardware", tripod_toml(tmp_path, emu.port, retries=0, timeout=2 * HUNG_TIMEOUT),
               "--log", str(tmp_path / "p.csv"))
    err = capsys.readouterr().err
    assert emu.snapshot().modes[0] == "position"  # M1 was really never stopped
    assert code == 3, err
    assert "motors confirmed stopped: back;" in err and "NOT confirmed stopped (cut their power): front (" in err


LATE = "late"


class ScriptedDevice:
    """A pty whose far end answers the n-th request with ``script[n]``: a delay [s] before 0xFF, ``LATE``
    (0xFF when the next request arrives: after any client timeout, whatever the load) or None (no
    answer); requests beyond the script are not answered."""

    def __init__(self, script: list[float | str | None]) -> None:
        self.script, self.requests = list(script), []
        self.master, self._slave = os.openpty()
        tty.setraw(self.master)
        tty.setraw(self._slave)
        self.port = os.ttyname(self._slave)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        import select

        buf, held = bytearray(), 0
        while not self._stop.is_set():
            if not select.select([self.master], [], [], 0.005)[0]:
                continue
            buf += os.read(self.master, 256)
            while len(buf) >= 2 and len(buf) >= 4 + P.REQUEST_DATA_LEN[buf[1]]:
                n = 4 + P.REQUEST_DATA_LEN[buf[1]]
                self.requests.append(bytes(buf[:n]))
                del buf[:n]
                for _ in range(held):
                    os.write(self.master, b"\xff")
                held = 0
                delay = self.script.pop(0) if self.script else None
                if delay == LATE:
                    held += 1
                elif delay is not None:
                    threading.Timer(delay, os.write, (self.master, b"\xff")).start()

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
        os.close(self.master)
        os.close(self._slave)


def test_late_ack_on_a_pty_does_not_acknowledge_the_next_write() -> None:
    device = ScriptedDevice([LATE])  # the first write is acknowledged after its timeout, nothing after
    try:
        with RoboClaw(device.port, 0x80, timeout=0.05, retries=0) as rc:
            with pytest.raises(RoboClawTimeout):
                rc.duty(1, 16384)
            with pytest.raises(RoboClawError):
                rc.duty(1, 0)  # the late 0xFF of the first write arrives while this one waits
        assert device.requests[-1] == P.duty_frame(0x80, 1, 0)  # the stop went out all the same
    finally:
        device.close()


# --------------------------------------------------------------------------- unplugged mid-play
def test_port_disappearing_mid_play(emu: RoboClawEmulator, tmp_path: Path, result_file: str,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    emu.disconnect_after(at_step(10))
    code = cli(result_file, "--hardware", tripod_toml(tmp_path, emu.port), "--log", str(tmp_path / "p.csv"))
    err = capsys.readouterr().err
    assert code == 3 and "RoboClawConnectionError" in err
    assert "NOT confirmed stopped (cut their power): front (" in err and "; back (" in err


def test_port_raising_mid_play(emu: RoboClawEmulator) -> None:
    """pyserial raises on every call once the USB device is gone."""
    state = {"writes": 0}

    def unplug(frame: bytes) -> None:
        state["writes"] += 1
        if state["writes"] >= at_step(10):
            raise serial.SerialException("write failed: [Errno 5] Input/output error")

    with pytest.raises(RoboClawConnectionError, match="Input/output error") as info:
        play_trajectory(smooth_u(), DT, NAMES, tripod_config(), port_override=emu.port,
                        open_port=hooked_opener(before=unplug))
    report = info.value.stop_report  # type: ignore[attr-defined]
    assert [c.label for c in report.unconfirmed] == NAMES and report.interruptions == ()


# --------------------------------------------------------------------------- defect 3: stall abort, firmware
@pytest.mark.parametrize("jam_at_step", [0, 30])
def test_stalled_encoder_aborts_and_stops(tmp_path: Path, jam_at_step: int) -> None:
    """On virtual time (shared by the playback and the emulated motors): a loaded machine that runs a
    few steps late cannot make the free motor lag and abort before the jam."""
    from tests.test_hardware_playback import VirtualTime

    time_ = VirtualTime()
    with RoboClawEmulator(clock=time_.clock) as emu:
        emu.after_packets(at_step(jam_at_step), lambda: emu.jam(1))
        log = tmp_path / "stall.csv"
        u = smooth_u(60) if jam_at_step == 0 else np.concatenate([smooth_u(30), smooth_u(30)])
        with pytest.raises(TrackingError, match=r"'front'.*tracking error \d+ counts.*jammed cable") as info:
            play_trajectory(u, DT, NAMES, tripod_config(), port_override=emu.port, log_path=log,
                            clock=time_.clock, sleep=time_.sleep)
        stopped = stopped_after_last_move(emu)
    assert stopped
    rows = list(csv.reader(log.open()))[1:]
    assert jam_at_step < len(rows) < 60  # aborted during the trajectory, not after it
    assert info.value.stop_report.all_confirmed  # type: ignore[attr-defined]


def test_stall_abort_through_the_cli(emu: RoboClawEmulator, tmp_path: Path, result_file: str,
                                     capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    emu.jam(2)
    monkeypatch.chdir(tmp_path)  # the default log goes to the working directory
    assert cli(result_file, "--hardware", tripod_toml(tmp_path, emu.port, max_tracking_error_time=0.1)) == 1
    err = capsys.readouterr().err
    assert "TrackingError: motor 'back'" in err and "max_tracking_error_time = 0.1 s" in err
    assert "motors confirmed stopped: front, back" in err
    (log,) = tmp_path.glob("play_gait_*.csv")
    assert f"log kept at {log.name}" in err


def test_tracking_abort_needs_the_error_for_the_whole_hold_time() -> None:
    cfg = tripod_config(max_tracking_error_time=0.1)
    monitor = TrackingMonitor(plan_trajectory(np.zeros((50, 2)), 0.02, NAMES, cfg), cfg)  # still: no lag expected
    over, within = [int(monitor.bound[0]) + 5, 0], [int(monitor.bound[0]), 0]
    for k in range(5):  # above the bound for 0.08 s ...
        monitor.check(0.02 * k, k, over)
    monitor.check(0.10, 5, within)  # ... back within it: the timer restarts
    for k in range(6, 11):
        monitor.check(0.02 * k, k, over)
    with pytest.raises(TrackingError, match=r"'front'.* for 0.10 s \(settings.max_tracking_error_time = 0.1 s"):
        monitor.check(0.22, 11, over)
    for k in range(12, 50):
        monitor.check(0.02 * k, k, within)  # at the bound, never


def test_fast_trajectory_near_the_limits_does_not_trip_the_abort() -> None:
    """98 % of max_speed: the error exceeds max_tracking_error, but not beyond the lag the limits explain.

    On virtual time: a loaded machine running late sends a burst of steps the motors cannot follow at
    98 % of their top speed, which is a real lag (and would rightly abort), not the one under test."""
    from tests.test_hardware_playback import VirtualTime

    cfg, time_ = tripod_config(), VirtualTime()
    cfg = dataclasses.replace(cfg, motors={name: dataclasses.replace(m, max_accel=80000.0)      # a gentle ramp:
                                           for name, m in cfg.motors.items()})              # a lag to explain
    u = 0.0155 * np.sin(np.pi * np.linspace(0, 1, 30))[:, None] ** 2 * np.ones((1, 2))
    with RoboClawEmulator(clock=time_.clock) as emu:
        summary = play_trajectory(u, DT, NAMES, cfg, port_override=emu.port, clock=time_.clock, sleep=time_.sleep)
    bound = TrackingMonitor(plan_trajectory(u, DT, NAMES, cfg), cfg).bound[0]
    assert summary.steps_sent == 30 and summary.max_tracking_error_counts > bound


@pytest.mark.parametrize("firmware, match", [
    ("USB Roboclaw 2x7a v3.1.10", r"'USB Roboclaw 2x7a v3.1.10' \(version 3.1.10\) is not one this driver "
                                  r"supports \(4.x\); set settings.allow_untested_firmware = true"),
    ("Arduino Uno", r"'Arduino Uno' is not a RoboClaw version"),
])
def test_unsupported_firmware_refused_before_motion(firmware: str, match: str) -> None:
    with RoboClawEmulator(firmware=firmware) as emu:
        with pytest.raises(PlaybackError, match=match):
            play_trajectory(smooth_u(10, 0.001), DT, NAMES, tripod_config(), port_override=emu.port)
        assert not MOVES & set(emu.commands())


def test_untested_firmware_allowed_with_a_warning() -> None:
    """On virtual time: on a loaded machine a late step adds the re-timing warning (it did in CI)."""
    from tests.test_hardware_playback import VirtualTime
    time_ = VirtualTime()
    with RoboClawEmulator(firmware="USB Roboclaw 2x7a v5.0.1", clock=time_.clock) as emu:
        summary = play_trajectory(smooth_u(10, 0.001), DT, NAMES, tripod_config(allow_untested_firmware=True),
                                  port_override=emu.port, clock=time_.clock, sleep=time_.sleep)
    assert summary.steps_sent == 10 and len(summary.warnings) == 1
    assert "version 5.0.1" in summary.warnings[0] and "warning: " in str(summary)
