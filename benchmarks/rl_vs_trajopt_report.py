"""The report of ``benchmarks/bench_rl_vs_trajopt.py``: tables, findings, a plot and the README
table, from the rows that script collects (pure formatting; nothing here runs a simulation).

A row is a dict with ``kind`` ("trajopt", "ppo", "sac" or "ppo5x"), ``method``, ``speeds``
(BL/min over the shared window, one per seed), ``upright``, ``sim_steps``, ``wall_time_s``,
``periods`` and ``curves`` (per seed, ``(simulation steps, BL/min)`` at each checkpoint); a
trajopt row also has ``speed_10_cycles``, ``n_cycle``, ``n_keyframes``, ``budget``,
``optimisations``, ``in_env`` (the gait replayed in the environment, limit on) and
``limit_excess_m`` (the independent check of the motor limit). ``fidelity`` (per seed): the
speed at each number of physics steps per control step (half, its own and 2x, 4x, 8x); the
credible speed is the slowest of them (:func:`credible`).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

PAPER = {"tripod": 6.1, "puppy": 8.6}          # paper Table I, simulation [BL/min]


def mean_spread(values: list[float]) -> str:
    """``mean ± std (each / seed)`` [BL/min] (one value: the value)."""
    v = np.asarray(values, dtype=float)
    if len(v) == 1:
        return f"{v[0]:.2f}"
    return f"{v.mean():.2f} ± {v.std(ddof=1):.2f} ({' / '.join(f'{x:.1f}' for x in v)})"


def credible(r: dict) -> list[float]:
    """Per seed, the slowest speed over its own and the other physics (NaN: it fell on one)."""
    return [min(f.values()) if f and np.isfinite(list(f.values())).all() else float("nan")
            for f in r.get("fidelity", [{}] * len(r["speeds"]))]


def _fine_note(r: dict) -> str:
    return "; ".join(", ".join(f"{v:.1f}" for _, v in sorted(f.items())) + f" at {'/'.join(map(str, sorted(f)))} steps"
                     for f in r.get("fidelity", []))


def _by_kind(rows: list[dict]) -> dict[str, dict]:
    return {r["kind"]: r for r in rows}


def _trajopt_note(r: dict) -> str:
    e = r["in_env"]
    return (f"{r['n_cycle']}-step cycle, {r['n_keyframes']} keyframes; {r['speed_10_cycles']:.2f} BL/min over the "
            f"search's {r['eval_cycles']} cycles; {r['optimisations']} optimisations; "
            f"budget {r['budget']:,} steps; replayed in the "
            f"env with its motor limit: {e:.2f} ({100 * abs(e - r['speeds'][0]) / abs(r['speeds'][0]):.2f} % off); "
            f"largest step - v_max h = {r['limit_excess_m']:+.1e} m")


def table(rows: list[dict]) -> str:
    """One line per method: runs, simulation steps, wall time, speed, upright, notes."""
    lines = ["| method | runs | simulation steps | wall time [s] | speed [BL/min] | credible [BL/min] | upright | "
             "at other physics [BL/min] | notes |",
             "|---|---:|---:|---:|---|---|---|---|---|"]
    for r in rows:
        if r["kind"] == "trajopt":
            note = _trajopt_note(r)
        else:
            note = (f"seed{'s' if len(r['seeds']) > 1 else ''} {', '.join(map(str, r['seeds']))}; {r['n_envs']} envs; closed- vs open-loop replay: "
                    f"max COM difference {max(r['replay_err']):.1e} m; control period "
                    f"{', '.join(f'{p:.0f}' for p in r['periods'])} steps")
        lines.append(f"| {r['method']} | {len(r['speeds'])} | {int(np.mean(r['sim_steps'])):,} | "
                     f"{np.mean(r['wall_time_s']):.0f} | {mean_spread(r['speeds'])} | {mean_spread(credible(r))} | "
                     f"{sum(r['upright'])}/{len(r['upright'])} | {_fine_note(r)} | {note} |")
    return "\n".join(lines)


def overtakes(long: dict, speed: float, base_steps: int) -> tuple[int, float] | None:
    """The first checkpoint ``(steps, BL/min)`` of the long RL run faster than ``speed``, or None."""
    for steps, v in long["curves"][0]:
        if steps > 0 and v > speed:
            return int(steps), float(v)
    return None


def findings(rows: list[dict]) -> list[str]:
    """What the rows say: trajopt against every RL seed at the baseline's budget, and whether
    RL with 5x the budget overtakes it."""
    k = _by_kind(rows)
    tj = k.get("trajopt")
    if tj is None:
        return []
    v_tj = tj["speeds"][0]
    out = [f"trajopt `--speed max`: {v_tj:.2f} BL/min over the RL window ({tj['speed_10_cycles']:.2f} over its "
           f"{tj['eval_cycles']} cycles, {'upright' if all(tj['upright']) else 'NOT upright'}), "
           f"{tj['sim_steps'][0]:,} simulation "
           f"steps against one PPO seed's {int(np.mean(k['ppo']['sim_steps'])) if 'ppo' in k else 0:,}, "
           f"{tj['wall_time_s'][0]:.0f} s."]
    c_tj = credible(tj)[0]
    out.append(f"credible speeds (the slowest at half, its own and 2x, 4x, 8x its physics steps): trajopt {c_tj:.2f} "
               f"BL/min; " + "; ".join(f"{k[kind]['method']} best seed {np.nanmax(credible(k[kind])):.2f}"
                                      for kind in ("ppo", "sac") if kind in k and np.isfinite(credible(k[kind])).any()))
    for kind in ("ppo", "sac"):
        if kind not in k:
            continue
        r = k[kind]
        v = np.asarray(r["speeds"])
        c = np.asarray(credible(r))
        out.append(f"{r['method']}: {v.mean():.2f} BL/min on average over {len(v)} seeds (best {v.max():.2f}), "
                   f"{sum(r['upright'])}/{len(v)} upright, {int(np.mean(r['sim_steps'])):,} steps; "
                   f"{int((v > v_tj).sum())} of {len(v)} seeds faster than trajopt; credibly (the slowest over the "
                   f"physics), {int((c > c_tj).sum())} of {len(v)}.")
    if "ppo5x" in k and "ppo" in k:
        long, base = k["ppo5x"], int(np.mean(k["ppo"]["sim_steps"]))
        first = overtakes(long, v_tj, base)
        curve = ", ".join(f"{s / base:.2f}x {v:.2f}" for s, v in long["curves"][0] if s > 0)
        verdict = (f"overtakes trajopt at {first[0]:,} steps ({first[0] / base:.1f}x the budget, {first[1]:.2f} BL/min)"
                   if first else "stays below trajopt")
        out.append(f"{long['method']} (seed {long['seeds'][0]}): {long['speeds'][0]:.2f} BL/min after "
                   f"{long['sim_steps'][0]:,} steps, {long['wall_time_s'][0]:.0f} s; it {verdict}. Checkpoints "
                   f"(multiple of the budget, BL/min): {curve}.")
    return out


def plot(results: dict[str, list[dict]], path: Path) -> None:
    """Speed against simulation steps per robot: trajopt's gait, each RL seed's checkpoints, the
    long PPO run."""
    import matplotlib
    import matplotlib.ticker
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(results), figsize=(6.2 * len(results), 4.4), squeeze=False)
    style = {"ppo": ("tab:blue", "-"), "sac": ("tab:orange", "-"), "ppo5x": ("tab:green", "--")}
    for ax, (robot, rows) in zip(axes[0], results.items()):
        for r in rows:
            if r["kind"] == "trajopt":
                ax.plot([r["sim_steps"][0]], [r["speeds"][0]], "*", color="k", markersize=13,
                        label=f"trajopt --speed max ({r['speeds'][0]:.1f})")
                ax.axhline(r["speeds"][0], color="k", linewidth=0.6, alpha=0.5)
                continue
            color, ls = style[r["kind"]]
            for i, c in enumerate(r["curves"]):
                pts = [(x, y) for x, y in c if x > 0]
                if pts:
                    xs, ys = zip(*pts)
                    ax.plot(xs, ys, marker=".", linestyle=ls, color=color, alpha=0.8,
                            label=f"{r['method']} ({len(r['curves'])} seed{'s' if len(r['curves']) > 1 else ''})"
                            if i == 0 else None)
        ax.axhline(PAPER[robot], color="grey", linestyle=":", label=f"paper, simulation ({PAPER[robot]})")
        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel("simulation steps used (log)")
        ax.set_ylabel("speed [body lengths / min]")
        ax.set_title(f"{robot.capitalize()}: speed vs simulation steps")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def readme_table(results: dict[str, list[dict]], law: str) -> str:
    """The README's table: one line per robot under ``law``."""
    lines = ["| robot, law | trajopt `--speed max` | PPO, 3 seeds | SAC, 3 seeds | PPO, 5x the budget (1 seed) |",
             "|---|---|---|---|---|"]
    for robot, rows in results.items():
        k = _by_kind(rows)
        cells = []
        if "trajopt" in k:
            t = k["trajopt"]
            cells.append(f"{t['speeds'][0]:.2f} BL/min, credible {credible(t)[0]:.2f} ({t['n_cycle']}-step cycle, "
                         f"{t['n_keyframes']} keyframes), {t['sim_steps'][0]:,} steps, {t['wall_time_s'][0]:.0f} s")
        else:
            cells.append("not run")
        for kind in ("ppo", "sac"):
            r = k.get(kind)
            cells.append(f"{mean_spread(r['speeds'])} BL/min, credible {mean_spread(credible(r))}, "
                         f"{int(np.mean(r['sim_steps'])):,} steps, {np.mean(r['wall_time_s']):.0f} s" if r else "not run")
        r = k.get("ppo5x")
        cells.append(f"{r['speeds'][0]:.2f} BL/min, {r['sim_steps'][0]:,} steps, {r['wall_time_s'][0]:.0f} s"
                     if r else "not run")
        lines.append(f"| {robot.capitalize()}, {law} law | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def write_report(results: dict[str, list[dict]], meta: dict, md_path: Path, missing: list[str]) -> str:
    """Write the report (``md_path`` and the plot beside it, same stem); returns its text."""
    png = md_path.with_suffix(".png")
    if results:
        plot(results, png)
    md = [f"# Fastest gaits under the motors' limit: trajopt against RL on the same physics, {meta['law']} law"
          f"{' (QUICK CHECK, not a result)' if meta['quick'] else ''}", "",
          f"Generated by `python benchmarks/bench_rl_vs_trajopt.py --contact {meta['contact']}` on {meta['date']} "
          f"from the sweep `{meta['spec']}` (runs in `{meta['sweep_dir']}`, not kept): {meta['machine']}. Every run "
          "of both sides in that one sweep, two runs at a time on the machine (wall times comparable, not quiet).", "",
          "Same physics, same motors, same evaluation on both sides. Physics: the robot files, "
          f"{meta['law']} contact law, {meta.get('physics', 'the environments')}; the gearmotors "
          f"({meta.get('motors', 'their limits')}) in trajopt's constraints and in the environment RL trains and is "
          "scored in. Credible speed: the slowest of the speeds at the run's own physics and with half (16.5 ms: "
          "the steps the hold stage of `--speed max` asks for too; not at one step per control step) and 2x, 4x and "
          "8x as many physics steps (RL closed loop through the environment). "
          f"Speed: trajopt's metric (`evaluate_controls`), mean COM speed along +x in body lengths per minute over "
          f"{meta['window']} steps after {meta['n_prep']} prep steps from the exact rest state; RL's deterministic "
          "policy closed loop in the environment; trajopt's keyframes repeated to fill the same window; upright = "
          "tilt <= 60 deg and COM >= half its rest height throughout. Simulation steps: trajopt every rollout "
          "step of its search (Gauss-Newton rollouts, Jacobian rollouts, line-search trials, seed screening and "
          "its own evaluations); RL its training environment steps (its checkpoint evaluations are not counted). "
          "RL: mean ± standard deviation over seeds, each seed in brackets; trajopt is deterministic (one run).", ""]
    if missing:
        md += ["Runs not done (left out): " + "; ".join(missing), ""]
    for robot, rows in results.items():
        md += [f"## {robot.capitalize()} (paper, simulation: {PAPER[robot]} BL/min)", "", table(rows), ""]
        md += [f"- {f}" for f in findings(rows)] + [""]
    if results:
        md += [f"![speed vs simulation steps]({png.name})", "",
               "Star: trajopt's gait (its line across the panel); solid lines: each RL seed's checkpoints; "
               "dashed: PPO with 5x the budget.", "", "## Hyper-parameters", ""]
        for robot, rows in results.items():
            md += [f"- {robot} {r['method']}: `{json.dumps(r['hyperparams'], default=str)}`"
                   for r in rows if r.get("hyperparams")]
        md += ["", "## README table", "", readme_table(results, meta["law"]), ""]
    text = "\n".join(md)
    md_path.parent.mkdir(parents=True, exist_ok=True)
    tmp = md_path.with_suffix(".md.tmp")
    tmp.write_text(text)
    tmp.replace(md_path)
    return text
