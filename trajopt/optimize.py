"""``optimize_gait``: forward shooting with sensitivity analysis and Gauss-Newton (paper III).

>>> import gymnasium as gym, soft_envs
>>> from trajopt import optimize_gait
>>> result = optimize_gait(gym.make("SoftTripod-v0"), task="walk")
>>> result.save("tripod_walk.npz")

Tasks: ``"walk"`` (straight line at ``speed_bl_per_min`` along ``heading_deg``), ``"turn"``
(quarter circle to the ``turn`` side; paper: symmetry off, warm-started from a walk),
``"incline"`` (a walk on an environment whose gravity is rotated; the same objective), or a
custom ``target`` array (K+1, 2).
"""
from __future__ import annotations

import time
from dataclasses import asdict
from typing import Any, Callable

import numpy as np

from soft_envs.sim import SimulationError

from .evaluation import evaluate_controls, zero_slack_controls
from .gauss_newton import GaussNewtonOptions, gauss_newton
from .hooks import as_hooks
from .objectives import ObjectiveWeights, gait_residuals
from .parameterization import GaitParameterization
from .results import Result
from .targets import bl_per_min_to_mps, from_array, quarter_circle, straight_line

__all__ = ["optimize_gait", "GaitProblem", "DEFAULT_SPEED", "TASKS"]

TASKS = ("walk", "turn", "incline", "custom")
#: default target speeds [BL/min], a little above the paper's Table I (Tripod 6.1, Puppy 8.6)
DEFAULT_SPEED = {"tripod": 8.0, "puppy": 10.0}


class GaitProblem:
    """The shooting problem: parameters z -> controls -> rollout -> residuals and Jacobian.

    Counts the simulation steps it spends (``sim_steps``; a rollout with sensitivities counts
    its steps once, like the paper's forward sensitivity recurrence alongside the steps)."""

    def __init__(self, hooks, param: GaitParameterization, target: np.ndarray,
                 weights: ObjectiveWeights):
        self.hooks = hooks
        self.param = param
        self.target = target
        self.weights = weights
        self.dudz = param.dudz(2)
        self.u_offset = param.offset(2)
        self.sim_steps = 0
        self.rollouts = 0
        self.last_traj = None

    def controls(self, z: np.ndarray) -> np.ndarray:
        """Controls (K, n_motors) of the two-cycle problem for parameters z."""
        return self.u_offset + self.dudz @ z

    def __call__(self, z: np.ndarray, need_jac: bool = True):
        u = self.controls(z)
        traj = self.hooks.rollout(u, dudz=self.dudz if need_jac else None)
        self.sim_steps += len(u)
        self.rollouts += 1
        r, J, terms = gait_residuals(traj, self.target, z, self.param, self.hooks.robot.body_length,
                                     self.weights, need_jac)
        if need_jac:
            self.last_traj = traj
        return r, J, {"terms": terms}


def _target_for(task: str, hooks, n_steps: int, speed: float, heading_deg: float, turn: str,
                target) -> np.ndarray:
    x0, _ = hooks.reset_state()
    start = hooks.robot.com(x0)[[0, 2]]
    v = bl_per_min_to_mps(speed, hooks.robot.body_length)
    if target is not None:
        return from_array(target, n_steps)
    if task in ("walk", "incline"):
        return straight_line(start, n_steps, hooks.dt, v, heading_deg)
    if task == "turn":
        return quarter_circle(start, n_steps, hooks.dt, v, heading_deg, direction=turn)
    raise ValueError(f"task must be one of {TASKS} (or give target=...), got {task!r}")


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


