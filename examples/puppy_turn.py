"""Turn the Puppy through a quarter circle (paper IV-B), warm-started from its walk.

Run:  python examples/puppy_turn.py      (about five minutes: the walk, then the turn)

The turn is the walk's problem with three changes (trajopt's defaults for ``task="turn"``):
the COM target is a quarter circle over the horizon (prep + 2 cycles, 168 steps), the objective
also tracks the body's heading (the yaw of the best-fit rotation of all nodes from the rest
shape, with its exact derivative through the rollout's dx/dz), and each motor's cycle has 12
keyframes without bilateral symmetry, so the legs on the two sides may differ, joined by
straight lines (under the motors' speed limit a cable then moves at the motor's full speed). The Coulomb
contact law is the default (the robot files') and the turn's whatever the file says: the turn
pivots on feet that stick, which the paper's viscous-like friction cannot hold. The starts are the walk (as three strides per cycle) and
the walk with one side's motors played backwards (tank turns) and eight random patterns;
Gauss-Newton refines the best.

From the shell: `trajopt optimize puppy --task walk` then
`trajopt optimize puppy --task turn --warm-start results/puppy_walk.npz` (`--turn left`).

SOFT_ENVS_QUICK=1 (the project's convention for CI) shrinks the work to a smoke test and saves
results/puppy_turn_example_quick.npz instead of results/puppy_turn_example.npz.
"""
import os

from soft_envs.envs import make_gradient_env
from trajopt import GaitSpec, GaussNewtonOptions, optimize_gait

QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"
short = dict(n_prep=4, n_cycle=12) if QUICK else {}
iterations = 1 if QUICK else 10

# 1. the walk (the Coulomb law, as the robot file says); its keyframes start the turn
walk = optimize_gait("puppy", "walk", gait=GaitSpec.for_task("walk", **short),
                     options=GaussNewtonOptions(max_iter=iterations), n_seeds=1 if QUICK else 8, eval_cycles=2)
print(walk.summary())

# 2. the turn, on the Coulomb law (optimize_gait picks it for a robot name; an env keeps its own)
env = make_gradient_env("puppy", contact="coulomb")
turn = optimize_gait(env, "turn", turn="right", warm_start=walk, gait=GaitSpec.for_task("turn", **short),
                     options=GaussNewtonOptions(max_iter=iterations), n_seeds=1 if QUICK else 8, eval_cycles=6)
ev = turn.evaluation
print(turn.summary())
print(f"heading over the optimised horizon: {ev['horizon_heading_change_deg']:+.1f} deg "
      f"(target +90); the COM {ev['horizon_rms_to_target_bl']:.3f} body lengths (RMS) from the quarter circle")
print("heading per cycle [deg], 6 cycles:", " ".join(f"{v:+.1f}" for v in ev["heading_per_cycle_deg"]))
print(f"speed along the path: {ev['cycle_path_speed_bl_per_min']:.2f} BL/min; upright: {ev['upright']}")
path = turn.save("results/puppy_turn_example_quick.npz" if QUICK else "results/puppy_turn_example.npz")
print(f"saved {path}; watch it with: trajopt render {path}")
