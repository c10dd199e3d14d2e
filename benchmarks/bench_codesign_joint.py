"""Is an ensemble needed in co-design's joint Gauss-Newton, or is the credible screening enough?

From the checkpoint a ``bench_codesign.py`` run kept after its screening
(``OUT/codesign/ROBOT/screened.partial.json``: the screened design and gait, ranked by credible
speeds), the joint stage is run again, the same stages and acceptance by credible speed (the
hold replays), once on the default physics alone and once on each ensemble (the default and
``--ensembles``' physics steps per control step, the residuals stacked:
``trajopt.codesign.ensemble.CodesignEnsemble``), each resumed from a copy of that checkpoint in
``OUT/codesign-joint/ROBOT-off`` and ``ROBOT-ens-N[-N...]`` (no re-optimisation from scratch: the joint
stage is what differs). Reports the credible speed of each, its spread, the stages and the joint
stage's wall time and simulation steps, and writes OUT/codesign_joint_ensemble.md.

Run:  python benchmarks/bench_codesign.py ROBOT   (first: the run and its checkpoint)
      python benchmarks/bench_codesign_joint.py [ROBOT ...] [--ensembles N[,N...] ...] [--report-only]
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import shutil
import sys
import time
from pathlib import Path

from bench_codesign import SCREENED
from trajopt.codesign.run import PARTIAL, CodesignRun, run_codesign

HERE = Path(__file__).resolve().parent


def joint_from_screened(robot: str, out: Path, ensemble: tuple[int, ...], contact: str, reoptimise: bool = False
                        ) -> dict:
    """The joint stage resumed from ``out/codesign/ROBOT/screened.partial.json`` with ``ensemble``
    (() : none) in its own folder; its summary plus the joint stage's wall time and steps."""
    src = out / "codesign" / robot
    folder = _folder(out, robot, ensemble)
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    for part in ("baseline_walk.npz", "baseline_walk.json"):
        shutil.copy(src / part, folder / part)
    data = json.loads((src / SCREENED).read_text())
    data["settings"]["joint"]["ensemble"] = list(ensemble)     # the one setting that differs
    (folder / PARTIAL).write_text(json.dumps(data))
    run = CodesignRun(robot, folder, contact=contact, resume=True, reoptimise=reoptimise, workers=1)
    run.joint = dataclasses.replace(run.joint, ensemble=tuple(ensemble))
    return figures(run_codesign(run).summary, data)


def _folder(out: Path, robot: str, ensemble: tuple[int, ...]) -> Path:
    return out / "codesign-joint" / f"{robot}-{'ens-' + '-'.join(map(str, ensemble)) if ensemble else 'off'}"


def figures(summary: dict, screened: dict) -> dict:
    """A resumed run's summary with the joint stage's own figures: its wall time and simulation
    steps (the run's less the screening's, ``screened``: the checkpoint it resumed) and the screened
    gait's credible speed."""
    state = screened["state"]
    return {**summary, "joint_wall_time_s": summary["codesign_wall_time_s"] - state["wall_time_s"],
            "joint_sim_steps": summary["codesign_sim_steps"] - state["sim_steps"],
            "screened_slowest_bl_per_min": state["best_speed"], "screened_holds": state.get("best_holds")}


def _stages(stages: list[dict]) -> str:
    """Each stage's gait on the default physics: own speed, slowest, spread, accepted or not."""
    def one(r):
        slowest = r["slowest_bl_per_min"]
        fig = "fell" if slowest != slowest else f"{slowest:.2f}, {100 * r['spread']:.1f} %"
        return f"{r['speed_bl_per_min']:.2f}; {fig} ({'accepted' if r.get('accepted') else 'not accepted'})"
    return "; ".join(one(r) for r in stages) or "-"


def _reoptimised(s: dict) -> str:
    if "reoptimised_credible_ratio" not in s:
        return "not run"
    return (f"{s['reoptimised_slowest_bl_per_min']:.2f}, {100 * s['reoptimised_spread']:.1f} %, "
            f"{s['reoptimised_credible_ratio']:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("robots", nargs="*", default=["tripod", "puppy"])
    ap.add_argument("--ensembles", nargs="+", default=["8"], metavar="N[,N...]",
                    help="the ensembles measured besides the default physics alone, each its members' physics steps "
                         "per control step besides the default's, comma-separated (default: 8)")
    ap.add_argument("--contact", default="coulomb")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--reoptimise", action="store_true",
                    help="also re-optimise the written robot's gait from scratch (--speed max), as the full run does")
    ap.add_argument("--skip-off", action="store_true", help="only the ensembles (not the default physics alone)")
    ap.add_argument("--report-only", action="store_true",
                    help="no run: the table from the measurements made before (OUT/codesign-joint/*/joint.json)")
    args = ap.parse_args()
    ensembles = [tuple(int(n) for n in e.split(",")) for e in args.ensembles]
    lines = ["# Co-design's joint stage with and without an ensemble", "",
             f"Generated by `python benchmarks/bench_codesign_joint.py {' '.join(sys.argv[1:])}` on "
             f"{time.strftime('%Y-%m-%d')}, {args.contact} law: the joint Gauss-Newton resumed from the checkpoint "
             "each `bench_codesign.py` run kept after its screening, on the default physics alone (off) and on an "
             f"ensemble (4 and {' / '.join(', '.join(map(str, e)) for e in ensembles)} physics steps per control step); every stage "
             "accepted only when its credible rank improves; "
             f"{os.cpu_count()} shared CPU cores, Python {platform.python_version()}.", "",
             "| robot | joint ensemble | screened: slowest | each stage's gait: own; slowest, spread | after the "
             "joint stage: own, slowest, spread, holds | gain of the slowest | GN iterations | joint stage's steps | "
             "joint stage's wall time [min] | ratio of slowest to the shipped design's | re-optimised from the files: "
             "slowest, spread, ratio |", "|---|---|---:|---|---|---:|---:|---:|---:|---:|---|"]
    for robot in args.robots:
        for ens in (() if not args.skip_off else None, *ensembles):
            if ens is None:
                continue
            if args.report_only:
                s = figures(json.loads((_folder(args.out, robot, ens) / "codesign.json").read_text()),
                            json.loads((args.out / "codesign" / robot / SCREENED).read_text()))
            else:
                s = joint_from_screened(robot, args.out, ens, args.contact, args.reoptimise)
            gain = s["after_slowest_bl_per_min"] / s["screened_slowest_bl_per_min"] - 1
            row = (f"| {robot} | {'off' if not ens else ', '.join(map(str, ens))} | "
                   f"{s['screened_slowest_bl_per_min']:.2f} | {_stages(s['stages'])} | {s['after_bl_per_min']:.2f}, "
                   f"{s['after_slowest_bl_per_min']:.2f}, {100 * s['after_spread']:.1f} %, "
                   f"{'yes' if s['after_holds'] else 'no'} | {100 * gain:+.1f} % | "
                   f"{s['iterations']} | {s['joint_sim_steps']:,} | {s['joint_wall_time_s'] / 60:.1f} | "
                   f"{s['credible_ratio']:.2f} | {_reoptimised(s)} |")
            lines.append(row)
            print(row, flush=True)
    lines += ["", "The slowest speed is over 16.5, 8.25, 4.125 and 2.06 ms physics steps (the hold stage's replays); "
              "the co-designed gait after the joint stage is the one on the written robot (3 more Gauss-Newton "
              "iterations there, kept when their credible rank is higher)."]
    path = args.out / "codesign_joint_ensemble.md"
    path.write_text("\n".join(lines) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
