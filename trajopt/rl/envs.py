"""The environments the RL baseline trains and is evaluated on.

The physics is the registered Gymnasium environment, unchanged (the latest ids,
``SoftTripod-v2`` / ``SoftPuppy-v2``, under the Coulomb law by default or the paper's with
``contact="paper"``: same simulator, motor speed limit, reward and termination as documented in
:class:`soft_envs.envs.tripod.SoftTripodEnv`). Two choices are made here, both recorded in the
run's ``rl_config.json``:

* **Episode length** ``max_episode_steps = 168`` simulation steps (:data:`TRAIN_HORIZON`), the
  horizon ``trajopt`` optimises over (``GaitSpec()``: 24 prep steps + 2 cycles of 72), so both
  methods see episodes of the same length (``gymnasium.make`` alone gives 300,
  ``soft_envs.MAX_EPISODE_STEPS``); the evaluation (:mod:`trajopt.rl.evaluate`) then plays
  24 + 6 x 72 steps, like ``trajopt``'s. A benchmark task id trains on its registered 300 steps,
  over which its score is defined (:func:`trajopt.rl.training.episode_steps_for`).
* **Translation-invariant observation** (:class:`DropHorizontalPosition`): the COM x and z
  relative to the start (two entries of the environment's ``com_position`` observation) are
  removed. They grow without bound as the robot walks and carry no information a walking
  policy needs (the COM velocity, the orientation, the height and the gait phase are kept),
  and a policy trained on 168-step
  episodes would otherwise see positions at evaluation (456 steps) it never saw in training.
"""
from __future__ import annotations

import itertools
import multiprocessing
import signal
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ..optim.gait import DEFAULT_EVAL_CYCLES, GaitSpec

__all__ = ["ROBOTS", "ROBOT_IDS", "COULOMB_IDS", "GAIT", "TRAIN_HORIZON", "DEFAULT_EVAL_CYCLES",  # noqa: F822 (module __getattr__)
           "DropHorizontalPosition", "make_env", "robot_name", "env_id", "task_of", "env_choices", "rl_target", "run_contact",
           "run_substeps"]

#: robots of the RL baseline: the shipped robots (their Gymnasium ids: ``soft_envs.ENV_IDS_BY_ROBOT``)
ROBOTS = ("tripod", "puppy")
#: trajopt's gait (prep phase, cycle length, cycles optimised): the phases the policy is measured in
GAIT = GaitSpec()
#: 168 simulation steps: trajopt's optimisation horizon, the RL baseline's episode length
TRAIN_HORIZON = GAIT.n_steps()


def __getattr__(name: str):
    """``ROBOT_IDS`` (robot -> ``-v0`` id) and ``COULOMB_IDS`` (robot -> the latest id, ``-v2``), read from
    ``soft_envs.ENV_IDS_BY_ROBOT`` on first use (``trajopt --help`` imports no soft_envs)."""
    law = {"ROBOT_IDS": "paper", "COULOMB_IDS": "coulomb"}.get(name)
    if law is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from soft_envs import ENV_IDS_BY_ROBOT
    return {robot: ENV_IDS_BY_ROBOT[robot][law] for robot in ROBOTS}


def task_of(ref: str) -> str | None:
    """The task key (``"climb_step"``) of a task id (``"SoftTripodClimbStep-v0"``,
    :data:`soft_envs.TASK_ENV_IDS`); None for anything else."""
    from soft_envs import TASK_IDS_BY_TASK
    return next((task for task, ids in TASK_IDS_BY_TASK.items() if ref in ids.values()), None)


