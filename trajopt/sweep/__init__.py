"""Sweeps of gait optimisations, RL trainings and evaluations on Ray (``trajopt sweep``).

    trajopt sweep examples/sweep_speeds.toml --out results/sweeps/speeds            # local, all cores
    trajopt sweep examples/rl_seeds.toml --out results/sweeps/rl --address auto     # a running cluster

A sweep file (:mod:`trajopt.sweep.spec`) lists runs with parameter grids, their options checked
against the kinds' descriptions (:mod:`trajopt.sweep.kinds`); each run is one Ray task
(:mod:`trajopt.sweep.task`) that calls the library functions the single ``trajopt`` command
calls and writes under ``OUT/<run>/``; :mod:`trajopt.sweep.runner` schedules them, resumes and records
faults; :mod:`trajopt.sweep.summary` writes summary.csv, summary.md and summary.png. Ray is an
optional dependency (``pip install soft-envs[ray]``), imported only when a sweep starts. The
``trajopt sweep`` command is :mod:`trajopt.cli.sweep`.
"""
from .runner import SweepOutcome, run_sweep
from .spec import KINDS, Run, SweepSpec, load_spec, quick_requested
from .summary import write_summary
from .task import execute, read_status

__all__ = ["load_spec", "run_sweep", "write_summary", "execute", "read_status", "quick_requested",
           "SweepSpec", "SweepOutcome", "Run", "KINDS"]
