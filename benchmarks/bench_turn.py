"""The Puppy's turn under the motors' limits, and whether its heading holds at finer steps.

Table I's turn (``trajopt optimize puppy --task turn``, warm-started from the walk) keeps the
paper's 72-step cycle. Under the gearmotors' torque-speed line it turns +77 deg over the
optimised horizon (prep + 2 cycles), short of the quarter circle. The cycle period is free, as
``--speed max`` treats it: this script optimises the turn at each cycle length given, from the
same walk, and replays every result independently (:func:`bench_headline.fine_replay`: a bare
environment whose one physics step is ``dt / n``, the controls joined by straight lines in
time, from rest) at n = 2, 4, 8 and 16 physics steps per 0.033 s control step (16.5, 8.25,
4.125 and 2.06 ms), with the motors' torque-speed line checked at every physics step.

Prints per result the heading change over the horizon (prep + 2 cycles) and over prep + 6
cycles at each n, the smallest of each, their spread ``(max - min) / min``, the rate [deg/s]
and the worst line excess. The bar (issue "the headline, re-earned"): >= +80 deg over the
horizon and >= +190 deg over 6 cycles at every n, upright, the line held to 2 %.

    python benchmarks/bench_turn.py --make /tmp/turns                       # cycles 72 84 96 (~15 min)
    python benchmarks/bench_turn.py --make /tmp/turns --cycle-steps 96      # one of them
    python benchmarks/bench_turn.py --make /tmp/turns --cycle-steps 96 --ensemble 2   # optimised at 16.5 ms too
    python benchmarks/bench_turn.py RESULT.npz ...                          # results made before
    python benchmarks/bench_turn.py --make /tmp/turns --out benchmarks/results/turn.md
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

from bench_headline import MAX_EXCESS, STEPS, fine_replay
from common import write_generated_table
from trajopt.results import Result

ROOT = Path(__file__).resolve().parent.parent
WALK = ROOT / "benchmarks" / "results" / "puppy_walk_coulomb.npz"       # Table I's walk (bench_trajopt.py)
BAR_HORIZON_DEG, BAR_SIX_CYCLES_DEG = 80.0, 190.0


def make(out: Path, cycles: list[int], walk: Path, ensemble: list[int] | None = None) -> list[Path]:
    """``trajopt optimize puppy --task turn --warm-start WALK --cycle-steps C`` for each C, into
    ``out`` (``ensemble``: ``--ensemble N ...`` too, optimised on those physics as well)."""
    out.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    paths = []
    for c in cycles:
        name = f"puppy_turn_c{c}" + ("_ensemble" + "_".join(map(str, ensemble)) if ensemble else "")
        extra = ["--ensemble", *map(str, ensemble)] if ensemble else []
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "trajopt.cli", "optimize", "puppy", "--task", "turn", "--warm-start",
                        str(walk), "--cycle-steps", str(c), "--out", str(out), "--name", name, "--quiet",
                        "--overwrite", *extra], check=True, env=env, stdout=subprocess.DEVNULL)
        print(f"trajopt optimize puppy --task turn --cycle-steps {c} {' '.join(extra)}: "
              f"{time.perf_counter() - t0:.0f} s wall", flush=True)
        paths.append(out / f"{name}.npz")
    return paths


def turn_row(path: Path) -> dict:
    """One result replayed at every n over prep + 2 and prep + 6 cycles (module docstring)."""
    res = Result.load(path)
    s = res.settings
    horizon = [fine_replay(res, n, 2) for n in STEPS]
    six = [fine_replay(res, n, 6) for n in STEPS]
    h = [r["heading"] for r in horizon]
    h6 = [r["heading"] for r in six]
    seconds = (s["n_prep"] + 2 * s["n_cycle"]) * res.dt
    row = {"file": path.name, "cycle": int(s["n_cycle"]), "keyframes": int(s["n_keyframes"]),
           "own_horizon": float(res.evaluation.get("horizon_heading_change_deg", float("nan"))),
           "horizon": h, "six": h6, "min_horizon": min(h), "min_six": min(h6),
           "spread_horizon": (max(h) - min(h)) / abs(min(h)), "spread_six": (max(h6) - min(h6)) / abs(min(h6)),
           "rate": min(h) / seconds, "upright": all(r["upright"] for r in horizon + six),
           "excess": max(r["excess"] for r in horizon + six), "torque": max(r["torque"] for r in horizon + six)}
    row["held"] = bool(row["min_horizon"] >= BAR_HORIZON_DEG and row["min_six"] >= BAR_SIX_CYCLES_DEG
                       and row["upright"] and row["excess"] <= MAX_EXCESS and row["torque"] <= MAX_EXCESS)
    return row


def table(rows: list[dict]) -> str:
    steps = " | ".join(f"{33 / n:.3g} ms" for n in STEPS)
    lines = [f"| result | cycle, keyframes | own horizon [deg] | horizon: {steps} | smallest | spread | "
             f"6 cycles: {steps} | smallest | spread | rate [deg/s] | line excess | bar | held |"]
    lines.append("|" + "---|" * (lines[0].count("|") - 1))
    for r in rows:
        lines.append(f"| {r['file']} | {r['cycle']}, {r['keyframes']} | {r['own_horizon']:+.1f} | "
                     + " | ".join(f"{v:+.1f}" for v in r["horizon"]) + f" | {r['min_horizon']:+.1f} | "
                     f"{100 * r['spread_horizon']:.1f} % | " + " | ".join(f"{v:+.1f}" for v in r["six"])
                     + f" | {r['min_six']:+.1f} | {100 * r['spread_six']:.1f} % | {r['rate']:.1f} | "
                     f"{100 * r['excess']:+.1f} % | >= +{BAR_HORIZON_DEG:g} / +{BAR_SIX_CYCLES_DEG:g} | "
                     f"{'yes' if r['held'] else 'NO'} |")
    lines += ["", "Heading change [deg] of the body over the prep phase and 2 cycles (the optimised horizon) "
              "and over the prep phase and 6 cycles, replayed at each physics step; spread = (max - min) / "
              "smallest; rate: the smallest horizon heading per second of horizon; line excess: the worst "
              "winding step's v / v0 + tau / stall - 1 over every physics step (<= 2 %)."]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", nargs="*", type=Path)
    ap.add_argument("--make", type=Path, metavar="OUT", help="first optimise the turn at each --cycle-steps into OUT")
    ap.add_argument("--cycle-steps", type=int, nargs="+", default=[72, 84, 96], help="with --make (72 84 96)")
    ap.add_argument("--ensemble", type=int, nargs="+", default=None, metavar="N",
                    help="with --make: optimise on these physics steps per control step as well (trajopt optimize --ensemble)")
    ap.add_argument("--walk", type=Path, default=WALK, help=f"the walk to warm-start from ({WALK.relative_to(ROOT)})")
    ap.add_argument("--out", type=Path, help="write the table to this markdown file")
    args = ap.parse_args()
    files = list(args.results) + (make(args.make, args.cycle_steps, args.walk, args.ensemble) if args.make else [])
    if not files:
        ap.error("give result files or --make OUT")
    text = table([turn_row(p) for p in files])
    print(text)
    if args.out:
        write_generated_table(args.out, "The Puppy's turn under the motors' torque-speed line, replayed at 16.5, 8.25, "
                              "4.125 and 2.06 ms", "bench_turn.py", sys.argv[1:],
                              "module docstring of benchmarks/bench_turn.py", text)

if __name__ == "__main__":
    main()
