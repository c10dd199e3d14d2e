"""How credible each quoted speed is: results replayed at every physics step from 33 to 2.06 ms.

For every result file given (or made with ``--make``), the speed of its evaluation replayed with
1, 2, 4, 8 and 16 physics steps per 0.033 s control step (33, 16.5, 8.25, 4.125, 2.06 ms), the
speed at its own physics, and the deviation at 4x finer steps than its own (the converged-physics
bar: within 3 %). ``--make OUT`` first makes the README's gaits with the project's commands, under
the default physics and (``--before``) under one step of 33 ms, the physics they were made with
before sub-steps (``--substeps 1``):

* ``trajopt optimize tripod --task walk`` and ``puppy --task walk`` (Table I's walks),
* ``trajopt optimize puppy --task turn`` (the quarter circle),
* ``trajopt optimize puppy --task incline --angle 10 --warm-start <the walk>``,
* ``trajopt optimize tripod|puppy --task walk --speed max`` (with ``--speed-max``: minutes each).

Run: ``python benchmarks/bench_fidelity.py results/*.npz`` or
``python benchmarks/bench_fidelity.py --make /tmp/fid [--before] [--speed-max]``.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

from common import report
from trajopt.fidelity import speed_at
from trajopt.replay import result_substeps
from trajopt.results import Result

ROOT = Path(__file__).resolve().parents[1]
STEPS = (1, 2, 4, 8, 16)


def _optimize(out: Path, name: str, *args: str) -> Path:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    subprocess.run([sys.executable, "-m", "trajopt.cli", "optimize", *args, "--out", str(out), "--name", name,
                    "--quiet", "--overwrite"], check=True, env=env)
    return out / f"{name}.npz"


def make(out: Path, before: bool, speed_max: bool) -> list[Path]:
    """The README's gaits under the default physics (and one step of 33 ms with ``before``)."""
    out.mkdir(parents=True, exist_ok=True)
    made = []
    for tag, extra in [("", ())] + ([("_33ms", ("--substeps", "1"))] if before else []):
        walk = {r: _optimize(out, f"{r}_walk{tag}", r, "--task", "walk", *extra) for r in ("tripod", "puppy")}
        made += list(walk.values())
        made.append(_optimize(out, f"puppy_turn{tag}", "puppy", "--task", "turn", *extra))
        made.append(_optimize(out, f"puppy_incline10{tag}", "puppy", "--task", "incline", "--angle", "10",
                              "--warm-start", str(walk["puppy"]), *extra))
        if speed_max:
            made += [_optimize(out, f"{r}_speedmax{tag}", r, "--task", "walk", "--speed", "max", *extra)
                     for r in ("tripod", "puppy")]
    return made


def row(path: Path) -> dict:
    res = Result.load(path)
    n = result_substeps(res)
    speeds = {m: speed_at(res, m)["speed_bl_per_min"] for m in sorted(set(STEPS) | {n, 4 * n})}
    own, finer = speeds[n], speeds[4 * n]
    out = {"result": path.name, "made at [ms]": round(33.0 / n, 3)}
    out |= {f"{33.0 / m:g} ms": round(speeds[m], 3) for m in STEPS}
    out |= {"own": round(own, 3), "4x finer": round(finer, 3),
            "deviation": f"{100 * (finer - own) / abs(own):+.2f} %" if own else "n/a",
            "within 3 %": bool(own and abs(finer - own) <= 0.03 * abs(own))}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", nargs="*", type=Path, help="result files (.npz)")
    ap.add_argument("--make", type=Path, default=None, metavar="OUT", help="make the README's gaits into OUT first")
    ap.add_argument("--before", action="store_true", help="with --make: also under one step of 33 ms")
    ap.add_argument("--speed-max", action="store_true", help="with --make: also the --speed max gaits")
    args = ap.parse_args()
    paths = list(args.results)
    if args.make is not None:
        paths += make(args.make, args.before, args.speed_max)
    if not paths:
        ap.error("give result files or --make OUT")
    report("speed [BL/min] of each result at every physics step (control step 33 ms)", [row(p) for p in paths])


if __name__ == "__main__":
    main()
