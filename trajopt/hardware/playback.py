"""Play an optimised cable trajectory on RoboClaw-driven motors.

:func:`play_trajectory` is the last step of the pipeline::

    cfg = load_hardware_config("hw.toml")
    summary = play_trajectory(res.u_post, res.dt, res.motor_names, cfg, log_path="run.csv")

Sequence: validate (motor names, cable-length bounds, per-step speed and
acceleration against the configured limits -- *before* any port is opened);
open the ports; pre-flight (firmware of every controller, battery voltage,
duty 0 and encoder reset); optional pre-roll to the first sample; stream one
"move now" command (65/66, buffer flag 1, speed / accel from the config) per
motor per step on the grid ``start + k * dt`` (absolute deadlines, so sleep
errors never accumulate), read every encoder back and append commanded vs
measured counts to a CSV flushed after each row; finally -- also on any error
or Ctrl-C -- send duty 0 to both channels of every reachable controller.

**Assumption**: when playback starts, the robot rests at its assembly pose
(every cable just taut, ``u = 0``).  The pre-flight check resets the encoders
there, so encoder 0 means ``u = 0``.
"""

from __future__ import annotations

import csv
import logging
import os
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence, TextIO

import numpy as np

from .config import HardwareConfig
from .driver import RoboClaw, open_serial
from .errors import PlaybackError, RoboClawConnectionError, RoboClawError
from .trajectory import TrajectoryPlan, iter_command_stream, plan_trajectory

log = logging.getLogger("trajopt.hardware")

OpenPort = Callable[[str, HardwareConfig], Any]


@dataclass(frozen=True)
class PlaybackSummary:
    """What happened during a playback (or what would happen, for a dry run)."""

    steps_planned: int
    steps_sent: int
    max_tracking_error_counts: int | None  # max |commanded - measured| over logged steps (~1 step of lag)
    timing_drift_steps: float  # lateness of the last step w.r.t. start + k*dt, in steps
    max_lateness_steps: float  # worst lateness of any step, in steps
    duration_s: float
    log_path: str | None = None
    dry_run: bool = False
    firmware: dict[str, str] = field(default_factory=dict)
    stop_failures: tuple[str, ...] = ()

    def __str__(self) -> str:
        if self.dry_run:
            return f"dry run: {self.steps_planned} steps planned, nothing sent"
        err = "n/a" if self.max_tracking_error_counts is None else f"{self.max_tracking_error_counts} counts"
        text = (f"{self.steps_sent}/{self.steps_planned} steps sent in {self.duration_s:.2f} s; "
                f"max tracking error {err}; timing drift {self.timing_drift_steps:+.3f} steps "
                f"(worst lateness {self.max_lateness_steps:.3f} steps)")
        if self.log_path:
            text += f"; log: {self.log_path}"
        if self.stop_failures:
            text += f"; COULD NOT STOP: {'; '.join(self.stop_failures)}"
        return text


class CsvLog:
    """Incremental CSV log (``time, step, <motor>_commanded, <motor>_measured, ...``), flushed per row."""

    def __init__(self, path: str | os.PathLike[str], motor_names: Sequence[str]) -> None:
        self.path = os.fspath(path)
        self._fh = open(self.path, "w", newline="", encoding="utf-8")
        self._writer = csv.writer(self._fh)
        header = ["time", "step"]
        for name in motor_names:
            header += [f"{name}_commanded", f"{name}_measured"]
        self._write(header)

    def _write(self, row: list[Any]) -> None:
        self._writer.writerow(row)
        self._fh.flush()  # survives a crash of this process

    def row(self, t: float, step: int, commanded: Sequence[int], measured: Sequence[int]) -> None:
        """Append one step."""
        cells: list[Any] = [f"{t:.6f}", step]
        for c, m in zip(commanded, measured):
            cells += [int(c), int(m)]
        self._write(cells)

    def close(self) -> None:
        """Close the file."""
        self._fh.close()


def _default_open(port: str, config: HardwareConfig) -> Any:
    return open_serial(port, baudrate=config.baudrate, timeout=config.timeout)


