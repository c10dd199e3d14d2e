"""Trajectory playback end to end on emulated controllers (real ptys, pyserial), faults and the CLI hook."""

from __future__ import annotations

import argparse
import importlib
import csv
import dataclasses
import io
import sys
import types
from pathlib import Path
from typing import Iterator

import numpy as np
import pytest

pytest.importorskip("serial")

from trajopt.hardware import protocol as P  # noqa: E402
from trajopt.cli.play import add_play_parser, run_play  # noqa: E402
from trajopt.hardware.config import EXAMPLE_TRIPOD, HardwareConfig, load_hardware_config  # noqa: E402
from trajopt.hardware.emulator import RoboClawEmulator  # noqa: E402
from trajopt.hardware.errors import PlaybackError, RoboClawConnectionError, RoboClawTimeout  # noqa: E402
from trajopt.hardware.monitor import TrackingMonitor  # noqa: E402
from trajopt.hardware.playback import play_trajectory  # noqa: E402
from trajopt.hardware.trajectory import TrajectoryLimitError, iter_command_stream, plan_trajectory  # noqa: E402

DT = 0.033
MOTION = {P.Cmd.SPEED_ACCEL_DECEL_POSITION_M1, P.Cmd.SPEED_ACCEL_DECEL_POSITION_M2, P.Cmd.DUTY_M1, P.Cmd.DUTY_M2,
          P.Cmd.SPEED_M1, P.Cmd.SPEED_M2}
MOVES = {P.Cmd.SPEED_ACCEL_DECEL_POSITION_M1, P.Cmd.SPEED_ACCEL_DECEL_POSITION_M2}


def smooth_u(k: int = 60, amplitude: float = 0.01) -> np.ndarray:
    """(k, 2) smooth contraction from rest back to rest [m]."""
    s = np.linspace(0.0, 1.0, k)
    return amplitude * np.stack([np.sin(np.pi * s) ** 2, 0.5 * (1 - np.cos(2 * np.pi * s))], axis=1)


def tripod_config(timeout: float = 1.0, retries: int = 2, **settings: object) -> HardwareConfig:
    """The shipped Tripod file; the reply timeout is generous (a loaded machine must not fail a test)."""
    cfg = load_hardware_config(EXAMPLE_TRIPOD)
    return dataclasses.replace(cfg, timeout=timeout, retries=retries, **settings)


def stopped_after_last_move(emu: RoboClawEmulator, address: int = 0x80) -> bool:
    """Duty 0 reached both channels after the last move, and both are idle now."""
    commands = emu.commands(address)
    last_move = max((i for i, c in enumerate(commands) if c in MOVES), default=-1)
    after = set(commands[last_move + 1:])
    return {P.Cmd.DUTY_M1, P.Cmd.DUTY_M2} <= after and emu.snapshot(address).modes == ("idle", "idle")


def read_log(path: Path) -> tuple[list[str], np.ndarray]:
    rows = list(csv.reader(path.open()))
    return rows[0], np.array(rows[1:], dtype=float).reshape(-1, len(rows[0]))


@pytest.fixture
def emu() -> Iterator[RoboClawEmulator]:
    with RoboClawEmulator() as e:
        yield e


class FakeTime:
    """Deterministic clock: every reading costs 1 ms, every sleep overshoots by 40 % of a step."""

    def __init__(self, dt: float) -> None:
        self.t, self.dt, self.sleeps = 1000.0, dt, []

    def clock(self) -> float:
        self.t += 0.001
        return self.t

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.t += seconds + 0.4 * self.dt


