"""The headline's bar: is a gait's speed a property of the robot, of its motors and not of the step?

Every result file given is replayed independently (not through the environments' sub-steps: a
bare environment whose one physics step is ``dt / n``, the result's controls joined by straight
lines in time, from rest, its prep phase and ``--cycles`` cycles) at n = 2, 4, 8 and 16 physics
steps per 0.033 s control step (16.5, 8.25, 4.125 and 2.06 ms). At every physics step the
motors' torque-speed line is checked: the normalised excess ``v / v0 + tau / stall - 1`` of
every winding step (tau of the state before and after it, v the winding speed of that step),
and the load torque against the gearbox's ``max_torque``.

Prints, per result, the speed at each n, the slowest, the spread ``(max - min) / min`` and the
worst line excess, and whether the bar holds:

* the slowest of the four >= 12.2 BL/min (Tripod) and >= 17.2 (Puppy): twice Table I;
* the spread <= 5 %;
* the line holds to 2 % (excess <= 0.02) and the torque stays under ``max_torque`` (+2 %).

    python benchmarks/bench_headline.py results/tripod_speedmax.npz results/puppy_speedmax.npz
    python benchmarks/bench_headline.py --make /tmp/headline      # runs both --speed max first
    python benchmarks/bench_headline.py --make /tmp/headline --ensemble --jobs 2   # and with --ensemble

``--out FILE`` writes the table (markdown, with the command that made it) to FILE.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from common import write_generated_table
from soft_envs.envs import MotorLaw, make_gradient_env
from trajopt.evaluation import evaluate_controls
from trajopt.replay import result_controls
from trajopt.results import Result
from trajopt.results.robot_match import locate_robot

ROOT = Path(__file__).resolve().parents[1]
STEPS = (2, 4, 8, 16)
#: the bar: twice Table I's simulated speeds (paper: Tripod 6.1, Puppy 8.6 BL/min)
BAR = {"tripod": 12.2, "puppy": 17.2}
MAX_SPREAD = 0.05
MAX_EXCESS = 0.02


def fine_replay(res: Result, n: int, n_cycles: int) -> dict:
    """``res`` replayed with one physics step of ``res.dt / n`` (module docstring): its speed
    [BL/min], uprightness, heading change over the replay (prep and cycles) [deg], worst line
    excess and peak torque against ``max_torque``."""
    s = res.settings
    env = make_gradient_env(locate_robot(res), incline_deg=float(s.get("incline_deg", 0.0)),
                            heading_deg=float(s.get("heading_deg", 0.0)), timestep=res.dt / n,
                            contact=s.get("contact", "paper"), substeps=1)
    robot = env.robot
    u, n_prep, n_cycle = result_controls(res, robot, n_cycles)
    u = np.vstack([robot.u_rest, u])                          # u_{-1} = rest at t = 0
    t = res.dt * np.arange(len(u))
    tf = res.dt / n * np.arange(1, n * (len(u) - 1) + 1)
    uf = np.stack([np.interp(tf, t, u[:, m]) for m in range(u.shape[1])], axis=1)
    seen = {}
    ev = evaluate_controls(env, uf, n_prep=n * n_prep, n_cycle=n * n_cycle,
                           heading_deg=float(s.get("heading_deg", 0.0)),
                           check_rollout=lambda traj: seen.setdefault("traj", traj))
    out = {"n": n, "speed": float(ev["speed_bl_per_min"]), "upright": bool(ev.get("upright", False)),
           "heading": float(ev.get("heading_change_deg", float("nan"))), "excess": float("nan"), "torque": float("nan")}
    if "traj" in seen:
        law = MotorLaw.of_robot(robot)
        tau = law.torque(seen["traj"].cable_deformation)                   # (steps + 1, M)
        v = np.diff(np.vstack([u[0], uf]), axis=0) / (res.dt / n)
        excess = np.maximum(v / law.no_load_speed + tau[:-1] / law.stall_torque,
                            v / law.no_load_speed + tau[1:] / law.stall_torque) - 1
        out["excess"] = float(np.where(v > 0, excess, -np.inf).max())
        out["torque"] = float((tau / law.max_torque).max() - 1)
    return out


def robot_kind(res: Result) -> str | None:
    name = Path(str(res.robot)).stem if str(res.robot).endswith(".toml") else str(res.robot)
    return next((k for k in BAR if k in name.lower()), None)


def bar_row(path: Path, n_cycles: int) -> dict:
    res = Result.load(path)
    t0 = time.process_time()
    rows = [fine_replay(res, n, n_cycles) for n in STEPS]
    speeds = np.array([r["speed"] for r in rows])
    slowest = float(speeds.min())
    spread = float((speeds.max() - speeds.min()) / abs(slowest)) if slowest else float("nan")
    excess = max(r["excess"] for r in rows)
    torque = max(r["torque"] for r in rows)
    kind = robot_kind(res)
    bar = BAR.get(kind)
    upright = all(r["upright"] for r in rows)
    held = bool(bar is not None and slowest >= bar and spread <= MAX_SPREAD and excess <= MAX_EXCESS
                and torque <= MAX_EXCESS and upright)
    return {"file": path.name, "robot": kind or str(res.robot), "own": float(res.evaluation.get("speed_bl_per_min",
                                                                                               float("nan"))),
            "substeps": int(res.settings.get("substeps", 1)), "motor_model": res.settings.get("motor_model", "?"),
            "rows": rows, "slowest": slowest, "spread": spread, "excess": excess, "torque": torque,
            "upright": upright, "bar": bar, "held": held, "cpu_s": time.process_time() - t0}


def table(rows: list[dict], n_cycles: int) -> str:
    head = ("| result | physics, motors | own speed | " + " | ".join(f"{33 / n:.3g} ms" for n in STEPS)
            + " | slowest | spread | line excess | torque / max | bar | held |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        speeds = " | ".join(f"{x['speed']:.2f}{'' if x['upright'] else ' (fell)'}" for x in r["rows"])
        lines.append(f"| {r['file']} | {r['substeps']} steps, {r['motor_model']} | {r['own']:.2f} | {speeds} | "
                     f"{r['slowest']:.2f} | {100 * r['spread']:.1f} % | {100 * r['excess']:+.1f} % | "
                     f"{100 * r['torque']:+.1f} % | {r['bar'] if r['bar'] is not None else '-'} | "
                     f"{'yes' if r['held'] else 'NO'} |")
    lines.append("")
    lines.append(f"Speeds [BL/min] over the prep phase and {n_cycles} cycles, replayed at each physics step; "
                 f"spread = (max - min) / slowest; line excess: the worst winding step's "
                 f"v / v0 + tau / stall - 1 over every physics step (<= 2 %); torque / max: the peak load "
                 f"torque against max_torque (<= +2 %).")
    return "\n".join(lines)


def make(out: Path, ensemble: bool = False, jobs: int = 1) -> list[Path]:
    """``trajopt optimize ROBOT --speed max`` for both robots into ``out`` (``ensemble``: also
    with ``--ensemble``, named ``ROBOT_speedmax_ensemble``), ``jobs`` at a time."""
    out.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    runs = [(robot, extra) for extra in ([[], ["--ensemble"]] if ensemble else [[]]) for robot in ("tripod", "puppy")]
    names = [f"{robot}_speedmax{'_ensemble' if extra else ''}" for robot, extra in runs]
    order = sorted(range(len(runs)), key=lambda i: (not runs[i][1], runs[i][0] != "puppy"))   # longest first
    pending, running = list(order), []
    while pending or running:
        while pending and len(running) < max(1, jobs):
            i = pending.pop(0)
            robot, extra = runs[i]
            cmd = [sys.executable, "-m", "trajopt.cli", "optimize", robot, "--speed", "max", *extra,
                   "--out", str(out), "--name", names[i], "--quiet", "--overwrite"]
            running.append((i, subprocess.Popen(cmd, env=env), time.perf_counter()))
        time.sleep(1.0)
        for entry in list(running):
            i, proc, t0 = entry
            if proc.poll() is None:
                continue
            running.remove(entry)
            if proc.returncode:
                raise SystemExit(f"trajopt optimize for {names[i]} failed (exit {proc.returncode})")
            print(f"trajopt optimize {runs[i][0]} --speed max {' '.join(runs[i][1])}: "
                  f"{time.perf_counter() - t0:.0f} s wall", flush=True)
    return [out / f"{name}.npz" for name in names]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", nargs="*", type=Path)
    ap.add_argument("--make", type=Path, metavar="OUT", help="first run --speed max for both robots into OUT")
    ap.add_argument("--ensemble", action="store_true", help="with --make: also --speed max --ensemble")
    ap.add_argument("--jobs", type=int, default=1, help="with --make: optimisations run at a time (1)")
    ap.add_argument("--cycles", type=int, default=10, help="cycles replayed after the prep phase (10)")
    ap.add_argument("--out", type=Path, help="write the table to this markdown file")
    args = ap.parse_args()
    files = list(args.results) + (make(args.make, args.ensemble, args.jobs) if args.make else [])
    if not files:
        ap.error("give result files or --make OUT")
    rows = [bar_row(p, args.cycles) for p in files]
    text = table(rows, args.cycles)
    print(text)
    if args.out:
        write_generated_table(args.out, "The headline's bar: the fastest gaits replayed at 16.5, 8.25, 4.125 and 2.06 ms",
                              "bench_headline.py", sys.argv[1:], "module docstring of benchmarks/bench_headline.py: the "
                              "bar is a slowest speed >= twice Table I, a spread <= 5 % and the motors' line held to 2 % "
                              "at every physics step", text)

if __name__ == "__main__":
    main()
