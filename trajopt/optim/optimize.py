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
:func:`~trajopt.optim.start.choose_start` (resume, given z0, or the best of the warm start and the
seeds, moved into the motors' limits; :mod:`trajopt.optim.start`),
:func:`gauss_newton` (the solve, recorded by :class:`Recorder`), :func:`finish` (zero-slack
controls and the evaluation over ``eval_cycles`` cycles).
"""
from __future__ import annotations

import time
from dataclasses import asdict
from typing import Any, Callable

import numpy as np

from soft_envs.envs import GradientEnv, MotorLaw, RolloutStopped, SimulationError, as_gradient_env

from ..evaluation import evaluate_controls, zero_slack_controls
from .ensemble import EnsembleProblem, credible_speed, ensemble_substeps, member_env
from .gait import GaitSpec
from .gauss_newton import GaussNewtonResult, gauss_newton
from .heading import HeadingMeasure
from .motor_limit import (IDEAL, SPEED, TORQUE_SPEED, choose_motor_model, describe_projection, max_step_of_env,
                          settings_entry, speed_limit_constraints)
from .motor_torque import LINE_TOLERANCE, MotorLine, line_settings_entry, motor_load_entry
from .optimize_settings import OptimizeSettings, settings_with
from .objectives import HeadingTarget, ObjectiveWeights, gait_residuals, objective_stop
from .parameterization import GaitParameterization
from ..results.result import Result
from ..results.robot_match import fingerprint_of
from ..tasks.targets import bl_per_min_to_mps, from_array
from ..tasks.registry import TASKS, Task, get_task
from .start import RESUME_KEYS, Start, check_resume, choose_start, newton_tol_of   # noqa: F401  (re-exported)

__all__ = ["optimize_gait", "OptimizeSettings", "GaitProblem", "Start", "Recorder", "build_problem", "choose_start", "check_resume",
           "finish", "DEFAULT_SPEED", "TASKS", "TASK_CONTACT"]

#: the contact law a task runs on when none is chosen (absent: the robot file's):
#: :attr:`trajopt.tasks.Task.contact` of each task (the turn's Coulomb: the README's turn row)
TASK_CONTACT = {name: t.contact for name, t in TASKS.items() if t.contact is not None}
#: default target speeds [BL/min], a little above the paper's Table I (Tripod 6.1, Puppy 8.6)
DEFAULT_SPEED = {"tripod": 8.0, "puppy": 10.0}


class GaitProblem:
    """The shooting problem: parameters z -> controls -> rollout -> residuals and Jacobian.

    Counts the simulation steps it spends (``sim_steps``; a rollout with sensitivities counts
    its steps once, like the paper's forward sensitivity recurrence alongside the steps).
    ``heading``: target headings of the body for the heading term (used when
    ``weights.heading > 0``; the rollouts then keep ``dxdz``). ``max_step`` (M,): the motors'
    speed limit as the largest change of a control in a step [m] (None: no limit); its
    inequalities on z are ``speed_limit`` (:mod:`trajopt.optim.motor_limit`). ``motor_model``:
    with ``"torque-speed"`` the motors' torque-speed line too (``line``,
    :mod:`trajopt.optim.motor_torque`): its rows are linearised at every accepted iterate
    (:meth:`linearised_constraints`) and a line-search trial whose rollout breaks it by more than
    :data:`~trajopt.optim.motor_torque.LINE_TOLERANCE` is refused (a failed trial).
    :attr:`constraints` is what Gauss-Newton keeps."""

    def __init__(self, env: GradientEnv, param: GaitParameterization, target: np.ndarray,
                 weights: ObjectiveWeights, heading: HeadingTarget | None = None,
                 max_step: np.ndarray | None = None, motor_model: str | None = None):
        self.env = env
        self.max_step = max_step
        self.motor_model = (SPEED if max_step is not None else IDEAL) if motor_model is None else motor_model
        self.speed_limit = None if max_step is None else speed_limit_constraints(param, max_step)
        no_load = None if max_step is None else np.asarray(max_step, dtype=np.float64) / env.timestep
        self.law = MotorLaw.of_robot(env.robot, no_load)
        self.line = MotorLine(param, self.law, env.timestep) if self.motor_model == TORQUE_SPEED else None
        self.param = param
        self.target = target
        self.weights = weights
        self.heading = heading
        self.dudz = param.dudz()
        self.u_offset = param.offset()
        self.sim_steps = 0
        self.rollouts = 0
        self.refused_trials = 0           # line-search trials refused for breaking the motors' line
        self.last_traj = None
        self._last_jacobian = None        # (z's bytes, store_dxdz, trajectory) of the last rollout with sensitivities

    def controls(self, z: np.ndarray) -> np.ndarray:
        """Controls (K, n_motors) of the optimised horizon (prep + ``gait.n_cycles`` cycles)."""
        return self.u_offset + self.dudz @ z

    #: ``__call__`` takes a ``bound`` (:func:`~trajopt.optim.gauss_newton.gauss_newton`'s trials)
    stops_above = True

    def rollout(self, z: np.ndarray, sensitivities: bool = False, store_dxdz: bool = False, stop=None):
        """The rollout of keyframes ``z`` (with ``dgammadz`` and ``dcomdz`` when ``sensitivities``;
        ``stop``: see :meth:`soft_envs.envs.GradientEnv.rollout`). Its steps are counted, those of
        a stopped rollout as far as it went. The last rollout with sensitivities is kept: asked
        again for the same z (the start moved into the motors' line, then Gauss-Newton's first
        evaluation there), it is returned without simulating (a rollout is a function of z: the
        problem's environment and robot do not change during its life)."""
        key = np.asarray(z, dtype=np.float64).tobytes()
        memo = self._last_jacobian
        if sensitivities and memo is not None and memo[0] == key and (memo[1] or not store_dxdz):
            return memo[2]
        u = self.controls(z)
        self.rollouts += 1
        try:
            traj = self.env.rollout(u, dudz=self.dudz if sensitivities else None, store_dxdz=store_dxdz, stop=stop)
        except RolloutStopped as stopped:
            self.sim_steps += stopped.k
            raise
        self.sim_steps += len(u)
        if sensitivities:
            self._last_jacobian = (key, store_dxdz, traj)
        return traj

    def __call__(self, z: np.ndarray, need_jac: bool = True, bound: float | None = None):
        return self.evaluate(z, need_jac, bound=bound)

    def evaluate(self, z: np.ndarray, need_jac: bool = True, check: bool = True, bound: float | None = None):
        """``(r, J, info)`` at ``z`` (J None without ``need_jac``). With ``check``, a trial (no
        ``need_jac``) that breaks the motors' line beyond the tolerance raises SimulationError.
        ``bound`` (no ``need_jac``): the rollout ends with :class:`~soft_envs.envs.RolloutStopped`
        as soon as the objective must exceed it (:func:`~trajopt.optim.objectives.objective_stop`):
        a trial or a seed whose value can no longer be accepted."""
        with_heading = self.heading is not None and self.weights.heading > 0
        stop = None
        if bound is not None and not need_jac and np.isfinite(bound):
            stop = objective_stop(bound, self.target, z, self.param, self.env.robot.body_length, self.weights,
                                  len(self.dudz), len(self.env.robot.tendons))
        traj = self.rollout(z, need_jac, store_dxdz=need_jac and with_heading, stop=stop)
        if check and not need_jac and self.line is not None:
            worst = self.line.worst(z, traj.cable_deformation)
            if worst.excess > LINE_TOLERANCE:
                self.refused_trials += 1
                raise SimulationError(f"trial refused: {worst.describe(self.env.robot.motor_names)}")
        r, J, terms = gait_residuals(traj, self.target, z, self.param, self.env.robot.body_length,
                                     self.weights, need_jac, self.heading)
        if need_jac:
            self.last_traj = traj
        return r, J, {"terms": terms}

    def linearised_constraints(self, z: np.ndarray):
        """The speed limit's rows and the line's, linearised at ``z`` (call after ``self(z, True)``)."""
        traj = self.last_traj
        return self.speed_limit & self.line.linearised(z, traj.cable_deformation, traj.dgammadz)

    @property
    def constraints(self):
        """What Gauss-Newton keeps: the linearisation of the line as a function of z
        (``"torque-speed"``), the speed limit's rows (``"speed"``), or None."""
        return self.linearised_constraints if self.line is not None else self.speed_limit


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
                  max_step: np.ndarray | None = None, motor_model: str | None = None) -> GaitProblem:
    """The shooting problem of ``task`` on ``env``: keyframe parameterisation of ``gait``, the
    target COM path at ``speed_bl_per_min`` along ``heading_deg`` (or ``target``), the
    objective's ``weights``, the motors' limit ``max_step`` (None: none) and model
    (:class:`GaitProblem`)."""
    param = GaitParameterization.for_robot(env.robot, gait)
    the_task = get_task(task)
    path = _target_path(the_task, env, param.n_steps(), speed_bl_per_min, heading_deg, turn, target)
    heading = None
    v = bl_per_min_to_mps(speed_bl_per_min, env.robot.body_length)
    yaw = the_task.target_heading(param.n_steps(), env.timestep, v, turn) if target is None else None
    if yaw is not None:                  # e.g. the turn: the body turns as the arc does, from where it faces
        measure = HeadingMeasure(env.reset_state()[0], env.robot.node_masses)
        heading = HeadingTarget(measure, yaw)
    return GaitProblem(env, param, path, weights, heading, max_step, motor_model)


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
    line = problem.line if problem.line is not None else MotorLine(problem.param, problem.law, env.timestep)
    result.evaluation["motor_load"] = motor_load_entry(line, z, traj.cable_deformation)
    if problem.line is not None:
        result.evaluation["motor_load"]["refused_trials"] = problem.refused_trials
    members = getattr(problem, "members", None)
    if members:                      # an ensemble: every member's speed, the slowest is the credible one
        evs = [result.evaluation] + [evaluate_controls(m.env, m.param.controls(z, eval_cycles), n_prep=gait.n_prep,
                                                       n_cycle=gait.n_cycle, heading_deg=heading_deg)
                                     for m in members[1:]]
        result.evaluation["ensemble"] = [{"substeps": int(m.env.substeps),
                                          "speed_bl_per_min": float(ev.get("speed_bl_per_min", float("nan"))),
                                          "upright": bool(ev.get("upright", False))} for m, ev in zip(members, evs)]
        result.evaluation["credible_bl_per_min"] = credible_speed(evs)
        result.evaluation["evaluation_sim_steps"] = sum(len(m.param.controls(z, eval_cycles)) * w
                                                        for m, w in zip(members, problem._weight))
    return result


def optimize_gait(env: Any, task: str = "walk", settings: OptimizeSettings | None = None, *,
                  warm_start: Result | None = None, z0: np.ndarray | None = None, resume: Result | None = None,
                  callback: Callable[[dict, Result], bool | None] | None = None, robot_spec: str | None = None,
                  **fields: Any) -> Result:
    """Optimise a gait and return a :class:`Result` (evaluated over ``settings.eval_cycles`` cycles).

    ``env``: a Gymnasium env offering :class:`~soft_envs.envs.GradientEnv` (its contact law is
    used), or a robot / name / robot.toml path (:func:`~soft_envs.envs.make_gradient_env`, with
    the task's contact law :attr:`trajopt.tasks.Task.contact`: Coulomb for the turn, else the robot file's).
    ``settings``: what to optimise for and under which limits
    (:class:`~trajopt.optim.optimize_settings.OptimizeSettings`: the gait's shape, the target's
    speed, heading and side, the weights, the Gauss-Newton options, the seeds, the evaluation's
    cycles, the motors' model, the ensemble); ``**fields`` replace its fields
    (``optimize_gait(env, "walk", speed_bl_per_min=10)``).

    ``warm_start``: another result whose keyframes are a starting candidate (e.g. turn from walk;
    symmetric and asymmetric parameterisations are converted, and 4 keyframes repeated to 12). The
    start is the best objective among the warm start and ``param.seeds(n_seeds)``. ``z0``: a
    given start. ``resume``: continue an interrupted result (same settings; its z, history and
    damping are picked up). ``callback(entry, partial_result)`` runs after each Gauss-Newton
    iteration (checkpointing, progress); returning True stops the optimisation. ``robot_spec``:
    how the result names its robot (default the robot's name).

    A start outside the motors' limits (a warm start made without them) is first moved into
    them, and the projection printed and recorded in ``settings["start_projection"]``; the
    result records the motors' model in ``settings["motor_model"]``, the speed limit in
    ``settings["motor_limit"]``, the line in ``settings["motor_line"]``; an ensemble's result each
    member's speed in ``evaluation["ensemble"]`` and the slowest,
    ``evaluation["credible_bl_per_min"]`` (``settings["ensemble"]``: the members' physics steps).
    """
    s = settings_with(settings, fields)
    gait, weights, target, turn, heading_deg = s.gait, s.weights, s.target, s.turn, s.heading_deg
    eval_cycles, options, speed_bl_per_min = s.eval_cycles, s.options, s.speed_bl_per_min
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
    recorded = {**gait.to_settings(), "speed_bl_per_min": speed, "heading_deg": heading_deg, "turn": turn,
                "incline_deg": float(env.incline_deg), "weights": weights.to_dict(),
                "gauss_newton": asdict(options), "eval_cycles": eval_cycles,
                "warm_start": warm_start.settings.get("source") if warm_start is not None else None,
                "control": "length", "contact": env.contact_model, "substeps": int(env.substeps),
                "newton_tol": newton_tol_of(env)}
    model = choose_motor_model(env, s.motor_model, s.motor_limit)
    max_step = max_step_of_env(env) if model != IDEAL else None
    recorded["motor_limit"] = settings_entry(robot, max_step, env.timestep)
    recorded["motor_model"] = model
    recorded["motor_line"] = line_settings_entry(MotorLaw.of_robot(robot, max_step / env.timestep), env.timestep) \
        if model == TORQUE_SPEED else None
    members = ensemble_substeps(env, s.ensemble)
    if len(members) > 1:
        recorded["ensemble"] = members
    if resume is not None:
        check_resume(resume, task, recorded, fingerprint_of(robot))
    problem = build_problem(env, task, gait, speed_bl_per_min=speed, heading_deg=heading_deg, turn=turn,
                            target=target, weights=weights, max_step=max_step, motor_model=model)
    if len(members) > 1:
        problem = EnsembleProblem([problem] + [
            build_problem(member_env(env, n), task, gait, speed_bl_per_min=speed, heading_deg=heading_deg, turn=turn,
                          target=target, weights=weights, max_step=max_step, motor_model=model) for n in members[1:]])
    start = choose_start(problem, resume=resume, z0=z0, warm_start=warm_start, n_seeds=s.n_seeds)
    if start.projection is not None:
        recorded["start_projection"] = start.projection
        print(describe_projection(start.projection, recorded.get("warm_start") or "the start", max_step))
    recorder = Recorder(problem, robot_spec or robot.name, task, recorded, start.history, callback)
    gn = gauss_newton(problem, start.z, *problem.param.bounds(), options, callback=recorder.on_iteration,
                      lam=start.lam, first_iteration=start.first_iteration, rejections=start.rejections,
                      constraints=problem.constraints)
    return finish(recorder, gn, eval_cycles, heading_deg)
