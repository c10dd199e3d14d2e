"""A random agent on SoftPuppy-v2: the Gymnasium side of soft_envs in a few lines.

Run:  python examples/gym_random_agent.py [frame.png]

What it shows: make the environment, reset it with a seed, step it with random actions, read
the reward terms and the centre-of-mass displacement from ``info``, and save a rendered frame.
A random policy does not walk; see examples/simulate_tripod.py and ``trajopt`` for gaits.

SOFT_ENVS_QUICK=1 (the project's convention for CI) shrinks the work to a smoke test.
"""
import os
import sys
import tempfile
from pathlib import Path

import gymnasium as gym
import numpy as np
from PIL import Image

import soft_envs  # noqa: F401  -- importing the package registers SoftTripod-v2 and SoftPuppy-v2

QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"      # CI smoke test: fewer steps
N_STEPS = 10 if QUICK else 100

# Actions are 8 motor commands in [-1, 1] (-1: cable released, +1: fully pulled in); the motors
# follow them at their real speed limit. rgb_array rendering is offscreen (no display needed).
env = gym.make("SoftPuppy-v2", render_mode="rgb_array")   # Coulomb law; contact="paper": the paper's
obs, info = env.reset(seed=42)                    # seeds the reset noise and everything random
env.action_space.seed(42)                         # ... and the random actions, for repeatability
print(f"observation: {obs.shape[0]} numbers; parts: {env.unwrapped.observation_structure}")

totals = {"reward_forward": 0.0, "reward_ctrl": 0.0, "reward_survive": 0.0}
for step in range(N_STEPS):                       # 100 steps of 0.033 s = 3.3 s of simulated time
    action = env.action_space.sample()
    obs, reward, terminated, truncated, info = env.step(action)
    for key in totals:
        totals[key] += info[key]
    if terminated or truncated:                   # fell over, or the simulation failed
        print(f"episode ended at step {step}: {info.get('sim_failure', 'robot fell over')}")
        obs, info = env.reset()

print("summed reward terms:", {k: round(v, 3) for k, v in totals.items()})
dx, dy, dz = 1000 * info["displacement"]          # COM now minus COM at reset [m -> mm]
print(f"COM displacement: x {dx:+.2f} mm (forward), y {dy:+.2f} mm (up), z {dz:+.2f} mm (right)")
print(f"applied cable contractions [mm]: {np.round(1000 * info['u'], 2)}")

frame = env.render()                              # uint8 array (360, 480, 3)
out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp()) / "puppy_random.png"
Image.fromarray(frame).save(out)
print(f"saved a {frame.shape[1]}x{frame.shape[0]} frame to {out}")
env.close()
