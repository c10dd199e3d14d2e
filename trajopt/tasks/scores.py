"""Each benchmark task's score: one number per episode of its Gymnasium id, the same for a
policy (closed loop) and an optimised gait (open loop), so that both are ranked on the task's
own terms (docs/tasks.md, benchmarks/results/suite.md).

An episode is the id as registered (``gym.make(id, difficulty=...)``: ``soft_envs.MAX_EPISODE_STEPS``
= 300 steps of 33 ms, ended early by the task's own termination: a fall, a failed simulation or a
success), started with ``reset(seed=s)`` for ``s = 0, 1, ...``; its score (:data:`SCORES`):

* walk, walk up / down a slope, cross rough terrain: **speed** [BL/min], the COM's advance along
  the target heading (along the slope) over the episode, per minute of the whole episode (a fall
  keeps what was made before it);
* turn: **turn** [deg], the body's heading turned towards ``turn_direction`` over the episode;
* climb a step, cross a trench: **advance** [BL], the COM's advance along +x (the finish, half
  a body length beyond the obstacle, ends the episode with a success);
* reach a goal: **approach** [BL], the horizontal distance to the goal gained (at most the goal's
  distance less ``goal_radius_bl``, where it succeeds);
* carry a payload: **speed** [BL/min] as the walk's, with the payload on: its fall ends the
  episode, which keeps what was made before it (per minute of the whole episode);
* push a box: **pushed** [BL], the box's displacement along +x over the episode (the task
  succeeds at ``push_distance_bl``).

Each episode also reports the task's return (the sum of its rewards), its length and its success.
This module needs :mod:`soft_envs.envs` (Gymnasium) when an episode is played, not on import.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

__all__ = ["Score", "SCORES", "score_of", "play_episode", "evaluate_on_task", "summarise", "EPISODES",
           "default_episodes"]

#: evaluation episodes per run (seeds 0, 1, 2): the task's own randomness (goal, terrain, drawn
#: physics) varies between them; one with ``SOFT_ENVS_QUICK=1`` (:func:`default_episodes`)
EPISODES = 3


def default_episodes() -> int:
    """:data:`EPISODES`, or 1 under ``SOFT_ENVS_QUICK=1`` (the project's quick mode, CI)."""
    return 1 if os.environ.get("SOFT_ENVS_QUICK", "") not in ("", "0") else EPISODES


@dataclass(frozen=True)
class Score:
    """A task's score: its ``name``, ``unit`` and what it measures (``description``)."""

    name: str
    unit: str
    description: str


_SPEED = Score("speed", "BL/min", "the COM's advance along the heading over the episode, per minute of it")
#: task key (``soft_envs.TASKS``) -> its score
SCORES: dict[str, Score] = {
    "walk": _SPEED,
    "turn": Score("turn", "deg", "the heading turned towards turn_direction over the episode"),
    "slope_up": _SPEED,
    "slope_down": _SPEED,
    "rough_terrain": _SPEED,
    "climb_step": Score("advance", "BL", "the COM's advance along +x over the episode (success: past the finish)"),
    "cross_trench": Score("advance", "BL", "the COM's advance along +x over the episode (success: past the finish)"),
    "reach_goal": Score("approach", "BL", "the horizontal distance to the goal gained over the episode (success: "
                        "within goal_radius_bl of it)"),
    "carry": Score("speed", "BL/min", "the COM's advance along +x per minute of the episode, with the payload on "
                   "(its fall ends the episode)"),
    "push_box": Score("pushed", "BL", "the box's displacement along +x over the episode (success: "
                      "push_distance_bl)"),
}


def score_of(task: str) -> Score:
    """The score of ``task``; a ValueError naming the tasks otherwise."""
    try:
        return SCORES[task]
    except (KeyError, TypeError):
        raise ValueError(f"task must be one of {tuple(SCORES)}, got {task!r}") from None


def _box_x(info: dict[str, Any]) -> float:
    """The box's displacement along +x since the reset [m] (NaN without a box)."""
    d = info.get("box_displacement")
    return math.nan if d is None else float(d[0])


def play_episode(env, act: Callable[[np.ndarray, int], Any], seed: int, n_steps: int | None = None) -> dict[str, Any]:
    """One episode of ``env`` (a task id, possibly wrapped) from ``reset(seed=seed)``, the action
    of step k being ``act(obs, k)``, until it ends (or ``n_steps``). Returns the COM (K+1, 3),
    the yaw (K+1,), the goal distances (reach a goal), the box's displacement along +x (push a
    box, carry a payload), the return, the length, the success and whether it terminated (and
    why)."""
    obs, info = env.reset(seed=seed)
    coms, yaws, goals = [info["com"]], [info["yaw"]], [info.get("goal_distance", math.nan)]
    boxes = [_box_x(info)]
    ret, success, k, why = 0.0, False, 0, "truncated"
    while n_steps is None or k < n_steps:
        obs, reward, terminated, truncated, info = env.step(act(obs, k))
        k += 1
        ret += float(reward)
        coms.append(info["com"])
        yaws.append(info["yaw"])
        goals.append(info.get("goal_distance", math.nan))
        boxes.append(_box_x(info))
        success |= bool(info.get("is_success", False))
        if terminated or truncated:
            why = ("sim_failure" if "sim_failure" in info else "success" if info.get("is_success") else
                   "unhealthy" if terminated else "truncated")
            break
    return {"com": np.array(coms), "yaw": np.array(yaws), "goal_distance": np.array(goals),
            "box_x": np.array(boxes), "return": ret,
            "steps": k, "success": success, "end": why, "seed": int(seed)}


def _episode_score(task: str, base, rec: dict[str, Any], episode_steps: int) -> float:
    com, L = rec["com"], float(base.robot.body_length)
    if task == "turn":
        sign = 1.0 if base.locomotion_task.turn_direction == "right" else -1.0     # +yaw: from +x towards +z
        turned = np.angle(np.exp(1j * np.diff(rec["yaw"]))).sum()
        return float(np.degrees(sign * turned))
    if task == "reach_goal":
        return float((rec["goal_distance"][0] - rec["goal_distance"][-1]) / L)
    if task == "push_box":
        return float((rec["box_x"][-1] - rec["box_x"][0]) / L)
    advance = float((com[-1] - com[0]) @ base.locomotion_task.heading) / L
    if SCORES[task].name == "speed":
        return advance / (episode_steps * base.dt) * 60.0
    return advance


def evaluate_on_task(env, act: Callable[[np.ndarray, int], Any], *, episodes: int | None = None,
                     first_seed: int = 0) -> dict[str, Any]:
    """The task's score of ``act`` on ``env`` (a task id made by the caller: ``gym.make(id,
    difficulty=...)``, or the RL baseline's wrapped one) over ``episodes`` episodes seeded
    ``first_seed, first_seed + 1, ...`` (None: :func:`default_episodes`): the per-episode scores, returns, lengths, successes and
    ends, and their means (:func:`summarise`), with the level, the episode length, the control step
    ``control_dt_s`` (one simulation step: an environment step is ``frame_skip`` of them) and the
    physics steps per control step ``substeps``."""
    from soft_envs import TASK_ENV_IDS
    from soft_envs.envs.tasks import TaskEnv
    base = env.unwrapped
    if not isinstance(base, TaskEnv):
        raise ValueError(f"{type(base).__name__} is no benchmark task (one of soft_envs.TASK_ENV_IDS: "
                         f"{sorted(TASK_ENV_IDS)[0]}, ...)")
    episodes = default_episodes() if episodes is None else episodes
    if int(episodes) < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes!r}")
    limit = getattr(env, "spec", None) and env.spec.max_episode_steps
    from soft_envs import MAX_EPISODE_STEPS
    episode_steps = int(limit or MAX_EPISODE_STEPS)
    rows = []
    for s in range(int(first_seed), int(first_seed) + int(episodes)):
        rec = play_episode(env, act, s, n_steps=episode_steps)
        rows.append({"seed": s, "score": _episode_score(base.task_name, base, rec, episode_steps),
                     "return": rec["return"], "steps": rec["steps"], "success": rec["success"], "end": rec["end"]})
    return summarise(base.task_name, rows, difficulty=base.difficulty, episode_steps=episode_steps,
                     control_dt_s=float(base.timestep), substeps=int(base.substeps))


def summarise(task: str, rows: list[dict[str, Any]], **extra: Any) -> dict[str, Any]:
    """The evaluation of per-episode ``rows``: their means and the task's score description."""
    sc = score_of(task)
    return {"task": task, "score_name": sc.name, "score_unit": sc.unit,
            "score": float(np.mean([r["score"] for r in rows])),
            "return": float(np.mean([r["return"] for r in rows])),
            "success_rate": float(np.mean([r["success"] for r in rows])),
            "episodes": rows, **extra}
