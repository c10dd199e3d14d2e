"""A policy or an optimised gait played on a benchmark task's Gymnasium id and scored with the
task's own score (:mod:`.scores`): the one evaluation of the task suite (``trajopt sweep``'s
``task_score``, benchmarks/bench_suite.py).

* :func:`policy_on_task`: an RL run trained on a task id (``trajopt rl train
  SoftTripodClimbStep-v0``), closed loop, deterministic, through its normalisation statistics,
  on the id with the run's own keywords (difficulty, contact law, physics steps) and the
  registered episode length;
* :func:`policy_task_hold`: how credible that score is, by the headline's protocol
  (:mod:`trajopt.search.hold`): the same policy closed loop with half, twice and four times its
  run's physics steps per control step (16.5, 4.125 and 2.06 ms around 8.25 ms); the lowest score
  is the credible one, and it holds when the scores spread at most 5 % of it;
* :func:`gait_on_task`: an optimised gait (``trajopt optimize ROBOT --task climb_step``) played
  open loop, its prep phase then its cycle repeated, each control step commanded as the
  environment's action (``control_to_action``), on the task id of its robot with its difficulty.
"""
from __future__ import annotations

import math
import numbers
import os
from typing import Any

__all__ = ["policy_on_task", "policy_task_hold", "gait_on_task", "gait_task_hold", "task_hold", "task_id_of"]


def task_id_of(task: str, robot: str) -> str:
    """The Gymnasium id of ``task`` (a key of :data:`soft_envs.TASKS`) on ``robot``; ValueError
    naming what exists otherwise."""
    from soft_envs import TASK_IDS_BY_TASK
    if task not in TASK_IDS_BY_TASK:
        raise ValueError(f"task must be one of {tuple(TASK_IDS_BY_TASK)}, got {task!r}")
    ids = TASK_IDS_BY_TASK[task]
    if robot not in ids:
        raise ValueError(f"task {task!r} has ids for {sorted(ids)} only, got robot {robot!r}")
    return ids[robot]


def _check_substeps(substeps: Any) -> None:
    """None, or a whole number >= 1 (an int, a NumPy integer or a whole float); ValueError naming it otherwise."""
    if substeps is None:
        return
    if isinstance(substeps, bool) or not isinstance(substeps, numbers.Real) or not math.isfinite(substeps) \
            or int(substeps) != substeps or int(substeps) < 1:
        raise ValueError(f"substeps must be a whole number >= 1, got {substeps!r}")


def policy_on_task(model: str | os.PathLike | Any, *, episodes: int | None = None,
                   substeps: int | None = None, first_seed: int = 0) -> dict[str, Any]:
    """The task's score of an RL run trained on a task id (a run directory, model or
    :class:`~trajopt.rl.evaluate.LoadedPolicy`): :func:`.scores.evaluate_on_task` of its
    deterministic policy, with ``env_id`` and the run's training budget added. ``substeps``:
    physics steps per control step (default the run's own; more: finer physics, same control).
    ``first_seed``: the first episode's seed (the suite's 0; the tuning study holds its own out)."""
    from soft_envs import MAX_EPISODE_STEPS
    from ..rl.envs import make_env, run_contact, run_substeps, task_of
    from ..rl.evaluate import LoadedPolicy, load_policy
    from .scores import evaluate_on_task
    _check_substeps(substeps)
    policy = model if isinstance(model, LoadedPolicy) else load_policy(model)
    cfg = policy.config["env"]
    if task_of(cfg["robot"]) is None:
        raise ValueError(f"{policy.path}: trained on {cfg['robot']!r}, not on a task id; its figure is "
                         "trajopt's metric (trajopt rl evaluate)")
    kwargs = {**cfg.get("env_kwargs", {}), "contact": run_contact(policy.config),
              "substeps": run_substeps(policy.config) if substeps is None else int(substeps)}
    env = make_env(cfg["robot"], frame_skip=int(cfg.get("frame_skip", 1)), max_episode_steps=MAX_EPISODE_STEPS,
                   drop_com_xz=bool(cfg.get("drop_com_xz", True)), env_kwargs=kwargs)
    try:
        ev = evaluate_on_task(env, lambda obs, k: policy.act(obs), episodes=episodes, first_seed=first_seed)
    finally:
        env.close()
    return {**ev, "env_id": cfg["robot"], "method": f"{policy.algo} (closed loop)",
            "sim_steps": policy.config.get("sim_steps"), "wall_time_s": policy.config.get("wall_time_s")}