def _add_note(exc: BaseException, note: str) -> None:
    if hasattr(exc, "add_note"):  # Python >= 3.11
        exc.add_note(note)


def _wait_until(deadline: float, clock: Callable[[], float], sleep: Callable[[float], None]) -> float:
    """Sleep until ``clock() >= deadline``; return the clock reading."""
    now = clock()
    while now < deadline:
        sleep(deadline - now)
        now = clock()
    return now


def stop_all_reachable(drivers: dict[tuple[str, int], RoboClaw]) -> list[str]:
    """Duty 0 on both channels of every controller; returns descriptions of those that failed.

    A port that reported a connection error is not tried again for its other controllers.
    """
    failures: list[str] = []
    dead: set[str] = set()
    for (port, address), drv in drivers.items():
        if port in dead:
            failures.append(f"{port} {address:#04x}: port unusable")
            continue
        try:
            drv.stop_all()
        except RoboClawError as exc:
            failures.append(f"{port} {address:#04x}: {exc}")
            if isinstance(exc, RoboClawConnectionError):
                dead.add(port)
    return failures


def _preflight(drivers: dict[tuple[str, int], RoboClaw], config: HardwareConfig,
               zero_encoders: bool) -> dict[str, str]:
    firmware: dict[str, str] = {}
    for (port, address), drv in drivers.items():
        firmware[f"{port}@{address:#04x}"] = drv.read_firmware()
        volts = drv.read_main_battery_voltage()
        if volts < config.min_battery_voltage:
            raise PlaybackError(f"controller {address:#04x} on {port}: main battery {volts:.1f} V is below "
                                f"min_battery_voltage = {config.min_battery_voltage:.1f} V ({config.path})")
    for drv in drivers.values():
        drv.stop_all()  # a motor holding an old position target would jump when its encoder is reset
        if zero_encoders:
            drv.reset_encoders()
    return firmware


def _preroll(plan: TrajectoryPlan, motor_drivers: list[RoboClaw], clock: Callable[[], float],
             sleep: Callable[[float], None], tolerance: int) -> None:
    """Move to the first sample at the configured limits and wait until every motor is there."""
    target = plan.counts[0]
    for motor, drv, pos in zip(plan.motors, motor_drivers, target):
        accel = int(motor.max_accel)
        drv.speed_accel_decel_position(motor.channel, accel, int(motor.max_speed), accel, int(pos), buffer=False)
    budget = max(abs(int(p)) / m.max_speed + 2 * m.max_speed / m.max_accel for m, p in zip(plan.motors, target))
    deadline = clock() + 2.0 * budget + 1.0
    while True:
        measured = [drv.read_encoder(m.channel).count for m, drv in zip(plan.motors, motor_drivers)]
        if all(abs(c - int(p)) <= tolerance for c, p in zip(measured, target)):
            return
        if clock() > deadline:
            raise PlaybackError(f"pre-roll: motors did not reach the first sample {list(map(int, target))} "
                                f"(at {measured}) within {2.0 * budget + 1.0:.1f} s")
        sleep(min(plan.dt, 0.05))