class VirtualTime:
    """One clock for the playback and the emulated motors: time passes only when the playback sleeps,
    so the motion between two steps is exactly one ``dt`` whatever the load of the machine."""

    def __init__(self) -> None:
        self.t = 1000.0

    def clock(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.t += max(seconds, 0.0)


# --------------------------------------------------------------------------- end to end
def test_play_tripod_end_to_end(tmp_path: Path) -> None:
    cfg = tripod_config()
    u = smooth_u()
    log = tmp_path / "play.csv"
    time = VirtualTime()
    with RoboClawEmulator(clock=time.clock) as emu:
        summary = play_trajectory(u, DT, ["front", "back"], cfg, port_override=emu.port, log_path=log,
                                  clock=time.clock, sleep=time.sleep)
        check_end_to_end(emu, cfg, u, log, summary)


def check_end_to_end(emu: RoboClawEmulator, cfg: HardwareConfig, u: np.ndarray, log: Path, summary) -> None:
    assert summary.steps_sent == summary.steps_planned == 60
    assert abs(summary.timing_drift_steps) < 1e-9 and summary.duration_s == pytest.approx(60 * DT)  # virtual time
    assert summary.firmware == {f"{emu.port}@0x80": "USB Roboclaw 2x7a v4.1.34"}
    header, rows = read_log(log)
    assert header == ["time", "step", "front_commanded", "front_measured", "back_commanded", "back_measured"]
    assert rows.shape == (60, 6)
    np.testing.assert_array_equal(rows[:, 1], np.arange(60))
    commanded, measured = rows[:, 2::2], rows[:, 3::2]
    expected = np.stack([cfg.motors[n].to_counts(u[:, j]) for j, n in enumerate(["front", "back"])], axis=1)
    np.testing.assert_array_equal(commanded, expected)
    # Following a ramp of speed v with decel a, the trapezoid lags ~v^2/(2a) behind the latest target,
    # which itself is one grid step ahead; allow twice that plus a few counts.
    m = cfg.motors["front"]
    step = np.abs(np.diff(commanded, axis=0)).max()
    lag = (step / DT) ** 2 / (2 * m.max_accel)
    err = np.abs(commanded - measured)
    assert err.max() <= 2 * (step + lag) + 5
    assert summary.max_tracking_error_counts == err.max()
    assert measured[:, 0].max() > 0.8 * commanded[:, 0].max()  # the motor really moved
    # motion commands went out exactly as the dry run lists them; motors stopped at the end
    sent = [p for p in emu.received if p.command in MOVES]
    planned = [c.frame for c in iter_command_stream(plan_trajectory(u, DT, ["front", "back"],
                                                                     cfg.with_port_override(emu.port)))
               if c.frame[1] in MOVES]
    assert [bytes((0x80, p.command)) + p.data for p in sent] == [f[:-2] for f in planned]
    assert stopped_after_last_move(emu)
    assert summary.stop is not None and summary.stop.all_confirmed and summary.stop.confirmed == ("front", "back")
    assert "motors confirmed stopped: front, back" in str(summary)


def test_drift_free_schedule_with_fake_clock(emu: RoboClawEmulator) -> None:
    """Sleeps overshoot by 0.4 steps each time; deadlines are absolute, so lateness never accumulates."""
    fake = FakeTime(DT)
    cfg = tripod_config(max_tracking_error=1.0)  # fake time runs ahead of the emulated motors
    summary = play_trajectory(smooth_u(), DT, ["front", "back"], cfg, port_override=emu.port,
                              clock=fake.clock, sleep=fake.sleep)
    assert summary.steps_sent == 60
    assert 0.3 < summary.max_lateness_steps < 1.0  # a naive sleep(dt) loop would end ~24 steps late
    assert abs(summary.timing_drift_steps) < 1.0
    assert summary.duration_s == pytest.approx(60 * DT, abs=DT)


def test_preroll_and_loops(emu: RoboClawEmulator) -> None:
    u = 0.002 + smooth_u(12, 0.001)  # starts away from the assembly pose, periodic
    summary = play_trajectory(u, 0.03, ["front", "back"], tripod_config(), port_override=emu.port, loops=2)
    assert summary.steps_sent == 24
    first_target = tripod_config().motors["front"].to_counts(u[0, 0])
    moves = [p for p in emu.received if p.command == P.Cmd.SPEED_ACCEL_DECEL_POSITION_M1]
    assert moves[0].data[12:16] == first_target.to_bytes(4, "big", signed=True)  # pre-roll move
    assert len(moves) == 1 + 24


def test_dry_run_verbose_prints_stream_without_port() -> None:
    out = io.StringIO()
    cfg = tripod_config()  # port /dev/ttyACM0 does not exist here: nothing may be opened
    summary = play_trajectory(smooth_u(5, 0.0002), DT, ["front", "back"], cfg, dry_run=True, out=out, verbose=True)
    lines = out.getvalue().strip().splitlines()
    assert summary.dry_run and summary.steps_sent == 0 and summary.steps_planned == 5
    packets = [line for line in lines if " | " in line]
    assert "read firmware" in packets[0] and packets[0].endswith("80 15 59 0c")
    assert any("front M1 move to" in line and "| 80 41" in line for line in packets)
    assert packets[-1].endswith("80 21 00 00 6c ce")  # final stop of M2
    assert len(packets) == 5 + 5 * 4 + 2
    assert lines[-1] == "27 packets would be sent"


def test_dry_run_prints_a_summary_not_packets() -> None:
    out = io.StringIO()
    play_trajectory(smooth_u(600, 0.01), DT / 2, ["front", "back"], tripod_config(), dry_run=True, out=out)
    lines = out.getvalue().strip().splitlines()
    assert len(lines) == 4 and not any(" | " in line for line in lines)
    assert lines[0] == "600 steps (600 samples x 1 loop) of 0.0165 s = 9.90 s on /dev/ttyACM0 0x80"
    assert lines[1].startswith("  front (0x80 M1): counts 0..1138 (u 0.00..10.00 mm), peak speed ")
    assert lines[-1] == "2407 packets would be sent (--verbose lists them)"


# --------------------------------------------------------------------------- refusals
def test_speed_limit_refused_before_any_command(emu: RoboClawEmulator) -> None:
    u = smooth_u()
    u[30, 1] -= 0.008  # an 8 mm drop within one step: ~ 28 000 counts/s
    with pytest.raises(TrajectoryLimitError, match=r"'back'.*speed \d+ counts/s between steps (29 -> 30|30 -> 31)"):
        play_trajectory(u, DT, ["front", "back"], tripod_config(), port_override=emu.port)
    assert emu.received == []


def test_accel_limit_and_bounds_refused(emu: RoboClawEmulator) -> None:
    u = smooth_u()
    zigzag = np.zeros((10, 2))
    zigzag[1::2, 0] = 0.0005  # 57 counts up and down every 10 ms: within max_speed (~5700 counts/s), but
    # ~1 100 000 counts/s^2 (at 0.033 s steps no trajectory within max_speed exceeds the example's max_accel)
    with pytest.raises(TrajectoryLimitError, match=r"'front'.*acceleration \d+ counts/s\^2 at step 1 exceeds"):
        play_trajectory(zigzag, 0.010, ["front", "back"], tripod_config(), port_override=emu.port)
    with pytest.raises(TrajectoryLimitError, match=r"'front'.*u = 0.05 m at step 3 outside"):
        bad = np.zeros((6, 2))
        bad[3:, 0] = 0.05
        play_trajectory(bad, 100.0, ["front", "back"], tripod_config(), port_override=emu.port)
    with pytest.raises(TrajectoryLimitError, match="loop wrap-around"):
        play_trajectory(np.linspace(0, 0.01, 60)[:, None].repeat(2, 1), DT, ["front", "back"], tripod_config(),
                        port_override=emu.port, loops=2)
    with pytest.raises(ValueError, match="'middle'"):
        play_trajectory(u, DT, ["front", "middle"], tripod_config(), port_override=emu.port)
    assert emu.received == []


def test_existing_or_unwritable_log_refused_before_any_port(emu: RoboClawEmulator, tmp_path: Path) -> None:
    log = tmp_path / "earlier_run.csv"
    log.write_text("keep me")
    with pytest.raises(ValueError, match="earlier_run.csv already exists"):
        play_trajectory(smooth_u(), DT, ["front", "back"], tripod_config(), port_override=emu.port, log_path=log)
    with pytest.raises(ValueError, match="cannot write the playback log .*missing"):
        play_trajectory(smooth_u(), DT, ["front", "back"], tripod_config(), port_override=emu.port,
                        log_path=tmp_path / "missing" / "run.csv")
    assert log.read_text() == "keep me" and emu.received == []


def test_low_battery_refused_before_motion(emu: RoboClawEmulator, tmp_path: Path) -> None:
    emu.set_battery_voltage(9.8)
    log = tmp_path / "never.csv"
    with pytest.raises(PlaybackError, match=r"9\.8 V is below min_battery_voltage = 10\.5") as info:
        play_trajectory(smooth_u(), DT, ["front", "back"], tripod_config(), port_override=emu.port, log_path=log)
    assert not MOVES & set(emu.commands())
    assert not log.exists()  # no step was played: no log left behind
    assert info.value.stop_report.confirmed == ("front", "back")  # type: ignore[attr-defined]


def test_port_that_cannot_be_opened(tmp_path: Path) -> None:
    with RoboClawEmulator() as emu_a:
        cfg = load_hardware_config(two_port_config(tmp_path, emu_a.port, "/dev/zz-does-not-exist"))
        with pytest.raises(RoboClawConnectionError, match="zz-does-not-exist") as info:
            play_trajectory(smooth_u(), DT, ["front", "back"], cfg)
        report = info.value.stop_report  # type: ignore[attr-defined]
        assert report.confirmed == ("front", f"{emu_a.port} 0x80 M2 (unused)") and report.all_confirmed
        assert report.unreached == ("back (/dev/zz-does-not-exist not opened)",)
        assert not MOVES & set(emu_a.commands())


# --------------------------------------------------------------------------- faults mid-playback
def two_port_config(tmp_path: Path, port_a: str, port_b: str) -> Path:
    path = tmp_path / "two_ports.toml"
    motor = ("[motors.{name}]\nport = \"{port}\"\naddress = 0x80\nchannel = 1\nspool_radius = 0.005\n"
             "max_speed = 4500\nmax_accel = 30000\n")
    path.write_text("[settings]\ntimeout = 1.0\nretries = 1\nmin_battery_voltage = 10.5\n"
                    + motor.format(name="front", port=port_a) + motor.format(name="back", port=port_b))
    return path


def test_disconnect_mid_playback_stops_reachable_motors(tmp_path: Path) -> None:
    with RoboClawEmulator() as emu_a, RoboClawEmulator() as emu_b:
        cfg = load_hardware_config(two_port_config(tmp_path, emu_a.port, emu_b.port))
        # pre-flight: firmware, battery, duty 0 x2, reset = 5 packets; then 2 per step -> dies at step 10
        emu_a.disconnect_after(5 + 2 * 10 + 1)
        log = tmp_path / "crash.csv"
        with pytest.raises(RoboClawConnectionError) as info:
            play_trajectory(smooth_u(), DT, ["front", "back"], cfg, log_path=log)
        assert info.value.address == 0x80
        assert any("log kept" in note for note in getattr(info.value, "__notes__", []))
        assert not emu_a.connected
        assert stopped_after_last_move(emu_b)
        report = info.value.stop_report  # type: ignore[attr-defined]
        assert report.confirmed == ("back", f"{emu_b.port} 0x80 M2 (unused)")
        assert [c.label for c in report.unconfirmed] == ["front", f"{emu_a.port} 0x80 M2 (unused)"]
        assert "duty 0 not acknowledged" in report.unconfirmed[0].detail
        header, rows = read_log(log)
        assert len(header) == 6 and rows.shape == (10, 6)


def test_keyboard_interrupt_stops_motors(emu: RoboClawEmulator, monkeypatch: pytest.MonkeyPatch) -> None:
    check = TrackingMonitor.check

    def ctrl_c_at_step_5(self: TrackingMonitor, t: float, step: int, measured: object) -> None:
        check(self, t, step, measured)  # type: ignore[arg-type]
        if step == 5:  # at a step, not after some sleeps: a loaded machine running late may not sleep
            raise KeyboardInterrupt

    monkeypatch.setattr(TrackingMonitor, "check", ctrl_c_at_step_5)
    with pytest.raises(KeyboardInterrupt) as info:
        play_trajectory(smooth_u(), DT, ["front", "back"], tripod_config(), port_override=emu.port)
    assert stopped_after_last_move(emu)
    assert info.value.stop_report.all_confirmed  # type: ignore[attr-defined]


def test_unresponsive_controller_raises_timeout(emu: RoboClawEmulator) -> None:
    emu.hang()
    with pytest.raises(RoboClawTimeout, match="READ_FIRMWARE.*no complete reply.*after 2 attempts") as info:
        play_trajectory(smooth_u(), DT, ["front", "back"], tripod_config(timeout=0.1, retries=1),
                        port_override=emu.port)
    # firmware read, a probe of the line (failed: the read is not re-sent), then the stop on the way out
    assert emu.commands()[:3] == [P.Cmd.READ_FIRMWARE, P.Cmd.READ_MAIN_BATTERY, P.Cmd.READ_ENCODER_M1]
    assert {P.Cmd.DUTY_M1, P.Cmd.DUTY_M2} <= set(emu.commands())
    assert not MOVES & set(emu.commands())
    report = info.value.stop_report  # type: ignore[attr-defined]
    assert report.confirmed == () and [c.label for c in report.unconfirmed] == ["front", "back"]


# --------------------------------------------------------------------------- CLI hook
@pytest.fixture
def fake_results(monkeypatch: pytest.MonkeyPatch) -> dict[str, object]:
    """Stand-in for ``trajopt.results`` (written separately): Result.load returns a prepared object."""
    store: dict[str, object] = {}

    class Result:
        @staticmethod
        def load(path: str) -> object:
            if path not in store:
                raise FileNotFoundError(path)
            return store[path]

    module = types.ModuleType("trajopt.results")
    module.Result = Result  # type: ignore[attr-defined]
    module.__path__ = list(importlib.import_module("trajopt.results").__path__)   # its other modules stay real
    monkeypatch.setitem(sys.modules, "trajopt.results", module)
    store["res.npz"] = types.SimpleNamespace(u_post=smooth_u(), dt=DT, motor_names=["front", "back"])
    return store


def parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="trajopt")
    add_play_parser(parser.add_subparsers(dest="command", required=True))
    return parser.parse_args(argv)


