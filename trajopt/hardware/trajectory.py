"""Trajectory planning for playback: cable lengths -> encoder targets, limit checks, dry-run stream.

Everything here is pure (no serial port): :func:`plan_trajectory` validates a
trajectory against a :class:`~trajopt.hardware.config.HardwareConfig` and
:func:`iter_command_stream` lists, byte for byte, what playback would send.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator, Sequence

import numpy as np

from . import protocol as P
from .config import HardwareConfig, MotorConfig


class TrajectoryLimitError(ValueError):
    """The trajectory violates a motor's speed / acceleration / cable-length limit."""


@dataclass(frozen=True)
class TrajectoryPlan:
    """A validated trajectory: integer encoder targets per step and motor. Streamed: the samples
    before ``loop_start`` once (an optimised gait's prep phase, from rest), then the samples from
    ``loop_start`` on (its cycles) ``loops`` times."""

    motors: tuple[MotorConfig, ...]
    counts: np.ndarray  # (K, n_motors) int64 encoder targets (device frame, direction applied)
    dt: float
    loops: int
    loop_start: int = 0

    @property
    def n_steps(self) -> int:
        """Total number of streamed steps (``loop_start + loops * (K - loop_start)``)."""
        k = int(self.counts.shape[0])
        return self.loop_start + (k - self.loop_start) * self.loops

    def index(self, step: int) -> int:
        """The sample streamed at ``step``."""
        k = int(self.counts.shape[0])
        return step if step < k else self.loop_start + (step - self.loop_start) % (k - self.loop_start)

    def sample(self, step: int) -> np.ndarray:
        """The encoder targets streamed at ``step``."""
        return self.counts[self.index(step)]

    @property
    def needs_preroll(self) -> bool:
        """True if the first sample is not the assembly pose (counts 0)."""
        return bool(np.any(self.counts[0] != 0))


def _order(k: int, loops: int, loop_start: int) -> np.ndarray:
    """The samples streamed, as far as every transition shows: once, then (looped) the loop
    again from ``loop_start``."""
    first = np.arange(k)
    return np.concatenate([first, np.arange(loop_start, k)]) if loops > 1 else first


def _step_label(order: np.ndarray, i: int, k: int) -> str:
    """Label of the transition between the ``i``-th and ``i + 1``-th streamed samples."""
    a, b = int(order[i]), int(order[i + 1])
    return f"steps {a} -> {b}" + (" (loop wrap-around)" if i + 1 >= k else "")


def check_limits(motor: MotorConfig, u: np.ndarray, dt: float, loops: int, loop_start: int = 0) -> None:
    """Raise :class:`TrajectoryLimitError` if ``u`` (one motor's column) breaks a limit of ``motor``.

    Speeds are first differences and accelerations second differences of the
    (unrounded) encoder targets on the time grid; with ``loops > 1`` the
    wrap-around from the last sample back to sample ``loop_start`` is checked too.  The move
    from the assembly pose to the first sample is done separately (pre-roll)
    at the configured limits and is not checked here.
    """
    k = len(u)
    for i, value in enumerate(u):
        if motor.u_min is not None and value < motor.u_min or motor.u_max is not None and value > motor.u_max:
            raise TrajectoryLimitError(
                f"motor {motor.name!r}: u = {value:.6g} m at step {i} outside the bounds "
                f"[u_min, u_max] = [{motor.u_min}, {motor.u_max}] m")
    c = motor.to_counts_float(u)
    if np.any(np.abs(c) > P.INT32_MAX):
        raise TrajectoryLimitError(f"motor {motor.name!r}: encoder target beyond int32 range")
    order = _order(k, loops, loop_start)
    seq = c[order]
    vel = np.diff(seq) / dt
    if vel.size:
        i = int(np.argmax(np.abs(vel)))
        if abs(vel[i]) > motor.max_speed:
            raise TrajectoryLimitError(
                f"motor {motor.name!r}: speed {abs(vel[i]):.0f} counts/s between {_step_label(order, i, k)} "
                f"exceeds max_speed {motor.max_speed:.0f} counts/s")
    acc = np.diff(seq, 2) / dt**2
    if acc.size:
        i = int(np.argmax(np.abs(acc)))
        if abs(acc[i]) > motor.max_accel:
            raise TrajectoryLimitError(
                f"motor {motor.name!r}: acceleration {abs(acc[i]):.0f} counts/s^2 at step {int(order[i + 1])}"
                f"{' (loop wrap-around)' if i + 1 >= k - 1 and loops > 1 else ''} "
                f"exceeds max_accel {motor.max_accel:.0f} counts/s^2")