def play_trajectory(u_post: np.ndarray, dt: float, motor_names: Sequence[str], config: HardwareConfig, *,
                    loops: int = 1, log_path: str | os.PathLike[str] | None = None, dry_run: bool = False,
                    clock: Callable[[], float] = time.monotonic, sleep: Callable[[float], None] = time.sleep,
                    port_override: str | None = None, open_port: OpenPort | None = None,
                    out: TextIO | None = None, zero_encoders: bool = True,
                    preroll_tolerance: int = 5) -> PlaybackSummary:
    """Stream ``u_post`` (K, n_motors) [m, step ``dt`` s] to the motors named ``motor_names``.

    Args:
        loops: play the trajectory this many times back to back (wrap-around is limit-checked).
        log_path: CSV log written incrementally (kept on errors); ``None`` = no log.
        dry_run: print the command stream (readable + hex) to ``out`` instead of opening any port.
        clock, sleep: time source and sleeper (injectable for tests).
        port_override: use this port for every motor (e.g. an emulator's pty).
        open_port: ``(port, config) -> serial-like``; default ``serial.serial_for_url``.
        zero_encoders: reset encoders in pre-flight (robot at assembly pose); False keeps the counts.
        preroll_tolerance: counts within which the pre-roll to the first sample counts as arrived.

    Raises:
        ValueError: bad arguments / unknown motor; :class:`TrajectoryLimitError` (a ValueError)
            for limit violations -- both before any port is opened.
        PlaybackError: pre-flight failure (e.g. low battery).
        RoboClawError: communication failure (after the reachable motors were stopped).
    """
    config = config.with_port_override(port_override)
    plan = plan_trajectory(u_post, dt, motor_names, config, loops)
    if dry_run:
        stream = out if out is not None else sys.stdout
        for cmd in iter_command_stream(plan, zero_encoders):
            print(cmd, file=stream)
        return PlaybackSummary(plan.n_steps, 0, None, 0.0, 0.0, 0.0, None, dry_run=True)

    opener = open_port or _default_open
    serials: dict[str, Any] = {}
    drivers: dict[tuple[str, int], RoboClaw] = {}
    csv_log: CsvLog | None = None
    steps_sent, max_err, late, max_late, duration = 0, None, 0.0, 0.0, 0.0
    firmware: dict[str, str] = {}
    try:
        for port, address in config.controllers(list(motor_names)):
            if port not in serials:
                serials[port] = opener(port, config)
            drivers[(port, address)] = RoboClaw(serials[port], address, timeout=config.timeout,
                                                retries=config.retries)
        motor_drivers = [drivers[(m.port, m.address)] for m in plan.motors]
        firmware = _preflight(drivers, config, zero_encoders)
        if log_path is not None:
            csv_log = CsvLog(log_path, motor_names)
        if plan.needs_preroll:
            _preroll(plan, motor_drivers, clock, sleep, preroll_tolerance)
        k = plan.counts.shape[0]
        t0 = clock()
        for step in range(plan.n_steps):
            now = _wait_until(t0 + step * plan.dt, clock, sleep)
            late = (now - t0) / plan.dt - step
            max_late = max(max_late, late)
            targets = plan.counts[step % k]
            for motor, drv, pos in zip(plan.motors, motor_drivers, targets):
                accel = int(motor.max_accel)
                drv.speed_accel_decel_position(motor.channel, accel, int(motor.max_speed), accel, int(pos),
                                               buffer=False)
            measured = [drv.read_encoder(m.channel).count for m, drv in zip(plan.motors, motor_drivers)]
            steps_sent += 1
            err = int(np.max(np.abs(np.asarray(measured) - targets)))
            max_err = err if max_err is None else max(max_err, err)
            if csv_log is not None:
                csv_log.row(now - t0, step, targets, measured)
        _wait_until(t0 + plan.n_steps * plan.dt, clock, sleep)  # let the last step run its interval
        duration = clock() - t0
    except BaseException as exc:  # includes KeyboardInterrupt: stop first, then re-raise
        failures = stop_all_reachable(drivers)
        for failure in failures:
            log.error("could not stop motors: %s", failure)
        if failures:
            _add_note(exc, "could not stop: " + "; ".join(failures))
        if csv_log is not None:
            _add_note(exc, f"playback log kept at {csv_log.path} ({steps_sent} steps)")
        raise
    else:
        failures = stop_all_reachable(drivers)
        for failure in failures:
            log.error("could not stop motors: %s", failure)
    finally:
        if csv_log is not None:
            csv_log.close()
        for ser in serials.values():
            try:
                ser.close()
            except Exception:  # noqa: BLE001 - closing a dead port must not mask the real error
                pass
    return PlaybackSummary(plan.n_steps, steps_sent, max_err, late, max_late, duration,
                           csv_log.path if csv_log else None, False, firmware, tuple(failures))
