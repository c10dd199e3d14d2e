"""A speed that belongs to the robot: a fast Tripod gait optimised on one physics, and on three at once.

Run:  python examples/credible_gait.py      (a few minutes on two cores)

An optimiser exploits whatever its model allows, the time step included (docs/fidelity.md): a
fast gait optimised on the default physics (4 implicit-Euler steps of 8.25 ms per 0.033 s
control step) may walk at another speed when the same controls are replayed with finer steps.
``optimize_gait(..., ensemble=(2, 8))`` optimises the gait on the default physics and on 2 and
8 steps per control step at once (their residuals stacked, :mod:`trajopt.optim.ensemble`), and
reports the *credible* speed, the slowest of the three. Both gaits are then replayed at 2x, 4x
and 8x finer steps (:func:`trajopt.fidelity.fidelity`, what ``trajopt evaluate --fidelity``
prints): the spread says how much of a speed is the step's.

From the shell: `trajopt optimize tripod --speed max --ensemble` (the search of
examples/fastest_gait.py, every candidate on the ensemble, ranked by its credible speed).

SOFT_ENVS_QUICK=1 (the project's convention for CI): one Gauss-Newton iteration of a short gait,
replayed at 2x finer steps only; saves results/tripod_credible_example_quick.npz.
"""
import os

from trajopt import GaitSpec, GaussNewtonOptions, optimize_gait
from trajopt.fidelity import fidelity

QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"
gait = GaitSpec(n_prep=4 if QUICK else 24, n_cycle=12, n_cycles=2 if QUICK else 4, n_keyframes=4,
                interpolation="linear")
options = GaussNewtonOptions(max_iter=1 if QUICK else 6)
factors = (2,) if QUICK else (2, 4, 8)

for name, ensemble in (("default physics alone", ()), ("ensemble of 2, 4, 8 steps", (2, 8))):
    res = optimize_gait("tripod", gait=gait, speed_bl_per_min=20.0, options=options, n_seeds=0 if QUICK else 4,
                        eval_cycles=2 if QUICK else 10, ensemble=ensemble)
    ev = res.evaluation
    members = ", ".join(f"{m['speed_bl_per_min']:.2f} at {m['substeps']} steps" for m in ev.get("ensemble", []))
    print(f"{name}: {ev['speed_bl_per_min']:.2f} BL/min at the default physics"
          + (f"; members {members}; credible {ev['credible_bl_per_min']:.2f} BL/min" if members else ""))
    fid = fidelity(res, factors)
    print("  replayed: " + ", ".join(f"{r['speed_bl_per_min']:.2f} at {r['physics_dt_ms']:.3g} ms" for r in fid["rows"])
          + f"; spread {100 * fid['spread']:.1f} %")
path = res.save("results/tripod_credible_example_quick.npz" if QUICK else "results/tripod_credible_example.npz")
print(f"saved {path}")
