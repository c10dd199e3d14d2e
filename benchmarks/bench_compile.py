"""The simulator's cold compile: ``python -m soft_envs.sim.warmup`` on an empty numba cache.

Each run is a fresh process with an empty ``NUMBA_CACHE_DIR`` (a new temporary folder, so no
cache of a checkout is touched) that compiles every kernel (``compile_kernels`` and
``compile_box_kernels`` of the Tripod) and then counts the compiled versions of the package's
kernels (numba compiles a kernel once per distinct argument types: a read-only and a writeable
array are two). Prints per run the CPU time, the wall time and the number of versions. With
``--against REF`` the runs alternate between this checkout and ``REF`` (a git worktree made for
the purpose and removed after): the CPU-time ratio of one run is the figure to read on a shared
machine.

Run: python benchmarks/bench_compile.py [--robot tripod] [--repeat 2] [--against HEAD~1]
"""
from __future__ import annotations

import argparse
import json
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

#: run in the child: compile everything, then count each kernel's compiled versions
CHILD = """
import json, sys
from soft_envs.sim import warmup
warmup.main([sys.argv[1]])
from numba.core.registry import CPUDispatcher
versions = {}
for name, mod in list(sys.modules.items()):
    if name.startswith("soft_envs"):
        for attr, value in vars(mod).items():
            if isinstance(value, CPUDispatcher) and value.py_func.__module__ == name:
                versions[name + "." + attr] = len(value.signatures)
print("VERSIONS " + json.dumps(versions))
"""


def run(checkout: Path, robot: str) -> dict:
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, SOFT_ENVS_COMPILE_AHEAD="0", PYTHONPATH=str(checkout))
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-c", CHILD, robot], env=env, cwd=checkout, capture_output=True,
                              text=True)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"the warm-up of {checkout} failed:\n{proc.stderr[-2000:]}")
    versions = json.loads(proc.stdout.split("VERSIONS ", 1)[1])
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"cpu_s": cpu, "wall_s": wall, "kernels": len(versions), "versions": sum(versions.values()),
            "twice_or_more": sorted(k for k, v in versions.items() if v > 1), "load_1min": os.getloadavg()[0]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--robot", default="tripod")
    p.add_argument("--repeat", type=int, default=2)
    p.add_argument("--against", metavar="REF", help="a git ref to compare with (runs alternate)")
    args = p.parse_args()
    checkouts = {"this checkout": ROOT}
    worktree = None
    if args.against:
        worktree = Path(tempfile.mkdtemp(prefix="bench_compile_"))
        subprocess.run(["git", "worktree", "add", "--detach", str(worktree), args.against], cwd=ROOT, check=True,
                       capture_output=True)
        checkouts[args.against] = worktree
    runs: dict[str, list[dict]] = {name: [] for name in checkouts}
    try:
        for i in range(args.repeat):
            for name, path in checkouts.items():
                r = run(path, args.robot)
                runs[name].append(r)
                print(f"run {i + 1} {name:>14}: CPU {r['cpu_s']:6.1f} s, wall {r['wall_s']:6.1f} s, "
                      f"{r['versions']} versions of {r['kernels']} kernels (load {r['load_1min']:.2f})", flush=True)
    finally:
        if worktree is not None:
            subprocess.run(["git", "worktree", "remove", "--force", str(worktree)], cwd=ROOT, capture_output=True)
    rows = []
    for name, rs in runs.items():
        rows.append({"checkout": name, "cpu_s_median": statistics.median(r["cpu_s"] for r in rs),
                     "wall_s_median": statistics.median(r["wall_s"] for r in rs), "versions": rs[-1]["versions"],
                     "kernels": rs[-1]["kernels"]})
        print(f"{name}: compiled more than once: "
              f"{', '.join(k.split('.', 2)[-1] for k in rs[-1]['twice_or_more']) or 'none'}")
    if args.against:
        ratios = [a["cpu_s"] / b["cpu_s"] for a, b in zip(runs["this checkout"], runs[args.against])]
        print(f"CPU time, this checkout / {args.against}, per run: {', '.join(f'{r:.2f}' for r in ratios)}")
    report("cold compile of the simulator's kernels", rows)


if __name__ == "__main__":
    main()