def policy_task_hold(model: str | os.PathLike | Any, *, factors=None, max_spread: float | None = None,
                     episodes: int | None = None, reference: dict[str, Any] | None = None) -> dict[str, Any]:
    """Whether an RL run's task score (:func:`policy_on_task`) holds at other physics steps: the
    policy closed loop on its id with its run's physics steps per control step times each of
    ``factors`` (default :data:`~trajopt.search.hold.HOLD_FACTORS`: half, twice and four times),
    the control step unchanged, scored as at its own. ``reference``: :func:`policy_on_task`'s
    evaluation at the run's own physics when already made (the sweep's ``task_score``; the replays
    then play as many episodes as it did, whatever ``episodes``). Returns :func:`task_hold`'s dict."""
    from ..rl.envs import run_substeps
    from ..rl.evaluate import LoadedPolicy, load_policy
    policy = model if isinstance(model, LoadedPolicy) else load_policy(model)
    own = reference if reference is not None else policy_on_task(policy, episodes=episodes)
    if "substeps" not in own:               # an evaluation made before it recorded them: the run's own
        n = run_substeps(policy.config)
        own = {**own, "substeps": n if n is not None else policy_on_task(policy, episodes=1)["substeps"]}
    return task_hold(lambda n: policy_on_task(policy, episodes=len(own["episodes"]), substeps=n), own,
                     factors=factors, max_spread=max_spread)


def gait_task_hold(result: Any, *, factors=None, max_spread: float | None = None, episodes: int | None = None,
                   reference: dict[str, Any] | None = None) -> dict[str, Any]:
    """:func:`policy_task_hold` of an optimised gait played open loop on its task's id
    (:func:`gait_on_task`, its task and difficulty). Returns :func:`task_hold`'s dict."""
    from ..replay import result_substeps
    from ..results.result import Result
    res = result if isinstance(result, Result) else Result.load(result)
    own = reference if reference is not None else gait_on_task(res, episodes=episodes)
    if "substeps" not in own:               # an evaluation made before it recorded them: the gait's own
        own = {**own, "substeps": int(result_substeps(res))}
    return task_hold(lambda n: gait_on_task(res, episodes=len(own["episodes"]), substeps=n), own,
                     factors=factors, max_spread=max_spread)


