"""What the converged default physics costs: sub-stepped against one step per control step.

The default physics of the Coulomb law takes 4 implicit-Euler steps of 8.25 ms per 0.033 s
control step (``ContactLaw.default_substeps``; why: docs/fidelity.md). This script measures its
cost against one step of 33 ms (``substeps=1``, the physics of release 0.1.0), alternately in one
run (CPU time of single-threaded work, best of ``--repeat`` rounds), as ratios:

1. per simulated second on the Puppy's gait: a plain rollout and a rollout with the
   sensitivities of 16 parameters, 168 control steps of the gait of
   ``benchmarks/common.gait_controls`` (target: <= 2x);
2. the main job, ``trajopt optimize tripod --task walk`` (target: <= 1.5x), as a subprocess
   (numba's cache warm, one thread): this checkout's default against ``--before CHECKOUT``, a
   checkout of the code before sub-steps (release 0.1.0, e.g. ``git worktree add /tmp/v010
   0a2df0c``), and against this checkout with ``--substeps 1``.

Run: ``python benchmarks/bench_physics_cost.py --before /tmp/v010`` (``--quick``: part 1 only,
one round).
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from common import gait_controls, report
from soft_envs.sim import Simulator, load_robot

ROOT = Path(__file__).resolve().parents[1]


def _rollout_seconds(robot, substeps: int, nz: int) -> float:
    """CPU seconds of one 168-step rollout of the gait (with ``nz`` sensitivity columns)."""
    sim = Simulator(robot, substeps=substeps)
    u = gait_controls(robot)
    start = sim.rest_state(robot.u_rest)
    dudz = None if nz == 0 else 1e-3 * np.random.default_rng(0).normal(size=(len(u), robot.n_motors, nz))
    t0 = time.process_time()
    sim.rollout(u, x0=start, dudz=dudz)
    return time.process_time() - t0


def _main_job_seconds(root: Path, *extra: str) -> float:
    """CPU seconds (children's) of ``trajopt optimize tripod --task walk`` of the checkout ``root``."""
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", NUMBA_NUM_THREADS="1",
               PYTHONPATH=os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")]))
    with tempfile.TemporaryDirectory() as out:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        subprocess.run([sys.executable, "-m", "trajopt.cli", "optimize", "tripod", "--task", "walk", *extra,
                        "--out", out, "--quiet"], check=True, env=env, stdout=subprocess.DEVNULL,
                       cwd=root)          # -m puts the working directory first on sys.path: the checkout's
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="alternating rounds (best of)")
    ap.add_argument("--quick", action="store_true", help="rollouts only, one round")
    ap.add_argument("--before", type=Path, default=None, metavar="CHECKOUT",
                    help="a checkout of the code before sub-steps (0a2df0c) for the main job's ratio")
    args = ap.parse_args()
    repeat = 1 if args.quick else args.repeat
    robot = load_robot("puppy")
    rows = []
    with threadpool_limits(1):
        for nz, what in ((0, "rollout"), (16, "rollout with 16 sensitivities")):
            _rollout_seconds(robot, 4, nz)                # compile and warm up
            best = {1: np.inf, 4: np.inf}
            for _ in range(repeat):
                for n in (1, 4):
                    best[n] = min(best[n], _rollout_seconds(robot, n, nz))
            rows.append({"measure": f"Puppy gait {what}, per simulated second", "one step [s]": best[1] / 5.544,
                         "4 sub-steps [s]": best[4] / 5.544, "ratio": best[4] / best[1], "target": "<= 2x"})
    if not args.quick:
        jobs = {"now": (ROOT,), "now --substeps 1": (ROOT, "--substeps", "1")}
        if args.before is not None:
            jobs["before"] = (args.before,)
        for job in jobs.values():
            _main_job_seconds(*job)                       # numba's caches, the imports
        best = {k: np.inf for k in jobs}
        for _ in range(repeat):
            for k, job in jobs.items():
                best[k] = min(best[k], _main_job_seconds(*job))
        for k in [k for k in jobs if k != "now"]:
            rows.append({"measure": f"trajopt optimize tripod --task walk (CPU): against {k}", "one step [s]": best[k],
                         "4 sub-steps [s]": best["now"], "ratio": best["now"] / best[k], "target": "<= 1.5x"})
    report("cost of the converged physics (best of alternating rounds, CPU time)", rows)


if __name__ == "__main__":
    main()
