"""How fragile is a gait? Replay it under perturbed friction, stiffness, masses, motors, timing and
slopes, and report the spread of its speed.

Run:  python examples/gait_robustness.py                (a few minutes)
      SOFT_ENVS_QUICK=1 python examples/gait_robustness.py   (tiny settings, as CI runs it)

It uses ``results/tripod_walk_example.npz`` if ``examples/optimize_tripod_walk.py`` has written it,
otherwise a hand-made keyframe gait of the Tripod, and writes results/robustness_example/
(results/robustness_example_quick/ quick; the README's ``trajopt robustness`` command writes
results/robustness/). The same from the shell:

    trajopt robustness results/tripod_walk_example.npz --samples 32 --cycles 4 --out results/robustness_example
"""
import os
from pathlib import Path

import numpy as np

from soft_envs.envs import load_robot
from trajopt import GaitParameterization, GaitSpec
from trajopt.cli import main
from trajopt.results.result import Result

QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"
OUT = Path("results") / ("robustness_example_quick" if QUICK else "robustness_example")
gait_file = Path("results") / "tripod_walk_example.npz"
if QUICK or not gait_file.is_file():
    robot = load_robot("tripod")
    spec = GaitSpec(n_prep=4, n_cycle=12, n_cycles=1, n_keyframes=2, symmetry=False) if QUICK else GaitSpec()
    param = GaitParameterization.for_robot(robot, spec)
    # keyframes [m] of (front, back): lift the middle leg, swing it forward, put it down, push back
    pattern = [[1, 1], [1, 0], [0, 0], [0, 1]] if spec.n_keyframes == 4 else [[1, 0], [0, 1]]
    kf = 0.014 * np.array(pattern, dtype=float).T           # about 2.8 BL/min on the paper's law
    z = param.z_from_keyframes(kf)
    u = param.controls(z)
    settings = {**spec.to_settings(), "keyframes": kf.tolist(), "heading_deg": 0.0, "incline_deg": 0.0}
    gait_file = Result(robot="tripod", task="walk", motor_names=robot.motor_names, dt=0.033, z=z, u=u, u_post=u,
                       target=np.zeros((len(u) + 1, 2)), com=np.zeros((len(u) + 1, 3)),
                       settings=settings).save(OUT / "hand_gait.npz")
samples, cycles = (3, 1) if QUICK else (32, 4)
raise SystemExit(main(["robustness", str(gait_file), "--samples", str(samples), "--cycles", str(cycles),
                       "--out", str(OUT)]))
