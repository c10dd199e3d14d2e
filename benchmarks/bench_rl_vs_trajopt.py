"""Fastest gaits under the motors' limit: trajectory optimisation against RL on the same
physics.

The runs are a sweep file (``trajopt sweep``, one Ray task per run; on a cluster the same
file runs unchanged): ``examples/rl_seeds_coulomb.toml`` (``--contact coulomb``, the default
law) or ``examples/rl_seeds.toml`` (``--contact paper``). For each robot (Tripod, Puppy):

* **trajopt** ``trajopt optimize ROBOT --speed max`` (the fastest gait within the motors'
  limits; cycle length and keyframes searched) with a budget of one PPO seed's simulation
  steps. Its gait is also stepped through the Gymnasium environment with the motor limit on, and
  the limit is checked independently of the optimiser (the controls rebuilt from the keyframes
  and the robot file, every step over 10 cycles, rest and wrap-around included).
* **PPO** and **SAC** (``trajopt rl train``, Stable-Baselines3, documented hyper-parameters),
  three seeds each, every checkpoint scored with the shared metric.
* **PPO with 5x the budget**, one seed per robot: does RL keep improving?

Both sides are also replayed, the same way, with half the physics steps per control step (16.5 ms
under the Coulomb law's default 4 steps of 8.25 ms; left out at one step per control step) and
2x, 4x and 8x as many (RL's policy closed loop through the environment, ``substeps``): the steps
of the headline's bar and one finer, :data:`COMPARISON_FACTORS`. The credible speed of a gait or a
policy is the slowest of them (:mod:`trajopt.fidelity`, :func:`trajopt.rl.evaluate.policy_fidelity`).

Same physics (robot files, contact law, motors) and the same evaluation on both sides:
trajopt's ``evaluate_controls``, mean COM speed along +x in body lengths per minute over 432
steps after 24 prep steps from the exact rest state, upright throughout (trajopt's keyframes
repeated to fill the window; RL's deterministic policy closed loop in the environment).
Simulation steps: trajopt every rollout step of its search (optimisations with Jacobian
rollouts, line-search trials and seed screening, and its own evaluations:
``evaluation["search_sim_steps"]``); RL its training environment steps. Wall time: each run's
own, all runs of one sweep on the same machine.

This script runs the sweep (skipping runs already done in the sweep directory) and then the
report (:mod:`rl_vs_trajopt_report`): ``benchmarks/results/rl_vs_trajopt_coulomb.md`` / ``.png``
(``--contact paper``: ``rl_vs_trajopt.md`` / ``.png``).

Run:  python benchmarks/bench_rl_vs_trajopt.py                         (about an hour on 2 cores)
      python benchmarks/bench_rl_vs_trajopt.py --contact paper
      python benchmarks/bench_rl_vs_trajopt.py --report-only           (the report from the runs done)
      python benchmarks/bench_rl_vs_trajopt.py --quick                 (minutes; checks the pipeline only)
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import soft_envs  # noqa: F401
from bench_fastest_gait import independent_limit_check
from rl_vs_trajopt_report import write_report
from trajopt import Result
from trajopt.evaluation import evaluate_controls
from trajopt.optim.gait import GaitSpec
from trajopt.replay import env_for_result, result_parameterization
from trajopt.rl.envs import GAIT, env_id, run_substeps
from trajopt.fidelity import fidelity, substeps_at
from trajopt.replay import result_substeps
from trajopt.rl.evaluate import load_policy, play_controls_in_env, policy_fidelity, run_metric
from trajopt.sweep import load_spec, quick_requested, read_status, run_sweep, write_summary
from trajopt.sweep.summary import statuses_on_disk

HERE = Path(__file__).resolve().parent
SPECS = {"coulomb": HERE.parent / "examples" / "rl_seeds_coulomb.toml",
         "paper": HERE.parent / "examples" / "rl_seeds.toml"}
REPORTS = {"coulomb": "rl_vs_trajopt_coulomb.md", "paper": "rl_vs_trajopt.md"}
LAW_NAMES = {"coulomb": "Coulomb", "paper": "the paper's"}
N_PREP = GAIT.n_prep
EVAL_STEPS = 6 * GAIT.n_cycle                   # 432 steps after the prep phase


#: the physics both sides are replayed at, as factors of their own physics steps per control step:
#: half (16.5 ms: the hold stage of --speed max asks for it, so RL is asked too) and 2x, 4x, 8x
COMPARISON_FACTORS = (0.5, 2, 4, 8)


def comparison_factors(substeps: int) -> tuple[float, ...]:
    """:data:`COMPARISON_FACTORS` that give a whole number of physics steps (no half of one step:
    :func:`trajopt.fidelity.substeps_at` refuses it)."""
    out = []
    for f in COMPARISON_FACTORS:
        try:
            substeps_at(substeps, f)
        except ValueError:
            continue
        out.append(f)
    return tuple(out)


def dominant_period(u: np.ndarray) -> float:
    """Period [simulation steps] of the strongest non-constant Fourier component of the
    controls (summed over motors)."""
    u = np.asarray(u, dtype=np.float64)
    spec = (np.abs(np.fft.rfft(u - u.mean(axis=0), axis=0)) ** 2).sum(axis=1)
    if len(spec) < 2 or spec[1:].max() <= 0:
        return float("inf")
    return len(u) / (int(np.argmax(spec[1:])) + 1)


# ----------------------------------------------------------------------------- collect
def trajopt_row(run_dir: Path, name: str) -> dict:
    """A ``--speed max`` result: its speed over the RL window, in the environment with the motor
    limit, the independent limit check, its simulation steps and wall time."""
    res = Result.load(run_dir / f"{name}.npz")
    s, ev = res.settings, res.evaluation
    physics = env_for_result(res)            # the result's robot and contact law
    param = result_parameterization(res, physics.robot)
    gait = GaitSpec.from_settings(s)
    n_cycles = max(1, math.ceil(EVAL_STEPS / s["n_cycle"]))
    u = param.controls(res.z, n_cycles)
    window = evaluate_controls(physics, u, n_prep=s["n_prep"], n_cycle=s["n_cycle"])
    env = gym.make(env_id(res.robot), contact=physics.contact_model, reset_noise_scale=0.0,
                   terminate_when_unhealthy=False, max_episode_steps=len(u))      # motor limit on
    acts = env.unwrapped.control_to_action(u)
    rec = play_controls_in_env(env, lambda obs, k: acts[k], len(u), seed=0)
    in_env = run_metric(env, rec["u"], rec["x"], gait=gait)["speed_bl_per_min"]
    env.close()
    search = s["search"]
    fid = fidelity(res, comparison_factors(result_substeps(res)), n_cycles=n_cycles)    # the same window, other physics
    return {"method": "trajopt `--speed max`", "kind": "trajopt", "fidelity": [_fine_speeds(fid)], "n_cycle": int(s["n_cycle"]),
            "n_keyframes": int(s["n_keyframes"]), "speeds": [float(window["speed_bl_per_min"])],
            "upright": [bool(window["upright"]) and bool(ev["upright"])],
            "speed_10_cycles": float(ev["speed_bl_per_min"]), "eval_cycles": int(s["eval_cycles"]),
            "sim_steps": [int(ev["search_sim_steps"])],
            "wall_time_s": [float(ev["search_wall_time_s"])], "budget": int(search["settings"]["max_sim_steps"] or 0),
            "optimisations": int(search["runs"]), "in_env": float(in_env),
            "limit_excess_m": independent_limit_check(res, res.robot),
            "periods": [dominant_period(u[s["n_prep"]:])],
            "curves": [[(int(ev["search_sim_steps"]), float(window["speed_bl_per_min"]))]]}


def _fine_speeds(fid: dict) -> dict:
    """``{physics steps per control step: BL/min (NaN when it fell)}`` of a fidelity table."""
    return {int(r["substeps"]): (float(r["speed_bl_per_min"]) if r["upright"] else float("nan")) for r in fid["rows"]}


def rl_group(rows: list[tuple[Path, dict]], kind: str, method: str) -> dict:
    """The seeds of one RL set-up: final speeds, steps, wall times, checkpoint curves."""
    out = {"method": method, "kind": kind, "seeds": [], "speeds": [], "upright": [], "sim_steps": [],
           "wall_time_s": [], "periods": [], "curves": [], "replay_err": [], "hyperparams": None}
    for run_dir, st in rows:
        m = st["metrics"]
        res = Result.load(run_dir / "policy.npz")
        cfg = json.loads((run_dir / "rl_config.json").read_text())
        out["seeds"].append(st["params"]["seed"])
        out["speeds"].append(m["speed_bl_per_min"])
        out["upright"].append(bool(m["upright"]))
        out["sim_steps"].append(int(m["sim_steps"]))
        out["wall_time_s"].append(float(m["train_wall_time_s"]))
        out["periods"].append(dominant_period(res.u[N_PREP:]))
        out["replay_err"].append(res.evaluation.get("replay_max_com_error_m", float("nan")))
        curve = {int(a): float(b) for a, b in m.get("curve", [])}
        curve[int(m["sim_steps"])] = float(m["speed_bl_per_min"])         # the final model
        out["curves"].append(sorted(curve.items()))
        out["hyperparams"] = cfg["hyperparams"]
        policy = load_policy(run_dir / "model.zip")
        factors = comparison_factors(run_substeps(policy.config) or 1)
        out.setdefault("fidelity", []).append(_fine_speeds(policy_fidelity(policy, factors)))
        out["n_envs"] = cfg["n_envs"]
    return out


def collect(spec, sweep_dir: Path) -> tuple[dict[str, list[dict]], list[str]]:
    """Rows per robot (trajopt, PPO, SAC, the long PPO run) from the finished runs; the runs not
    done are listed separately. The long RL run is the one whose timesteps exceed its algorithm's
    seeds' (``NAME_ppo5x_seedS`` in the shipped sweep files)."""
    results: dict[str, list[dict]] = {}
    rl: dict[tuple[str, str, int], list] = {}
    missing = []
    for run in spec.runs:
        st = read_status(sweep_dir / run.name)
        if not st or st.get("status") != "done":
            missing.append(f"{run.name} ({(st or {}).get('status', 'not run')}: {(st or {}).get('reason', '')})")
            continue
        robot = run.params["robot"]
        if run.kind == "optimize":
            results.setdefault(robot, []).append(trajopt_row(sweep_dir / run.name, run.name))
        elif run.kind == "rl-train":
            key = (robot, run.params["algo"], int(run.params["timesteps"]))
            rl.setdefault(key, []).append((sweep_dir / run.name, st))
    for (robot, algo, steps), rows in sorted(rl.items(), key=lambda kv: (kv[0][0], kv[0][2], kv[0][1])):
        base = min(s for (r, a, s) in rl if r == robot and a == algo)
        if steps > base:
            group = rl_group(rows, f"{algo}5x", f"{algo.upper()}, {steps / base:.0f}x the budget")
        else:
            group = rl_group(rows, algo, algo.upper())
        results.setdefault(robot, []).append(group)
    order = {"trajopt": 0, "ppo": 1, "sac": 2, "ppo5x": 3}
    return {r: sorted(rows, key=lambda x: order.get(x["kind"], 9)) for r, rows in results.items()}, missing


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--contact", choices=sorted(SPECS), default="coulomb",
                    help="contact law: its sweep file and report (default coulomb)")
    ap.add_argument("--spec", type=Path, default=None, help="sweep file (default: the law's, examples/rl_seeds*.toml)")
    ap.add_argument("--out", type=Path, default=HERE / "results", help="report directory (default benchmarks/results)")
    ap.add_argument("--sweep-dir", type=Path, default=None,
                    help="sweep directory (default results/sweeps/rl_LAW; the runs are not kept)")
    ap.add_argument("--quick", action="store_true", help="the sweep's tiny variant (also SOFT_ENVS_QUICK=1)")
    ap.add_argument("--workers", type=int, default=None, help="local Ray CPUs (default: all)")
    ap.add_argument("--address", default=None, help="an existing Ray cluster (auto, HOST:PORT, ray://HOST:PORT)")
    ap.add_argument("--serial", action="store_true", help="no Ray: the runs one after another")
    ap.add_argument("--only", action="append", metavar="PATTERN", default=None,
                    help="run only the sweep's runs whose name matches (repeatable, e.g. '*_seed?'); "
                         "the report lists the others as not run")
    ap.add_argument("--report-only", action="store_true", help="no runs: the report from the sweep directory")
    args = ap.parse_args()
    quick = quick_requested(args.quick)
    spec_path = args.spec or SPECS[args.contact]
    sweep_dir = args.sweep_dir or Path("results") / "sweeps" / f"rl_{args.contact}{'_quick' if quick else ''}"
    spec = load_spec(spec_path, sweep_dir, quick=quick)
    t0 = time.perf_counter()
    if not args.report_only:
        outcome = run_sweep(spec.only(args.only), sweep_dir, workers=args.workers, address=args.address,
                            serial=args.serial)
        write_summary(spec, statuses_on_disk(spec, sweep_dir, outcome.statuses), sweep_dir)
        if outcome.interrupted:
            raise SystemExit(130)
    import stable_baselines3
    import torch
    results, missing = collect(spec, sweep_dir)
    meta = {"date": time.strftime("%Y-%m-%d"), "quick": quick, "spec": f"examples/{spec_path.name}",
            "sweep_dir": str(sweep_dir), "contact": args.contact, "law": LAW_NAMES[args.contact],
            "window": EVAL_STEPS, "n_prep": N_PREP,
            "physics": ("4 physics steps of 8.25 ms per 0.033 s control step (`-v2`)" if args.contact == "coulomb"
                        else "one physics step per 0.033 s control step"),
            "motors": ("the torque-speed line and the gearbox limit, `[[motors]]`" if args.contact == "coulomb"
                       else "the speed limit, `[[motors]] max_speed_rpm`"),
            "machine": f"{os.cpu_count()} CPU cores ({platform.processor() or platform.machine()}), Python "
                       f"{platform.python_version()}, stable-baselines3 {stable_baselines3.__version__}, "
                       f"torch {torch.__version__}"}
    md_path = args.out / (REPORTS[args.contact] if not quick else f"quick_{REPORTS[args.contact]}")
    print(write_report(results, meta, md_path, missing))
    print(f"\nwrote {md_path} and {md_path.with_suffix('.png')} ({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
