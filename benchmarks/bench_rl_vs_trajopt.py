"""Is model-based trajectory optimisation worth it over RL on the same simulator?

For each robot (Tripod, Puppy), in one run:

* **trajopt**: ``optimize_gait(task="walk")`` with the default target speed (the paper's set-up,
  the ``trajopt optimize`` defaults), and once more with a higher target speed (the objective
  tracks a target speed; RL maximises speed, so this shows what trajopt gives when asked for
  more). Every Gauss-Newton iterate of the default-target run (the callback's partial
  Result) is evaluated with the shared metric for the speed-vs-steps curve. The final gait is also played open loop in the
  Gymnasium environment (its controls as actions through ``control_to_action``), with the
  motor speed limit off and on, to confirm that both methods see the same physics.
* **PPO** and **SAC** (Stable-Baselines3, :mod:`trajopt.rl`, documented hyper-parameters,
  ``n_envs = os.cpu_count()`` subprocess environments), every checkpoint evaluated with the
  shared metric.

The metric is trajopt's (``trajopt.evaluation.evaluate_controls``): mean COM speed along the
target direction in body lengths per minute over 6 gait cycles of 72 steps after 24 prep
steps, from the exact rest state; "upright" over the whole run. Simulation steps: for trajopt
all rollouts of the optimisation (seed search, Gauss-Newton, line search; a rollout with
sensitivities counts its steps once); for RL the environment steps of training. Evaluation
rollouts are not counted for either. Wall times are for this machine (see the header of the
report) with the other methods not running at the same time.

Writes benchmarks/results/rl_vs_trajopt.md (tables, findings, a README section) and
rl_vs_trajopt.png (speed vs simulation steps), the runs and raw numbers under
benchmarks/results/rl_runs/, and prints the report.

Run:  python benchmarks/bench_rl_vs_trajopt.py            (about 20 minutes on 2 cores)
      python benchmarks/bench_rl_vs_trajopt.py --quick    (a minute; checks the script only)
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
from soft_envs.envs import make_gradient_env
from trajopt import GaussNewtonOptions, optimize_gait
from trajopt.evaluation import evaluate_controls
from trajopt.gait import GaitSpec
from trajopt.optimize import DEFAULT_SPEED
from trajopt.parameterization import GaitParameterization
from trajopt.rl.envs import GAIT, ROBOT_IDS
from trajopt.rl.evaluate import evaluate_policy_metric, export_result, load_policy, play_controls_in_env, run_metric
from trajopt.rl.training import checkpoint_steps, train

HERE = Path(__file__).resolve().parent
EVAL_CYCLES = 6
N_PREP, N_CYCLE = GAIT.n_prep, GAIT.n_cycle   # trajopt's gait: prep and cycle [simulation steps]
PAPER = {"tripod": 6.1, "puppy": 8.6}          # paper Table I, simulation [BL/min]
#: environment steps of RL training (frame_skip 1: = simulation steps)
BUDGETS = {"tripod": {"ppo": 30_000, "sac": 20_000}, "puppy": {"ppo": 15_000, "sac": 8_000}}
GN_ITERATIONS = 12
HIGH_SPEED_FACTOR = 1.5                        # the second trajopt run asks for 1.5x the default


# ----------------------------------------------------------------------------- trajopt
def run_trajopt(robot: str, speed: float, max_iter: int, runs: Path, label: str, curve: bool = True) -> dict:
    hooks = make_gradient_env(robot)           # the environment (reset noise 0) as gradient hooks
    iterates: list[tuple[int, float, np.ndarray]] = []

    def on_iteration(entry, partial):
        iterates.append((int(entry["sim_steps_total"]), float(entry["wall_time_total"]), partial.z.copy()))

    t0 = time.perf_counter()
    res = optimize_gait(hooks, "walk", speed_bl_per_min=speed, eval_cycles=EVAL_CYCLES, robot_spec=robot,
                        options=GaussNewtonOptions(max_iter=max_iter), callback=on_iteration)
    wall = time.perf_counter() - t0
    res.save(runs / f"{robot}_trajopt_{label}.npz")
    s = res.settings
    param = GaitParameterization.for_robot(hooks.robot, GaitSpec.from_settings(s))
    cache: dict[bytes, float] = {res.z.tobytes(): res.evaluation["speed_bl_per_min"]}
    points = []
    for steps, _, z in (iterates if curve else []):
        key = z.tobytes()
        if key not in cache:
            cache[key] = evaluate_controls(hooks, param.controls(z, EVAL_CYCLES), n_prep=s["n_prep"],
                                           n_cycle=s["n_cycle"])["speed_bl_per_min"]
        points.append((steps, cache[key]))
    ev = res.evaluation
    points = sorted(set(points + [(int(ev["optimization_sim_steps"]), ev["speed_bl_per_min"])]))
    u = param.controls(res.z, EVAL_CYCLES)
    in_env = {}
    for tag, rpm in (("no_limit", None), ("motor_limit", "default")):
        kw = {} if rpm == "default" else {"motor_speed_rpm": None}
        env = gym.make(ROBOT_IDS[robot], reset_noise_scale=0.0, terminate_when_unhealthy=False,
                       max_episode_steps=len(u), **kw)
        acts = env.unwrapped.control_to_action(u)
        rec = play_controls_in_env(env, lambda obs, k, acts=acts: acts[k], len(u), seed=0)
        m = run_metric(env, rec["u"], rec["x"])
        in_env[tag] = {"speed_bl_per_min": m["speed_bl_per_min"], "upright": m["upright"],
                       "max_control_error_m": float(np.abs(rec["u"] - u).max())}
        env.close()
    du = float(np.abs(np.diff(np.vstack([np.zeros(u.shape[1]), u]), axis=0)).max())
    return {"method": f"trajopt ({label})", "kind": "trajopt", "target_speed": speed,
            "sim_steps": int(ev["optimization_sim_steps"]), "wall_time_s": wall,
            "speed_bl_per_min": ev["speed_bl_per_min"], "upright": ev["upright"],
            "iterations": len(res.history), "status": res.status, "curve": points, "in_env": in_env,
            "max_du_per_step_m": du, "dominant_period_steps": dominant_period(u[N_PREP:]),
            "speed_per_cycle": ev["speed_per_cycle_bl_per_min"]}


# ----------------------------------------------------------------------------- RL
def run_rl(robot: str, algo: str, budget: int, runs: Path, seed: int) -> dict:
    n_envs = os.cpu_count() or 1
    run = train(robot, algo, budget, seed=seed, out=runs, n_envs=n_envs, progress_bar=False,
                checkpoint_every=max(budget // 4, 1), overwrite=True)
    curve = []
    for ck in run.checkpoints:
        ev = evaluate_policy_metric(load_policy(ck), n_cycles=EVAL_CYCLES)
        curve.append((checkpoint_steps(ck) * run.config["env"]["frame_skip"], ev["speed_bl_per_min"]))
    res = export_result(run.run_dir, runs / f"{robot}_{algo}_rl.npz", n_cycles=EVAL_CYCLES)
    ev = res.evaluation
    curve.append((run.sim_steps, ev["speed_bl_per_min"]))
    return {"method": algo.upper(), "kind": algo, "sim_steps": run.sim_steps, "wall_time_s": run.wall_time_s,
            "speed_bl_per_min": ev["speed_bl_per_min"], "upright": ev["upright"], "n_envs": n_envs,
            "curve": sorted(set(curve)), "replay_max_com_error_m": ev["replay_max_com_error_m"],
            "dominant_period_steps": dominant_period(res.u[N_PREP:]),
            "max_du_per_step_m": float(np.abs(np.diff(res.u, axis=0)).max()),
            "speed_per_cycle": ev["speed_per_cycle_bl_per_min"], "hyperparams": run.config["hyperparams"]}


def dominant_period(u: np.ndarray) -> float:
    """Period [simulation steps] of the strongest non-constant Fourier component of the
    controls (summed over motors)."""
    u = np.asarray(u, dtype=np.float64)
    spec = (np.abs(np.fft.rfft(u - u.mean(axis=0), axis=0)) ** 2).sum(axis=1)
    if len(spec) < 2 or spec[1:].max() <= 0:
        return float("inf")
    k = int(np.argmax(spec[1:])) + 1
    return len(u) / k


def first_reaching(curve: list[tuple[int, float]], speed: float) -> int | None:
    for steps, v in sorted(curve):
        if np.isfinite(v) and v >= speed:
            return steps
    return None


# ----------------------------------------------------------------------------- report
def table(rows: list[dict]) -> str:
    head = ("| method | simulation steps | wall time [s] | speed [BL/min] | upright | notes |\n"
            "|---|---:|---:|---:|---|---|\n")
    lines = []
    for r in rows:
        if r["kind"] == "trajopt":
            e = r["in_env"]
            note = (f"target {r['target_speed']:g} BL/min, {r['iterations']} GN iterations ({r['status']}); "
                    f"gait replayed in the env: {e['no_limit']['speed_bl_per_min']:.2f} (motor limit off) / "
                    f"{e['motor_limit']['speed_bl_per_min']:.2f} (on)")
        else:
            note = (f"{r['n_envs']} envs; closed-loop vs open-loop replay of its controls: "
                    f"max COM difference {r['replay_max_com_error_m']:.1e} m")
        note += f"; control period {r['dominant_period_steps']:.0f} steps"
        lines.append(f"| {r['method']} | {r['sim_steps']:,} | {r['wall_time_s']:.0f} | "
                     f"{r['speed_bl_per_min']:.2f} | {'yes' if r['upright'] else 'no'} | {note} |")
    return head + "\n".join(lines)


def plot(results: dict[str, list[dict]], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(results), figsize=(6.2 * len(results), 4.4), squeeze=False)
    style = {"trajopt": dict(marker="o", color="k"), "ppo": dict(marker="s", color="tab:blue"),
             "sac": dict(marker="^", color="tab:orange")}
    for ax, (robot, rows) in zip(axes[0], results.items()):
        for r in rows:
            pts = [(x, y) for x, y in r["curve"] if x > 0]      # log axis: step 0 left out
            xs, ys = zip(*pts) if pts else ((), ())
            kw = dict(style[r["kind"]])
            if r["kind"] == "trajopt" and "default" not in r["method"]:
                kw.update(linestyle="--", markerfacecolor="none")
            ax.plot(xs, ys, label=r["method"], **kw)
        ax.axhline(PAPER[robot], color="grey", linestyle=":", label=f"paper, simulation ({PAPER[robot]})")
        ax.set_xscale("log")
        ax.set_xlabel("simulation steps used (log)")
        ax.set_ylabel("speed [body lengths / min], 6 cycles")
        ax.set_title(f"{robot.capitalize()}: speed vs simulation steps")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def findings(robot: str, rows: list[dict]) -> list[str]:
    tj = next(r for r in rows if r["kind"] == "trajopt")
    out = []
    e = tj["in_env"]
    out.append(f"Same physics: trajopt's {robot} gait scores {tj['speed_bl_per_min']:.3f} BL/min through "
               f"`evaluate_controls` and {e['no_limit']['speed_bl_per_min']:.3f} / "
               f"{e['motor_limit']['speed_bl_per_min']:.3f} BL/min stepped through the Gymnasium env with the "
               f"motor speed limit off / on (its largest contraction change per step is "
               f"{1000 * tj['max_du_per_step_m']:.2f} mm, so the limit never binds).")
    for r in rows:
        if r["kind"] == "trajopt":
            continue
        ratio = r["sim_steps"] / tj["sim_steps"]
        reach = first_reaching(r["curve"], tj["speed_bl_per_min"])
        reach_txt = (f"first matched or beat trajopt's default-target speed at the checkpoint after "
                     f"{reach:,} steps ({reach / tj['sim_steps']:.1f}x trajopt's steps)" if reach is not None
                     else "never reached trajopt's default-target speed in its budget")
        out.append(f"{r['method']}: {r['speed_bl_per_min']:.2f} BL/min ({'upright' if r['upright'] else 'FELL'}) "
                   f"after {r['sim_steps']:,} steps = {ratio:.1f}x trajopt's {tj['sim_steps']:,}, "
                   f"{r['wall_time_s']:.0f} s vs {tj['wall_time_s']:.0f} s; {reach_txt}. Its controls repeat every "
                   f"~{r['dominant_period_steps']:.0f} steps (trajopt: the 72-step cycle by construction).")
    return out


def readme_section(results: dict[str, list[dict]], budgets: dict) -> str:
    lines = ["## RL baseline", "",
             "`trajopt rl` trains Stable-Baselines3 PPO or SAC on `SoftTripod-v0` / `SoftPuppy-v0` and "
             "scores the policy with trajopt's own metric (COM speed along the target over 6 cycles of 72 "
             "steps after 24 prep steps, deterministic policy, exact rest start), so the numbers are "
             "directly comparable; `trajopt rl export` turns a policy into a trajopt `Result` that "
             "`trajopt render` and `trajopt play` accept.", "",
             "```bash",
             "pip install -e \".[rl]\"",
             "trajopt rl train tripod --algo ppo --timesteps 30000 --out runs/",
             "trajopt rl evaluate runs/tripod_ppo_seed0",
             "trajopt rl export runs/tripod_ppo_seed0 --out results/tripod_ppo.npz",
             "```", "",
             "One run of `python benchmarks/bench_rl_vs_trajopt.py` (full report: "
             "`benchmarks/results/rl_vs_trajopt.md`), speed in body lengths per minute, simulation steps "
             "spent:", "",
             "| robot | trajopt (default target) | PPO | SAC |", "|---|---|---|---|"]
    for robot, rows in results.items():
        cells = []
        for kind in ("trajopt", "ppo", "sac"):
            r = next((r for r in rows if r["kind"] == kind), None)
            cells.append("-" if r is None else f"{r['speed_bl_per_min']:.1f} BL/min, {r['sim_steps']:,} steps, "
                                               f"{r['wall_time_s']:.0f} s" + ("" if r["upright"] else ", fell"))
        lines.append(f"| {robot.capitalize()} | " + " | ".join(cells) + " |")
    lines += ["", _verdict(results), ""]
    return "\n".join(lines)


def _verdict(results: dict[str, list[dict]]) -> str:
    parts = []
    for robot, rows in results.items():
        tj = next(r for r in rows if r["kind"] == "trajopt")
        rl = [r for r in rows if r["kind"] != "trajopt"]
        best = max(rl, key=lambda r: r["speed_bl_per_min"] if np.isfinite(r["speed_bl_per_min"]) else -np.inf)
        faster = best["speed_bl_per_min"] > tj["speed_bl_per_min"]
        parts.append(
            f"{robot.capitalize()}: trajopt reached {tj['speed_bl_per_min']:.1f} BL/min with {tj['sim_steps']:,} "
            f"simulation steps; the best RL policy ({best['method']}) reached {best['speed_bl_per_min']:.1f} BL/min "
            f"with {best['sim_steps']:,} ({best['sim_steps'] / tj['sim_steps']:.1f}x as many)"
            + (", i.e. faster, with a gait trajopt's parameterisation (a 72-step cycle of 4 keyframes) "
               f"cannot express (its controls repeat every ~{best['dominant_period_steps']:.0f} steps)."
               if faster and best["dominant_period_steps"] < 0.5 * N_CYCLE else
               (", i.e. faster." if faster else ", i.e. slower.")))
    parts.append("Caveats: trajopt tracks a target speed (its objective) while RL maximises speed (its "
                 "reward); trajopt returns a smooth periodic keyframed gait by construction while an RL "
                 "gait is whatever the policy found, here fast oscillations at the motor speed limit that "
                 "may exploit the contact model (penalty contact, lagged friction); none of these gaits "
                 "has been tried on hardware here. Single runs (one seed each); wall times on the machine "
                 "in the report.")
    return " ".join(parts)


def answer(results: dict[str, list[dict]]) -> list[str]:
    """The direct answer, robot by robot, plus the caveats that apply to these numbers (all
    statements are computed from the measurements)."""
    out, reach_ratios = [], []
    for robot, rows in results.items():
        tj = next(r for r in rows if r["kind"] == "trajopt")
        rl = [r for r in rows if r["kind"] != "trajopt" and np.isfinite(r["speed_bl_per_min"])]
        if not rl:
            continue
        best = max(rl, key=lambda r: r["speed_bl_per_min"])
        reach = [x for x in (first_reaching(r["curve"], tj["speed_bl_per_min"]) for r in rl) if x is not None]
        txt = (f"- **{robot.capitalize()}**: trajopt {tj['speed_bl_per_min']:.1f} BL/min with {tj['sim_steps']:,} "
               f"simulation steps ({tj['wall_time_s']:.0f} s); best RL ({best['method']}) "
               f"{best['speed_bl_per_min']:.1f} BL/min with {best['sim_steps']:,} steps "
               f"({best['wall_time_s']:.0f} s), {best['speed_bl_per_min'] / tj['speed_bl_per_min']:.1f}x "
               "trajopt's speed. ")
        if reach:
            reach_ratios.append((robot, min(reach) / tj["sim_steps"]))
            txt += (f"The first RL checkpoint at or above trajopt's speed came after {min(reach):,} steps "
                    f"({min(reach) / tj['sim_steps']:.1f}x trajopt's steps).")
        else:
            txt += "No RL checkpoint reached trajopt's speed within its budget."
        out.append(txt)
    if reach_ratios:
        lo, hi = min(r for _, r in reach_ratios), max(r for _, r in reach_ratios)
        verdict = (f"- Simulation steps to trajopt's speed: RL needed {lo:.1f}-{hi:.1f}x trajopt's steps "
                   "(checkpoint resolution)" if lo != hi else
                   f"- Simulation steps to trajopt's speed: RL needed {lo:.1f}x trajopt's steps (checkpoint resolution)")
        verdict += (", not orders of magnitude more. " if hi < 10 else ". ")
        verdict += ("With these budgets the RL policies end up faster than trajopt's gaits on every robot."
                    if all(any(r["kind"] != "trajopt" and r["speed_bl_per_min"]
                               > next(t for t in rows if t["kind"] == "trajopt")["speed_bl_per_min"] for r in rows)
                           for rows in results.values()) else "")
        out.append(verdict)
    caveats = ["Objectives differ: trajopt tracks a target speed (paper III), RL maximises forward speed "
               "(the env's reward)."]
    high = [(robot, r, next(t for t in rows if t["kind"] == "trajopt"))
            for robot, rows in results.items() for r in rows if r["kind"] == "trajopt" and "1.5x" in r["method"]]
    if high and all(r["speed_bl_per_min"] <= t["speed_bl_per_min"] + 0.05 for _, r, t in high):
        caveats[-1] += " Asking trajopt for 1.5x the default target speed did not make it faster (rows 'target 1.5x')."
    for robot, rows in results.items():
        tj = next(r for r in rows if r["kind"] == "trajopt")
        if tj["status"] == "stalled" and len({round(v, 6) for _, v in tj["curve"]}) == 1:
            caveats.append(f"{robot.capitalize()}: trajopt's Gauss-Newton stalled (status 'stalled' after "
                           f"{tj['iterations']} iterations without a decrease): its gait is the best of its "
                           "starting patterns, unimproved by the optimiser. Worth a look on the trajopt side.")
    fast = [(robot, r) for robot, rows in results.items() for r in rows
            if r["kind"] != "trajopt" and r["dominant_period_steps"] < 0.5 * N_CYCLE]
    if fast:
        periods = ", ".join(f"{robot} {r['method']} ~{r['dominant_period_steps']:.0f}" for robot, r in fast)
        caveats.append("The RL gaits are fast oscillations at the motor speed limit (dominant control "
                       f"period in steps of 0.033 s: {periods}); trajopt's gaits have the 72-step cycle of "
                       "4 keyframes by construction and cannot express them. Such vibration gaits may "
                       "exploit the contact model (penalty contact, lagged viscous-like friction); nothing "
                       "here shows that they transfer to hardware. Render one with `trajopt render "
                       "benchmarks/results/rl_runs/tripod_sac_rl.npz --gif sac.gif`.")
    caveats.append("One seed per method and small budgets: the RL curves are still rising (see the plot); "
                   "wall times are from a 2-core machine shared with other work.")
    return out + ["", "Caveats:", ""] + [f"- {c}" for c in caveats]


def write_report(results: dict[str, list[dict]], meta: dict, out: Path) -> str:
    png = out / "rl_vs_trajopt.png"
    plot(results, png)
    budgets = meta["budgets"]
    md = [f"# RL baseline vs trajectory optimisation{' (QUICK CHECK, not a result)' if meta['quick'] else ''}", "",
          f"Generated by `python benchmarks/bench_rl_vs_trajopt.py` on {meta['date']}: {meta['machine']}; "
          f"whole benchmark {meta['total_s'] / 60:.1f} min. One seed ({meta['seed']}) per method.", "",
          "## Answer", ""] + answer(results) + ["",
          "## Set-up", "",
          "Metric (both sides): trajopt's `evaluate_controls`: mean COM speed along +x in body lengths per "
          f"minute over {EVAL_CYCLES} cycles of {N_CYCLE} steps after {N_PREP} prep steps (dt = 0.033 s), from "
          "the exact rest state; upright = tilt <= 60 deg and COM >= half its rest height throughout. RL: "
          "deterministic policy, closed loop in the env (motor speed limit on, as in training). "
          "Simulation steps: trajopt = every rollout step of the optimisation (seed search, Gauss-Newton, "
          "line search; sensitivities included, not counted extra); RL = training environment steps "
          "(episodes of 168 steps, trajopt's horizon). Evaluations are not counted. Wall time: trajopt one "
          "process (including its final 6-cycle evaluation); RL training with subprocess environments, "
          "checkpoint evaluation excluded. The machine was shared with other work, so wall times are "
          "indicative.", "",
          "Budgets (environment steps): " + "; ".join(
              f"{r}: PPO {b['ppo']:,}, SAC {b['sac']:,}" for r, b in budgets.items())
          + f"; trajopt at most {meta['max_iter']} Gauss-Newton iterations (`trajopt optimize` uses 15).", ""]
    for robot, rows in results.items():
        md += [f"## {robot.capitalize()} (paper, simulation: {PAPER[robot]} BL/min)", "", table(rows), ""]
        md += [f"- {f}" for f in findings(robot, rows)] + [""]
    md += [f"![speed vs simulation steps]({png.name})", "",
           "Curves: trajopt = each Gauss-Newton iterate's gait (the optimiser's callback), RL = each "
           "checkpoint (the untrained policy, step 0, is in summary.json, not on the log axis), all with "
           "the metric above.", "",
           "## Hyper-parameters", "",
           "See `trajopt/rl/hyperparams.py` for the reasons. As used:", ""]
    for robot, rows in results.items():
        for r in rows:
            if "hyperparams" in r:
                md.append(f"- {robot} {r['method']}: `{json.dumps(r['hyperparams'], default=str)}`")
    md += ["", "## README section (to paste)", "", "~~~markdown", readme_section(results, budgets), "~~~", ""]
    text = "\n".join(md)
    (out / "rl_vs_trajopt.md").write_text(text)
    return text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", nargs="+", choices=sorted(ROBOT_IDS), default=["tripod", "puppy"])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quick", action="store_true", help="tiny budgets: checks that the script runs")
    ap.add_argument("--out", type=Path, default=HERE / "results", help="report directory")
    ap.add_argument("--report-only", action="store_true",
                    help="rebuild the report and plot from OUT/rl_runs/summary.json (no training)")
    args = ap.parse_args()
    out = args.out
    runs = out / "rl_runs"
    if args.report_only:
        data = json.loads((runs / "summary.json").read_text())
        text = write_report(data["results"], data["meta"], out)
        print(text)
        return
    budgets = {r: dict(BUDGETS[r]) for r in args.robots}
    max_iter = GN_ITERATIONS
    if args.quick:
        budgets = {r: {"ppo": 512, "sac": 384} for r in args.robots}
        max_iter = 1
    runs.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    results: dict[str, list[dict]] = {}
    for robot in args.robots:
        rows = []
        speed = DEFAULT_SPEED[robot]
        for label, v in (("default target", speed), (f"target {HIGH_SPEED_FACTOR:g}x", HIGH_SPEED_FACTOR * speed)):
            print(f"[{time.perf_counter() - t_start:6.0f} s] {robot}: trajopt, {label} ({v:g} BL/min)", flush=True)
            # the iterates' curve for the default target only (each evaluation costs 456 steps)
            rows.append(run_trajopt(robot, v, max_iter, runs, label.replace(" ", "_"),
                                    curve=label.startswith("default")))
            rows[-1]["method"] = f"trajopt ({label}, {v:g} BL/min)"
        for algo in ("ppo", "sac"):
            print(f"[{time.perf_counter() - t_start:6.0f} s] {robot}: {algo.upper()}, {budgets[robot][algo]} steps",
                  flush=True)
            rows.append(run_rl(robot, algo, budgets[robot][algo], runs, args.seed))
        results[robot] = rows

    import stable_baselines3
    import torch
    meta = {"date": time.strftime("%Y-%m-%d"), "total_s": time.perf_counter() - t_start, "seed": args.seed,
            "quick": args.quick, "budgets": budgets, "max_iter": max_iter,
            "machine": f"{os.cpu_count()} CPU cores ({platform.processor() or platform.machine()}), Python "
                       f"{platform.python_version()}, stable-baselines3 {stable_baselines3.__version__}, "
                       f"torch {torch.__version__}"}
    (runs / "summary.json").write_text(json.dumps({"meta": meta, "results": results}, indent=1, default=float))
    print(write_report(results, meta, out))
    print(f"\nwrote {out / 'rl_vs_trajopt.md'}, {out / 'rl_vs_trajopt.png'} and {runs / 'summary.json'}")


if __name__ == "__main__":
    main()
