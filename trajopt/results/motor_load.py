"""A result's motors under load, as ``trajopt play --dry-run`` reports them, without the
simulator: numpy only, so playback (:mod:`trajopt.hardware`) stays free of ``soft_envs``.

The load torque of every state of the optimised horizon is recorded when a result is made
(``evaluation["motor_load"]["torque_nm"]``, (K+1, M) [N m],
:func:`trajopt.optim.motor_torque.motor_load_entry`); results of before it are simulated when
``soft_envs`` is at hand (:func:`simulated_torque`, imported lazily). The motors' figures come
from the robot.toml the result's fingerprint records (:func:`motor_figures`: ``max_speed_rpm``,
``spool_radius``, ``stall_torque``, ``max_torque``, defaults for keys it leaves out).

For the controls as streamed (``u_post``: from rest ``u = 0`` into its first row, row to row,
and from the last row back to the first when looped) each motor's **line margin** is
``-max(e)`` over its winding steps, ``e = du / (v_0 h) + tau / tau_stall - 1`` with the torque of
the state before the step and of the state after it (the looped wrap-around: before only): a
positive margin is room under the line, a negative one a step the motor cannot make (it falls
behind). A **peak torque** beyond ``max_torque`` (more than the optimiser's tolerance, 1 %)
breaks the gearbox's limit: play refuses such a gait unless ``--force``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["MotorFigures", "motor_figures", "recorded_torque", "simulated_torque", "MotorLoadReport",
           "load_report", "TORQUE_TOLERANCE"]

#: relative excess of ``max_torque`` a played gait may show (the optimiser's tolerance)
TORQUE_TOLERANCE = 0.01
_DEFAULTS = {"max_speed_rpm": 100.0, "spool_radius": 0.005, "stall_torque": 0.39, "max_torque": 0.196}


@dataclass(frozen=True)
class MotorFigures:
    """Per motor (M,): the no-load contraction speed ``v0`` [m/s], ``stall_torque`` and
    ``max_torque`` [N m]."""

    v0: np.ndarray
    stall_torque: np.ndarray
    max_torque: np.ndarray


def motor_figures(fingerprint: dict[str, Any] | None) -> MotorFigures | None:
    """The motors of the robot.toml a fingerprint records (None when it records none)."""
    motors = (fingerprint or {}).get("toml", {}).get("motors") if isinstance(fingerprint, dict) else None
    if not isinstance(motors, list) or not motors or not all(isinstance(m, dict) for m in motors):
        return None
    try:
        get = {k: np.array([float(m.get(k, d)) for m in motors]) for k, d in _DEFAULTS.items()}
    except (TypeError, ValueError):
        return None
    return MotorFigures(get["max_speed_rpm"] * 2 * np.pi / 60 * get["spool_radius"], get["stall_torque"],
                        get["max_torque"])


def recorded_torque(res: Any) -> np.ndarray | None:
    """(K+1, M) the load torques recorded when ``res`` was made (None: none recorded)."""
    load = (getattr(res, "evaluation", None) or {}).get("motor_load")
    if not isinstance(load, dict) or "torque_nm" not in load:
        return None
    tau = np.asarray(load["torque_nm"], dtype=np.float64)
    return tau if tau.ndim == 2 and tau.shape == (len(res.u) + 1, len(res.motor_names)) else None


def simulated_torque(res: Any) -> np.ndarray:
    """(K+1, M) the load torques of ``res``'s controls, simulated (needs ``soft_envs``; an
    ImportError without it)."""
    from soft_envs.envs import MotorLaw

    from ..replay import replay
    env, _, traj = replay(res)
    return MotorLaw.of_robot(env.robot).torque(traj.cable_deformation)


@dataclass(frozen=True)
class MotorLoadReport:
    """Per motor: ``peak_torque`` [N m], ``margin`` to the line (normalised; < 0: beyond it),
    and the figures; ``over_max_torque`` (M,) bool."""

    names: list[str]
    peak_torque: np.ndarray
    margin: np.ndarray
    figures: MotorFigures

    @property
    def over_max_torque(self) -> np.ndarray:
        return self.peak_torque > self.figures.max_torque * (1 + TORQUE_TOLERANCE)

    @property
    def over_line(self) -> np.ndarray:
        return self.margin < -TORQUE_TOLERANCE

    def describe(self) -> str:
        parts = [f"{n} peak {p:.3f} N m ({100 * p / mx:.0f} % of max_torque {mx:g}), line margin {100 * g:+.1f} %"
                 for n, p, g, mx in zip(self.names, self.peak_torque, self.margin, self.figures.max_torque)]
        return "predicted load of each motor (torque-speed line, robot.toml stall_torque / max_torque): " + "; ".join(parts)


def load_report(res: Any, torque: np.ndarray, loops: int = 1) -> MotorLoadReport | None:
    """The report of ``res``'s ``u_post`` as streamed ``loops`` times (module docstring) under the
    load torques ``torque`` (K+1, M) of its states; None without recorded motors."""
    figures = motor_figures(getattr(res, "robot_fingerprint", None))
    u = np.asarray(res.u_post, dtype=np.float64)
    if figures is None or u.ndim != 2 or u.shape[1] != len(figures.v0) or torque.shape != (len(u) + 1, u.shape[1]):
        return None
    step = figures.v0 * float(res.dt)
    du = np.diff(np.vstack([np.zeros(u.shape[1]), u]), axis=0)                 # from rest, row to row
    winding = np.maximum(du, 0.0) / step
    excess = np.maximum(winding + torque[:-1] / figures.stall_torque, winding + torque[1:] / figures.stall_torque) - 1
    if loops > 1:                                                              # the wrap-around, looped
        wrap = np.maximum(u[0] - u[-1], 0.0) / step + torque[-1] / figures.stall_torque - 1
        excess = np.vstack([excess, wrap])
    return MotorLoadReport(list(res.motor_names), torque.max(axis=0), -excess.max(axis=0), figures)
