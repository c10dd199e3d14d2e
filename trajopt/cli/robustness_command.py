"""``trajopt robustness``: runs :func:`trajopt.robustness.report.run_robustness_study` and prints
its report (the perturbations and the replays: :mod:`trajopt.robustness`)."""
from __future__ import annotations

from ..robustness.study import PERTURBATIONS
from ..robustness.report import run_robustness_study

__all__ = ["run_robustness"]


def run_robustness(args) -> int:
    report, written = run_robustness_study(args.result, args.out, samples=args.samples, cycles=args.cycles,
                                           seed=args.seed, workers=getattr(args, "workers", 1),
                                           overwrite=getattr(args, "overwrite", False))
    q, d = report["speed_bl_per_min"], report["heading_drift_deg_per_cycle"]
    print(f"  nominal speed      {report['nominal'].get('speed_bl_per_min', float('nan')):.2f} BL/min "
          f"(upright {report['nominal'].get('upright')})")
    print(f"  perturbed speed    median {q['median']:.2f}, 5th-95th percentile {q['p5']:.2f} - {q['p95']:.2f} BL/min")
    print(f"  upright            {100 * report['upright_fraction']:.0f} % of {report['samples']} "
          f"({report['failed']} failed)")
    print(f"  heading drift      median {d['median_abs']:.2f}, 95th percentile {d['p95_abs']:.2f} deg/cycle")
    for w in report["worst"]:
        keys = ", ".join(f"{k} {w[k]:.3g}" for k in PERTURBATIONS)
        print(f"  worst: sample {w['index']}: {w['speed_bl_per_min']:.2f} BL/min, upright {w['upright']}: {keys}")
    print(f"wrote {', '.join(str(p) for p in written)}")
    return 0
