"""Where Gauss-Newton starts (:func:`choose_start`): an interrupted run resumed (its settings and
robot checked, :func:`check_resume`), given keyframes, or the best of a warm start and the seeds;
moved into the motors' speed limit (:func:`trajopt.optim.motor_limit.project_start`) and, under the
torque-speed model, into the torque-speed line (:func:`trajopt.optim.motor_torque.project_into_line`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from soft_envs.envs import RolloutStopped, SimulationError

from ..results.result import Result
from ..results.robot_match import describe_difference
from .gait import GaitSpec
from .motor_limit import gait_constraints, motor_model_of, project_start, rest_keyframes
from .motor_torque import project_into_line

__all__ = ["Start", "choose_start", "check_resume", "newton_tol_of", "RESUME_KEYS"]

#: the settings a resumed run must share with the interrupted one (besides the task)
RESUME_KEYS = ("n_prep", "n_cycle", "n_cycles", "n_keyframes", "symmetry", "interpolation", "speed_bl_per_min", "heading_deg",
               "turn", "incline_deg", "contact", "substeps", "motor_limit", "motor_model", "motor_line",
               "ensemble", "newton_tol")


def newton_tol_of(env) -> float:
    """The Newton tolerance [m] each physics step of ``env`` is solved to (recorded as a result's
    ``settings["newton_tol"]``: 1e-6 m with sub-steps, 1e-8 m at one physics step per control
    step; :func:`soft_envs.sim.substeps.newton_tolerance`)."""
    return float(env.simulator.newton.options.tol)


@dataclass
class Start:
    """Where Gauss-Newton starts: parameters ``z``, and for a resumed run its history, damping,
    next iteration number and current streak of rejected steps."""

    z: np.ndarray
    history: list[dict] = field(default_factory=list)
    lam: float | None = None
    first_iteration: int = 1
    rejections: int = 0
    #: how far the start was moved into the motors' speed limit (None: it obeyed it), see
    #: :func:`trajopt.optim.motor_limit.project_start`; with the torque-speed line, its
    #: ``"line"`` entry says how far into the line (:func:`trajopt.optim.motor_torque.project_into_line`)
    projection: dict[str, Any] | None = None


def check_resume(resume: Result, task: str, settings: dict[str, Any],
                 fingerprint: dict[str, Any] | None = None) -> None:
    """The one check that an interrupted run ``resume`` can be continued with ``settings`` on
    the robot of ``fingerprint`` (the error names ``resume.settings["source"]``, its file, when set)."""
    saved = {**resume.settings, **GaitSpec.from_settings(resume.settings).to_settings(),
             "contact": resume.settings.get("contact", "paper"),        # older results: the paper's law,
             "substeps": resume.settings.get("substeps", 1),             # one physics step per control step
             "motor_model": motor_model_of(resume.settings), "motor_line": resume.settings.get("motor_line"),
             # results made before the tolerance was recorded resume at today's
             "newton_tol": resume.settings.get("newton_tol", settings.get("newton_tol"))}
    differ = {k: (saved.get(k), settings[k]) for k in RESUME_KEYS if k in settings and saved.get(k) != settings[k]}
    source = resume.settings.get("source")
    if differ or resume.task != task:
        raise ValueError(f"{source + ': ' if source else ''}cannot resume: the settings differ from the "
                         f"interrupted run's (saved, asked): {differ or {'task': (resume.task, task)}}")
    changed = describe_difference(resume.robot_fingerprint, fingerprint) \
        if (resume.robot_fingerprint and fingerprint) else None
    if changed:
        raise ValueError(f"{source + ': ' if source else ''}cannot resume: the robot is not the interrupted "
                         f"run's ({changed}); start afresh (--overwrite)")


def _best_seed(problem: Any, seeds: list[np.ndarray]) -> np.ndarray:
    best, best_f = seeds[0], np.inf
    for z in seeds:
        try:     # a start is moved into the line after; a seed above the best so far cannot win: stopped
            r, _, _ = problem.evaluate(z, need_jac=False, check=False, bound=best_f)
        except (SimulationError, RolloutStopped):
            continue
        f = 0.5 * float(r @ r)
        if f < best_f:
            best, best_f = z, f
    return best


def _resumed(resume: Result) -> Start:
    history = list(resume.history)
    start = Start(z=np.asarray(resume.z, dtype=np.float64), history=history)
    if history:
        start.lam, start.first_iteration = history[-1].get("lambda_next"), history[-1]["iteration"] + 1
        for entry in reversed(history):        # the run of rejected steps it stopped in
            if entry.get("accepted", True):
                break
            start.rejections += 1
    return start


def choose_start(problem: Any, *, resume: Result | None = None, z0: np.ndarray | None = None,
                 warm_start: Result | None = None, n_seeds: int = 8) -> Start:
    """Continue ``resume`` (check its settings with :func:`check_resume` first), or start at
    ``z0``, or at the best objective among ``warm_start``'s keyframes and ``param.seeds(n_seeds)``
    (cheap rollouts without sensitivities; ``n_seeds=0`` with a warm start: the warm start). The
    warm start's keyframes may be fewer, repeated (:meth:`GaitParameterization.keyframes_from`).
    For a turn (a problem with target headings) the warm start with either side's motors
    played backwards (:meth:`GaitParameterization.one_side_reversed`, tank turns) are candidates
    too: the walk's strides alone hardly rotate the body, and Gauss-Newton is local."""
    param = problem.param
    if resume is not None:
        start = _resumed(resume)
    elif z0 is not None:
        start = Start(z=np.asarray(z0, dtype=np.float64))
        if start.z.shape == (param.nz,):
            start.z, start.projection = _within_limit(problem, start.z)
    else:
        candidates = []
        if warm_start is not None:
            kf = np.asarray(warm_start.settings.get("keyframes"), dtype=np.float64)
            try:
                kf = param.keyframes_from(kf)
            except ValueError as err:
                source = warm_start.settings.get("source")
                raise ValueError(f"{source + ': ' if source else ''}warm start: {err}") from None
            candidates.append(np.clip(param.z_from_keyframes(kf), *param.bounds()))
            if problem.heading is not None and not param.symmetry:      # a turn: tank turns too
                candidates += [np.clip(param.z_from_keyframes(param.one_side_reversed(kf, side)), *param.bounds())
                               for side in (0, 1)]
        n_warm = len(candidates)
        candidates += param.seeds(n_seeds) if (n_seeds > 0 or not candidates) else []
        moved = [_within_limit(problem, z) for z in candidates]       # every candidate obeys the motors
        candidates = [z for z, _ in moved]
        start = Start(z=candidates[0] if len(candidates) == 1 else _best_seed(problem, candidates))
        if n_warm:       # report the warm start's projection
            start.projection = moved[0][1]
    if start.z.shape != (param.nz,):
        raise ValueError(f"starting parameters must have shape ({param.nz},), got {start.z.shape}")
    if resume is None and problem.line is not None:          # into the torque-speed line
        start.z, line = _within_line(problem, start.z)
        if line is not None:
            start.projection = {**(start.projection or {}), "line": line}
    return start


def _within_limit(problem: Any, z: np.ndarray) -> tuple[np.ndarray, dict[str, Any] | None]:
    """``z`` projected into the motors' speed limit (and report), unchanged without one."""
    if problem.speed_limit is None:
        return z, None
    param = problem.param
    return project_start(np.clip(z, *param.bounds()), param, gait_constraints(param, problem.max_step))


def _within_line(problem: Any, z: np.ndarray) -> tuple[np.ndarray, dict[str, Any] | None]:
    """``z`` moved into the motors' torque-speed line (and report; None: it obeyed it)."""
    param = problem.param
    return project_into_line(z, problem.line, problem.rollout, gait_constraints(param, problem.max_step),
                             rest_keyframes(param))
