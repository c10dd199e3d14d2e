"""``optimize_gait``: forward shooting with sensitivity analysis and Gauss-Newton (paper III).

>>> import gymnasium as gym, soft_envs
>>> from trajopt import optimize_gait
>>> result = optimize_gait(gym.make("SoftTripod-v2"), task="walk")
>>> result.save("tripod_walk.npz")

Tasks (:data:`trajopt.tasks.TASKS`): ``"walk"`` (straight line at ``speed_bl_per_min`` along
``heading_deg``), ``"turn"`` (quarter circle to the ``turn`` side; paper: symmetry off,
warm-started from a walk), ``"incline"`` (a walk on an environment whose gravity is rotated;
the same objective), or a custom ``target`` array (K+1, 2). Each task gives its target, heading
term, gait shape, weights and default contact law (:class:`trajopt.tasks.Task`).

The steps, in order: :func:`build_problem` (parameterisation, target path, objective),
:func:`choose_start` (resume, given z0, or the best of the warm start and the seeds),
:func:`gauss_newton` (the solve, recorded by :class:`Recorder`), :func:`finish` (zero-slack
controls and the evaluation over ``eval_cycles`` cycles).
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import Any, Callable

import numpy as np

from soft_envs.envs import GradientEnv, SimulationError, as_gradient_env

from ..evaluation import DEFAULT_EVAL_CYCLES, evaluate_controls, zero_slack_controls
from .gait import GaitSpec
from .gauss_newton import GaussNewtonOptions, GaussNewtonResult, gauss_newton
from .heading import HeadingMeasure
from .motor_limit import (describe_projection, gait_constraints, max_step_of_env, project_start, settings_entry,
                          speed_limit_constraints)
from .objectives import HeadingTarget, ObjectiveWeights, gait_residuals
from .parameterization import GaitParameterization
from ..results.result import Result
from ..results.robot_match import describe_difference, fingerprint_of
from ..tasks.targets import bl_per_min_to_mps, from_array
from ..tasks.registry import TASKS, Task, get_task

__all__ = ["optimize_gait", "GaitProblem", "Start", "Recorder", "build_problem", "choose_start", "check_resume",
           "finish", "DEFAULT_SPEED", "TASKS", "TASK_CONTACT"]

#: the contact law a task runs on when none is chosen (absent: the robot file's):
#: :attr:`trajopt.tasks.Task.contact` of each task (the turn's Coulomb: the README's turn row)
TASK_CONTACT = {name: t.contact for name, t in TASKS.items() if t.contact is not None}
#: default target speeds [BL/min], a little above the paper's Table I (Tripod 6.1, Puppy 8.6)
DEFAULT_SPEED = {"tripod": 8.0, "puppy": 10.0}
#: the settings a resumed run must share with the interrupted one (besides the task)
RESUME_KEYS = ("n_prep", "n_cycle", "n_cycles", "n_keyframes", "symmetry", "interpolation", "speed_bl_per_min", "heading_deg",
               "turn", "incline_deg", "contact", "substeps", "motor_limit")


class GaitProblem:
    """The shooting problem: parameters z -> controls -> rollout -> residuals and Jacobian.

    Counts the simulation steps it spends (``sim_steps``; a rollout with sensitivities counts
    its steps once, like the paper's forward sensitivity recurrence alongside the steps).
    ``heading``: target headings of the body for the heading term (used when
    ``weights.heading > 0``; the rollouts then keep ``dxdz``). ``max_step`` (M,): the motors'
    speed limit as the largest change of a control in a step [m] (None: no limit); its
    inequalities on z are ``speed_limit`` (:mod:`trajopt.optim.motor_limit`)."""

    def __init__(self, env: GradientEnv, param: GaitParameterization, target: np.ndarray,
                 weights: ObjectiveWeights, heading: HeadingTarget | None = None,
                 max_step: np.ndarray | None = None):
        self.env = env
        self.max_step = max_step
        self.speed_limit = None if max_step is None else speed_limit_constraints(param, max_step)
        self.param = param
        self.target = target
        self.weights = weights
        self.heading = heading
        self.dudz = param.dudz()
        self.u_offset = param.offset()
        self.sim_steps = 0
        self.rollouts = 0
        self.last_traj = None

    def controls(self, z: np.ndarray) -> np.ndarray:
        """Controls (K, n_motors) of the optimised horizon (prep + ``gait.n_cycles`` cycles)."""
        return self.u_offset + self.dudz @ z

    def __call__(self, z: np.ndarray, need_jac: bool = True):
        u = self.controls(z)
        with_heading = self.heading is not None and self.weights.heading > 0
        traj = self.env.rollout(u, dudz=self.dudz if need_jac else None, store_dxdz=need_jac and with_heading)
        self.sim_steps += len(u)
        self.rollouts += 1
        r, J, terms = gait_residuals(traj, self.target, z, self.param, self.env.robot.body_length,
                                     self.weights, need_jac, self.heading)
        if need_jac:
            self.last_traj = traj
        return r, J, {"terms": terms}


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
    #: :func:`trajopt.optim.motor_limit.project_start`
    projection: dict[str, Any] | None = None


# ---------------------------------------------------------------------- 1. the problem
def _target_path(task: Task, env: GradientEnv, n_steps: int, speed: float, heading_deg: float, turn: str,
                 target) -> np.ndarray:
    if target is not None:
        return from_array(target, n_steps)
    x0, _ = env.reset_state()
    start = env.robot.com(x0)[[0, 2]]
    v = bl_per_min_to_mps(speed, env.robot.body_length)
    return task.target_path(start, n_steps, env.timestep, v, heading_deg, turn)


def build_problem(env: GradientEnv, task: str, gait: GaitSpec, *, speed_bl_per_min: float, heading_deg: float,
                  turn: str, target: np.ndarray | None, weights: ObjectiveWeights,
                  max_step: np.ndarray | None = None) -> GaitProblem:
    """The shooting problem of ``task`` on ``env``: keyframe parameterisation of ``gait``, the
    target COM path at ``speed_bl_per_min`` along ``heading_deg`` (or ``target``), the
    objective's ``weights``, the motors' limit ``max_step`` (None: none)."""
    param = GaitParameterization.for_robot(env.robot, gait)
    the_task = get_task(task)
    path = _target_path(the_task, env, param.n_steps(), speed_bl_per_min, heading_deg, turn, target)
    heading = None
    v = bl_per_min_to_mps(speed_bl_per_min, env.robot.body_length)
    yaw = the_task.target_heading(param.n_steps(), env.timestep, v, turn) if target is None else None
    if yaw is not None:                  # e.g. the turn: the body turns as the arc does, from where it faces
        measure = HeadingMeasure(env.reset_state()[0], env.robot.node_masses)
        heading = HeadingTarget(measure, yaw)
    return GaitProblem(env, param, path, weights, heading, max_step)


# ---------------------------------------------------------------------- 2. the start
def check_resume(resume: Result, task: str, settings: dict[str, Any],
                 fingerprint: dict[str, Any] | None = None) -> None:
    """The one check that an interrupted run ``resume`` can be continued with ``settings`` on
    the robot of ``fingerprint`` (the error names ``resume.settings["source"]``, its file, when set)."""
    saved = {**resume.settings, **GaitSpec.from_settings(resume.settings).to_settings(),
             "contact": resume.settings.get("contact", "paper"),         # older results: the paper's law,
             "substeps": resume.settings.get("substeps", 1)}             # one physics step per control step
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


def _best_seed(problem: GaitProblem, seeds: list[np.ndarray]) -> np.ndarray:
    best, best_f = seeds[0], np.inf
    for z in seeds:
        try:
            r, _, _ = problem(z, need_jac=False)
        except SimulationError:
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


def choose_start(problem: GaitProblem, *, resume: Result | None = None, z0: np.ndarray | None = None,
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
    return start


def _within_limit(problem: GaitProblem, z: np.ndarray) -> tuple[np.ndarray, dict[str, Any] | None]:
    """``z`` projected into the motors' speed limit (and report), unchanged without one."""
    if problem.speed_limit is None:
        return z, None
    param = problem.param
    return project_start(np.clip(z, *param.bounds()), param, gait_constraints(param, problem.max_step))


# ---------------------------------------------------------------------- 3. the solve
class Recorder:
    """Gauss-Newton's iterations as history entries and partial :class:`Result` s."""

    def __init__(self, problem: GaitProblem, robot_name: str, task: str, settings: dict[str, Any],
                 history: list[dict], callback: Callable[[dict, Result], bool | None] | None):
        self.problem, self.robot_name, self.task, self.settings = problem, robot_name, task, settings
        self.history, self.callback = history, callback
        self.fingerprint = fingerprint_of(problem.env.robot)      # ties the result to its robot
        self.t_start = time.perf_counter()

    def result(self, z: np.ndarray, status: str, history: list[dict]) -> Result:
        p = self.problem
        u = p.controls(z)
        return Result(robot=self.robot_name, task=self.task, motor_names=p.env.robot.motor_names,
                      dt=p.env.timestep, z=z, u=u, u_post=u.copy(), target=p.target,
                      com=np.zeros((len(u) + 1, 3)),
                      settings={**self.settings, "keyframes": p.param.keyframes(z).tolist()},
                      history=history, status=status, robot_fingerprint=self.fingerprint)

    def on_iteration(self, entry: dict) -> bool | None:
        z_now = entry["z"]
        entry = {k: v for k, v in entry.items() if k not in ("z", "lam")} | {"lambda_next": entry["lam"]}
        entry["sim_steps_total"] = self.problem.sim_steps
        entry["wall_time_total"] = time.perf_counter() - self.t_start
        self.history.append(entry)
        if self.callback is not None:
            return self.callback(entry, self.result(z_now, "running", list(self.history)))
        return None


# ---------------------------------------------------------------------- 4. the result
def finish(recorder: Recorder, gn: GaussNewtonResult, eval_cycles: int, heading_deg: float) -> Result:
    """The result of the solve: controls, their zero-slack version (paper III-B-2), the COM,
    and the evaluation over ``eval_cycles`` cycles."""
    problem = recorder.problem
    env, z = problem.env, gn.z
    traj = problem.last_traj if problem.last_traj is not None else env.rollout(problem.controls(z))
    result = recorder.result(z, gn.status, recorder.history)
    result.com = traj.com
    robot = env.robot
    result.u_post = zero_slack_controls(result.u, traj.cable_deformation, robot.tendon_motor, robot.u_bounds)
    gait = problem.param.gait
    result.evaluation = evaluate_controls(env, problem.param.controls(z, eval_cycles), n_prep=gait.n_prep,
                                          n_cycle=gait.n_cycle, heading_deg=heading_deg,
                                          target=problem.target if eval_cycles >= gait.n_cycles else None)
    result.evaluation["optimization_sim_steps"] = problem.sim_steps
    result.evaluation["optimization_wall_time_s"] = time.perf_counter() - recorder.t_start
    result.evaluation["objective"] = gn.objective
    return result


def optimize_gait(env: Any, task: str = "walk", *, gait: GaitSpec | None = None,
                  speed_bl_per_min: float | None = None, heading_deg: float = 0.0, turn: str = "right",
                  target: np.ndarray | None = None, weights: ObjectiveWeights | None = None,
                  options: GaussNewtonOptions = GaussNewtonOptions(), warm_start: Result | None = None,
                  z0: np.ndarray | None = None, n_seeds: int = 8, eval_cycles: int = DEFAULT_EVAL_CYCLES,
                  robot_spec: str | None = None,
                  callback: Callable[[dict, Result], bool | None] | None = None,
                  resume: Result | None = None, motor_limit: bool = True) -> Result:
    """Optimise a gait and return a :class:`Result` (evaluated over ``eval_cycles`` cycles).

    ``env``: a Gymnasium env offering :class:`~soft_envs.envs.GradientEnv` (its contact law is
    used), or a robot / name / robot.toml path (:func:`~soft_envs.envs.make_gradient_env`, with
    the task's contact law :attr:`trajopt.tasks.Task.contact`: Coulomb for the turn, else the robot file's).
    ``gait``: the control trajectory's shape; default ``GaitSpec.for_task(task)``, the paper's
    24 + 2 x 72 steps and 4 keyframes, symmetric except for the turn (paper IV-B), which has 12
    keyframes (:data:`~trajopt.tasks.TURN_KEYFRAMES`). ``weights``: default
    ``ObjectiveWeights.for_task(task)`` (the turn also tracks the body's heading).
    ``warm_start``: another result whose keyframes are a starting candidate (e.g. turn from walk;
    symmetric and asymmetric parameterisations are converted, and 4 keyframes repeated to 12). The
    start is the best objective
    among the warm start and ``param.seeds(n_seeds)`` (cheap rollouts without sensitivities);
    ``n_seeds=0`` with a warm start starts from the warm start alone. ``resume``: continue an
    interrupted result (same settings; its z, history and damping are picked up).
    ``callback(entry, partial_result)`` runs after each Gauss-Newton iteration (checkpointing,
    progress); returning True stops the optimisation. ``motor_limit``: every step of the
    controls obeys the motors' speed limit (the environment's ``motor_speed``: the robot's
    ``max_speed_rpm`` unless overridden; :mod:`trajopt.optim.motor_limit`); a start outside it (a
    warm start made without it) is first projected into it, and the projection printed and
    recorded in ``settings["start_projection"]``; the limit is recorded in
    ``settings["motor_limit"]``. ``motor_limit=False`` optimises without (the results of
    before the limit).
    """
    the_task = get_task(task)
    if the_task.needs_target and target is None:
        raise ValueError(f"task={task!r} needs a target array")
    env = as_gradient_env(env, contact=the_task.contact)
    if eval_cycles < 1:
        raise ValueError(f"eval_cycles must be >= 1, got {eval_cycles}")
    robot = env.robot
    gait = GaitSpec.for_task(task) if gait is None else gait
    weights = ObjectiveWeights.for_task(task) if weights is None else weights
    speed = float(speed_bl_per_min if speed_bl_per_min is not None else DEFAULT_SPEED.get(robot.name, 8.0))
    settings = {**gait.to_settings(), "speed_bl_per_min": speed, "heading_deg": heading_deg, "turn": turn,
                "incline_deg": float(env.incline_deg), "weights": weights.to_dict(),
                "gauss_newton": asdict(options), "eval_cycles": eval_cycles,
                "warm_start": warm_start.settings.get("source") if warm_start is not None else None,
                "control": "length", "contact": env.contact_model, "substeps": int(env.substeps)}
    max_step = max_step_of_env(env) if motor_limit else None
    settings["motor_limit"] = settings_entry(robot, max_step, env.timestep)
    if resume is not None:
        check_resume(resume, task, settings, fingerprint_of(robot))
    problem = build_problem(env, task, gait, speed_bl_per_min=speed, heading_deg=heading_deg, turn=turn,
                            target=target, weights=weights, max_step=max_step)
    start = choose_start(problem, resume=resume, z0=z0, warm_start=warm_start, n_seeds=n_seeds)
    if start.projection is not None:
        settings["start_projection"] = start.projection
        print(describe_projection(start.projection, settings.get("warm_start") or "the start", max_step))
    recorder = Recorder(problem, robot_spec or robot.name, task, settings, start.history, callback)
    gn = gauss_newton(problem, start.z, *problem.param.bounds(), options, callback=recorder.on_iteration,
                      lam=start.lam, first_iteration=start.first_iteration, rejections=start.rejections,
                      constraints=problem.speed_limit)
    return finish(recorder, gn, eval_cycles, heading_deg)
