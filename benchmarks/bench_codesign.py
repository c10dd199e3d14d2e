"""Co-design targets: one ``trajopt codesign`` run per shipped robot, Coulomb law,
motors' limits on.

For each robot: the shipped design's fastest gait (``--speed max``, the baseline), the
co-designed robot's gait (>= 1.25x the baseline), the written robot reloaded from its files with
its gait re-optimised from scratch by ``--speed max`` (>= 1.2x), the independent constraint
checks of the written files, and the run's wall time (<= 20 minutes on the 2-core machine) and
Gauss-Newton iterations. The primary figures are credible speeds, as the run reports them
(``codesign.json``): each gait's slowest speed over 16.5, 8.25, 4.125 and 2.06 ms physics steps
(the baseline's and the re-optimised gait's from their searches' hold stages), its spread
(max - min) / slowest, and the ratios of the slowest speeds. Prints the figures and writes
benchmarks/results/codesign.md; each run's folder (robot, gaits, report, picture) under
benchmarks/results/codesign/ROBOT/.

The checkpoint after the screening is kept, ``DIR/screened.partial.json``: from it
``benchmarks/bench_codesign_joint.py`` measures the joint stage with and without an ensemble.

Every gait is also replayed independently as the headline's bar replays it
(``bench_headline.bar_row``: the same four steps, the torque-speed line checked at every one),
the last table.

Run:  python benchmarks/bench_codesign.py [ROBOT ...] [--contact LAW] [--baseline-dir DIR]
      (--baseline-dir: reuse DIR/ROBOT_base.npz, made by `trajopt optimize ROBOT --speed max`;
      the time of the run then excludes that search, which the table says)
      python benchmarks/bench_codesign.py [ROBOT ...] --replay-only   (the report from the runs'
      folders under OUT/codesign/, their codesign.json and gaits; no co-design is run)
      --joint-ensemble N[,N...]|off: the joint Gauss-Newton's ensemble (default 2,8, as trajopt codesign)
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import platform
import sys
import time
from pathlib import Path

from bench_headline import MAX_SPREAD, bar_row
from trajopt.cli.codesign import ensemble_counts
from trajopt.codesign.run import CodesignRun, run_codesign
from trajopt.codesign.summary import describe_credible

HERE = Path(__file__).resolve().parent
TARGET_RATIO, TARGET_REOPT, TARGET_MINUTES = 1.25, 1.2, 20.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("robots", nargs="*", default=["tripod", "puppy"])
    ap.add_argument("--contact", default="coulomb")
    ap.add_argument("--baseline-dir", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--screen", choices=("warm", "scratch"), default="warm", help="the screening's score")
    ap.add_argument("--rounds", type=int, default=None, help="screening rounds at most (default: ScreenSettings')")
    ap.add_argument("--screen-rank", choices=("slowest", "holds-first"), default="slowest",
                    help="how the screening ranks its candidates (default: slowest, as trajopt codesign)")
    ap.add_argument("--workers", type=int, default=None, help="processes scoring the screening's candidates "
                    "(default: one per core)")
    ap.add_argument("--joint-ensemble", type=ensemble_counts, default=None, metavar="N[,N...]|off",
                    help="the joint Gauss-Newton's ensemble, as trajopt codesign's (default 2,8)")
    ap.add_argument("--replay-only", action="store_true",
                    help="no co-design: the report from the folders of runs made before (OUT/codesign/ROBOT/)")
    args = ap.parse_args()
    rows = []
    for robot in args.robots:
        if args.replay_only:
            summary = json.loads((args.out / "codesign" / robot / "codesign.json").read_text())
            rows.append((robot, summary, float(summary["wall_time_s"]), False))
            continue
        base = args.baseline_dir / f"{robot}_base.npz" if args.baseline_dir else None
        out = args.out / "codesign" / robot
        t0 = time.perf_counter()
        run = CodesignRun(robot, out, contact=args.contact, baseline=base, overwrite=True, workers=args.workers)
        run.screen = dataclasses.replace(run.screen, score=args.screen, rank=args.screen_rank,
                                         rounds=run.screen.rounds if args.rounds is None else args.rounds)
        if args.joint_ensemble is not None:
            run.joint = dataclasses.replace(run.joint, ensemble=args.joint_ensemble)
        (out / SCREENED).unlink(missing_ok=True)
        with keep_screened():
            outcome = run_codesign(run)
        wall = time.perf_counter() - t0
        s = outcome.summary
        rows.append((robot, s, wall, base is not None))
        print(f"{robot}: {describe_credible(s)} (targets {TARGET_RATIO}, {TARGET_REOPT}); {s['iterations']} "
              f"Gauss-Newton iterations; {wall / 60:.1f} min (target {TARGET_MINUTES:g}); checks "
              f"{'passed' if s['checks_passed'] else 'FAILED'}", flush=True)
    run = CodesignRun(args.robots[0], args.out, contact=args.contact, workers=args.workers)
    rounds = run.screen.rounds if args.rounds is None else args.rounds
    lines = ["# Co-design (`trajopt codesign ROBOT --vary routing,stiffness,legs`)", "",
             f"Generated by `python benchmarks/bench_codesign.py {' '.join(sys.argv[1:])}` on "
             f"{time.strftime('%Y-%m-%d')}, {args.contact} law, motors' limits on; "
             + ("the runs made before under the output folder (each robot's codesign.json), their gaits replayed; "
                if args.replay_only else f"{rounds} screening rounds at most, their candidates scored in "
                f"{run.n_workers()} process{'es' if run.n_workers() > 1 else ''}; ")
             + f"{os.cpu_count()} shared CPU cores, Python {platform.python_version()}.", "",
             "Credible speeds (the primary figures, from each run's codesign.json): each gait's slowest speed "
             "over 16.5, 8.25, 4.125 and 2.06 ms physics steps [BL/min], its spread (max - min) / slowest, and "
             "the ratios of the slowest speeds to the shipped design's (NaN: it fell at a step):", "",
             "| robot | shipped design's `--speed max`: slowest, spread | co-designed: slowest, spread | ratio "
             "(target 1.25) | re-optimised from the files: slowest, spread | ratio (target 1.2) | all hold (<= 5 %) "
             "| joint ensemble | GN iterations | co-design steps | wall time [min] (target 20) | checks |",
             "|---|---|---|---:|---|---:|---|---|---:|---:|---:|---|"]
    for robot, s, wall, reused in rows:
        cells = [_credible_cell(s, g) for g in ("before", "after", "reoptimised")]
        held = all(s.get(f"{g}_holds") for g in ("before", "after", "reoptimised"))
        lines.append(f"| {robot} | {cells[0]} | {cells[1]} | {s.get('credible_ratio', float('nan')):.2f} | {cells[2]} | "
                     f"{s.get('reoptimised_credible_ratio', float('nan')):.2f} | {'yes' if held else 'no'} | "
                     f"{','.join(map(str, s.get('joint_ensemble') or [])) or 'off'} | {s['iterations']} | "
                     f"{s['codesign_sim_steps']:,} | {wall / 60:.1f}{' (baseline search reused)' if reused else ''} | "
                     f"{'passed' if s['checks_passed'] else 'FAILED'} |")
    lines += ["", "At the own physics (8.25 ms) alone:", "",
              "| robot | shipped design, fastest gait [BL/min] | co-designed [BL/min] | ratio | "
              "re-optimised from the files [BL/min] | ratio |", "|---|---:|---:|---:|---:|---:|"]
    for robot, s, wall, reused in rows:
        lines.append(f"| {robot} | {s['before_bl_per_min']:.2f} | {s['after_bl_per_min']:.2f} | {s['ratio']:.2f} | "
                     f"{s.get('reoptimised_bl_per_min', float('nan')):.2f} | {s.get('reoptimised_ratio', float('nan')):.2f} |")
    lines += ["", "Each robot's report: `codesign/ROBOT/codesign.md` (every design change, the checks, the picture).",
              "", "The gaits replayed independently by the headline's protocol (`bench_headline.bar_row`, the "
              "torque-speed line checked at every step): the slowest, the spread, and the ratios of the slowest "
              "speeds:", "",
              "| robot | shipped design: slowest, spread | co-designed: slowest, spread | ratio (target 1.25) | "
              "re-optimised: slowest, spread | ratio (target 1.2) | all hold (<= 5 %) | worst line excess |",
              "|---|---|---|---:|---|---:|---|---:|"]
    for robot, *_ in rows:
        folder = args.out / "codesign" / robot
        gaits = [folder / "baseline_walk.npz", folder / f"{robot}_walk.npz", folder / f"{robot}_walk_reoptimised.npz"]
        bars = [bar_row(g, 10) if g.is_file() else None for g in gaits]
        base = bars[0]["slowest"] if bars[0] else float("nan")
        cells = [f"{b['slowest']:.2f}, {100 * b['spread']:.1f} %" if b else "not made" for b in bars]
        ratios = [b["slowest"] / base if b else float("nan") for b in bars[1:]]
        held = all(b is not None and b["upright"] and b["spread"] <= MAX_SPREAD for b in bars)
        excess = max((b["excess"] for b in bars if b), default=float("nan"))
        lines.append(f"| {robot} | {cells[0]} | {cells[1]} | {ratios[0]:.2f} | {cells[2]} | {ratios[1]:.2f} | "
                     f"{'yes' if held else 'no'} | {100 * excess:+.1f} % |")
        print(f"{robot}: replayed by the headline's protocol: {base:.2f} -> {ratios[0] * base:.2f} ({ratios[0]:.2f}x); "
              f"re-optimised {ratios[1] * base:.2f} ({ratios[1]:.2f}x)", flush=True)
    path = args.out / "codesign.md"
    path.write_text("\n".join(lines) + "\n")
    print(f"wrote {path}")


#: the run's checkpoint as the screening left it (benchmarks/bench_codesign_joint.py resumes from it)
SCREENED = "screened.partial.json"


@contextlib.contextmanager
def keep_screened():
    """Keep a copy of a run's first checkpoint after its screening, ``DIR/screened.partial.json``."""
    import trajopt.codesign.run as run_module
    original = run_module._write_json

    def write(path, data):
        original(path, data)
        state = data.get("state", {})
        if path.name == run_module.PARTIAL and state.get("screened") and not state.get("history") \
                and not (path.parent / SCREENED).exists():
            original(path.parent / SCREENED, data)

    run_module._write_json = write
    try:
        yield
    finally:
        run_module._write_json = original


def _credible_cell(s: dict, gait: str) -> str:
    slowest = s.get(f"{gait}_slowest_bl_per_min", float("nan"))
    if not slowest == slowest:
        return "falls at a physics step" if f"{gait}_slowest_bl_per_min" in s else "not made"
    return f"{slowest:.2f}, {100 * s[f'{gait}_spread']:.1f} %"


if __name__ == "__main__":
    main()