def optimize_gait(env: Any, task: str = "walk", *, speed_bl_per_min: float | None = None,
                  heading_deg: float = 0.0, turn: str = "right", symmetry: bool | None = None,
                  n_keyframes: int = 4, n_prep: int = 24, n_cycle: int = 72,
                  target: np.ndarray | None = None, weights: ObjectiveWeights = ObjectiveWeights(),
                  options: GaussNewtonOptions = GaussNewtonOptions(), warm_start: Result | None = None,
                  z0: np.ndarray | None = None, n_seeds: int = 8, eval_cycles: int = 6,
                  robot_spec: str | None = None,
                  callback: Callable[[dict, Result], bool | None] | None = None,
                  resume: Result | None = None) -> Result:
    """Optimise a gait and return a :class:`Result` (evaluated over ``eval_cycles`` cycles).

    ``env``: a Gymnasium env with gradient hooks, or a robot / name / robot.toml path.
    ``symmetry``: default on for walk/incline, off for turn (paper IV-B).
    ``warm_start``: another result whose keyframes are a starting candidate (e.g. turn from walk;
    symmetric and asymmetric parameterisations are converted). The start is the best objective
    among the warm start and ``param.seeds(n_seeds)`` (cheap rollouts without sensitivities);
    ``n_seeds=0`` with a warm start starts from the warm start alone. ``resume``: continue an interrupted result
    (same settings; its z, history and damping are picked up).
    ``callback(entry, partial_result)`` runs after each Gauss-Newton iteration (checkpointing,
    progress); returning True stops the optimisation.
    """
    if task not in TASKS:
        raise ValueError(f"task must be one of {TASKS}, got {task!r}")
    if task == "custom" and target is None:
        raise ValueError("task='custom' needs a target array")
    hooks = as_hooks(env)
    if hooks.simulator.control != "length":
        raise ValueError("optimize_gait optimises contracted cable lengths; the environment's simulator "
                         f"uses {hooks.simulator.control!r} control")
    if eval_cycles < 1:
        raise ValueError(f"eval_cycles must be >= 1, got {eval_cycles}")
    robot = hooks.robot
    name = robot_spec or robot.name
    speed = float(speed_bl_per_min if speed_bl_per_min is not None else DEFAULT_SPEED.get(robot.name, 8.0))
    sym = (task != "turn") if symmetry is None else bool(symmetry)
    param = GaitParameterization(robot.u_bounds, robot.mirror_map, n_prep, n_cycle, n_keyframes, sym)
    K = param.n_steps(2)
    tgt = _target_for(task, hooks, K, speed, heading_deg, turn, target)
    lo, hi = param.bounds()
    history: list[dict] = []
    lam, first, rejections = None, 1, 0
    problem = GaitProblem(hooks, param, tgt, weights)
    if resume is not None:
        z_start = np.asarray(resume.z, dtype=np.float64)
        history = list(resume.history)
        if history:
            lam, first = history[-1].get("lambda_next"), history[-1]["iteration"] + 1
            for entry in reversed(history):        # the run of rejected steps it stopped in
                if entry.get("accepted", True):
                    break
                rejections += 1
    elif z0 is not None:
        z_start = np.asarray(z0, dtype=np.float64)
    else:
        candidates = []
        if warm_start is not None:
            kf = np.asarray(warm_start.settings.get("keyframes"), dtype=np.float64)
            if kf.shape != (robot.n_motors, n_keyframes):
                raise ValueError(f"warm start has keyframes of shape {kf.shape}, this problem needs "
                                 f"({robot.n_motors}, {n_keyframes})")
            candidates.append(np.clip(param.z_from_keyframes(kf), lo, hi))
        candidates += param.seeds(n_seeds) if (n_seeds > 0 or not candidates) else []
        z_start = candidates[0] if len(candidates) == 1 else _best_seed(problem, candidates)
    if z_start.shape != (param.nz,):
        raise ValueError(f"starting parameters must have shape ({param.nz},), got {z_start.shape}")
    settings = {"n_prep": n_prep, "n_cycle": n_cycle, "n_keyframes": n_keyframes, "symmetry": sym,
                "speed_bl_per_min": speed, "heading_deg": heading_deg, "turn": turn,
                "incline_deg": float(getattr(hooks, "incline_deg", 0.0)), "weights": weights.to_dict(),
                "gauss_newton": asdict(options), "eval_cycles": eval_cycles,
                "warm_start": warm_start.settings.get("source") if warm_start is not None else None,
                "control": hooks.simulator.control}
    if resume is not None:
        keys = ("n_prep", "n_cycle", "n_keyframes", "symmetry", "speed_bl_per_min", "heading_deg", "turn",
                "incline_deg")
        differ = {k: (resume.settings.get(k), settings[k]) for k in keys if resume.settings.get(k) != settings[k]}
        if differ or resume.task != task:
            raise ValueError(f"cannot resume: the settings differ from the interrupted run's (saved, asked): "
                             f"{differ or {'task': (resume.task, task)}}")
    t_start = time.perf_counter()

    def make_result(z, status, hist) -> Result:
        u = problem.controls(z)
        return Result(robot=name, task=task, motor_names=robot.motor_names, dt=hooks.dt, z=z, u=u,
                      u_post=u.copy(), target=tgt, com=np.zeros((K + 1, 3)),
                      settings={**settings, "keyframes": param.keyframes(z).tolist()},
                      history=hist, status=status)

    def on_iteration(entry: dict) -> bool | None:
        z_now = entry["z"]
        entry = {k: v for k, v in entry.items() if k not in ("z", "lam")} | {"lambda_next": entry["lam"]}
        entry["sim_steps_total"] = problem.sim_steps
        entry["wall_time_total"] = time.perf_counter() - t_start
        history.append(entry)
        if callback is not None:
            return callback(entry, make_result(z_now, "running", list(history)))
        return None

    gn = gauss_newton(problem, z_start, lo, hi, options, callback=on_iteration, lam=lam,
                      first_iteration=first, rejections=rejections)
    z = gn.z
    traj = problem.last_traj if problem.last_traj is not None else hooks.rollout(problem.controls(z))
    result = make_result(z, gn.status, history)
    result.com = traj.com
    result.u_post = zero_slack_controls(result.u, traj.cable_deformation, robot.tendon_motor, robot.u_bounds)
    u_eval = param.controls(z, eval_cycles)
    result.evaluation = evaluate_controls(hooks, u_eval, n_prep=n_prep, n_cycle=n_cycle,
                                          heading_deg_target=heading_deg)
    result.evaluation["optimization_sim_steps"] = problem.sim_steps
    result.evaluation["optimization_wall_time_s"] = time.perf_counter() - t_start
    result.evaluation["objective"] = gn.objective
    return result
