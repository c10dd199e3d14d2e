"""The Tripod carrying a payload and pushing a box: the two tasks with a second body.

Run:  python examples/carry_and_push.py          (about 30 s)

What it shows: ``SoftTripodCarry-v0`` and ``SoftTripodPushBox-v0`` (and the Puppy's ids) add a
stiff box to the robot's simulation (a :class:`soft_envs.sim.Box`: 8 nodes, 5 tets, in the same
implicit-Euler solve, with mass, gravity, ground contact and contact with friction against the
robot's nodes; docs/tasks.md, docs/contact.md). One open-loop gait (both motors over their whole
range as raised cosines, a 0.66 s cycle, 'back' 3/8 of a cycle ahead of 'front': the gait of
examples/rough_ground.py) is played for 5 s at each difficulty, and we print how far the robot and
the box went, whether the payload fell, and how far the box was pushed.

SOFT_ENVS_QUICK=1 (the project's convention for CI) shrinks the work to a smoke test.
"""
import os

import gymnasium as gym
import numpy as np

import soft_envs  # noqa: F401  (registers the ids)

QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"
STEPS = 10 if QUICK else 150                     # environment steps of 33 ms (5 s; quick: 0.33 s)
LEVELS = ("easy",) if QUICK else ("easy", "medium", "hard")

for env_id in ("SoftTripodCarry-v0", "SoftTripodPushBox-v0"):
    for level in LEVELS:
        env = gym.make(env_id, difficulty=level)
        env.reset(seed=0)
        u_max = env.unwrapped.robot.u_bounds[:, 1]
        box = env.unwrapped.box
        ret, ended = 0.0, "ran 5 s" if not QUICK else f"ran {STEPS} steps"
        for k in range(STEPS):
            t = k * env.unwrapped.dt
            u = u_max * 0.5 * (1 - np.cos(2 * np.pi * t / 0.66 + np.array([0.0, 0.75 * np.pi])))
            _, reward, terminated, truncated, info = env.step(env.unwrapped.control_to_action(u))
            ret += reward
            if terminated:
                ended = ("payload fell" if info.get("payload_fell") else
                         "success" if info["is_success"] else "ended") + f" at step {k + 1}"
                break
        robot_dx, box_dx = 1e3 * info["displacement"][0], 1e3 * info["box_displacement"][0]
        what = (f"payload {1e3 * box.mass:.1f} g (mu {box.friction_coefficient:g}) moved {box_dx:+6.1f} mm"
                if "Carry" in env_id else f"box {1e3 * box.mass:.1f} g pushed {box_dx:+6.1f} mm")
        print(f"{env_id:22s} {level:6s}: robot {robot_dx:+6.1f} mm, {what}, tilt {info['box_tilt_deg']:4.1f} deg; "
              f"return {ret:+7.2f}; {ended}")
