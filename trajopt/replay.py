"""From a saved :class:`~trajopt.results.Result` back to the physics: the environment it was made
on, its controls for any number of cycles, and its trajectory. Used by the ``trajopt`` commands
(evaluate, render, export, plot) and by the RL baseline alike."""
from __future__ import annotations

from typing import Any

import numpy as np

from soft_envs.envs import GradientEnv, Trajectory, make_gradient_env

from .gait import GaitSpec
from .parameterization import GaitParameterization
from .results import Result

__all__ = ["env_for_result", "result_parameterization", "result_controls", "replay"]


def env_for_result(res: Result) -> GradientEnv:
    """A bare environment with the physics ``res`` was made on: its robot (shipped name or
    robot.toml path), slope, uphill heading, contact law and simulation time step ``res.dt``
    (results made before the contact law was recorded used the paper's law)."""
    s = res.settings
    return make_gradient_env(res.robot, incline_deg=float(s.get("incline_deg", 0.0)),
                             heading_deg=float(s.get("heading_deg", 0.0)), timestep=res.dt,
                             contact=s.get("contact", "paper"))


def result_parameterization(res: Result, robot: Any) -> GaitParameterization:
    """The keyframe parameterisation of an optimised result on ``robot``."""
    return GaitParameterization.for_robot(robot, GaitSpec.from_settings(res.settings))


def result_controls(res: Result, robot: Any, n_cycles: int | None = None) -> tuple[np.ndarray, int, int]:
    """``(u, n_prep, n_cycle)``: the controls of ``res`` for ``n_cycles`` cycles after the prep
    phase (keyframe results are re-expanded; ``None``: the optimised ``res.u``) and its phase
    lengths. Results without keyframes (RL exports) play their own ``u``; without a recorded
    gait it counts as one cycle with no prep."""
    s = res.settings
    if "keyframes" in s:
        param = result_parameterization(res, robot)
        u = res.u if n_cycles is None else param.controls(param.z_from_keyframes(np.asarray(s["keyframes"])),
                                                          n_cycles)
        return u, param.n_prep, param.n_cycle
    return res.u, int(s.get("n_prep", 0)), int(s.get("n_cycle", len(res.u)))


def replay(res: Result, n_cycles: int | None = None) -> tuple[GradientEnv, np.ndarray, Trajectory]:
    """``(env, u, traj)``: ``res`` played for ``n_cycles`` cycles (default: the optimised prep +
    cycles, ``res.u``) from the rest state of :func:`env_for_result`."""
    env = env_for_result(res)
    u, _, _ = result_controls(res, env.robot, n_cycles)
    return env, u, env.rollout(u)