def test_cli_parser() -> None:
    args = parse(["play", "r.npz", "--hardware", "hw.toml", "--dry-run", "--loops", "3", "--log", "x.csv",
                  "--port-override", "loop://"])
    assert (args.result, args.hardware, args.dry_run, args.loops, args.log, args.port_override) == \
        ("r.npz", "hw.toml", True, 3, "x.csv", "loop://")
    assert args.func is run_play
    with pytest.raises(SystemExit):
        parse(["play", "r.npz", "--hardware", "hw.toml", "--loops", "0"])


def test_cli_plays_and_dry_runs(fake_results: dict, emu: RoboClawEmulator, tmp_path: Path,
                                capsys: pytest.CaptureFixture[str]) -> None:
    args = parse(["play", "res.npz", "--hardware", str(EXAMPLE_TRIPOD), "--dry-run"])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert "move to" not in out and out.strip().splitlines()[-1] == "dry run: 60 steps planned, nothing sent"
    args = parse(["play", "res.npz", "--hardware", str(EXAMPLE_TRIPOD), "--dry-run", "--verbose"])
    assert args.func(args) == 0
    assert "move to" in capsys.readouterr().out
    fake_results["short.npz"] = types.SimpleNamespace(u_post=smooth_u(10, 0.0005), dt=0.03,
                                                      motor_names=["front", "back"])
    log = tmp_path / "ok.csv"
    hardware = tmp_path / "hw.toml"  # the shipped file with a generous reply timeout (a loaded machine)
    hardware.write_text(EXAMPLE_TRIPOD.read_text().replace("\ntimeout = 0.1\n", "\ntimeout = 1.0\n"))
    args = parse(["play", "short.npz", "--hardware", str(hardware), "--port-override", emu.port,
                  "--log", str(log)])
    assert args.func(args) == 0
    captured = capsys.readouterr()
    assert "10/10 steps sent" in captured.out and "motors confirmed stopped: front, back" in captured.out
    progress = [line for line in captured.err.splitlines() if " step " in line]
    assert progress[-1].startswith("trajopt play: step 10/10 (100 %)") and "\r" not in captured.err
    assert len(log.read_text().splitlines()) == 11


