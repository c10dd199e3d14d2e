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
errors never accumulate; after a stall of the process, e.g. Ctrl-Z, the grid is
re-timed from the late step instead of catching up in a burst, with a warning),
read every encoder back, append commanded vs
measured counts to a CSV flushed after each row and abort when a motor stays
off its target (:class:`~.monitor.TrackingMonitor`); finally -- also on any
exception, Ctrl-C (SIGINT), SIGTERM, SIGHUP, Ctrl-\\ (SIGQUIT) or any other catchable signal that
would end the process (:class:`~.signals.StopSignals`
raises them as KeyboardInterrupt / :class:`~.signals.Terminated` until the stop
begins, then holds them) -- stop both channels of every reachable controller
and confirm each stop by reading it back (:func:`~.stop.stop_motors`).  The
:class:`~.stop.StopReport` is in the summary, or attached to the exception
raised (``exc.stop_report``, and a note).  A signal held during the stop is
raised once the stop has ended (instead of a summary, or of a non-signal error,
which becomes its context).  SIGKILL cannot be caught: the controllers' own
serial timeout is the only remedy (docs/failure-modes.md).

**Assumption**: when playback starts, the robot rests at its assembly pose
(every cable just taut, ``u = 0``).  The pre-flight check resets the encoders
there, so encoder 0 means ``u = 0``.
"""


from __future__ import annotations

import dataclasses
import logging
import os
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence, TextIO

from . import protocol as P
from .config import HardwareConfig
from .driver import RoboClaw, open_serial
from .errors import PlaybackError
from .monitor import CsvLog, Progress, TrackingMonitor
from .signals import StopSignals, interruption, signal_label, signal_of
from .stop import StopReport, stop_motors
from .trajectory import TrajectoryPlan, describe_plan, iter_command_stream, plan_trajectory

log = logging.getLogger("trajopt.hardware")

#: a step this many steps late means the playback stalled (suspended, a frozen host): it is held
#: and re-timed from there instead of sending the missed steps at once
STALL_STEPS = 3.0

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
    stop: StopReport | None = None
    warnings: tuple[str, ...] = ()

    @property
    def stop_failures(self) -> tuple[str, ...]:
        """``"motor: why"`` for every channel whose stop was not confirmed (empty if all were)."""
        return () if self.stop is None else tuple(f"{c.label}: {c.detail}" for c in self.stop.unconfirmed)

    def __str__(self) -> str:
        if self.dry_run:
            return f"dry run: {self.steps_planned} steps planned, nothing sent"
        err = "n/a" if self.max_tracking_error_counts is None else f"{self.max_tracking_error_counts} counts"
        text = (f"{self.steps_sent}/{self.steps_planned} steps sent in {self.duration_s:.2f} s; "
                f"max tracking error {err}; timing drift {self.timing_drift_steps:+.3f} steps "
                f"(worst lateness {self.max_lateness_steps:.3f} steps)")
        if self.log_path:
            text += f"; log: {self.log_path}"
        if self.stop is not None:
            text += f"; {self.stop}"
        for warning in self.warnings:
            text += f"; warning: {warning}"
        return text


def _default_open(port: str, config: HardwareConfig) -> Any:
    return open_serial(port, baudrate=config.baudrate, timeout=config.timeout)


def _add_note(exc: BaseException, note: str) -> None:
    if hasattr(exc, "add_note"):  # Python >= 3.11
        exc.add_note(note)
    else:  # pragma: no cover - Python 3.10
        exc.__notes__ = [*getattr(exc, "__notes__", []), note]  # type: ignore[attr-defined]


def _wait_until(deadline: float, clock: Callable[[], float], sleep: Callable[[float], None]) -> float:
    """Sleep until ``clock() >= deadline``; return the clock reading."""
    now = clock()
    while now < deadline:
        sleep(deadline - now)
        now = clock()
    return now


def check_firmware(text: str, where: str, config: HardwareConfig) -> str | None:
    """Raise :class:`PlaybackError` for a firmware this driver does not support; a warning if allowed anyway."""
    version = P.parse_firmware_version(text)
    supported = ", ".join(f"{major}.x" for major in P.SUPPORTED_FIRMWARE_MAJOR)
    if version is None:
        raise PlaybackError(f"{where}: firmware string {text!r} is not a RoboClaw version (expected e.g. "
                            f"'USB Roboclaw 2x7a v4.1.34'); is another device on this port?")
    if version[0] in P.SUPPORTED_FIRMWARE_MAJOR:
        return None
    problem = (f"{where}: firmware {text!r} (version {'.'.join(map(str, version))}) is not one this driver "
               f"supports ({supported})")
    if not config.allow_untested_firmware:
        raise PlaybackError(f"{problem}; set settings.allow_untested_firmware = true in {config.path} to play anyway")
    return f"{problem}; playing anyway (settings.allow_untested_firmware = true)"


class _Run:
    """Ports, drivers, log and counters of one playback: everything needed to stop it and report."""

    def __init__(self, plan: TrajectoryPlan, config: HardwareConfig, clock: Callable[[], float],
                 sleep: Callable[[float], None], progress: Progress) -> None:
        self.plan, self.config, self.clock, self.sleep, self.progress = plan, config, clock, sleep, progress
        self.serials: dict[str, Any] = {}
        self.drivers: dict[tuple[str, int], RoboClaw] = {}
        self.csv: CsvLog | None = None
        self.monitor = TrackingMonitor(plan, config)
        self.firmware: dict[str, str] = {}
        self.warnings: list[str] = []
        self.steps_sent, self.late, self.max_late, self.duration = 0, 0.0, 0.0, 0.0

    def open(self, opener: OpenPort) -> None:
        for port, address in sorted({(m.port, m.address) for m in self.plan.motors}):
            if port not in self.serials:
                self.serials[port] = opener(port, self.config)
            self.drivers[(port, address)] = RoboClaw(self.serials[port], address, timeout=self.config.timeout,
                                                     retries=self.config.retries)

    def preflight(self, zero_encoders: bool) -> None:
        for (port, address), drv in self.drivers.items():
            where = f"controller {address:#04x} on {port}"
            text = self.firmware[f"{port}@{address:#04x}"] = drv.read_firmware()
            warning = check_firmware(text, where, self.config)
            if warning is not None:
                self.progress.say(f"warning: {warning}")
                self.warnings.append(warning)
            volts = drv.read_main_battery_voltage()
            if volts < self.config.min_battery_voltage:
                raise PlaybackError(f"{where}: main battery {volts:.1f} V is below min_battery_voltage = "
                                    f"{self.config.min_battery_voltage:.1f} V ({self.config.path})")
            self.progress.say(f"{where}: firmware {text!r}, battery {volts:.1f} V")
        for drv in self.drivers.values():
            drv.stop_all()  # a motor holding an old position target would jump when its encoder is reset
            if zero_encoders:
                drv.reset_encoders()

    def preroll(self, tolerance: int) -> None:
        """Move to the first sample at the configured limits and wait until every motor is there."""
        plan, target = self.plan, self.plan.counts[0]
        motor_drivers = [self.drivers[(m.port, m.address)] for m in plan.motors]
        for motor, drv, pos in zip(plan.motors, motor_drivers, target):
            accel = int(motor.max_accel)
            drv.speed_accel_decel_position(motor.channel, accel, int(motor.max_speed), accel, int(pos), buffer=False)
        budget = 2.0 * max(abs(int(p)) / m.max_speed + 2 * m.max_speed / m.max_accel
                           for m, p in zip(plan.motors, target)) + 1.0
        deadline = self.clock() + budget
        while True:
            measured = [drv.read_encoder(m.channel).count for m, drv in zip(plan.motors, motor_drivers)]
            if all(abs(c - int(p)) <= tolerance for c, p in zip(measured, target)):
                return
            if self.clock() > deadline:
                raise PlaybackError(f"pre-roll: motors did not reach the first sample {list(map(int, target))} "
                                    f"(at {measured}) within {budget:.1f} s")
            self.sleep(min(plan.dt, 0.05))

    def stream(self) -> None:
        """One move per motor per step on the grid t0 + k dt, encoders read back, log, tracking check.

        A step more than :data:`STALL_STEPS` late (the process was suspended: Ctrl-Z then ``fg``,
        a host that froze) is not followed by the missed steps in a burst: the trajectory is held
        where it stopped (the motors hold their last target meanwhile) and re-timed from the late
        step on, with a warning (also in the summary)."""
        plan = self.plan
        motor_drivers = [self.drivers[(m.port, m.address)] for m in plan.motors]
        t0 = start = self.clock()           # t0: the grid's origin (moved by a stall); start: the real one
        stalls: list[tuple[int, float]] = []
        for step in range(plan.n_steps):
            now = _wait_until(t0 + step * plan.dt, self.clock, self.sleep)
            self.late = (now - t0) / plan.dt - step
            self.max_late = max(self.max_late, self.late)
            if self.late > STALL_STEPS:                  # held: the grid moves on from here
                stalls.append((step, self.late * plan.dt))
                self.progress.say(f"warning: playback stalled {self.late * plan.dt:.2f} s before step {step} "
                                  "(suspended, or the host froze): the trajectory is held there and re-timed, "
                                  "not caught up in a burst")
                t0 = now - step * plan.dt
                self.late = 0.0
            targets = self.monitor.target(step)
            for motor, drv, pos in zip(plan.motors, motor_drivers, targets):
                accel = int(motor.max_accel)
                drv.speed_accel_decel_position(motor.channel, accel, int(motor.max_speed), accel, int(pos),
                                               buffer=False)
            measured = [drv.read_encoder(m.channel).count for m, drv in zip(plan.motors, motor_drivers)]
            self.steps_sent += 1
            if self.csv is not None:
                self.csv.row(now - start, step, targets, measured)
            self.monitor.check(now - start, step, measured)
            self.progress.step(step, now - start, self.monitor.max_error, self.late)
        _wait_until(t0 + plan.n_steps * plan.dt, self.clock, self.sleep)  # let the last step run its interval
        self.duration = self.clock() - start
        if stalls:
            held = sum(s for _, s in stalls)
            self.warnings.append(
                f"playback stalled {len(stalls)} time{'s' * (len(stalls) > 1)} ({held:.2f} s in all, first before "
                f"step {stalls[0][0]}): the trajectory was held there and re-timed (the motors held their last "
                "target), so it took that much longer than planned")

    def stop(self) -> StopReport:
        """Stop and confirm every reachable channel (never raises)."""
        names = {(m.port, m.address, m.channel): name for name, m in self.config.motors.items()}
        unreached = [f"{m.name} ({m.port} not opened)" for m in self.plan.motors if m.port not in self.serials]
        if self.drivers:
            self.progress.say("stopping the motors (duty 0, then reading each encoder back)")
        report = stop_motors(self.drivers, names, unreached=unreached)
        log.info("stop: %s", report)  # the report itself travels with the summary or the exception
        return report

    def finish(self, held: Sequence[int]) -> StopReport:
        """Stop (never raises), then close the log and the ports.

        ``held``: the signals the playback's :class:`StopSignals` held outside :func:`stop_motors`
        (while announcing the stop, while closing); they join the report's.
        """
        try:
            report = self.stop()
        finally:
            self.close()
        if held:
            report = dataclasses.replace(report, signals=report.signals + tuple(held),
                                         interruptions=report.interruptions + tuple(map(signal_label, held)))
        return report

    def close(self) -> None:
        if self.csv is not None:
            self.csv.close()
            if not self.csv.rows:  # failed before the first step: a header alone is clutter
                os.remove(self.csv.path)
        for ser in self.serials.values():
            try:
                ser.close()
            except Exception:  # noqa: BLE001 - closing a dead port must not mask the real error
                pass

    def summary(self, report: StopReport) -> PlaybackSummary:
        return PlaybackSummary(self.plan.n_steps, self.steps_sent, self.monitor.max_error, self.late, self.max_late,
                               self.duration, self.csv.path if self.csv else None, False, self.firmware, report,
                               tuple(self.warnings))


def _dry_run(plan: TrajectoryPlan, zero_encoders: bool, stream: TextIO, verbose: bool) -> PlaybackSummary:
    packets = 0
    for cmd in iter_command_stream(plan, zero_encoders):
        packets += 1
        if verbose:
            print(cmd, file=stream)
    for line in describe_plan(plan):
        print(line, file=stream)
    print(f"{packets} packets would be sent" + ("" if verbose else " (--verbose lists them)"), file=stream)
    return PlaybackSummary(plan.n_steps, 0, None, 0.0, 0.0, 0.0, None, dry_run=True)


def play_trajectory(u_post: Any, dt: float, motor_names: Sequence[str], config: HardwareConfig, *,
                    loops: int = 1, loop_start: int = 0, log_path: str | os.PathLike[str] | None = None,
                    dry_run: bool = False,
                    clock: Callable[[], float] = time.monotonic, sleep: Callable[[float], None] = time.sleep,
                    port_override: str | None = None, open_port: OpenPort | None = None,
                    out: TextIO | None = None, zero_encoders: bool = True, preroll_tolerance: int = 5,
                    verbose: bool = False, progress: TextIO | None = None) -> PlaybackSummary:
    """Stream ``u_post`` (K, n_motors) [m, step ``dt`` s] to the motors named ``motor_names``.

    Args:
        loops: play the trajectory this many times back to back (wrap-around is limit-checked).
        loop_start: with ``loops > 1``, the samples before it are played once and only the rest
            is repeated (an optimised gait: its prep phase once, its cycles ``loops`` times).
        log_path: CSV log written incrementally (kept on errors once a step was logged; an existing
            file is refused, ValueError); ``None`` = no log.
        dry_run: describe the plan on ``out`` (default stdout) instead of opening any port.
        clock, sleep: time source and sleeper of the schedule (injectable for tests).
        port_override: use this port for every motor (e.g. an emulator's pty).
        open_port: ``(port, config) -> serial-like``; default ``serial.serial_for_url``.
        zero_encoders: reset encoders in pre-flight (robot at assembly pose); False keeps the counts.
        preroll_tolerance: counts within which the pre-roll to the first sample counts as arrived.
        verbose: dry run: list every packet; playback: a progress line per step.
        progress: stream for progress lines (pre-flight, about every 10 % of the steps); ``None`` = none.

    Raises:
        ValueError: bad arguments / unknown motor; :class:`TrajectoryLimitError` (a ValueError)
            for limit violations -- both before any port is opened.
        PlaybackError: pre-flight failure (e.g. low battery, unsupported firmware);
            :class:`TrackingError` when a motor stays off its target.
        RoboClawError: communication failure.
        KeyboardInterrupt / :class:`~.signals.Terminated`: SIGINT / SIGTERM, SIGHUP, SIGQUIT ... received
            (during the playback or its stop).
        Any of these only after the stop sequence ran: its :class:`StopReport` is
        ``exc.stop_report`` (and a note on the exception).
    """
    config = config.with_port_override(port_override)
    plan = plan_trajectory(u_post, dt, motor_names, config, loops, loop_start)
    if dry_run:
        return _dry_run(plan, zero_encoders, out if out is not None else sys.stdout, verbose)
    run = _Run(plan, config, clock, sleep, Progress(progress, plan.n_steps, every=1 if verbose else None))
    if log_path is not None:  # before any port is opened
        try:
            run.csv = CsvLog(log_path, motor_names)
        except FileExistsError:
            raise ValueError(f"playback log {os.fspath(log_path)} already exists; choose another name") from None
        except OSError as exc:
            raise ValueError(f"cannot write the playback log {os.fspath(log_path)}: {exc}") from exc
    guard = StopSignals(notify=run.progress.say)
    with guard:  # SIGINT, SIGTERM, SIGHUP, SIGQUIT ...: raised (into the stop below) until the stop begins, then held
        try:
            run.open(open_port or _default_open)
            run.preflight(zero_encoders)
            if plan.needs_preroll:
                run.preroll(preroll_tolerance)
            run.stream()
        except BaseException as exc:  # includes KeyboardInterrupt and Terminated: stop first, then re-raise
            guard.holding = True  # first statement: no signal can end the stop from here on
            report = run.finish(guard.held)
            _attach(exc, report, run)
            signalled = _held_interruption(report) if signal_of(exc) is None else None
            if signalled is None:
                raise
            _add_note(signalled, f"received while stopping after {type(exc).__name__}: {exc}")
            _attach(signalled, report, run)
            raise signalled  # noqa: B904 - the error is its context: the signal came while handling it
        guard.holding = True
        report = run.finish(guard.held)
        signalled = _held_interruption(report)
        if signalled is not None:  # a signal during the final stop: the run ends as interrupted
            _attach(signalled, report, run)
            raise signalled
    return run.summary(report)


def _attach(exc: BaseException, report: StopReport, run: _Run) -> None:
    """Give ``exc`` the stop report (``exc.stop_report`` and a note) and say where the log is kept."""
    try:
        exc.stop_report = report  # type: ignore[attr-defined]
    except AttributeError:  # pragma: no cover - exception types without __dict__
        pass
    _add_note(exc, str(report))
    if run.csv is not None and run.csv.rows:
        _add_note(exc, f"playback log kept at {run.csv.path} ({run.csv.rows} steps)")


def _held_interruption(report: StopReport) -> BaseException | None:
    """The exception of the first signal held during the stop (KeyboardInterrupt / Terminated), if any."""
    return interruption(report.signals[0]) if report.signals else None
