"""Is model-based trajectory optimisation worth it over RL on the same simulator?

The runs are the sweep file ``examples/rl_seeds.toml`` (``trajopt sweep``, one Ray task per
run; on a cluster the same file runs unchanged): for each robot (Tripod, Puppy)

* **trajopt** walking gaits (``trajopt optimize``): the paper's 72-step cycle at the default
  target speed and at 1.5x it (the objective tracks a target; RL maximises speed), and a
  24-step cycle asked for 20 BL/min, scored over the same 432 steps. Each final gait is also
  played open loop in the Gymnasium environment (its controls as actions), motor speed limit
  off and on, to confirm that both methods see the same physics.
* **PPO** and **SAC** (``trajopt rl train``, Stable-Baselines3, documented hyper-parameters),
  three seeds each, every checkpoint scored with the shared metric.

This script runs the sweep (skipping runs already done in the sweep directory) and then the
report step: mean and spread over seeds, tables, findings and a plot. The metric is trajopt's
(``trajopt.evaluation.evaluate_controls``): mean COM speed along the target direction in body
lengths per minute over 432 steps after 24 prep steps, from the exact rest state; "upright"
over the whole run. Simulation steps: for trajopt all rollouts of the optimisation; for RL the
environment steps of training; evaluations are not counted.

Writes OUT/rl_vs_trajopt.md and OUT/rl_vs_trajopt.png; the runs under OUT/rl_sweep/.

Run:  python benchmarks/bench_rl_vs_trajopt.py                 (about an hour on 2 cores)
      python benchmarks/bench_rl_vs_trajopt.py --report-only   (the report from the runs done)
      python benchmarks/bench_rl_vs_trajopt.py --quick         (minutes; checks the pipeline only)
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import soft_envs  # noqa: F401
from trajopt import Result
from trajopt.gait import GaitSpec
from trajopt.replay import env_for_result, result_parameterization
from trajopt.rl.envs import GAIT, env_id
from trajopt.rl.evaluate import play_controls_in_env, run_metric

N_PREP, N_CYCLE = GAIT.n_prep, GAIT.n_cycle
from trajopt.sweep import load_spec, quick_requested, read_status, run_sweep, write_summary

HERE = Path(__file__).resolve().parent
SPEC = HERE.parent / "examples" / "rl_seeds.toml"
PAPER = {"tripod": 6.1, "puppy": 8.6}          # paper Table I, simulation [BL/min]
EVAL_STEPS = 6 * N_CYCLE                        # 432 steps after the prep phase


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
    res = Result.load(run_dir / f"{name}.npz")
    s, ev = res.settings, res.evaluation
    physics = env_for_result(res)            # the result's robot and contact law
    param = result_parameterization(res, physics.robot)
    u = param.controls(res.z, int(s["eval_cycles"]))
    in_env = {}
    for tag, kw in (("no_limit", {"motor_speed_rpm": None}), ("motor_limit", {})):
        env = gym.make(env_id(res.robot), contact=physics.contact_model, reset_noise_scale=0.0, terminate_when_unhealthy=False,
                       max_episode_steps=len(u), **kw)
        acts = env.unwrapped.control_to_action(u)
        rec = play_controls_in_env(env, lambda obs, k, acts=acts: acts[k], len(u), seed=0)
        m = run_metric(env, rec["u"], rec["x"], gait=GaitSpec.from_settings(s))
        in_env[tag] = m["speed_bl_per_min"]
        env.close()
    label = f"trajopt ({s['n_cycle']}-step cycle, target {s['speed_bl_per_min']:g} BL/min)"
    return {"method": label, "kind": "trajopt", "n_cycle": s["n_cycle"], "target_speed": s["speed_bl_per_min"],
            "speeds": [ev["speed_bl_per_min"]], "upright": [bool(ev["upright"])],
            "sim_steps": [int(ev["optimization_sim_steps"])], "wall_time_s": [ev["optimization_wall_time_s"]],
            "iterations": len(res.history), "status": res.status, "in_env": in_env,
            "max_du_per_step_m": float(np.abs(np.diff(np.vstack([np.zeros(u.shape[1]), u]), axis=0)).max()),
            "periods": [dominant_period(u[s["n_prep"]:])],
            "curves": [[(int(ev["optimization_sim_steps"]), ev["speed_bl_per_min"])]]}


def rl_group(rows: list[tuple[Path, dict]]) -> dict:
    first = rows[0][1]["params"]
    out = {"method": first["algo"].upper(), "kind": first["algo"], "seeds": [], "speeds": [], "upright": [],
           "sim_steps": [], "wall_time_s": [], "periods": [], "curves": [], "replay_err": [], "hyperparams": None}
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
        out["curves"].append(sorted({(int(a), float(b)) for a, b in m.get("curve", [])}
                                    | {(int(m["sim_steps"]), m["speed_bl_per_min"])}))
        out["hyperparams"] = cfg["hyperparams"]
        out["n_envs"] = cfg["n_envs"]
    return out


def collect(spec, sweep_dir: Path) -> tuple[dict[str, list[dict]], list[str]]:
    """Rows per robot from the finished runs; the runs not done are listed separately."""
    results: dict[str, list[dict]] = {}
    rl: dict[tuple[str, str], list] = {}
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
            rl.setdefault((robot, run.params["algo"]), []).append((sweep_dir / run.name, st))
    for (robot, _), rows in rl.items():
        results.setdefault(robot, []).append(rl_group(rows))
    return results, missing


# ----------------------------------------------------------------------------- report
def _ms(values: list[float]) -> str:
    v = np.asarray(values, dtype=float)
    if len(v) == 1:
        return f"{v[0]:.2f}"
    return f"{v.mean():.2f} ± {v.std(ddof=1):.2f} ({' / '.join(f'{x:.1f}' for x in v)})"


def table(rows: list[dict]) -> str:
    lines = ["| method | runs | simulation steps | wall time [s] | speed [BL/min] | upright | notes |",
             "|---|---:|---:|---:|---|---|---|"]
    for r in rows:
        if r["kind"] == "trajopt":
            e = r["in_env"]
            note = (f"{r['iterations']} GN iterations ({r['status']}); gait replayed in the env: "
                    f"{e['no_limit']:.2f} (motor limit off) / {e['motor_limit']:.2f} (on)")
        else:
            note = (f"seeds {', '.join(map(str, r['seeds']))}; {r['n_envs']} envs; closed- vs open-loop replay: "
                    f"max COM difference {max(r['replay_err']):.1e} m")
        note += f"; control period {', '.join(f'{p:.0f}' for p in r['periods'])} steps"
        up = sum(r["upright"])
        lines.append(f"| {r['method']} | {len(r['speeds'])} | {int(np.mean(r['sim_steps'])):,} | "
                     f"{np.mean(r['wall_time_s']):.0f} | {_ms(r['speeds'])} | {up}/{len(r['upright'])} | {note} |")
    return "\n".join(lines)


def plot(results: dict[str, list[dict]], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(results), figsize=(6.2 * len(results), 4.4), squeeze=False)
    colors = {"ppo": "tab:blue", "sac": "tab:orange"}
    for ax, (robot, rows) in zip(axes[0], results.items()):
        for r in rows:
            if r["kind"] == "trajopt":
                (x, y), = r["curves"][0]
                ax.plot([x], [y], "o" if r["n_cycle"] == N_CYCLE else "D", color="k",
                        markerfacecolor="k" if r["target_speed"] == min(t["target_speed"] for t in rows
                                                                       if t["kind"] == "trajopt") else "none",
                        label=r["method"])
                continue
            for i, c in enumerate(r["curves"]):
                pts = [(x, y) for x, y in c if x > 0]
                if pts:
                    xs, ys = zip(*pts)
                    ax.plot(xs, ys, marker=".", color=colors[r["kind"]], alpha=0.8,
                            label=f"{r['method']} ({len(r['curves'])} seeds)" if i == 0 else None)
        ax.axhline(PAPER[robot], color="grey", linestyle=":", label=f"paper, simulation ({PAPER[robot]})")
        ax.set_xscale("log")
        ax.set_xlabel("simulation steps used (log)")
        ax.set_ylabel("speed [body lengths / min]")
        ax.set_title(f"{robot.capitalize()}: speed vs simulation steps")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def findings(robot: str, rows: list[dict]) -> list[str]:
    paper = [r for r in rows if r["kind"] == "trajopt" and r["n_cycle"] == N_CYCLE]
    out = []
    if paper:
        tj = min(paper, key=lambda r: r["target_speed"])
        e = tj["in_env"]
        out.append(f"Same physics: trajopt's {robot} gait scores {tj['speeds'][0]:.3f} BL/min through "
                   f"`evaluate_controls` and {e['no_limit']:.3f} / {e['motor_limit']:.3f} BL/min stepped through "
                   f"the Gymnasium env with the motor speed limit off / on (largest contraction change per step "
                   f"{1000 * tj['max_du_per_step_m']:.2f} mm).")
    best_tj = max((r for r in rows if r["kind"] == "trajopt"), key=lambda r: r["speeds"][0], default=None)
    for r in rows:
        if r["kind"] == "trajopt" or best_tj is None:
            continue
        v = np.asarray(r["speeds"])
        beat = int((v > best_tj["speeds"][0]).sum())
        out.append(f"{r['method']}: {v.mean():.2f} BL/min on average over {len(v)} seeds (min {v.min():.2f}, max "
                   f"{v.max():.2f}), {sum(r['upright'])}/{len(v)} upright, {int(np.mean(r['sim_steps'])):,} steps "
                   f"({np.mean(r['sim_steps']) / best_tj['sim_steps'][0]:.1f}x the best trajopt gait's "
                   f"{best_tj['sim_steps'][0]:,}); {beat} of {len(v)} seeds faster than the best trajopt gait "
                   f"({best_tj['speeds'][0]:.2f} BL/min, {best_tj['method']}). Control periods "
                   f"{', '.join(f'{p:.0f}' for p in r['periods'])} steps.")
    return out


def _column(r: dict, rows: list[dict]) -> str:
    if r["kind"] != "trajopt":
        return f"{r['method']}, seeds {' / '.join(map(str, r['seeds']))}"
    same = sorted(t["target_speed"] for t in rows if t["kind"] == "trajopt" and t["n_cycle"] == r["n_cycle"])
    rank = "" if len(same) == 1 else (", default target" if r["target_speed"] == same[0] else ", higher target")
    return f"trajopt, {r['n_cycle']}-step cycle{rank}"


def readme_section(results: dict[str, list[dict]]) -> str:
    first = next(iter(results.values()))
    lines = ["| robot | " + " | ".join(_column(r, first) for r in first) + " |", "|---|" + "---|" * len(first)]
    for robot, rows in results.items():
        cells = []
        for r in rows:
            target = f"target {r['target_speed']:g}: " if r["kind"] == "trajopt" else ""
            cells.append(f"{target}{_ms(r['speeds'])} BL/min, {int(np.mean(r['sim_steps'])):,} steps, "
                         f"{np.mean(r['wall_time_s']):.0f} s")
        lines.append(f"| {robot.capitalize()} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def write_report(results: dict[str, list[dict]], meta: dict, out: Path, missing: list[str]) -> str:
    png = out / "rl_vs_trajopt.png"
    if results:
        plot(results, png)
    md = [f"# RL baseline vs trajectory optimisation{' (QUICK CHECK, not a result)' if meta['quick'] else ''}", "",
          f"Generated by `python benchmarks/bench_rl_vs_trajopt.py` on {meta['date']} from the sweep "
          f"`{meta['spec']}` (runs in `{meta['sweep_dir']}`): {meta['machine']}. RL: mean ± standard deviation "
          "over seeds, each seed in brackets; trajopt is deterministic (one run per set-up).", "",
          "Metric (both sides): trajopt's `evaluate_controls`: mean COM speed along +x in body lengths per minute "
          f"over {EVAL_STEPS} steps after {N_PREP} prep steps (dt = 0.033 s) from the exact rest state; upright = "
          "tilt <= 60 deg and COM >= half its rest height throughout. RL: deterministic policy, closed loop in the "
          "env (motor speed limit on, as in training). Simulation steps: trajopt = every rollout step of the "
          "optimisation; RL = training environment steps. Wall time: trajopt one process, RL training (two "
          "environments in the run's process), two runs at a time on the machine; indicative only.", ""]
    if missing:
        md += ["Runs not done (left out): " + "; ".join(missing), ""]
    for robot, rows in results.items():
        md += [f"## {robot.capitalize()} (paper, simulation: {PAPER[robot]} BL/min)", "", table(rows), ""]
        md += [f"- {f}" for f in findings(robot, rows)] + [""]
    if results:
        md += [f"![speed vs simulation steps]({png.name})", "",
               "Points: trajopt's final gaits (filled: default target, open: 1.5x, diamond: 24-step cycle); "
               "lines: each RL seed's checkpoints.", "", "## Hyper-parameters", ""]
        for robot, rows in results.items():
            md += [f"- {robot} {r['method']}: `{json.dumps(r['hyperparams'], default=str)}`"
                   for r in rows if r.get("hyperparams")]
        md += ["", "## README table (to paste)", "", readme_section(results), ""]
    text = "\n".join(md)
    (out / "rl_vs_trajopt.md").write_text(text)
    return text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spec", type=Path, default=SPEC, help="sweep file (default examples/rl_seeds.toml)")
    ap.add_argument("--out", type=Path, default=HERE / "results", help="report directory")
    ap.add_argument("--sweep-dir", type=Path, default=None, help="sweep directory (default OUT/rl_sweep)")
    ap.add_argument("--quick", action="store_true", help="the sweep's tiny variant (also SOFT_ENVS_QUICK=1)")
    ap.add_argument("--workers", type=int, default=None, help="local Ray CPUs (default: all)")
    ap.add_argument("--address", default=None, help="an existing Ray cluster (auto, HOST:PORT, ray://HOST:PORT)")
    ap.add_argument("--serial", action="store_true", help="no Ray: the runs one after another")
    ap.add_argument("--report-only", action="store_true", help="no runs: the report from the sweep directory")
    args = ap.parse_args()
    quick = quick_requested(args.quick)
    sweep_dir = args.sweep_dir or args.out / ("rl_sweep_quick" if quick else "rl_sweep")
    spec = load_spec(args.spec, sweep_dir, quick=quick)
    t0 = time.perf_counter()
    if not args.report_only:
        outcome = run_sweep(spec, sweep_dir, workers=args.workers, address=args.address, serial=args.serial)
        write_summary(spec, outcome.statuses, sweep_dir)
        if outcome.interrupted:
            raise SystemExit(130)
    import stable_baselines3
    import torch
    results, missing = collect(spec, sweep_dir)
    meta = {"date": time.strftime("%Y-%m-%d"), "quick": quick, "spec": str(args.spec.name), "sweep_dir": str(sweep_dir),
            "machine": f"{os.cpu_count()} CPU cores ({platform.processor() or platform.machine()}), Python "
                       f"{platform.python_version()}, stable-baselines3 {stable_baselines3.__version__}, "
                       f"torch {torch.__version__}"}
    print(write_report(results, meta, args.out, missing))
    print(f"\nwrote {args.out / 'rl_vs_trajopt.md'} and {args.out / 'rl_vs_trajopt.png'} "
          f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