def test_cli_hardware_error_exits_nonzero_and_keeps_log(fake_results: dict, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    with RoboClawEmulator() as emu_a, RoboClawEmulator() as emu_b:
        hw = two_port_config(tmp_path, emu_a.port, emu_b.port)
        emu_a.disconnect_after(5 + 2 * 5 + 1)
        log = tmp_path / "cli.csv"
        args = parse(["play", "res.npz", "--hardware", str(hw), "--log", str(log)])
        assert args.func(args) == 3  # port A vanished: its motor's stop cannot be confirmed
        assert stopped_after_last_move(emu_b)
    err = capsys.readouterr().err
    assert "hardware error" in err and "RoboClawConnectionError" in err and str(log) in err
    assert "motors confirmed stopped: back" in err and "NOT confirmed stopped (cut their power): front" in err
    assert len(log.read_text().splitlines()) == 1 + 5


def test_cli_input_errors(fake_results: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[motors.left]\nport = 1\n")
    assert run_play(parse(["play", "res.npz", "--hardware", str(bad)])) == 2
    assert str(bad) in capsys.readouterr().err
    assert run_play(parse(["play", "missing.npz", "--hardware", str(EXAMPLE_TRIPOD)])) == 2
    fake_results["fast.npz"] = types.SimpleNamespace(u_post=smooth_u(), dt=DT / 10, motor_names=["front", "back"])
    assert run_play(parse(["play", "fast.npz", "--hardware", str(EXAMPLE_TRIPOD), "--dry-run"])) == 2
    assert "exceeds" in capsys.readouterr().err


# --------------------------------------------------------------------------- issue #40
def test_loops_repeat_the_cycles_not_the_prep() -> None:
    """``--loops N`` of an optimised gait: the prep phase once (from rest), then its cycles N
    times; the wrap-around checked is the cycle's, not the jump back to the prep's start."""
    prep = 0.004 * np.linspace(0.0, 1.0, 8)[:, None] * np.ones((1, 2))          # from rest up to the cycle
    s = np.arange(24) / 12.0
    cycles = 0.004 + 0.002 * np.stack([np.sin(2 * np.pi * s), np.cos(2 * np.pi * s) - 1], axis=1)
    u = np.vstack([prep, cycles])
    with pytest.raises(TrajectoryLimitError, match="loop wrap-around"):    # the whole, looped: a jump to rest
        plan_trajectory(u, DT, ["front", "back"], tripod_config(), loops=3)
    plan = plan_trajectory(u, DT, ["front", "back"], tripod_config(), loops=3, loop_start=8)
    assert plan.n_steps == 8 + 3 * 24
    cfg = tripod_config()
    expected = [cfg.motors["front"].to_counts(v) for v in np.concatenate([u[:, 0], np.tile(u[8:, 0], 2)])]
    assert [int(plan.sample(k)[0]) for k in range(plan.n_steps)] == expected
    time = VirtualTime()
    with RoboClawEmulator(clock=time.clock) as emu:
        summary = play_trajectory(u, DT, ["front", "back"], cfg, port_override=emu.port, loops=3, loop_start=8,
                                  clock=time.clock, sleep=time.sleep)
    assert summary.steps_sent == 8 + 3 * 24


class SuspendedTime(VirtualTime):
    """Virtual time, and a stall of ``seconds`` (Ctrl-Z then fg, a host that froze) before step ``at``."""

    def __init__(self, at_sleep: int, seconds: float) -> None:
        super().__init__()
        self.calls, self.at, self.stall = 0, at_sleep, seconds

    def sleep(self, seconds: float) -> None:
        super().sleep(seconds)
        self.calls += 1
        if self.calls == self.at:
            self.t += self.stall


def test_a_stall_holds_the_trajectory_instead_of_a_burst(tmp_path: Path) -> None:
    """Issue #40: after a suspension the missed steps went out at once (a 17 mm jump of
    targets) and the playback exited 0 silently. The trajectory is held where it stopped and
    re-timed from there; the summary says so."""
    cfg = tripod_config()
    u = smooth_u()
    time = SuspendedTime(at_sleep=20, seconds=1.0)
    log = tmp_path / "p.csv"
    with RoboClawEmulator(clock=time.clock) as emu:
        summary = play_trajectory(u, DT, ["front", "back"], cfg, port_override=emu.port, log_path=log,
                                  clock=time.clock, sleep=time.sleep)
    assert summary.steps_sent == 60
    _, rows = read_log(log)
    gaps = np.diff(rows[:, 0])
    assert gaps.max() > 0.9 and np.sort(gaps)[-2] < 2 * DT       # one hold, then a step per dt again
    assert any("stalled" in w and "held" in w for w in summary.warnings), summary.warnings
    assert "warning: playback stalled" in str(summary)
