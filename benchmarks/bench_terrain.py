"""Terrain benchmark: environment steps/s on rough ground against the plane, in one run.

For the Tripod and the Puppy (``make_gradient_env``: default contact law and sub-steps, no
wrappers), env steps/s with a smooth periodic action (benchmarks/common.py's gait-like control
mapped to actions) on

  * the plane ``y = 0`` (no ground: the original contact kernels),
  * a flat :class:`~soft_envs.sim.ground.HeightField` (the field's kernels, nothing to climb),
  * rough ground (``HeightField.rough``: RMS 3 mm, wavelength 5 cm),

and the ratio rough / plane (target >= 0.7x). The three are measured alternately, best of
``REPEATS`` runs of ``STEPS`` steps from the same reset (the machine may be shared).
Run: python benchmarks/bench_terrain.py [--steps N]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from common import gait_controls
from soft_envs.envs.factory import make_gradient_env
from soft_envs.sim import HeightField

REPEATS = 3
TARGET = 0.7
GROUNDS = {"plane": None, "flat field": HeightField.flat(), "rough": HeightField.rough(0.003, 0.05, seed=0)}


def steps_per_second(env, actions: np.ndarray) -> float:
    env.reset(seed=0)
    t0 = time.perf_counter()
    for a in actions:
        env.step(a)
    return len(actions) / (time.perf_counter() - t0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=150)
    args = parser.parse_args()
    for name in ("tripod", "puppy"):
        envs = {g: make_gradient_env(name, ground=f) for g, f in GROUNDS.items()}
        robot = envs["plane"].unwrapped.robot
        u = gait_controls(robot, K=args.steps)
        lo, hi = robot.u_bounds[:, 0], robot.u_bounds[:, 1]
        actions = np.clip(2.0 * (u - lo) / (hi - lo) - 1.0, -1.0, 1.0)
        best = {g: 0.0 for g in envs}
        for g, env in envs.items():                  # compile and warm up
            steps_per_second(env, actions[:5])
        for _ in range(REPEATS):
            for g, env in envs.items():
                best[g] = max(best[g], steps_per_second(env, actions))
        ratio = best["rough"] / best["plane"]
        print(f"{name}: " + ", ".join(f"{g} {v:.0f} steps/s" for g, v in best.items())
              + f"; rough / plane = {ratio:.2f}x (target >= {TARGET}x: {'met' if ratio >= TARGET else 'NOT met'})")


if __name__ == "__main__":
    main()
