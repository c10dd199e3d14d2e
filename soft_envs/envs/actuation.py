"""The motors of an environment: actions in [-1, 1] -> commanded cable contractions, followed as
the motors can (the law: :mod:`soft_envs.sim.motors`).

``u_cmd = u_min + (a + 1) / 2 (u_max - u_min)`` per motor; in every simulation step the applied
contraction moves towards ``u_cmd`` as the motor model allows (``motor_model``):

* ``"torque-speed"`` (the default): winding at most ``v_max (1 - tau / stall_torque) * timestep``
  at the load torque ``tau`` of the state before the step, and not at all once ``tau`` reaches
  the gearbox's ``max_torque``; unwinding at most ``v_max * timestep``;
* ``"speed"``: at most ``v_max * timestep`` either way (the law of ``-v0`` and ``-v1``);
* ``"ideal"``: ``u_cmd`` at once.

``v_max = rpm * 2 pi / 60 * spool_radius`` is the no-load contraction speed; the rpm is each
motor's ``max_speed_rpm`` from the robot (``motor_speed_rpm="robot"``, the default:
:attr:`~soft_envs.sim.Robot.max_contraction_speed`), or one number for every motor (an override),
or ``None``: no speed limit (the torque limit of ``"torque-speed"`` still holds).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..sim import Robot
from ..sim.motors import TORQUE_SPEED, MotorLaw, check_motor_model, motor_step

__all__ = ["Actuation", "MOTOR_SPEED_FROM_ROBOT"]

#: the ``motor_speed_rpm`` that means "each motor's ``max_speed_rpm`` from the robot file"
MOTOR_SPEED_FROM_ROBOT = "robot"


class Actuation:
    """Action <-> contraction maps and the law of a robot's motors.

    ``lo``, ``hi``, ``range`` (M,) contraction bounds [m]; ``speed`` (M,) no-load contraction
    speed [m/s]; ``du_max`` (M,) largest change of the contraction in one simulation step [m];
    ``model`` the motor model; ``law`` the motors' :class:`~soft_envs.sim.motors.MotorLaw` (torques)."""

    def __init__(self, robot: Robot, motor_speed_rpm: float | str | None, timestep: float,
                 motor_model: str = TORQUE_SPEED):
        self.lo, self.hi = robot.u_bounds[:, 0].copy(), robot.u_bounds[:, 1].copy()
        self.range = self.hi - self.lo
        if isinstance(motor_speed_rpm, str) and motor_speed_rpm == MOTOR_SPEED_FROM_ROBOT:
            self.speed = robot.max_contraction_speed
        else:
            radius = np.array([m.spool_radius for m in robot.motors])
            rpm = math.inf if motor_speed_rpm is None else float(motor_speed_rpm)
            self.speed = rpm * 2.0 * math.pi / 60.0 * radius
        self.du_max = self.speed * timestep
        self.model = check_motor_model(motor_model)
        self.law = MotorLaw.of_robot(robot, self.speed)

    def check_action(self, action: Any) -> np.ndarray:
        """``action`` as float64 clipped to [-1, 1]; ValueError for a wrong shape, a non-numeric
        dtype (complex included: its imaginary part would be dropped), a dict, NaN or inf."""
        if isinstance(action, Mapping):
            raise ValueError(f"action must be an array of {self.lo.size} numbers in [-1, 1], one per motor, "
                             f"got a {type(action).__name__} (keys {list(action)[:5]})")
        a = np.asarray(action)
        if a.dtype.kind == "c":
            raise ValueError(f"action must be real, got complex dtype {a.dtype}: {a.tolist()}")
        if a.shape != self.lo.shape:
            raise ValueError(f"action must have shape {self.lo.shape}, got {a.shape}")
        try:
            a = a.astype(np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"action must be numeric, got dtype {a.dtype}") from None
        if not np.isfinite(a).all():
            raise ValueError(f"action contains NaN or inf: {a.tolist()}")
        return np.clip(a, -1.0, 1.0)

    def command(self, a: np.ndarray) -> np.ndarray:
        """Commanded contractions [m] of a checked action ``a``."""
        return self.lo + 0.5 * (a + 1.0) * self.range

    def to_action(self, u: Any) -> np.ndarray:
        """The action (float64, not clipped) commanding contractions ``u`` [m], (..., M)."""
        return 2.0 * (np.asarray(u, dtype=np.float64) - self.lo) / self.range - 1.0

    def torque(self, tension: np.ndarray) -> np.ndarray:
        """(M,) each motor's load torque [N m] of the tendon tensions ``tension`` (T,) [N]."""
        return self.law.torque_of_tensions(tension)

    def follow(self, u: np.ndarray, u_cmd: np.ndarray, tau: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
        """``(u_next, limited)``: the contraction one simulation step after ``u`` when the motors
        drive towards ``u_cmd`` under load torque ``tau`` [N m] (of the state before the step;
        needed by ``"torque-speed"`` only), and which motors the law held back
        (:func:`soft_envs.sim.motors.motor_step`)."""
        return motor_step(u, u_cmd, tau, self.du_max, self.law.stall_torque, self.law.max_torque, self.model)
