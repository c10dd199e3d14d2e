"""First run on a fresh install: ``trajopt optimize ROBOT --task walk`` on a cold numba cache.

Each run is a fresh ``trajopt`` process with an empty ``NUMBA_CACHE_DIR`` (a new temporary
folder, so no cache of this checkout is touched), alternately with the largest kernel compiled
ahead in a child process (``SOFT_ENVS_COMPILE_AHEAD=1``; by default only when a core is idle, see
``soft_envs.sim.warmup.compile_ahead``) and without (``=0``: numba compiles each kernel on first
use); then once more on the warm cache the last run left. Prints wall time and CPU time (the
process and its children) per run, the medians and the cold/warm ratios. The child only helps
when a core is idle: on a loaded machine it takes CPU time from the main process and the wall
times say little (the load average is printed with each run).

Run: python benchmarks/bench_first_run.py [--robot tripod] [--repeat 2] [--iterations 10]
"""
from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import report

ROOT = Path(__file__).resolve().parents[1]


def run(robot: str, iterations: int, cache: str, ahead: bool, out: str) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, SOFT_ENVS_COMPILE_AHEAD="1" if ahead else "0",
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    cmd = [sys.executable, "-m", "trajopt.cli", "optimize", robot, "--task", "walk", "--out", out, "--quiet",
           "--iterations", str(iterations)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    said = "compiling the simulator's kernels" in proc.stdout
    return {"wall_s": wall, "cpu_s": cpu, "said_compiling": said, "load_1min": os.getloadavg()[0]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--robot", default="tripod")
    p.add_argument("--repeat", type=int, default=2, help="cold runs of each kind (alternating)")
    p.add_argument("--iterations", type=int, default=10, help="Gauss-Newton iterations per run")
    args = p.parse_args()
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_first_run_") as tmp:
        cache = ""
        for r in range(args.repeat):
            for ahead in (False, True):
                cache = tempfile.mkdtemp(dir=tmp, prefix="numba_")
                res = run(args.robot, args.iterations, cache, ahead, str(Path(tmp) / "out"))
                rows.append({"cache": "cold", "compile_ahead": ahead, "run": r + 1, **res})
                print(rows[-1], flush=True)
        res = run(args.robot, args.iterations, cache, True, str(Path(tmp) / "out"))
        rows.append({"cache": "warm", "compile_ahead": True, "run": 1, **res})
    report(f"trajopt optimize {args.robot} --task walk --iterations {args.iterations}: first run", rows)
    warm = rows[-1]["wall_s"]
    for ahead in (False, True):
        walls = [r["wall_s"] for r in rows if r["cache"] == "cold" and r["compile_ahead"] == ahead]
        cpus = [r["cpu_s"] for r in rows if r["cache"] == "cold" and r["compile_ahead"] == ahead]
        print(f"cold, compile ahead {'on ' if ahead else 'off'}: median wall {statistics.median(walls):.1f} s "
              f"({statistics.median(walls) / warm:.2f}x the warm run), median CPU {statistics.median(cpus):.1f} s")
    print(f"warm: wall {warm:.1f} s, CPU {rows[-1]['cpu_s']:.1f} s")


if __name__ == "__main__":
    main()
