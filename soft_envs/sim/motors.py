r"""The motors' law: a DC gearmotor's torque-speed line and its gearbox's torque limit.

The one home of the law; the environments (:mod:`soft_envs.envs.actuation`) step with it and
``trajopt``'s optimiser constrains gaits by it (re-exported by :mod:`soft_envs.envs`).

A motor winds its tendons (a tendon pair) on a spool of radius r: its contraction is
``u = r theta``. Its **load torque** is the spool radius times the tension of its tendons,

.. math::
    \tau_m = r_m \sum_{t \in m} T_t, \qquad T_t = Q'(\Gamma_t)

(``Q'`` the cables' one-sided quadratic, :mod:`.cables`; a slack tendon pulls nothing). A DC
gearmotor's speed falls linearly with the load torque, from the no-load speed
``omega_0`` at zero torque to zero at the stall torque ``tau_stall``; in contraction speed
``v_0 = omega_0 r`` (:attr:`.robot.Motor.max_contraction_speed`):

* while **winding** (du/dt > 0, pulling cable in against the tension):
  ``du/dt <= v_0 (1 - tau / tau_stall)``;
* at all times the **gearbox** limit ``tau <= tau_max``;
* while **unwinding** (du/dt < 0) the tension helps: ``|du/dt| <= v_0`` (the speed limit alone).
  Back-driving (a tension beyond the stall torque turning the motor backwards) is not modelled:
  a motor at or beyond its stall torque holds still.

The **normalised line excess** of a point (v, tau) of a winding motor is
``e = v / v_0 + tau / tau_stall - 1`` (<= 0 on or under the line).

Motor models (:data:`MOTOR_MODELS`), chosen by the environments' ``motor_model`` keyword and
``trajopt optimize --motor-model``: ``"torque-speed"`` (this law, the default), ``"speed"`` (the
speed limit ``|du/dt| <= v_0`` alone: the motors before the torque-speed line, which the
``-v0`` and ``-v1`` environments keep), ``"ideal"`` (no limit).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .contact.penalty import one_sided_quadratic

__all__ = ["MOTOR_MODELS", "TORQUE_SPEED", "SPEED", "IDEAL", "check_motor_model", "tendon_tensions",
           "load_torque", "winding_speed", "line_excess", "motor_step", "MotorLaw"]

TORQUE_SPEED, SPEED, IDEAL = "torque-speed", "speed", "ideal"
#: the motor models, the default first (module docstring)
MOTOR_MODELS = (TORQUE_SPEED, SPEED, IDEAL)


def check_motor_model(model: Any, where: str = "motor_model") -> str:
    """``model`` if it names a motor model, else a ValueError naming ``where``."""
    if not (isinstance(model, str) and model in MOTOR_MODELS):
        raise ValueError(f"{where} must be one of {', '.join(map(repr, MOTOR_MODELS))}, got {model!r}")
    return model


def tendon_tensions(gamma: np.ndarray, stiffness: np.ndarray, blend: float) -> tuple[np.ndarray, np.ndarray]:
    """``(T, dT/dGamma)`` (..., T) [N], [N/m]: each tendon's tension ``Q'(Gamma)`` and its
    derivative ``Q''(Gamma)`` for deformations ``gamma`` (..., T) [m] (:mod:`.cables`)."""
    _, dq, d2q = one_sided_quadratic(gamma, np.asarray(stiffness, dtype=np.float64), float(blend))
    return dq, d2q


def _motor_matrix(tendon_motor: np.ndarray, n_motors: int) -> np.ndarray:
    tm = np.asarray(tendon_motor, dtype=np.int64)
    A = np.zeros((len(tm), n_motors))
    has = tm >= 0
    A[np.flatnonzero(has), tm[has]] = 1.0
    return A


def load_torque(tension: np.ndarray, tendon_motor: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """(..., M) each motor's load torque ``tau_m = r_m sum_{t in m} T_t`` [N m] of the tendon
    tensions ``tension`` (..., T) [N]; ``tendon_motor`` (T,) the motor of each tendon (-1:
    passive), ``radius`` (M,) the spool radii [m]."""
    radius = np.asarray(radius, dtype=np.float64)
    return (np.asarray(tension, dtype=np.float64) @ _motor_matrix(tendon_motor, len(radius))) * radius


def winding_speed(tau: np.ndarray, no_load_speed: np.ndarray, stall_torque: np.ndarray) -> np.ndarray:
    """The fastest winding [m/s] at load torque ``tau``: ``v_0 max(0, 1 - tau / tau_stall)``
    (0 at and beyond the stall torque, also for an unlimited ``v_0 = inf``)."""
    share = np.maximum(1.0 - np.asarray(tau, dtype=np.float64) / np.asarray(stall_torque, dtype=np.float64), 0.0)
    v0 = np.broadcast_to(np.asarray(no_load_speed, dtype=np.float64), share.shape)
    return np.multiply(v0, share, out=np.zeros(share.shape), where=share > 0.0)


def line_excess(v: np.ndarray, tau: np.ndarray, no_load_speed: np.ndarray, stall_torque: np.ndarray
                ) -> np.ndarray:
    """The normalised line excess ``v / v_0 + tau / tau_stall - 1`` of winding at ``v`` [m/s]
    under load torque ``tau`` [N m] (<= 0: the motor can; module docstring)."""
    return (np.asarray(v, dtype=np.float64) / np.asarray(no_load_speed, dtype=np.float64)
            + np.asarray(tau, dtype=np.float64) / np.asarray(stall_torque, dtype=np.float64) - 1.0)


def motor_step(u: np.ndarray, u_cmd: np.ndarray, tau: np.ndarray, max_step: np.ndarray, stall_torque: np.ndarray,
               max_torque: np.ndarray, model: str = TORQUE_SPEED) -> tuple[np.ndarray, np.ndarray]:
    """``(u_next, limited)``: the contractions (M,) [m] a time step after ``u`` when the motors
    drive towards ``u_cmd`` under load torque ``tau`` (the state before the step) [N m], and
    which motors their law held back. ``max_step`` = ``v_0 h``: the no-load step [m].

    ``"torque-speed"``: winding moves at most ``v_0 h (1 - tau / tau_stall)``, and not at all at
    ``tau >= tau_max``; unwinding at most ``v_0 h``. ``"speed"``: at most ``v_0 h`` either way.
    ``"ideal"``: ``u_cmd``."""
    u, u_cmd = np.asarray(u, dtype=np.float64), np.asarray(u_cmd, dtype=np.float64)
    if model == IDEAL:
        return u_cmd.copy(), np.zeros(u.shape, dtype=bool)
    max_step = np.broadcast_to(np.asarray(max_step, dtype=np.float64), u.shape)
    d = u_cmd - u
    up = max_step
    if model == TORQUE_SPEED:
        tau = np.asarray(tau, dtype=np.float64)
        up = np.where(tau >= np.asarray(max_torque, dtype=np.float64), 0.0,
                      winding_speed(tau, max_step, stall_torque))
    elif model != SPEED:
        check_motor_model(model)
    limited = (d > up) | (d < -max_step)
    step = np.clip(d, -max_step, up)
    return np.where(limited, u + step, u_cmd), limited


@dataclass(frozen=True, eq=False)
class MotorLaw:
    """A robot's motors as the law needs them: per motor (M,) the spool ``radius`` [m], the
    no-load contraction speed ``no_load_speed`` ``v_0`` [m/s], ``stall_torque`` and
    ``max_torque`` [N m]; per tendon (T,) its motor ``tendon_motor`` (-1: passive) and
    ``stiffness`` [N/m]; the cables' C2 ``blend`` [m]."""

    radius: np.ndarray
    no_load_speed: np.ndarray
    stall_torque: np.ndarray
    max_torque: np.ndarray
    tendon_motor: np.ndarray
    stiffness: np.ndarray
    blend: float

    @classmethod
    def of_robot(cls, robot: Any, no_load_speed: np.ndarray | None = None) -> "MotorLaw":
        """The law of ``robot``'s motors (``no_load_speed`` [m/s] overrides the robot's
        :attr:`~.robot.Robot.max_contraction_speed`, e.g. an environment's ``motor_speed_rpm``)."""
        v0 = robot.max_contraction_speed if no_load_speed is None else no_load_speed
        return cls(radius=np.array([m.spool_radius for m in robot.motors], dtype=np.float64),
                   no_load_speed=np.asarray(v0, dtype=np.float64).copy(),
                   stall_torque=np.array([m.stall_torque for m in robot.motors], dtype=np.float64),
                   max_torque=np.array([m.max_torque for m in robot.motors], dtype=np.float64),
                   tendon_motor=np.asarray(robot.tendon_motor, dtype=np.int64).copy(),
                   stiffness=np.array([t.stiffness for t in robot.tendons], dtype=np.float64),
                   blend=float(robot.cable_blend))

    @property
    def n_motors(self) -> int:
        return len(self.radius)

    def torque_of_tensions(self, tension: np.ndarray) -> np.ndarray:
        """(..., M) load torques [N m] of tendon tensions ``tension`` (..., T) [N]."""
        return load_torque(tension, self.tendon_motor, self.radius)

    def torque(self, gamma: np.ndarray) -> np.ndarray:
        """(..., M) load torques [N m] of cable deformations ``gamma`` (..., T) [m]."""
        return load_torque(tendon_tensions(gamma, self.stiffness, self.blend)[0], self.tendon_motor, self.radius)

    def torque_jacobian(self, gamma: np.ndarray, dgammadz: np.ndarray) -> np.ndarray:
        """(..., M, nz) ``d tau / dz = r_m sum_{t in m} Q''(Gamma_t) dGamma_t/dz`` of deformations
        ``gamma`` (..., T) and their sensitivities ``dgammadz`` (..., T, nz)."""
        _, d2q = tendon_tensions(gamma, self.stiffness, self.blend)
        A = _motor_matrix(self.tendon_motor, self.n_motors) * self.radius[None, :]         # (T, M)
        return np.einsum("tm,...t,...tz->...mz", A, d2q, np.asarray(dgammadz, dtype=np.float64))