def rl_target(text: str) -> str:
    """``text`` when the RL baseline can train on it (a robot or a task id, :func:`robot_name`);
    the message of :func:`robot_name`'s ValueError otherwise (an ``argparse.ArgumentTypeError``: the
    command line's and a sweep's check)."""
    import argparse
    try:
        robot_name(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def env_choices() -> list[str]:
    """What the RL baseline trains on: the robots' names (their latest id) and the task ids."""
    from soft_envs import TASK_ENV_IDS
    return sorted(ROBOTS) + sorted(TASK_ENV_IDS)


def robot_name(robot: str) -> str:
    """``"tripod"`` for ``"tripod"``, ``"SoftTripod-v0"``, ``-v1``, ``-v2`` or a task id of the
    Tripod (``"SoftTripodWalk-v0"``; likewise the Puppy)."""
    from soft_envs import ENV_ROBOTS, TASK_ENV_IDS
    if robot in ROBOTS:
        return robot
    if ENV_ROBOTS.get(robot) in ROBOTS:
        return ENV_ROBOTS[robot]
    if robot in TASK_ENV_IDS:
        return TASK_ENV_IDS[robot][1]["robot"]
    all_ids = sorted(i for i, name in ENV_ROBOTS.items() if name in ROBOTS)
    raise ValueError(f"robot must be one of {sorted(ROBOTS)} (or their ids {all_ids}, or a task id "
                     f"{sorted(TASK_ENV_IDS)[0]} ...), got {robot!r}")


def env_id(robot: str) -> str:
    """The registered id the RL baseline makes for ``robot``: a task id as it is, else the
    robot's latest (``-v2``), under any contact law given as its ``contact`` keyword (the
    paper's law is ``contact="paper"`` on it, not ``-v0``, which Gymnasium reports out of date)."""
    from soft_envs import LATEST_ENV_IDS
    if task_of(robot) is not None:
        return robot
    return LATEST_ENV_IDS[robot_name(robot)]


def run_contact(config: Mapping[str, Any]) -> str:
    """The contact law of a run from its ``rl_config.json``: its ``env_kwargs["contact"]`` (runs
    record it since the Coulomb law became the default), else the law of the id it was made on
    (older runs: ``-v0`` the paper's, ``-v1`` Coulomb's), else the paper's."""
    from soft_envs import ENV_KWARGS
    kwargs = (config.get("env") or {}).get("env_kwargs") or {}
    return kwargs.get("contact") or ENV_KWARGS.get(config.get("env_id"), {}).get("contact", "paper")


def run_substeps(config: Mapping[str, Any]) -> int | None:
    """The physics steps per control step of a run from its ``rl_config.json``: its
    ``env_kwargs["substeps"]`` (runs record it since sub-steps exist), else its id's (``-v0`` and
    ``-v1``: 1; runs without an id: 1, made before sub-steps)."""
    from soft_envs import ENV_KWARGS
    kwargs = (config.get("env") or {}).get("env_kwargs") or {}
    if kwargs.get("substeps") is not None:
        return int(kwargs["substeps"])
    return ENV_KWARGS.get(config.get("env_id"), {"substeps": 1}).get("substeps")


class DropHorizontalPosition(gym.ObservationWrapper):
    """Removes the COM's x and z relative to the COM at reset (the first and third entries of
    the environment's ``com_position`` part; its second is the height): the policy becomes
    invariant to where on the ground the robot is. Everything else is passed through. Where the
    part lies comes from the environment's ``observation_structure`` (its parts and their sizes,
    in order); :attr:`dropped` holds the indices removed."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        parts = getattr(env.unwrapped, "observation_structure", None)
        if not parts or parts.get("com_position") != 3:
            raise ValueError(f"{type(env.unwrapped).__name__} has no 3-entry 'com_position' in its "
                             f"observation_structure ({parts!r})")
        start = sum(size for name, size in itertools.takewhile(lambda p: p[0] != "com_position", parts.items()))
        self.dropped = (start, start + 2)
        n = env.observation_space.shape[0]
        self._keep = np.array([i for i in range(n) if i not in self.dropped])
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(len(self._keep),), dtype=np.float64)

    def observation(self, observation: np.ndarray) -> np.ndarray:
        return np.asarray(observation, dtype=np.float64)[self._keep]


def make_env(robot: str, *, frame_skip: int = 1, max_episode_steps: int | None = TRAIN_HORIZON,
             drop_com_xz: bool = True, env_kwargs: Mapping[str, Any] | None = None,
             ignore_sigint_in_worker: bool = False) -> gym.Env:
    """One environment of the RL baseline: ``gym.make(id, max_episode_steps, frame_skip,
    **env_kwargs)`` (``id``: :func:`env_id` of ``robot``, a robot or a task id), wrapped in :class:`DropHorizontalPosition` when ``drop_com_xz``.

    ``max_episode_steps`` counts environment steps (``frame_skip`` simulation steps each);
    ``None`` keeps the registered ``soft_envs.MAX_EPISODE_STEPS`` (300).
    ``ignore_sigint_in_worker``: in a SubprocVecEnv worker, ignore Ctrl-C so that only the main
    process handles it (it saves the model and then closes the workers cleanly)."""
    import soft_envs  # noqa: F401  (registers the ids)

    if ignore_sigint_in_worker and multiprocessing.current_process().name != "MainProcess":
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    kwargs = dict(env_kwargs or {})
    kwargs["frame_skip"] = int(frame_skip)
    if max_episode_steps is not None:
        kwargs["max_episode_steps"] = int(max_episode_steps)
    env = gym.make(env_id(robot), **kwargs)
    if drop_com_xz:
        env = DropHorizontalPosition(env)
    return env
