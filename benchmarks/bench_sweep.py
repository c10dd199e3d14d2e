"""Sweep benchmark: eight short gait optimisations, on a local Ray with 2 workers
vs the same runs one after another in one process (``trajopt sweep --serial``).

Both use the same sweep file and the same code per run (:func:`trajopt.sweep.task.execute`: the
library function of the run's kind, writing its own directory); the serial baseline is what a hand-written loop does.
Prints the wall times, the ratio with the Ray start-up included and without it (Ray is
started first, on its own, and timed), and the machine's load average at the start and end
(the machine may be shared: rerun when it is quiet). Target: >= 1.7x on 2 cores.

Run:  python benchmarks/bench_sweep.py [--iterations 5] [--cycle-steps 72] [--order serial-first|ray-first]
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from trajopt.sweep import load_spec, run_sweep
from trajopt.sweep.runner import start_ray

SPEC = """
[sweep]
description = "bench_sweep: eight short Tripod walking optimisations"

[[runs]]
kind = "optimize"
name = "tripod_v{{speed:g}}"
[runs.args]
robot = "tripod"
iterations = {iterations}
seeds = 2
cycle_steps = {cycle_steps}
prep_steps = 24
cycles = 2
[runs.grid]
speed = [4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0]
"""


def load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def descendants_cpu_s(root: int) -> dict[str, float]:
    """CPU seconds of every living descendant process of ``root``, by command name (Ray's
    daemons and workers, read from /proc)."""
    procs = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as fh:
                    head, rest = fh.read().rsplit(")", 1)
                f = rest.split()
                procs[int(d)] = (head.split("(", 1)[1], int(f[1]), (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK"))
            except (OSError, IndexError, ValueError):
                pass
    out: dict[str, float] = {}
    for pid, (name, _, cpu) in procs.items():
        p = pid
        while p in procs and p != root:
            p = procs[p][1]
        if p == root and pid != root:
            out[name] = out.get(name, 0.0) + cpu
    return out


def runs_cpu_s(o) -> float:
    return sum(st.get("cpu_time_s", 0.0) for st in o.statuses.values())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--iterations", type=int, default=5, help="Gauss-Newton iterations per run")
    ap.add_argument("--cycle-steps", type=int, default=72)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--order", choices=["serial-first", "ray-first"], default="serial-first")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    spec_path = tmp / "bench.toml"
    spec_path.write_text(SPEC.format(iterations=args.iterations, cycle_steps=args.cycle_steps))
    print(f"load average at start: {load()} ({os.cpu_count()} CPUs); runs under {tmp}")

    cpu: dict[str, float] = {}

    def serial() -> float:
        out = tmp / "serial"
        t0 = time.perf_counter()
        o = run_sweep(load_spec(spec_path, out), out, serial=True)
        assert o.count("done") == 8, {k: v.get("reason") for k, v in o.statuses.items()}
        cpu["serial runs"] = runs_cpu_s(o)
        return time.perf_counter() - t0

    def on_ray() -> tuple[float, float]:
        out = tmp / "ray"
        t0 = time.perf_counter()
        ray, _ = start_ray(workers=args.workers)
        t_start = time.perf_counter() - t0
        try:
            o = run_sweep(load_spec(spec_path, out), out)
            daemons = descendants_cpu_s(os.getpid())
        finally:
            ray.shutdown()
        assert o.count("done") == 8, {k: v.get("reason") for k, v in o.statuses.items()}
        cpu["ray runs"] = runs_cpu_s(o)
        cpu["ray processes"] = sum(daemons.values())
        cpu["ray daemons"] = sum(v for k, v in daemons.items() if not k.startswith("ray::"))
        return time.perf_counter() - t0, t_start

    if args.order == "serial-first":
        t_serial = serial()
        t_ray, t_start = on_ray()
    else:
        t_ray, t_start = on_ray()
        t_serial = serial()
    print(f"eight optimisations ({args.iterations} Gauss-Newton iterations, {args.cycle_steps}-step cycles):")
    print(f"  one after another (one process): {t_serial:7.1f} s")
    print(f"  sweep on Ray, {args.workers} workers:        {t_ray:7.1f} s   (of which Ray start {t_start:.1f} s)")
    print(f"  ratio: {t_serial / t_ray:.2f}x with the Ray start, {t_serial / (t_ray - t_start):.2f}x without "
          f"(target >= 1.7x)")
    print(f"  CPU seconds: the runs {cpu['serial runs']:.1f} one after another, {cpu['ray runs']:.1f} as Ray tasks; "
          f"Ray's daemons {cpu['ray daemons']:.1f} (all Ray processes {cpu['ray processes']:.1f}). "
          f"Estimate for {args.workers} idle cores (all Ray CPU / {args.workers} + start): {cpu['ray processes'] / args.workers + t_start:.1f} s "
          f"vs {cpu['serial runs']:.1f} s one after another")
    print(f"load average at end: {load()}")


if __name__ == "__main__":
    main()
