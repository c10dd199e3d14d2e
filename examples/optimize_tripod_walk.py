"""Optimise a walking gait for the Tripod with shooting Gauss-Newton (paper III), then check it.

Run:  python examples/optimize_tripod_walk.py      (about half a minute)

The optimiser reaches the physics through the Gymnasium environment's gradient hooks (the
`soft_envs.envs.GradientEnv` protocol on `env.unwrapped`): every Gauss-Newton iteration is one
rollout with exact sensitivities (dx/dz of all 168 states) plus a short line search. A robot of
your own works the same way: `optimize_gait("results/my_robot/robot.toml", task="walk")` builds a bare
environment for it (`soft_envs.envs.make_gradient_env`); `gait=trajopt.GaitSpec(...)` changes the
phase lengths and keyframes. The same thing from the shell: `trajopt optimize tripod --task walk`.

SOFT_ENVS_QUICK=1 (the project's convention for CI) shrinks the work to a smoke test and writes
results/tripod_walk_example_quick.npz instead of results/tripod_walk_example.npz.
"""
import os

import gymnasium as gym

import soft_envs  # noqa: F401  (registers SoftTripod-v2 and SoftPuppy-v2, and -v0 for Table I)
from trajopt import GaitSpec, GaussNewtonOptions, Result, optimize_gait

# CI smoke test: a 4 + 2 x 12 step horizon, one iteration, one seed, one evaluation cycle
QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"
size = dict(gait=GaitSpec(n_prep=4, n_cycle=12), n_seeds=1, eval_cycles=1) if QUICK else {}

env = gym.make("SoftTripod-v2", reset_noise_scale=0.0)   # Coulomb law; contact="paper": the paper's
env.reset(seed=0)


def progress(entry, partial):
    print(f"iteration {entry['iteration']}: objective {entry['objective']:.4g} -> "
          f"{entry['objective_after']:.4g} (step {entry['step']:.1e}, {entry['time']:.1f} s)")


result = optimize_gait(env, task="walk", speed_bl_per_min=8.0,
                       options=GaussNewtonOptions(max_iter=1 if QUICK else 6), callback=progress, **size)
print(result.summary())
ev = result.evaluation
print(f"speed per cycle [BL/min]: {[round(v, 2) for v in ev['speed_per_cycle_bl_per_min']]} "
      f"(paper's Tripod: 6.1)")

# .npz + .json (one unit), written atomically; a quick run has its own name and never replaces a full one
path = result.save("results/tripod_walk_example_quick.npz" if QUICK else "results/tripod_walk_example.npz")
again = Result.load(path)
print(f"saved {path}; keyframes per motor [mm]:")
for name, kf in zip(again.motor_names, again.settings["keyframes"]):
    print(f"  {name:>6}: {[round(1000 * v, 1) for v in kf]}")
