"""The task suite: the benchmark's 20 task ids (docs/tasks.md) against three baselines, each scored
with the task's own score on the id itself (:mod:`trajopt.tasks.scores`).

The runs are one sweep file, ``examples/suite.toml`` (``trajopt sweep``: one Ray task per run,
a cluster runs it unchanged): per task and robot, ``trajopt optimize ROBOT --task TASK`` (the
task's slope or ground at its level, the gait played open loop on the id) and PPO and SAC, three
seeds each, trained on the id for one fixed budget (closed loop); every run with ``task_score =
true``, so its score on the id (3 episodes, seeds 0-2) is in its ``status.json``. This script
runs the sweep (runs already done in the sweep folder are skipped), measures each id's simulation
steps per second, draws each task (:mod:`soft_envs.render`, the Tripod at the start of an episode)
replays every run made at other physics steps (the headline's protocol: half, twice and four
times the run's physics steps per control step, 16.5-2.06 ms; :func:`trajopt.tasks.play.task_hold`,
``task_hold.json`` in the run's folder, made once) and writes the report: a table of task x robot x
method (mean +- std over the seeds of the task's score, the credible score, the lowest over the
physics steps, and how many runs hold within 5 %, success, simulation steps, wall time), runs not
made marked "not run" with the command that makes them.

Each run's figures are kept in the repository, in the ledger ``benchmarks/results/suite_runs.json``
(:mod:`suite_ledger`): the report is made from every run ever made, those in this machine's sweep
folder replacing their records, so a part of the suite made again on another machine (``--only``)
updates its rows and keeps the others.

Run:  python benchmarks/bench_suite.py                      (every run; ~10 hours of one core)
      python benchmarks/bench_suite.py --only 'SoftTripod*_ppo_*' --workers 1   (a part)
      python benchmarks/bench_suite.py --holds              (no runs: the replays at other physics steps
                                                             of the runs made, then the report)
      python benchmarks/bench_suite.py --report-only        (the report from the runs and replays made)
      python benchmarks/bench_suite.py --quick              (tiny budgets: PPO on every id, SAC on two,
                                                             trajopt on one, in a temporary folder;
                                                             tests/test_suite.py runs it)
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from soft_envs import TASK_IDS_BY_TASK  # noqa: E402
from soft_envs.envs.tasks.docs import TASK_DOCS  # noqa: E402
from trajopt.optim.optimize import DEFAULT_SPEED  # noqa: E402
from trajopt.results.files import atomic_write_bytes  # noqa: E402
from trajopt.rl.envs import robot_name, task_of  # noqa: E402
from trajopt.sweep import load_spec, read_status, run_sweep  # noqa: E402
from trajopt.tasks.registry import get_task  # noqa: E402
from trajopt.tasks.scores import SCORES, default_episodes  # noqa: E402

import suite_ledger  # noqa: E402

#: the suite's tasks: every task with a score (all of them)
TASKS = tuple(t for t in SCORES)

SPEC = ROOT / "examples" / "suite.toml"
SWEEP_DIR = ROOT / "results" / "sweeps" / "suite"
REPORT = HERE / "results" / "suite.md"
LEDGER = HERE / "results" / "suite_runs.json"    # every run's record (suite_ledger), tracked
IMAGES = HERE / "results" / "suite"
DOCS = ROOT / "docs" / "tasks.md"
TABLE_HEAD = ["| task | robot | method | score | credible (hold) | success | seeds | sim steps | wall time / run |",
              "|---|---|---|---|---|---|---|---|---|"]
HOLD_NAME = "task_hold.json"        # in a run's folder: its task score at other physics steps
ROBOTS = ("tripod", "puppy")
METHODS = {"trajopt": "trajopt (open loop)", "trajopt_max": "trajopt `--speed max` (open loop)", "ppo": "PPO",
           "sac": "SAC"}
#: the runs of the quick mode (CI): PPO on every id, SAC on two, trajopt on one terrain task
QUICK_ONLY = ["*_ppo_seed0", "SoftTripodWalk-v0_sac_seed0", "SoftPuppyClimbStep-v0_sac_seed0", "tripod_climb_step_trajopt"]
#: the runs the quick mode replays at other physics steps (one closed loop, one open loop)
QUICK_HOLDS = ["SoftTripodWalk-v0_sac_seed0", "tripod_climb_step_trajopt"]
#: why an open-loop gait cannot do a task as it is posed (docs/tasks.md says the same)
CLOSED_LOOP_ONLY = {
    "reach_goal": "the goal's direction is drawn at each reset (within +-90 degrees at medium): a gait walks "
                  "one heading (+x here) whatever the goal, and walks away from goals off to the side; the task "
                  "needs the goal in the observation, i.e. a policy",
    "rough_terrain": "a new terrain at each reset: the gait is optimised on the terrain of seed 0 and played "
                     "unchanged on others (allowed, but it cannot adapt to them)",
}


def group_of(run) -> tuple[str, str, str]:
    """(task, robot, method) of a suite run."""
    if run.kind == "optimize":
        level = run.params.get("difficulty", "medium")
        method = "trajopt_max" if run.params.get("speed") == "max" else "trajopt" if level == "medium" \
            else f"trajopt@{level}"
        return get_task(run.params["task"]).env_task, robot_name(run.params["robot"]), method
    return task_of(run.params["robot"]), robot_name(run.params["robot"]), run.params["algo"]


def collect(spec, sweep_dir: Path, ledger: dict | None = None) -> tuple[dict[tuple[str, str, str], dict], dict]:
    """Per (task, robot, method): the runs planned, the records of those done (in ``sweep_dir``, or
    else in ``ledger``, :mod:`suite_ledger`, when made with the sweep file's arguments now), those
    failed here, and the ledger's aggregate of the row until every run of it has a record again (the
    row keeps its aggregate's figures while it is made again run by run: those made so far are
    ``again``, not in ``done``); and the records of the runs done in ``sweep_dir`` (by name, for
    the ledger)."""
    ledger = ledger or suite_ledger.empty()
    groups: dict[tuple[str, str, str], dict] = {}
    local: dict[str, dict] = {}
    for run in spec.runs:
        group = group_of(run)
        g = groups.setdefault(group, {"planned": [], "runs": [], "done": [], "failed": [], "aggregate": None,
                                      "again": []})
        g["planned"].append(run.name)
        g["runs"].append(run)
        st = read_status(sweep_dir / run.name) or {}
        rec = None
        if st and (st.get("kind") != run.kind or st.get("params") != suite_ledger.jsonable(run.params)):
            g["failed"].append(f"{run.name}: its folder in {sweep_dir} holds a run made with other arguments "
                               f"({st.get('kind')}, {st.get('params')}): not used")
        elif st.get("status") == "done" and (st.get("metrics") or {}).get("task"):
            rec = local_record(run, group, sweep_dir / run.name, st)
            if rec is not None:
                local[run.name] = rec
        elif st.get("status") in ("failed", "interrupted"):
            g["failed"].append(f"{run.name}: {st.get('status')} ({st.get('reason', '')})")
        rec = suite_ledger.newer(rec, suite_ledger.current(ledger, run))
        if rec is not None:
            g["done"].append({**rec, "name": run.name, "local": rec is local.get(run.name),
                              "other_hp": other_hyperparams(run, rec.get("rl"))})
    for group, g in groups.items():
        agg = suite_ledger.aggregate(ledger, group, g["runs"])
        if agg is not None and not set(agg["runs"]) <= {r["name"] for r in g["done"]}:
            g["again"], g["done"] = sorted(r["name"] for r in g["done"]), []
            g["aggregate"] = {**agg, "other_hp": other_hyperparams(g["runs"][0], agg.get("rl"))}
    return groups, local


def local_record(run, group: tuple[str, str, str], folder: Path, status: dict) -> dict | None:
    """The ledger's record (:func:`suite_ledger.run_record`) of a run done in ``folder``; None
    when its task score cannot be read (as a run not made)."""
    import json
    try:
        task_score = json.loads((folder / "task_score.json").read_text())
    except (OSError, ValueError):
        return None
    rl = rl_config_of(folder) if run.kind == "rl-train" else None
    if run.kind == "rl-train" and rl is None:
        return None
    return suite_ledger.run_record(group, run, status, task_score, hold_of({**status, "run_dir": str(folder)}), rl)


def rl_config_of(folder: Path) -> dict | None:
    """What an RL run's record keeps of its ``rl_config.json`` (the algorithm, the id, the budget,
    the hyper-parameters and where they came from), None when it cannot be read."""
    import json
    try:
        cfg = json.loads((folder / "rl_config.json").read_text())
        return {"algo": cfg["algo"], "target": cfg["env"]["robot"], "n_envs": int(cfg["n_envs"]),
                "timesteps": int(cfg["timesteps"]), "hyperparams": suite_ledger.jsonable(cfg.get("hyperparams")),
                "hyperparams_source": cfg.get("hyperparams_source", "defaults")}
    except (OSError, ValueError, KeyError, TypeError):
        return None


def other_hyperparams(run, rl: dict | None) -> str | None:
    """For an RL run (its record's ``rl``) made with other hyper-parameters than the baseline trains
    with now on its id (the robot's tuned values adopted since, ``trajopt/rl/zoo/tuned.toml``):
    where its came from (``hyperparams_source``, "defaults" before runs recorded it); else None."""
    if run.kind != "rl-train" or not rl:
        return None
    from trajopt.rl.hyperparams import jsonable
    from trajopt.rl.tuning.tuned import task_hyperparams
    now, _ = task_hyperparams(rl["algo"], rl.get("target") or run.params["robot"], n_envs=int(rl["n_envs"]),
                              timesteps=int(rl["timesteps"]))      # a bad tuned.toml: its error
    now.update(parse_hp(run.params.get("hp")))
    return None if jsonable(now) == jsonable(rl.get("hyperparams")) else rl.get("hyperparams_source", "defaults")


def parse_hp(items) -> dict:
    """A run's ``hp`` overrides (``KEY=VALUE`` strings, as ``trajopt rl train --hp``)."""
    from trajopt.rl.hyperparams import parse_overrides
    return parse_overrides([items] if isinstance(items, str) else list(items or []))


def hold_of(status: dict) -> dict | None:
    """A done run's replays at other physics steps (``task_hold.json`` beside its task score),
    None when not made or made for another result (its own score differs: the run was re-made)."""
    import json
    try:
        hold = json.loads((Path(status["run_dir"]) / HOLD_NAME).read_text())
        own = hold.get("own_score", hold["scores"][hold["substeps"].index(hold["own_substeps"])])
        same = bool(np.isclose(float(own), status["metrics"]["task"]["score"], rtol=1e-9, atol=1e-12))
    except (OSError, ValueError, KeyError, IndexError, TypeError, AttributeError):    # unreadable: as not made
        return None
    return hold if same else None


def hold_jobs(spec, sweep_dir: Path, only: list[str] | None) -> list[tuple[str, str, Path]]:
    """The runs made (``only``: matching a pattern) of the main table (not the Levels') without
    their replays: (kind, run name, folder)."""
    jobs = []
    for run in spec.only(only).runs:
        if group_of(run)[2] not in METHODS:
            continue
        st = read_status(sweep_dir / run.name) or {}
        if st.get("status") == "done" and (st.get("metrics") or {}).get("task") and hold_of(
                {**st, "run_dir": str(sweep_dir / run.name)}) is None:
            jobs.append((run.kind, run.name, sweep_dir / run.name))
    return jobs


def make_hold(kind: str, name: str, folder: Path) -> str:
    """One run's replays (:func:`trajopt.tasks.play.task_hold`), written to its ``task_hold.json``."""
    import json
    from trajopt.tasks.play import gait_task_hold, policy_task_hold
    reference = json.loads((folder / "task_score.json").read_text())
    if kind == "optimize":
        hold = gait_task_hold(folder / f"{name}.npz", reference=reference)
    else:
        hold = policy_task_hold(folder, reference=reference)
    atomic_write_bytes(folder / HOLD_NAME, json.dumps(hold, indent=1).encode())
    verdict = "holds" if hold["holds"] else "does not hold"
    return (f"{name}: {' / '.join(f'{v:.3g}' for v in hold['scores'])} {hold['score_unit']} at "
            f"{' / '.join(f'{d:.3g}' for d in hold['physics_dt_ms'])} ms, spread {hold['spread']:.1%}: {verdict}")


def _make_hold_or_say(kind: str, name: str, folder: Path) -> str:
    """:func:`make_hold`, or what went wrong (the other runs' replays go on; the run's row says "–")."""
    try:
        return make_hold(kind, name, folder)
    except Exception as exc:                # noqa: BLE001 - reported by name, the suite goes on
        return f"{name}: not replayed: {type(exc).__name__}: {exc}"


def make_holds(jobs: list[tuple[str, str, Path]], workers: int | None) -> None:
    """The replays of ``jobs`` (:func:`make_hold`), ``workers`` processes at a time (default: all
    cores), each printed as it ends; one that fails is printed with why, and the others go on."""
    from concurrent.futures import as_completed
    from trajopt.workers import worker_pool
    workers = max(1, min(len(jobs), workers or os.cpu_count() or 1))
    if not jobs:
        return
    print(f"replaying {len(jobs)} runs at other physics steps ({workers} at a time)", flush=True)
    if workers == 1:
        for job in jobs:
            print("  " + _make_hold_or_say(*job), flush=True)
        return
    with worker_pool(workers, "soft_envs.envs.threads:limit_threads") as pool:
        futures = [pool.submit(_make_hold_or_say, *job) for job in jobs]
        for fut in as_completed(futures):
            print("  " + fut.result(), flush=True)


def cell(group: dict) -> dict | None:
    """A row's figures: the mean and spread of its scores (RL: over seeds; trajopt, one run: over
    its episodes), its credible score (the mean over the runs replayed of each one's lowest, NaN
    when a simulation failed), how many hold; from its runs' records, else its ledger aggregate."""
    done = group["done"]
    if not done:
        agg = group.get("aggregate")
        if agg is None:
            return None
        return {"mean": agg["mean"], "std": agg["std"], "n": agg["n"], "planned": len(group["planned"]),
                "credible": float("nan") if agg["credible"] is None and agg["replayed"] else agg["credible"],
                "replayed": agg["replayed"], "hold": agg["hold"], "spreads": [],
                "no_spread": agg["replayed"] if (agg["credible"] or 0) > 0 else 0,     # as a median would count
                "success": agg["success"], "sim_steps": agg["sim_steps"], "wall": agg["wall"],
                "unit": agg["score_unit"], "name": agg["score_name"],
                "other_hp": [agg["other_hp"]] if agg.get("other_hp") else [], "aggregate": agg["from"]}
    if len(done) == 1 and done[0]["kind"] == "optimize":
        mean, std = done[0]["score"], done[0]["episode_std"]
    else:
        scores = [r["score"] for r in done]
        mean, std = float(np.mean(scores)), float(np.std(scores, ddof=1)) if len(scores) > 1 else 0.0
    holds = [r["hold"] for r in done if r["hold"] is not None]
    slowest = [np.nan if h["slowest"] is None else h["slowest"] for h in holds]
    credible = (slowest[0] if len(slowest) == 1 else float(np.mean(slowest))) if holds else None
    spreads = [h["spread"] for h in holds if h["slowest"] is not None and h["slowest"] > 0 and h["spread"] is not None]
    return {"mean": float(mean), "std": float(std), "n": len(done), "planned": len(group["planned"]),
            "credible": credible, "replayed": len(holds),
            "hold": sum(h["holds"] for h in holds), "spreads": spreads,
            "no_spread": sum(h["spread"] is None and h["slowest"] is not None and h["slowest"] > 0 for h in holds),
            "success": float(np.mean([r["success_rate"] for r in done])),
            "sim_steps": _mean_known([r["sim_steps"] for r in done]),
            "wall": _mean_known([r["wall_time_s"] for r in done]),
            "unit": done[0]["score_unit"], "name": done[0]["score_name"],
            "other_hp": sorted({r["other_hp"] for r in done if r.get("other_hp")}), "aggregate": None}


def _mean_known(values: list) -> float:
    """The mean of the values known (a record may not keep its simulation steps or wall time), NaN if none."""
    known = [v for v in values if v is not None]
    return float(np.mean(known)) if known else float("nan")


def levels_table(groups: dict[tuple[str, str, str], dict]) -> list[str]:
    """The report's "Levels": trajopt's score (and success) at each level of each task and robot,
    one optimisation per level (``{robot}_{task}_trajopt_{level}``; medium is the table's row)."""
    levels = [("easy", "trajopt@easy"), ("medium", "trajopt"), ("hard", "trajopt@hard")]
    if not any(m == "trajopt@easy" for _, _, m in groups):
        return []
    lines = ["", "## Levels: one optimised gait per level", "",
             "trajopt (`trajopt optimize ROBOT --task TASK --difficulty LEVEL`, the budget above) at each level of "
             "each task, scored on the id at that level (± over the evaluation episodes; the success rate in "
             "brackets where the task has a success). How hard a level is for an optimised gait, and whether it "
             "can be done at all by an open-loop gait (the runs: `trajopt sweep examples/suite.toml --out "
             "results/sweeps/suite --only '*_trajopt_easy' --only '*_trajopt_hard'`):", "",
             "| task | robot | easy | medium | hard |", "|---|---|---|---|---|"]
    for task in TASKS:
        for robot in ROBOTS:
            row = [task, robot.capitalize()]
            for _, method in levels:
                g = groups.get((task, robot, method))
                c = cell(g) if g is not None else None
                if c is None:
                    row.append("not run")
                    continue
                text = f"{_fmt(c)} {SCORES[task].unit}"
                if TASK_DOCS[task].success:
                    text += f" ({c['success']:.0%})"
                row.append(text)
            lines.append("| " + " | ".join(row) + " |")
    return lines


def measure_rates(steps: int) -> dict[str, float]:
    """Simulation steps per second of each id (random actions, one process, after a warm-up)."""
    import gymnasium as gym
    rates = {}
    for task in TASKS:
        for robot in ROBOTS:
            env = gym.make(TASK_IDS_BY_TASK[task][robot])
            env.reset(seed=0)
            env.action_space.seed(0)
            env.step(env.action_space.sample())
            t0, n = time.perf_counter(), 0
            while n < steps:
                _, _, term, trunc, _ = env.step(env.action_space.sample())
                n += 1
                if term or trunc:
                    env.reset()
            rates[TASK_IDS_BY_TASK[task][robot]] = n / (time.perf_counter() - t0)
            env.close()
    return rates


def render_pictures(folder: Path, width: int, height: int) -> dict[str, Path]:
    """Each task on the Tripod at the start of an episode (seed 0, medium), one PNG per task."""
    import gymnasium as gym
    from PIL import Image
    folder.mkdir(parents=True, exist_ok=True)
    out = {}
    for task in TASKS:
        env = gym.make(TASK_IDS_BY_TASK[task]["tripod"], render_mode="rgb_array", width=width, height=height,
                       camera_config={"azimuth": 20.0, "elevation": 18.0})
        env.reset(seed=0)
        path = folder / f"{task}.png"
        tmp = path.with_name(f".{path.name}.tmp.png")
        Image.fromarray(env.render()).save(tmp)
        os.replace(tmp, path)
        env.close()
        out[task] = path
    return out


def _fmt(c: dict | None) -> str:
    if c is None:
        return "not run"
    digits = 1 if c["unit"] == "deg" else 2
    return f"{c['mean']:+.{digits}f} ± {c['std']:.{digits}f}"


def holds_summary(groups: dict[tuple[str, str, str], dict]) -> list[str]:
    """The report's "Which scores hold": per method, the runs replayed at other physics steps, how
    many hold, and the median spread (of the runs with a positive score whose spread is kept)."""
    rows, unkept = [], 0
    for method, label in METHODS.items():
        cells = [c for (_, _, m), g in groups.items() if m == method and (c := cell(g)) is not None and c["replayed"]]
        if not cells:
            continue
        spreads = [s for c in cells for s in c["spreads"]]
        missing = sum(c["no_spread"] for c in cells)
        unkept += missing
        median = f"{np.median(spreads):.1%}" if spreads else "–"
        if missing:
            median += f" (of {len(spreads)}; {missing} not kept)"
        rows.append(f"| {label} | {sum(c['replayed'] for c in cells)} | {sum(c['hold'] for c in cells)} | {median} |")
    if not rows:
        return []
    lines = ["", "## Which scores hold", "",
             "The runs replayed at 16.5, 4.125 and 2.06 ms (the column \"credible (hold)\"), per method: how many "
             "hold within 5 %, and the median spread of those scoring above 0. A spread says the score depends on "
             "the physics step: an open-loop gait or a policy exploiting the model, or, for a policy over 300 "
             "closed-loop steps on terrain drawn per episode, the growth of a small change of its path (chaos, "
             "which the evaluation's own ± shows too); the lowest score is the one to quote either way.", "",
             "| method | runs replayed | hold | median spread |", "|---|---|---|---|", *rows]
    if unkept:
        lines += ["", f"The spreads of {unkept} runs replayed were not kept (the ledger's older records, "
                  "`benchmarks/results/suite_runs.json`, keep whether they hold, not by how much): the medians are "
                  "of the others."]
    return lines


def _fmt_credible(c: dict | None) -> str:
    """The credible score (mean over the runs replayed of each one's lowest over the physics steps)
    and how many of those runs hold, "–" when none was replayed."""
    if c is None or not c["replayed"]:
        return "–"
    digits = 1 if c["unit"] == "deg" else 2
    mean = "a simulation failed" if not np.isfinite(c["credible"]) else f"{c['credible']:+.{digits}f}"
    missing = c["n"] - c["replayed"]
    return f"{mean} ({c['hold']}/{c['replayed']}{f', {missing} not replayed' if missing else ''})"


def report(spec, sweep_dir: Path, groups: dict[tuple[str, str, str], dict], rates: dict[str, float],
           pictures: dict[str, Path], path: Path, quick: bool, ledger: Path | None = None) -> str:
    """The report's markdown of the rows ``groups`` (:func:`collect`; written to ``path`` atomically)."""
    budgets = {}
    for run in spec.runs:
        budgets.setdefault(group_of(run)[2], run.params.get("timesteps", run.params.get("iterations", 10)))
    rel = os.path.relpath(sweep_dir, ROOT) if str(sweep_dir).startswith(str(ROOT)) else str(sweep_dir)
    cells = [c for g in groups.values() if (c := cell(g)) is not None]
    made = sum(c["n"] for c in cells)
    here = sum(1 for g in groups.values() for r in g["done"] if r.get("local"))
    if ledger is None:
        where = f"in `{rel}/`"
    else:
        kept = sorted({c["aggregate"] for c in cells if c["aggregate"]})
        where = (f"{here} of them in `{rel}/` on this machine, the others as the ledger "
                 f"`{os.path.relpath(ledger, ROOT) if str(ledger).startswith(str(ROOT)) else ledger}` keeps them "
                 "(`benchmarks/suite_ledger.py`: each run's record"
                 + (f"; the rows marked ‡ as one record of the row's runs, from {'; '.join(kept)}" if kept else "")
                 + ")")
    n_ep = default_episodes()
    lines = [f"# The task suite{' (quick: tiny budgets, no result)' if quick else ''}", "",
             f"Made by `python benchmarks/bench_suite.py{' --quick' if quick else ''}` on {platform.node()}, "
             f"{time.strftime('%Y-%m-%d')}; the runs of `examples/suite.toml` ({made} of "
             f"{len(spec.runs)} made; {where}). Every run is scored on its task's Gymnasium id (difficulty medium but in the Levels, "
             f"the registered 300-step episodes, {n_ep} episode{'s' * (n_ep > 1)}, seeds 0-{n_ep - 1}) with the "
             "task's own score (`trajopt.tasks.scores`):", ""]
    for task in TASKS:
        sc = SCORES[task]
        lines.append(f"- {task}: **{sc.name}** [{sc.unit}], {sc.description}")
    lines += ["", f"Budgets: PPO and SAC {budgets.get('ppo')} / {budgets.get('sac')} environment steps per run "
              f"(3 seeds); trajopt {budgets.get('trajopt')} Gauss-Newton iterations (one run; its ± is over its "
              "evaluation episodes, RL's over the seeds); trajopt `--speed max` its whole search (the cycle "
              "and the keyframes, about 12 optimisations and the hold stage's replays). Simulation steps: RL's training steps, trajopt's "
              "optimisation steps (rollouts, Jacobians, line searches); wall time per run includes the "
              "evaluation.", "",
              "Credible (hold): each run played again, its policy or gait unchanged, with half, twice and four "
              "times its physics steps per control step (16.5, 4.125 and 2.06 ms around the runs' 8.25 ms; the "
              "headline's protocol, `trajopt.tasks.play.task_hold`); its credible score is the lowest of the four, "
              "the column its mean over the runs replayed, and in brackets how many of them hold (score > 0 and "
              "the four within 5 % of the lowest) of how many replayed. A score that changes with the physics "
              "step is the model's, not the task's.", "",
              *TABLE_HEAD]
    missing = []
    for task in TASKS:
        for robot in ROBOTS:
            for method, label in METHODS.items():
                g = groups.get((task, robot, method))
                if g is None:
                    continue
                c = cell(g)
                if c is None or c["n"] < c["planned"]:
                    missing.append((task, robot, method, g))
                unit = SCORES[task].unit
                stale = bool(c and c["other_hp"])
                row = [task, robot.capitalize(), label + (" †" if stale else "") + (" ‡" if c and c["aggregate"] else ""),
                       f"{_fmt(c)} {unit}" if c else "not run", _fmt_credible(c),
                       (f"{c['success']:.0%}" if TASK_DOCS[task].success else "–") if c else "", f"{c['n']}/{c['planned']}" if c else f"0/{len(g['planned'])}",
                       f"{c['sim_steps']:,.0f}" if c else "", f"{c['wall']:.0f} s" if c else ""]
                lines.append("| " + " | ".join(row) + " |")
    stale = [st["other_hp"] for g in groups.values() for st in g["done"] if st.get("other_hp")]
    stale += [agg["other_hp"] for g in groups.values() if not g["done"] and (agg := g["aggregate"])
              and agg.get("other_hp") for _ in range(agg["n"])]
    if stale:
        sources = sorted(set(stale))
        lines += ["", f"† {len(stale)} runs were made with other hyper-parameters than `trajopt rl train` and the "
                  f"suite use on their ids now ({'; '.join(sources)}: the robot's tuned values, "
                  "`trajopt/rl/zoo/tuned.toml`, were adopted since, or the defaults changed; docs/tasks.md "
                  "\"Tuning the baselines\"). A row marked † holds at least one of them. `python benchmarks/bench_suite.py "
                  "--only PATTERN` makes them again (their folders, where this machine has them, moved aside "
                  "first: the sweep skips runs that are done), and each new run replaces its record in the ledger."]
    if any(c["aggregate"] for c in cells):
        again = sorted(n for g in groups.values() for n in g["again"])
        lines += ["", "‡ The row's runs are kept as one record of the row (its figures above, not each run's): "
                  "their folders were lost before the ledger kept each run. The row keeps that record until all "
                  "its runs are made again; then their records replace it."
                  + (f" Made again so far, not yet in their rows: {', '.join(f'`{n}`' for n in again)}." if again
                     else "")]
    lines += holds_summary(groups)
    lines += levels_table(groups)
    lines += ["", "## Open loop or closed loop", "",
              "Every task is a trajopt objective (`trajopt optimize ROBOT --task TASK [--difficulty LEVEL]`): walk, "
              "turn, the slopes, rough terrain, the step and the trench on the task's own slope or ground, carry and "
              "push with the task's box added to the robot (the walk's objective: the score says whether the payload "
              "stayed on and how far the box went), reach a goal as the walk along `--heading`. Where an open-loop gait falls short of the task as posed:", ""]
    lines += [f"- {task}: {why}" for task, why in CLOSED_LOOP_ONLY.items()]
    speeds = ", ".join(f"{DEFAULT_SPEED[r]:g} BL/min for the {r.capitalize()}" for r in ROBOTS if r in DEFAULT_SPEED)
    lines += ["", "trajopt's objective is the walk's of `trajopt optimize` as shipped: it tracks a COM path at the "
              f"robot's default target speed ({speeds}), not the fastest walk: that is the walk's "
              "`--speed max` row (the search of benchmarks/results/headline.md), the like-for-like baseline of "
              "RL on the walk; every optimisation starts from its own random seeds (the "
              "README's Puppy turn is warm-started from its walk, `--warm-start results/puppy_walk.npz`); RL "
              "maximises the task's reward."]
    turns = [cell(groups[("turn", "tripod", m)]) for m in METHODS if ("turn", "tripod", m) in groups]
    turns = [c for c in turns if c is not None]
    if turns and max(abs(c["mean"]) for c in turns) < 1.0:
        most = max(abs(c["mean"]) for c in turns)
        most = f"{most:.2f} degrees" if most >= 0.05 or not any(c["aggregate"] for c in turns) else \
            "less than 0.05 degrees"                # a row kept as its report's figure: to 0.1 degrees
        lines += ["", "The Tripod's two motors bend its middle leg forward and backward in its plane of symmetry "
                  "(assets/tripod/robot.toml): no control yaws it, and every method made on it turns it by "
                  f"{most} at most over an episode. The turn is the Puppy's task."]
    lines += ["", "## Cost", "", "Simulation steps per second of each id (random actions, one process; measured "
              "by this script on this machine, shared with other jobs):", "",
              "| id | steps/s | RL runs' cost at the budget (6 runs) |", "|---|---|---|"]
    rl_steps = 3 * (budgets.get("ppo") or 0) + 3 * (budgets.get("sac") or 0)
    for tid, rate in rates.items():
        lines.append(f"| `{tid}` | {rate:.0f} | {rl_steps / rate / 60:.0f} min (simulation alone) |")
    total = sum(rl_steps / r for r in rates.values())
    lines += ["", f"The RL runs of the full suite simulate {rl_steps * len(rates):,} steps: {total / 3600:.1f} hours "
              "of one core for the simulation alone (SAC's gradient steps and PPO's updates add to it: the wall "
              "times above).", ""]
    if missing:
        lines += ["## Not run", "", "Runs of `examples/suite.toml` not made (or not finished) in this report; "
                  "`python benchmarks/bench_suite.py` makes every one (it skips those done here or kept in the "
                  "ledger), a part: "
                  "`trajopt sweep examples/suite.toml --out results/sweeps/suite --only PATTERN` then "
                  "`python benchmarks/bench_suite.py --report-only`:", ""]
        for task, robot, method, g in missing:
            pat = _pattern(g["planned"])
            lines.append(f"- {task}, {robot}, {METHODS[method]}: `--only '{pat}'`"
                         + (f" ({'; '.join(g['failed'])})" if g["failed"] else ""))
        lines.append("")
    lines += ["## The tasks", ""]
    for task, pic in pictures.items():
        lines += [f"![{task}]({os.path.relpath(pic, path.parent)})", ""]
    text = "\n".join(lines)
    atomic_write_bytes(path, text.encode())
    return text


def update_docs(report_text: str, docs: Path = DOCS) -> None:
    """Each task's rows of the report into its section of docs/tasks.md (between the lines
    ``<!-- baselines TASK -->`` and ``<!-- /baselines TASK -->``), atomically."""
    text = docs.read_text()
    for task in TASKS:
        start, end = f"<!-- baselines {task} -->", f"<!-- /baselines {task} -->"
        if start not in text or end not in text:
            raise ValueError(f"{docs}: no '{start}' ... '{end}' block for the task {task!r}")
        width = TABLE_HEAD[0].count("|")                       # the main table's rows, not the levels'
        rows = [line for line in report_text.splitlines()
                if line.startswith(f"| {task} | ") and line.count("|") == width]
        a, b = text.index(start) + len(start), text.index(end)
        text = text[:a] + "\n" + "\n".join(TABLE_HEAD + rows) + "\n" + text[b:]
    atomic_write_bytes(docs, text.encode())


def _pattern(names: list[str]) -> str:
    """A shell pattern matching ``names`` (their common prefix, ``*``)."""
    prefix = os.path.commonprefix(names)
    return prefix if len(names) == 1 else prefix + "*"


def main(argv: list[str] | None = None) -> str:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spec", type=Path, default=SPEC, help="sweep file (default examples/suite.toml)")
    ap.add_argument("--sweep-dir", type=Path, default=None,
                    help="the sweep's folder (default results/sweeps/suite; --quick: a temporary one)")
    ap.add_argument("--report", type=Path, default=None,
                    help="report file (default benchmarks/results/suite.md; --quick: SWEEP_DIR/suite.md)")
    ap.add_argument("--quick", action="store_true", help="tiny budgets ([runs.quick]), also SOFT_ENVS_QUICK=1")
    ap.add_argument("--only", action="append", default=None, metavar="PATTERN", help="only the runs matching")
    ap.add_argument("--workers", type=int, default=None,
                    help="local Ray CPUs, and processes replaying runs at other physics steps (default: all)")
    ap.add_argument("--serial", action="store_true", help="no Ray: the runs one after another in this process")
    ap.add_argument("--holds", action="store_true",
                    help="no runs: the replays at other physics steps of the runs made (those missing), then the report")
    ap.add_argument("--report-only", action="store_true", help="no runs, no replays: the report from those made")
    ap.add_argument("--ledger", type=Path, default=LEDGER,
                    help="the runs' records kept in the repository, read and updated with the runs made here "
                         "(default benchmarks/results/suite_runs.json; not with --quick)")
    ap.add_argument("--no-ledger", action="store_true", help="the report from the sweep folder's runs alone")
    args = ap.parse_args(argv)
    quick = args.quick or os.environ.get("SOFT_ENVS_QUICK", "") not in ("", "0")
    sweep_dir = args.sweep_dir or (Path(tempfile.mkdtemp(prefix="suite_quick_")) if quick else SWEEP_DIR)
    report_path = args.report or (sweep_dir / "suite.md" if quick else REPORT)
    spec = load_spec(args.spec, sweep_dir, quick=quick)
    saved = os.environ.get("SOFT_ENVS_QUICK")
    if quick:
        os.environ["SOFT_ENVS_QUICK"] = "1"             # one evaluation episode per run (trajopt.tasks.scores)
    try:
        return _run(args, spec, sweep_dir, report_path, quick)
    finally:
        if saved is None:
            os.environ.pop("SOFT_ENVS_QUICK", None)
        else:
            os.environ["SOFT_ENVS_QUICK"] = saved


def _run(args, spec, sweep_dir: Path, report_path: Path, quick: bool) -> str:
    """The sweep (unless ``--report-only``), the rates, the pictures, the report (and the docs)."""
    ledger_path = None if quick or args.no_ledger else args.ledger
    if ledger_path:
        suite_ledger.load(ledger_path)               # a bad ledger: its error now, not after hours of runs
    if not (args.report_only or args.holds):
        sweep_dir.mkdir(parents=True, exist_ok=True)
        only = args.only or (QUICK_ONLY if quick else None)
        todo = spec.only(only)
        if ledger_path and not args.only:            # made elsewhere and kept: not made again unless asked
            kept = kept_runs(todo, sweep_dir, suite_ledger.load(ledger_path))
            if kept:
                print(f"{len(kept)} runs are kept in {ledger_path} and not made again (--only NAME makes one again)")
                todo = replace(todo, runs=[r for r in todo.runs if r.name not in kept])
        outcome = run_sweep(todo, sweep_dir, workers=args.workers, serial=args.serial)
        if outcome.interrupted:
            raise SystemExit(130)
    if not args.report_only:
        make_holds(hold_jobs(spec, sweep_dir, args.only or (QUICK_HOLDS if quick else None)),
                   1 if args.serial else args.workers)
    if ledger_path:
        with suite_ledger.locked(ledger_path):
            ledger = suite_ledger.load(ledger_path)
            _, local = collect(spec, sweep_dir, ledger)
            ledger, said = suite_ledger.update(ledger, local)
            suite_ledger.save(ledger_path, ledger)
        for line in said:
            print("  " + line)
        print(f"{len(local)} runs of {sweep_dir} in {ledger_path}")
    groups, _ = collect(spec, sweep_dir, ledger if ledger_path else None)
    rates = measure_rates(10 if quick else 100)
    pictures = render_pictures(sweep_dir / "images" if quick else IMAGES, *((160, 120) if quick else (480, 320)))
    text = report(spec, sweep_dir, groups, rates, pictures, report_path, quick, ledger_path)
    print(f"wrote {report_path}")
    if not quick and args.report is None:
        update_docs(text)
        print(f"wrote each task's rows into {DOCS}")
    return text


def kept_runs(spec, sweep_dir: Path, ledger: dict) -> set[str]:
    """The runs of ``spec`` not in ``sweep_dir`` that ``ledger`` keeps as made with the sweep file's
    arguments now (a record, or its row's aggregate)."""
    groups: dict[tuple[str, str, str], list] = {}
    for run in spec.runs:
        groups.setdefault(group_of(run), []).append(run)
    kept = set()
    for group, runs in groups.items():
        agg = suite_ledger.aggregate(ledger, group, runs)
        for run in runs:
            if read_status(sweep_dir / run.name) is None and (
                    suite_ledger.current(ledger, run) is not None or (agg is not None and run.name in agg["runs"])):
                kept.add(run.name)
    return kept


if __name__ == "__main__":
    main()
