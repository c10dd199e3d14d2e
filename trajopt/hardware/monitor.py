"""Watching a playback: the CSV log, the tracking-error abort and progress lines (no I/O on the port).

Tracking error of motor j at step k, measured right after target k was sent::

    error_k = |target_k - measured_k|
    lag_k   = |target_k - target_{k-1}| + max(v_k, v_{k-1})^2 / (2 max_accel),  v_k = |target_k - target_{k-1}| / dt

``lag_k`` is what a trapezoidal position controller explains: the step just
commanded plus the braking distance at the current speed.  When
``error_k - lag_k`` exceeds ``settings.max_tracking_error`` (metres of cable,
converted to counts per motor) for ``settings.max_tracking_error_time`` seconds,
:meth:`TrackingMonitor.check` raises :class:`~.errors.TrackingError` -- a jammed
cable, a stalled motor or a disconnected encoder -- and playback stops the motors.
"""

from __future__ import annotations

import csv
import os
from typing import Any, Sequence, TextIO

import numpy as np

from .config import HardwareConfig
from .errors import TrackingError
from .trajectory import TrajectoryPlan


class CsvLog:
    """Incremental CSV log (``time, step, <motor>_commanded, <motor>_measured, ...``), flushed per row.

    The file must not exist yet (FileExistsError).
    """

    def __init__(self, path: str | os.PathLike[str], motor_names: Sequence[str]) -> None:
        self.path = os.fspath(path)
        self._fh = open(self.path, "x", newline="", encoding="utf-8")  # never overwrites a file
        self._writer = csv.writer(self._fh)
        self.rows = 0
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
        self.rows += 1

    def close(self) -> None:
        """Close the file."""
        self._fh.close()


class TrackingMonitor:
    """Raise :class:`TrackingError` when a motor stays too far from its target for too long."""

    def __init__(self, plan: TrajectoryPlan, config: HardwareConfig) -> None:
        self.plan = plan
        self.config = config
        self.bound = np.array([abs(float(m.to_counts_float(config.max_tracking_error))) for m in plan.motors])
        self.accel = np.array([m.max_accel for m in plan.motors])
        self.max_error: int | None = None
        self._over_since: list[float | None] = [None] * len(plan.motors)

    def target(self, step: int) -> np.ndarray:
        """Encoder targets of ``step`` (before step 0: the first sample, reached by the pre-roll)."""
        return self.plan.sample(max(step, 0))

    def expected_lag(self, step: int) -> np.ndarray:
        """``lag_k`` of the module docstring, per motor [counts]."""
        move = np.abs(self.target(step) - self.target(step - 1)).astype(float)
        before = np.abs(self.target(step - 1) - self.target(step - 2)).astype(float)
        speed = np.maximum(move, before) / self.plan.dt
        return move + speed**2 / (2.0 * self.accel)

    def check(self, t: float, step: int, measured: Sequence[int]) -> None:
        """Record step ``step`` measured at time ``t`` [s]; raise if a motor has been off too long."""
        targets = self.target(step)
        error = np.abs(targets - np.asarray(measured, dtype=np.int64))
        self.max_error = max(int(error.max()), self.max_error or 0)
        lag = self.expected_lag(step)
        hold = self.config.max_tracking_error_time
        for j, motor in enumerate(self.plan.motors):
            if error[j] - lag[j] <= self.bound[j]:
                self._over_since[j] = None
                continue
            since = self._over_since[j] = t if self._over_since[j] is None else self._over_since[j]
            if t - since >= hold:  # type: ignore[operator]
                cable = abs(float(motor.to_length(int(error[j])))) * 1000
                raise TrackingError(
                    f"motor {motor.name!r} ({motor.port} {motor.address:#04x} M{motor.channel}): tracking error "
                    f"{int(error[j])} counts ({cable:.1f} mm of cable; commanded {int(targets[j])}, measured "
                    f"{int(measured[j])}) at step {step}; more than {self.bound[j]:.0f} counts "
                    f"(settings.max_tracking_error = {self.config.max_tracking_error:g} m) beyond the expected lag "
                    f"of {lag[j]:.0f} counts for {t - since:.2f} s (settings.max_tracking_error_time = {hold:g} s, "
                    f"{self.config.path}): jammed cable, stalled motor or disconnected encoder?")


class Progress:
    """Plain progress lines (no carriage returns: readable in log files), every ``every`` steps.

    A stream that fails (a terminal closed under a running playback, SIGHUP) is dropped, never
    raised: printing must not stand between a playback and its stop sequence.
    """

    def __init__(self, stream: TextIO | None, n_steps: int, every: int | None = None) -> None:
        self.stream = stream
        self.n_steps = n_steps
        self.every = every if every is not None else max(1, n_steps // 10)

    def step(self, step: int, t: float, max_error: int | None, lateness: float) -> None:
        """Print a line after step ``step`` (0-based) if it is due."""
        done = step + 1
        if self.stream is None or (done % self.every and done != self.n_steps):
            return
        err = "n/a" if max_error is None else f"{max_error} counts"
        self.say(f"step {done}/{self.n_steps} ({100 * done / self.n_steps:3.0f} %), t = {t:.2f} s, "
                 f"max tracking error {err}, lateness {lateness:+.3f} steps")

    def say(self, text: str) -> None:
        """Print one line (pre-flight, stop)."""
        if self.stream is None:
            return
        try:
            print(f"trajopt play: {text}", file=self.stream, flush=True)
        except (OSError, ValueError):  # EIO on a hung-up terminal, a closed file
            self.stream = None
