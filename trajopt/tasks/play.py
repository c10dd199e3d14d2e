"""A policy or an optimised gait played on a benchmark task's Gymnasium id and scored with the
task's own score (:mod:`.scores`): the one evaluation of the task suite (``trajopt sweep``'s
``task_score``, benchmarks/bench_suite.py).

* :func:`policy_on_task`: an RL run trained on a task id (``trajopt rl train
  SoftTripodClimbStep-v0``), closed loop, deterministic, through its normalisation statistics,
  on the id with the run's own keywords (difficulty, contact law, physics steps) and the
  registered episode length;
* :func:`gait_on_task`: an optimised gait (``trajopt optimize ROBOT --task climb_step``) played
  open loop, its prep phase then its cycle repeated, each control step commanded as the
  environment's action (``control_to_action``), on the task id of its robot with its difficulty.
"""
from __future__ import annotations

import math
import os
from typing import Any

__all__ = ["policy_on_task", "gait_on_task", "task_id_of"]


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


def policy_on_task(model: str | os.PathLike | Any, *, episodes: int | None = None) -> dict[str, Any]:
    """The task's score of an RL run trained on a task id (a run directory, model or
    :class:`~trajopt.rl.evaluate.LoadedPolicy`): :func:`.scores.evaluate_on_task` of its
    deterministic policy, with ``env_id`` and the run's training budget added."""
    from soft_envs import MAX_EPISODE_STEPS
    from ..rl.envs import make_env, run_contact, run_substeps, task_of
    from ..rl.evaluate import LoadedPolicy, load_policy
    from .scores import evaluate_on_task
    policy = model if isinstance(model, LoadedPolicy) else load_policy(model)
    cfg = policy.config["env"]
    if task_of(cfg["robot"]) is None:
        raise ValueError(f"{policy.path}: trained on {cfg['robot']!r}, not on a task id; its figure is "
                         "trajopt's metric (trajopt rl evaluate)")
    kwargs = {**cfg.get("env_kwargs", {}), "contact": run_contact(policy.config), "substeps": run_substeps(policy.config)}
    env = make_env(cfg["robot"], frame_skip=int(cfg.get("frame_skip", 1)), max_episode_steps=MAX_EPISODE_STEPS,
                   drop_com_xz=bool(cfg.get("drop_com_xz", True)), env_kwargs=kwargs)
    try:
        ev = evaluate_on_task(env, lambda obs, k: policy.act(obs), episodes=episodes)
    finally:
        env.close()
    return {**ev, "env_id": cfg["robot"], "method": f"{policy.algo} (closed loop)",
            "sim_steps": policy.config.get("sim_steps"), "wall_time_s": policy.config.get("wall_time_s")}


def gait_on_task(result: Any, *, task: str | None = None, difficulty: str | None = None,
                 episodes: int | None = None) -> dict[str, Any]:
    """The task's score of an optimised gait (a :class:`~trajopt.results.Result` or its path)
    played open loop on its task's id (``task``: a key of :data:`soft_envs.TASKS`, default the
    task the gait was optimised for, :attr:`trajopt.tasks.Task.env_task`) at ``difficulty``
    (default: the gait's, else the task's default), with the gait's contact law and physics steps."""
    import gymnasium as gym
    import numpy as np
    from soft_envs import MAX_EPISODE_STEPS
    from ..replay import result_controls, result_substeps
    from ..results.result import Result
    from .registry import get_task
    from .scores import evaluate_on_task
    res = result if isinstance(result, Result) else Result.load(result)
    task = task or get_task(res.task).env_task
    if task is None:
        raise ValueError(f"{res.path or 'the result'}: task {res.task!r} is no benchmark task; give task=")
    s = res.settings
    kwargs: dict[str, Any] = {"contact": s.get("contact", "paper"), "substeps": result_substeps(res)}
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
