"""``trajopt sweep SPEC.toml --out DIR [--workers N] [--address auto|ray://HOST:PORT]``."""
from __future__ import annotations

import argparse
import signal
from pathlib import Path

from ..argtypes import output_dir

__all__ = ["add_sweep_parser", "run_sweep_command"]


def add_sweep_parser(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "sweep", help="run a sweep file of optimisations, RL runs and evaluations on Ray",
        description="Run every run of a sweep file as a Ray task writing under DIR/<run>/; a rerun "
                    "skips finished runs and restarts the others. Needs pip install soft-envs[ray].")
    p.add_argument("spec", type=Path, help="sweep file (TOML), e.g. examples/sweep_speeds.toml")
    p.add_argument("--out", type=output_dir, required=True, help="sweep directory (one sub-directory per run)")
    p.add_argument("--workers", type=int, default=None, help="CPUs of the local Ray (default: all cores)")
    p.add_argument("--address", default=None,
                   help="an existing Ray cluster: auto (this node's), HOST:PORT, or ray://HOST:PORT (Ray client)")
    p.add_argument("--quick", action="store_true",
                   help="the sweep file's [runs.quick] arguments (tiny runs; also SOFT_ENVS_QUICK=1)")
    p.add_argument("--serial", action="store_true", help="no Ray: the runs one after another in this process")
    p.add_argument("--only", action="append", metavar="PATTERN", default=None,
                   help="only the runs whose name matches this shell pattern (repeatable), e.g. 'tripod_*'")
    p.add_argument("--dry-run", action="store_true", help="list the runs and what is done; run nothing")
    p.add_argument("--no-plot", action="store_true", help="no summary.png")
    p.set_defaults(func=run_sweep_command)
    return p


def run_sweep_command(args) -> int:
    from ..sweep.runner import run_sweep
    from ..sweep.spec import load_spec, quick_requested
    from ..sweep.summary import statuses_on_disk, write_summary
    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers must be >= 1, got {args.workers}")
    if args.workers is not None and args.address:
        raise ValueError("--workers sizes a local Ray; with --address the cluster decides")
    full = load_spec(args.spec, args.out, quick=quick_requested(args.quick))
    spec = full.only(args.only)
    if args.dry_run:
        return _dry_run(spec, args.out.resolve())
    n = len(spec.runs)
    print(f"sweep {args.spec}: {n} runs -> {args.out}" + (" (quick)" if quick_requested(args.quick) else "")
          + (f" (--only: {n} of {len(full.runs)})" if n != len(full.runs) else ""))
    outcome = run_sweep(spec, args.out, workers=args.workers, address=args.address, serial=args.serial)
    written = write_summary(full, statuses_on_disk(full, args.out, outcome.statuses), args.out, plot=not args.no_plot)
    print(f"{outcome.count('done')} done, {outcome.count('failed')} failed, "
          f"{outcome.count('interrupted')} interrupted of {n} runs ({len(outcome.skipped)} skipped as done) "
          f"in {outcome.wall_time_s:.1f} s; wrote {', '.join(str(w) for w in written)}")
    for name, st in outcome.statuses.items():
        if st.get("status") == "failed":
            print(f"  failed: {name}: {st.get('reason')}")
    if outcome.interrupted:
        print("interrupted: run the same command again to continue")
        return 128 + int(outcome.signal or signal.SIGINT)       # 130 Ctrl-C, 143 SIGTERM, as the other commands
    return 1 if outcome.count("failed") else 0


def _dry_run(spec, out: Path) -> int:
    """List the runs: done, to run, or refused (what their start would refuse: an unknown
    robot, a negative physical value); exit 2 when any is refused. Writes nothing."""
    from ..sweep.runner import plan
    from ..results.reservation import read_owner
    from ..sweep.task import SWEEP_LOCK, check_run
    todo, done = plan(spec, out)
    refused = 0
    for run in spec.runs:
        why = ""
        if run.name in done:
            state = "done"
        else:
            try:
                check_run(run)
                state = "to run"
            except ValueError as exc:
                state, why, refused = "refused", str(exc), refused + 1
        print(f"{state:<7} {run.name:<32} trajopt {' '.join(run.argv())}")
        if why:
            print(f"        {why}")
    print(f"{len(done)} done, {len(todo) - refused} to run" + (f", {refused} refused" if refused else ""))
    owner = read_owner(out / SWEEP_LOCK)
    if owner is not None:
        print(f"{out / SWEEP_LOCK}: a sweep holds this folder (pid {owner.get('pid')} on host {owner.get('host')})")
    return 2 if refused else 0
