"""From a saved :class:`~trajopt.results.Result` back to the physics: the environment it was made
on, its controls for any number of cycles, and its trajectory. Used by the ``trajopt`` commands
(evaluate, render, export, plot) and by the RL baseline alike.

The environment is only built for the robot the result was made for: :func:`env_for_result`
checks the result's robot fingerprint and motors (:func:`trajopt.results.robot_match.check_robot`) and
refuses another or an edited robot unless ``ignore_robot_mismatch`` (then it warns,
:class:`RobotMismatchWarning`).
"""
from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from soft_envs.envs import GradientEnv, Trajectory, load_robot, make_gradient_env

from .optim.gait import GaitSpec
from .optim.parameterization import GaitParameterization
from .results.result import Result
from .results.robot_match import check_robot, fingerprint_of, locate_robot

__all__ = ["env_for_result", "result_task_keywords", "result_ground", "result_box", "result_substeps", "result_parameterization", "result_controls", "replay",
           "RobotMismatchWarning"]


class RobotMismatchWarning(UserWarning):
    """A result is used on a robot other than its own (``ignore_robot_mismatch=True``)."""


def env_for_result(res: Result, *, ignore_robot_mismatch: bool = False, substeps: int | None = None) -> GradientEnv:
    """A bare environment with the physics ``res`` was made on: its robot (shipped name or
    robot.toml path), slope, uphill heading, contact law (results made before it was recorded
    used the paper's law), control step ``res.dt`` and physics sub-steps (results made before
    they were recorded used one; ``substeps`` replays with others, e.g. finer steps). A robot that
    is not the one ``res`` was made for raises :class:`~trajopt.results.robot_match.RobotMismatchError`
    (a ValueError), or warns with ``ignore_robot_mismatch``."""
    s = res.settings
    robot = load_robot(locate_robot(res))
    note = check_robot(res, fingerprint_of(robot), list(robot.motor_names),      # before the task's box is added
                       src=res.path or "the result", ignore=ignore_robot_mismatch)
    where = result_task_keywords(res, robot)
    env = make_gradient_env(robot, incline_deg=float(s.get("incline_deg", 0.0)),
                            heading_deg=float(s.get("heading_deg", 0.0)), timestep=res.dt,
                            contact=s.get("contact", "paper"),
                            substeps=result_substeps(res) if substeps is None else substeps,
                            ground=where.get("ground"), box=where.get("box"))
    if note is not None:
        warnings.warn(note, RobotMismatchWarning, stacklevel=2)
    return env


def result_task_keywords(res: Result, robot: Any) -> dict[str, Any]:
    """The keywords that put ``robot`` where a benchmark task's gait was optimised
    (``settings["env_task"]`` at its ``difficulty``: :func:`soft_envs.envs.tasks.task_keywords`,
    its ``ground`` or ``box``), ``{}`` for a gait of no benchmark task."""
    s = res.settings
    if not s.get("env_task"):
        return {}
    from soft_envs.envs.tasks import DEFAULT_DIFFICULTY, task_keywords
    return task_keywords(s["env_task"], robot, s.get("difficulty") or DEFAULT_DIFFICULTY)


def result_ground(res: Result, robot: Any):
    """The ground a benchmark task's gait was optimised on (``settings["env_task"]`` at its
    ``difficulty``: :meth:`trajopt.tasks.Task.environment`), or None (the robot file's)."""
    return result_task_keywords(res, robot).get("ground")


def result_box(res: Result, robot: Any):
    """The box a benchmark task's gait was optimised with (carry a payload, push a box: its
    ``settings["env_task"]`` at its ``difficulty``), or None."""
    return result_task_keywords(res, robot).get("box")


def result_substeps(res: Result) -> int:
    """The physics steps per control step ``res`` was made with (``settings["substeps"]``; 1 for
    results made before sub-steps, which all used one)."""
    return int(res.settings.get("substeps", 1))


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


def replay(res: Result, n_cycles: int | None = None, *,
           ignore_robot_mismatch: bool = False) -> tuple[GradientEnv, np.ndarray, Trajectory]:
    """``(env, u, traj)``: ``res`` played for ``n_cycles`` cycles (default: the optimised prep +
    cycles, ``res.u``) from the rest state of :func:`env_for_result`."""
    env = env_for_result(res, ignore_robot_mismatch=ignore_robot_mismatch)
    u, _, _ = result_controls(res, env.robot, n_cycles)
    return env, u, env.rollout(u)