def task_hold(evaluate, own: dict[str, Any], *, factors=None, max_spread: float | None = None) -> dict[str, Any]:
    """Whether a task score holds at other physics steps, by the headline's protocol
    (:mod:`trajopt.search.hold`): ``own`` is the evaluation (:func:`.scores.evaluate_on_task`'s
    dict) with its ``substeps`` physics steps per control step, ``evaluate(n)`` the same
    evaluation with ``n``, made for ``substeps`` times each of ``factors`` (default
    :data:`~trajopt.search.hold.HOLD_FACTORS`: half, twice and four times; whole numbers only: none
    left is refused). Every replay must be of the same id and level as ``own`` (ValueError).

    Returns ``substeps`` (increasing, the own included), ``physics_dt_ms`` and ``scores`` at each
    (NaN where an episode's simulation failed), and :func:`~trajopt.search.hold.hold_verdict`'s
    ``slowest`` (the credible score: the lowest), ``spread`` (``(max - min) / |slowest|``) and
    ``holds`` (no failure, ``slowest > 0`` and ``spread <= max_spread``, default 5 %); with
    ``own_substeps``, ``own_score`` (``own``'s score, even where a simulation failed), ``max_spread``,
    ``score_name``, ``score_unit`` and ``episodes``."""
    from soft_envs.envs import PAPER_TIMESTEP
    from ..search.hold import HOLD_FACTORS, MAX_SPREAD, hold_steps, hold_verdict
    max_spread = MAX_SPREAD if max_spread is None else float(max_spread)
    own_substeps = int(own["substeps"])
    factors = HOLD_FACTORS if factors is None else tuple(factors)
    steps = hold_steps(own_substeps, factors)
    if not steps:
        raise ValueError(f"factors {factors} of {own_substeps} physics steps per control step give no other whole "
                         "number of steps: nothing to replay")
    evs = {own_substeps: own}
    for n in steps:
        evs[n] = evaluate(n)
        for key in ("env_id", "difficulty"):
            if evs[n].get(key) != own.get(key):
                raise ValueError(f"the replay with {n} physics steps is on {key} {evs[n].get(key)!r}, the "
                                 f"evaluation it is compared with on {own.get(key)!r}")

    def score(ev: dict[str, Any]) -> float:
        failed = any(e.get("end") == "sim_failure" for e in ev["episodes"])
        return float("nan") if failed else float(ev["score"])

    ns = sorted(evs)
    scores = [score(evs[n]) for n in ns]
    control_ms = 1e3 * float(own.get("control_dt_s", PAPER_TIMESTEP))       # evaluations made before it was recorded
    return {"substeps": ns, "physics_dt_ms": [control_ms / n for n in ns], "scores": scores,
            **hold_verdict(scores, max_spread), "max_spread": max_spread, "own_substeps": int(own_substeps),
            "own_score": float(own["score"]),
            "score_name": own["score_name"], "score_unit": own["score_unit"], "episodes": len(own["episodes"])}


def gait_on_task(result: Any, *, task: str | None = None, difficulty: str | None = None,
                 episodes: int | None = None, substeps: int | None = None) -> dict[str, Any]:
    """The task's score of an optimised gait (a :class:`~trajopt.results.Result` or its path)
    played open loop on its task's id (``task``: a key of :data:`soft_envs.TASKS`, default the
    task the gait was optimised for, :attr:`trajopt.tasks.Task.env_task`) at ``difficulty``
    (default: the gait's, else the task's default), with the gait's contact law and physics steps
    (``substeps``: other physics steps per control step, the controls unchanged)."""
    import gymnasium as gym
    import numpy as np
    from soft_envs import MAX_EPISODE_STEPS
    from ..replay import result_controls, result_substeps
    from ..results.result import Result
    from .registry import get_task
    from .scores import evaluate_on_task
    _check_substeps(substeps)
    res = result if isinstance(result, Result) else Result.load(result)
    task = task or get_task(res.task).env_task
    if task is None:
        raise ValueError(f"{res.path or 'the result'}: task {res.task!r} is no benchmark task; give task=")
    s = res.settings
    kwargs: dict[str, Any] = {"contact": s.get("contact", "paper"),
                              "substeps": result_substeps(res) if substeps is None else int(substeps)}
    level = difficulty or s.get("difficulty")
    if level is not None:
        kwargs["difficulty"] = level
    env = gym.make(task_id_of(task, res.robot), **kwargs)
    base = env.unwrapped
    n_prep, n_cycle = int(s.get("n_prep", 0)), int(s.get("n_cycle", 1))
    n_cycles = max(1, math.ceil((MAX_EPISODE_STEPS - n_prep) / max(n_cycle, 1)))
    u, _, _ = result_controls(res, base.robot, n_cycles if "keyframes" in s else None)
    actions = base.control_to_action(np.asarray(u))
    try:
        ev = evaluate_on_task(env, lambda obs, k: actions[min(k, len(actions) - 1)], episodes=episodes)
    finally:
        env.close()
    return {**ev, "env_id": task_id_of(task, res.robot), "method": "trajopt (open loop)",
            "sim_steps": res.evaluation.get("search_sim_steps", res.evaluation.get("optimization_sim_steps")),
            "result": str(res.path or "")}