def plan_trajectory(u_post: np.ndarray, dt: float, motor_names: Sequence[str], config: HardwareConfig,
                    loops: int = 1, loop_start: int = 0) -> TrajectoryPlan:
    """Validate ``u_post`` (K, n_motors) [m] on a grid of step ``dt`` [s] and convert it to encoder
    targets; with ``loops > 1`` the samples from ``loop_start`` on are repeated (an optimised
    gait's cycles after its prep phase: ``loop_start = n_prep``)."""
    u = np.asarray(u_post, dtype=float)
    names = list(motor_names)
    if u.ndim != 2 or u.shape[0] < 1:
        raise ValueError(f"u_post must be a (K, n_motors) array with K >= 1, got shape {u.shape}")
    if u.shape[1] != len(names):
        raise ValueError(f"u_post has {u.shape[1]} columns but {len(names)} motor names were given: {names}")
    if len(set(names)) != len(names):
        raise ValueError(f"duplicate motor names: {names}")
    for name in names:
        if name not in config.motors:
            raise ValueError(f"motor {name!r} is not in the hardware config {config.path} "
                             f"(known: {', '.join(config.motors)})")
    if not np.all(np.isfinite(u)):
        raise ValueError("u_post contains NaN or infinite values")
    if not (isinstance(dt, (int, float)) and np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt = {dt!r} must be a positive number of seconds")
    loops = P.check_int("loops", loops, 1, 1_000_000)
    loop_start = P.check_int("loop_start", loop_start, 0, u.shape[0] - 1)
    motors = tuple(config.motors[n] for n in names)
    for j, motor in enumerate(motors):
        check_limits(motor, u[:, j], float(dt), loops, loop_start)
    counts = np.stack([m.to_counts(u[:, j]) for j, m in enumerate(motors)], axis=1).astype(np.int64)
    return TrajectoryPlan(motors, counts, float(dt), loops, loop_start)


# ----------------------------------------------------------------------------- dry run
def describe_plan(plan: TrajectoryPlan) -> list[str]:
    """Readable summary of a plan: duration, controllers, and per motor its range and peak speed/accel."""
    k = plan.counts.shape[0]
    controllers = sorted({(m.port, m.address) for m in plan.motors})
    shape = (f"{k} samples x {plan.loops} loop{'s' if plan.loops > 1 else ''}" if not plan.loop_start else
             f"{plan.loop_start} prep samples once, then {k - plan.loop_start} samples of cycles x {plan.loops} "
             f"loop{'s' if plan.loops > 1 else ''}")
    lines = [f"{plan.n_steps} steps ({shape}) of "
             f"{plan.dt:g} s = {plan.n_steps * plan.dt:.2f} s on "
             + ", ".join(f"{port} {address:#04x}" for port, address in controllers)]
    seq = plan.counts[_order(k, plan.loops, plan.loop_start)]
    for j, m in enumerate(plan.motors):
        counts = plan.counts[:, j]
        u = m.to_length(counts)
        speed = float(np.abs(np.diff(seq[:, j])).max(initial=0)) / plan.dt
        accel = float(np.abs(np.diff(seq[:, j], 2)).max(initial=0)) / plan.dt**2
        lines.append(f"  {m.name} ({m.address:#04x} M{m.channel}): counts {counts.min()}..{counts.max()} "
                     f"(u {u.min() * 1000:.2f}..{u.max() * 1000:.2f} mm), peak speed {speed:.0f} counts/s "
                     f"({100 * speed / m.max_speed:.0f} % of max_speed), peak accel {accel:.0f} counts/s^2 "
                     f"({100 * accel / m.max_accel:.0f} % of max_accel)")
    if plan.needs_preroll:
        lines.append("  pre-roll: every motor first moves to the first sample at its speed/accel limits")
    return lines


@dataclass(frozen=True)
class PlannedCommand:
    """One request of the command stream: when (s after start, ``None`` = not on the grid) and what."""

    time: float | None
    step: int | None
    port: str
    address: int
    description: str
    frame: bytes

    def __str__(self) -> str:
        when = "   setup  " if self.time is None else f"t={self.time:8.3f}s"
        step = "     " if self.step is None else f"{self.step:5d}"
        return f"{when} {step} {self.port} {self.address:#04x} {self.description:<58s} | {self.frame.hex(' ')}"


def move_frame(motor: MotorConfig, position: int) -> bytes:
    """Command 65/66 frame (execute immediately) toward ``position`` at the motor's configured limits."""
    accel = int(motor.max_accel)
    return P.speed_accel_decel_position_frame(motor.address, motor.channel, accel, int(motor.max_speed), accel,
                                              int(position), buffer=False)


def _move(motor: MotorConfig, position: int, time: float | None, step: int | None) -> PlannedCommand:
    desc = (f"{motor.name} M{motor.channel} move to {position} (speed {int(motor.max_speed)}, "
            f"accel {int(motor.max_accel)}, now)")
    return PlannedCommand(time, step, motor.port, motor.address, desc, move_frame(motor, position))


def iter_command_stream(plan: TrajectoryPlan, zero_encoders: bool = True) -> Iterator[PlannedCommand]:
    """Yield every request playback sends for ``plan`` (barring retries), in order."""
    controllers = sorted({(m.port, m.address) for m in plan.motors})
    for port, addr in controllers:
        yield PlannedCommand(None, None, port, addr, "read firmware", P.read_frame(addr, P.Cmd.READ_FIRMWARE))
        yield PlannedCommand(None, None, port, addr, "read main battery voltage",
                             P.read_frame(addr, P.Cmd.READ_MAIN_BATTERY))
    for port, addr in controllers:
        for ch in (1, 2):
            yield PlannedCommand(None, None, port, addr, f"M{ch} duty 0 (stop)", P.duty_frame(addr, ch, 0))
        if zero_encoders:
            yield PlannedCommand(None, None, port, addr, "reset encoders (assembly pose = 0)",
                                 P.reset_encoders_frame(addr))
    if plan.needs_preroll:
        for j, motor in enumerate(plan.motors):
            yield _move(motor, int(plan.counts[0, j]), None, None)
    for step in range(plan.n_steps):
        t = step * plan.dt
        for j, motor in enumerate(plan.motors):
            yield _move(motor, int(plan.sample(step)[j]), t, step)
        for motor in plan.motors:
            cmd = P.channel_command(P.Cmd.READ_ENCODER_M1, motor.channel)
            yield PlannedCommand(t, step, motor.port, motor.address, f"{motor.name} M{motor.channel} read encoder",
                                 P.read_frame(motor.address, cmd))
    for port, addr in controllers:
        for ch in (1, 2):
            yield PlannedCommand(None, None, port, addr, f"M{ch} duty 0 (stop)", P.duty_frame(addr, ch, 0))
