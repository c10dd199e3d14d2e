"""The benchmark's tasks: make every registered task id, take a few random steps, print the reward terms.

Run:  python examples/benchmark_tasks.py          (about 20 s)

What it shows: each task (walk, turn, slope up and down, rough terrain, climb a step, cross a
trench, reach a goal, carry a payload, push a box; docs/tasks.md) is a Gymnasium id per robot, made with ``gymnasium.make``
and a ``difficulty``; its observation is the robot's plus the task's parts
(``observation_structure``), and its reward is the sum of the terms in ``info`` (``reward_forward``,
``reward_ctrl``, ``reward_survive``, ``reward_success``). Random actions walk nowhere: the
figures show the terms' sizes, not a solution.

SOFT_ENVS_QUICK=1 (the project's convention for CI) shrinks the work to a smoke test.
"""
import os

import gymnasium as gym
import numpy as np

import soft_envs

QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"
STEPS = 5 if QUICK else 60                       # environment steps of 33 ms per id
DIFFICULTY = "medium"
TERMS = ("reward_forward", "reward_ctrl", "reward_survive", "reward_success")
ROBOT_PARTS = set(gym.make("SoftTripod-v2").unwrapped.observation_structure)     # the robot's own parts

for env_id in sorted(soft_envs.TASK_ENV_IDS, key=lambda i: (i.startswith("SoftPuppy"), i)):
    env = gym.make(env_id, difficulty=DIFFICULTY)
    obs, info = env.reset(seed=0)
    rng = np.random.default_rng(0)
    sums = dict.fromkeys(TERMS, 0.0)
    total, steps, ended = 0.0, 0, ""
    for _ in range(STEPS):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(-1.0, 1.0, env.action_space.shape))
        total += reward
        steps += 1
        for k in TERMS:
            sums[k] += info[k]
        if terminated or truncated:
            ended = (" (success)" if info["is_success"] else " (payload fell)" if info.get("payload_fell")
                     else " (ended: unhealthy or failed)")
            break
    extra = [k for k in env.unwrapped.observation_structure if k not in ROBOT_PARTS]
    terms = "  ".join(f"{k[7:]} {v:+7.3f}" for k, v in sums.items())
    print(f"{env_id:26s} obs {obs.size:2d}, act {env.action_space.shape[0]}, task parts {extra or '-'}; "
          f"{steps} steps: reward {total:+7.3f} = {terms}{ended}")
print(f"{len(soft_envs.TASK_ENV_IDS)} task ids made at difficulty {DIFFICULTY!r}; the robot ids "
      f"{', '.join(sorted(soft_envs.LATEST_ENV_IDS.values()))} are unchanged")
