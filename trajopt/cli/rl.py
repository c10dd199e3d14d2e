"""``trajopt rl``: train, evaluate and export the RL baseline.

    trajopt rl train tripod --algo ppo --timesteps 30000 --seed 0     # results/runs/tripod_ppo_seed0/
    trajopt rl train puppy --algo sac --timesteps 10000 --hp learning_rate=1e-3
    trajopt rl evaluate results/runs/tripod_ppo_seed0 [--cycles 6] [--seed 0] [--json]
    trajopt rl export results/runs/tripod_ppo_seed0                   # results/tripod_ppo_seed0.npz
    trajopt render results/tripod_ppo_seed0.npz                       # results/tripod_ppo_seed0.gif

This module imports neither Stable-Baselines3 nor PyTorch: the parser exists without them and
the commands say how to install them (``pip install soft-envs[rl]``).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..argtypes import (contact_law, cycles, difficulty_level, file_name, integer, nonnegative_float, number, output_dir, output_file, positive_int,
                        slope_deg)
from ..results.files import RESULTS_DIR, refuse_existing
from ..rl.envs import DEFAULT_EVAL_CYCLES, GAIT, ROBOTS, TRAIN_HORIZON, rl_target
from ..rl.hyperparams import ALGOS
from ..rl.options import RUNS_DIR, TRAIN_OPTIONS
from .table import print_table

SEED = integer(0, 2**32 - 1)          # what NumPy's legacy seeding accepts

__all__ = ["add_rl_parser"]


def add_rl_parser(sub) -> argparse.ArgumentParser:
    """Add ``rl`` (with ``train``, ``evaluate``, ``export``) to the ``trajopt`` sub-parsers."""
    rl = sub.add_parser("rl", help="RL baseline (Stable-Baselines3 PPO / SAC) on the same simulator",
                        description="RL baseline: Stable-Baselines3 PPO and SAC on SoftTripod-v2 / "
                                    "SoftPuppy-v2, scored with trajopt's metric. Needs "
                                    "pip install soft-envs[rl].")
    rsub = rl.add_subparsers(dest="rl_command", required=True)

    p = rsub.add_parser("train", help="train a policy (checkpoints, TensorBoard + CSV logs)")
    p.add_argument("robot", type=rl_target, metavar="ROBOT",
                   help=f"robot ({', '.join(sorted(ROBOTS))}: SoftTripod-v2 / SoftPuppy-v2) or a task id "
                        "(SoftTripodWalk-v0 ... SoftPuppyReachGoal-v0, docs/tasks.md)")
    p.add_argument("--algo", choices=ALGOS, default="ppo")
    p.add_argument("--timesteps", type=positive_int, default=30_000, help="environment steps to train for")
    p.add_argument("--seed", type=SEED, default=0)
    p.add_argument("--out", type=output_dir, default=RUNS_DIR,
                   help=f"parent directory of the run (default {RUNS_DIR}/)")
    p.add_argument("--name", type=file_name, default=None, help="run directory name (default ROBOT_ALGO_seedS)")
    p.add_argument("--n-envs", type=positive_int, default=None, help="parallel environments (default: CPU count)")
    p.add_argument("--vec-env", choices=["auto", "subproc", "dummy"], default="auto",
                   help="auto: SubprocVecEnv when n-envs > 1")
    p.add_argument("--frame-skip", type=positive_int, default=1, help="simulation steps per action")
    p.add_argument("--episode-steps", type=positive_int, default=None,
                   help=f"max_episode_steps (default {TRAIN_HORIZON}, trajopt's horizon, on a robot; a task id's "
                        "registered 300, over which its score is defined)")
    p.add_argument("--incline", type=slope_deg, default=0.0, help="ground slope [deg]")
    p.add_argument("--contact", type=contact_law, default=None, metavar="LAW",
                   help="ground contact law: coulomb (the default, feet that stick) or paper (II-C, Table I's; "
                        "made as contact=\"paper\" on the -v2 id)")
    p.add_argument("--heading", type=number(), default=0.0, help="walking direction [deg from +x to +z]")
    p.add_argument("--difficulty", type=difficulty_level, default=None, metavar="LEVEL",
                   help="a task id's level: easy, medium (its default) or hard")
    p.add_argument("--checkpoint-every", type=positive_int, default=None,
                   help="environment steps between checkpoints (default: a tenth of the budget)")
    p.add_argument("--hp", action="append", default=[], metavar="KEY=VALUE",
                   help="override a hyper-parameter (Python literal), repeatable")
    p.add_argument("--overwrite", action="store_true", help="replace an existing run of the same name")
    p.add_argument("--no-progress", action="store_true",
                   help="no progress bar (there is none either when stderr is not a terminal)")
    p.add_argument("--verbose", action="store_true", help="also print the SB3 logger to stdout")
    p.set_defaults(func=_cmd_train)

    p = rsub.add_parser("evaluate", help="trajopt's metric (BL/min along the target, upright) for a policy")
    p.add_argument("model", type=Path, help="run directory, its model.zip or a checkpoint .zip")
    p.add_argument("--cycles", type=cycles, default=DEFAULT_EVAL_CYCLES,
                   help=f"gait cycles of {GAIT.n_cycle} steps after {GAIT.n_prep} prep steps")
    p.add_argument("--seed", type=SEED, default=0)
    p.add_argument("--reset-noise", type=nonnegative_float, default=0.0,
                   help="reset noise [m] (default 0: trajopt's start, the exact rest state)")
    p.add_argument("--fidelity", action="store_true",
                   help="also play the policy closed loop at 2x, 4x and 8x finer physics steps (how credible its "
                        "speed is, as trajopt evaluate --fidelity); with --task: at half, twice and four times its "
                        "physics steps, the suite's protocol")
    p.add_argument("--task", action="store_true",
                   help="a run trained on a task id: its task's own score on the id instead (the suite's: 3 episodes, "
                        "seeds 0-2, the id's reset noise; --cycles, --seed and --reset-noise do not apply); with "
                        "--fidelity, also at 16.5, 4.125 and 2.06 ms physics steps, and whether it holds")
    p.add_argument("--json", action="store_true", help="print the evaluation as JSON")
    p.set_defaults(func=_cmd_evaluate)

    p = rsub.add_parser("export", help="save the policy's deterministic rollout as a trajopt Result (.npz)")
    p.add_argument("model", type=Path, help="run directory, its model.zip or a checkpoint .zip")
    p.add_argument("--out", type=output_file, default=None,
                   help=f"result file (.npz, with a .json sibling; default {RESULTS_DIR}/RUN_NAME.npz)")
    p.add_argument("--cycles", type=cycles, default=DEFAULT_EVAL_CYCLES)
    p.add_argument("--seed", type=SEED, default=0)
    p.add_argument("--reset-noise", type=nonnegative_float, default=0.0)
    p.add_argument("--overwrite", action="store_true", help="replace an existing result file")
    p.set_defaults(func=_cmd_export)

    p = rsub.add_parser("tune", help="tune PPO's or SAC's hyper-parameters on a task id (an Optuna study, resumable)",
                        description="Tune the RL baseline on a task id: each trial trains with the suite's budget "
                                    "and is scored by the task's own score on held-out seeds; the first trial is "
                                    "the documented defaults. The same command again goes on with the study. "
                                    "Needs pip install soft-envs[tune]. (trajopt.rl.tuning says how.)")
    p.add_argument("env", metavar="ID", help="a task id (SoftTripodWalk-v0 ... SoftPuppyPushBox-v0, docs/tasks.md)")
    p.add_argument("--algo", choices=ALGOS, default="ppo")
    p.add_argument("--trials", type=positive_int, default=20, help="trials to finish, the defaults' included (default 20)")
    p.add_argument("--workers", type=positive_int, default=1, help="processes sharing the study (default 1)")
    p.add_argument("--timesteps", type=positive_int, default=None,
                   help="environment steps per trial (default the suite's budget, 30000)")
    p.add_argument("--episodes", type=positive_int, default=None,
                   help="evaluation episodes per trial (default the suite's 3)")
    p.add_argument("--seed", type=SEED, default=0, help="seeds the TPE samplers (with the worker's number and the trials made)")
    p.add_argument("--out", type=output_dir, default=None, help="study folder (default results/tuning/ID_ALGO)")
    p.add_argument("--check", type=positive_int, default=None, metavar="N",
                   help="then train the best and the defaults with the suite's seeds 0..N-1 and score them as the "
                        "suite does, each also replayed at other physics steps (out/check/, out/check.json): does "
                        "the best beat the defaults on seeds it was not chosen on, credibly?")
    p.add_argument("--adopt", action="store_true",
                   help="with --check: if the best beat the defaults on the suite's seeds, at its own physics step "
                        "and at the lowest over the replays, make it the robot's tuned "
                        "values for the algorithm (trajopt/rl/zoo/tuned.toml, used on every task id of the robot) and "
                        "write the rl_zoo3 files again")
    p.add_argument("--json", action="store_true", help="print the study's summary (and the check) as JSON")
    p.set_defaults(func=_cmd_tune)
    return rl


def _missing(exc: Exception) -> int:
    print(f"trajopt: error: {exc}", file=sys.stderr)
    return 2


def _cmd_train(args) -> int:
    from ..rl import MissingRLDependencies
    try:
        from ..rl.options import train_with_options
        run = train_with_options(args.robot, **{k: v for k, v in vars(args).items() if k in TRAIN_OPTIONS})
    except MissingRLDependencies as exc:
        return _missing(exc)
    print(f"{run.status}: {run.timesteps} steps ({run.sim_steps} simulation steps) in "
          f"{run.wall_time_s:.1f} s; saved {run.model_path}")
    if run.status == "done" and run.config.get("task"):
        from ..tasks.play import policy_on_task               # the task's own score
        ev = policy_on_task(run.run_dir)
        print(f"  {ev['score_name']}: {ev['score']:.3f} {ev['score_unit']} (the task's score, mean of "
              f"{len(ev['episodes'])} episodes; success {ev['success_rate']:.0%})")
    elif run.status == "done":
        from ..rl.evaluate import evaluate_policy_metric      # the figure the user came for
        ev = evaluate_policy_metric(run.run_dir, n_cycles=DEFAULT_EVAL_CYCLES)
        print(f"  speed:       {ev['speed_bl_per_min']:.2f} BL/min along the target over {DEFAULT_EVAL_CYCLES} cycles "
              f"({'upright' if ev['upright'] else 'fell over'}; trajopt's metric, as trajopt rl evaluate)")
    print(f"  evaluate:    trajopt rl evaluate {run.run_dir}")
    print(f"  TensorBoard: tensorboard --logdir {run.run_dir / 'logs'}")
    if run.status == "interrupted":
        return 128 + (run.signal or 2)           # 130 for Ctrl-C, 143 for SIGTERM, as the other commands
    return 0


def _print_eval(ev: dict) -> None:
    rows = [("speed", f"{ev['speed_bl_per_min']:.3f} BL/min over {ev.get('cycles')} cycles "
                      f"(after {ev.get('n_prep')} prep steps)"),
            ("per cycle", " ".join(f"{v:.2f}" for v in ev.get("speed_per_cycle_bl_per_min", []))),
            ("displacement", f"{ev.get('displacement_m', float('nan')) * 1000:.2f} mm along the target"),
            ("heading change", f"{ev.get('heading_change_deg', float('nan')):+.1f} deg"),
            ("max tilt", f"{ev.get('max_tilt_deg', float('nan')):.1f} deg"),
            ("upright", str(ev["upright"]))]
    if "sim_failure" in ev:
        rows.append(("simulation failure", ev["sim_failure"]))
    print_table(rows)


def _cmd_evaluate(args) -> int:
    from ..rl import MissingRLDependencies
    try:
        from ..rl.evaluate import evaluate_policy_metric, load_policy
        policy = load_policy(args.model)
        if args.task:
            return _evaluate_on_task(policy, args)
        ev = evaluate_policy_metric(policy, n_cycles=args.cycles, seed=args.seed,
                                    reset_noise_scale=args.reset_noise)
        if args.fidelity:
            from ..rl.evaluate import policy_fidelity
            ev["fidelity"] = policy_fidelity(policy, n_cycles=args.cycles, seed=args.seed, reference=ev)
    except MissingRLDependencies as exc:
        return _missing(exc)
    if args.json:
        print(json.dumps({k: v for k, v in ev.items() if k != "com"}, indent=1))
    else:
        cfg = policy.config
        print(f"{cfg['robot']} {cfg['algo'].upper()} seed {cfg.get('seed')}, "
              f"{cfg.get('timesteps_done', '?')} training steps ({cfg.get('status', '?')}); {policy.path}")
        _print_eval(ev)
        if args.fidelity:
            from .commands import fidelity_text
            print(fidelity_text(ev["fidelity"]))
    return 0 if ev["upright"] else 1


def _evaluate_on_task(policy, args) -> int:
    """``trajopt rl evaluate --task``: the task's own score of a run trained on a task id
    (:func:`trajopt.tasks.play.policy_on_task`), with ``--fidelity`` its replays at other physics
    steps (:func:`trajopt.tasks.play.policy_task_hold`)."""
    from ..tasks.play import policy_on_task, policy_task_hold
    given = [f"--{k.replace('_', '-')}" for k, default in (("cycles", DEFAULT_EVAL_CYCLES), ("seed", 0), ("reset_noise", 0.0))
             if getattr(args, k) != default]
    if given:
        print(f"trajopt: error: --task scores the task's own episodes: {', '.join(given)} does not apply", file=sys.stderr)
        return 2
    if not policy.config.get("task"):
        print(f"trajopt: error: --task: {policy.path} was trained on {policy.config.get('env_id') or policy.config['env']['robot']!r}, not on a task "
              "id (trajopt rl evaluate without --task gives its speed)", file=sys.stderr)
        return 2
    ev = policy_on_task(policy)
    if args.fidelity:
        ev["hold"] = policy_task_hold(policy, reference=ev)
    if args.json:
        print(json.dumps(ev, indent=1))
        return 0
    cfg = policy.config
    print(f"{cfg['env']['robot']} {cfg['algo'].upper()} seed {cfg.get('seed')}, "
          f"{cfg.get('timesteps_done', '?')} training steps ({cfg.get('status', '?')}); {policy.path}")
    unit = ev["score_unit"]
    rows = [(ev["score_name"], f"{ev['score']:+.3f} {unit} (the task's score, mean of {len(ev['episodes'])} episodes)"),
            ("per episode", " ".join(f"{e['score']:+.3f}" for e in ev["episodes"]) + f" {unit}"),
            ("success", f"{ev['success_rate']:.0%}"),
            ("ends", ", ".join(e["end"] for e in ev["episodes"]))]
    print_table(rows)
    if args.fidelity:
        from .commands import task_hold_text
        print(task_hold_text(ev["hold"], 1e3 * ev["control_dt_s"]))
    return 0


def _cmd_export(args) -> int:
    from ..rl import MissingRLDependencies
    from ..results.result import result_path
    model = Path(args.model)
    default = RESULTS_DIR / f"{model.name if model.is_dir() else model.stem}.npz"
    path = result_path(args.out if args.out is not None else default)
    refuse_existing([path], args.overwrite)
    try:
        from ..rl.evaluate import export_result
        res = export_result(args.model, path, n_cycles=args.cycles, seed=args.seed,
                            reset_noise_scale=args.reset_noise, overwrite=args.overwrite)
    except MissingRLDependencies as exc:
        return _missing(exc)
    print(f"wrote {path}: {res.summary()}")
    print(f"  render: trajopt render {path}      # {RESULTS_DIR / (path.stem + '.gif')}")
    return 0


def _cmd_tune(args) -> int:
    from ..rl import MissingRLDependencies
    from ..rl.hyperparams import SUITE_TIMESTEPS
    try:
        import optuna  # noqa: F401
    except ImportError:
        print("trajopt: error: trajopt rl tune needs Optuna: pip install soft-envs[tune]", file=sys.stderr)
        return 2
    from ..rl.tuning import TuningWorkerError, check_best, default_out, tune
    if args.adopt and not args.check:
        print("trajopt: error: --adopt needs --check N (the best is adopted only if it beats the defaults on the "
              "suite's seeds)", file=sys.stderr)
        return 2
    out = args.out or default_out(args.env, args.algo)
    try:
        summary = tune(args.env, args.algo, trials=args.trials, out=out, workers=args.workers,
                       timesteps=args.timesteps or SUITE_TIMESTEPS, episodes=args.episodes, seed=args.seed)
        check = None
        if args.check and summary["best"] is not None:
            check = check_best(out, seeds=args.check, workers=args.workers)
    except MissingRLDependencies as exc:
        return _missing(exc)
    except TuningWorkerError as exc:
        print(f"trajopt: error: {exc}; the same command goes on with the study", file=sys.stderr)
        return 1
    if args.json:
        print(json.dumps({**summary, "check": check}, indent=1))
    else:
        print(tuning_text(summary))
        if check is not None:
            print(check_text(check))
    if summary["best"] is None:
        print("trajopt: error: no trial was scored (each one's error is listed)", file=sys.stderr)
        return 1
    if args.adopt:
        from ..rl.tuning import tuned
        from ..rl.tuning.adopt import adopt
        from ..rl.zoo import write_zoo_files
        table = adopt(out)                  # ValueError (exit 2) when the best did not beat the defaults
        written = write_zoo_files(tuned.TUNED_FILE.parent)      # the rl_zoo3 files beside it, with its values
        print(f"adopted trial {table['trial']} for {args.algo.upper()} on every task id of its robot: {tuned.TUNED_FILE}; "
              f"wrote {', '.join(str(w) for w in written)}", file=sys.stderr if args.json else sys.stdout)
    return 0


def check_text(check: dict) -> str:
    """The best and the defaults on the suite's seeds (:func:`trajopt.rl.tuning.check_best`)."""
    unit = check.get("score_unit") or ""
    if check["best"] is None:
        return f"check: {check['note']}: nothing to check"
    lines = [f"check on the suite's seeds {', '.join(map(str, check['seeds']))} (the suite's evaluation):"]
    for label in ("best", "defaults"):
        side = check[label]
        lines.append(f"  {label:8s} (trial {side['trial']}): {' '.join(f'{v:+.3f}' for v in side['scores'])}  "
                     f"mean {side['mean']:+.3f} +- {side['std']:.3f} {unit}")
        if "credible" in side:
            lines.append(f"  {'':8s} credibly: {' '.join(f'{v:+.3f}' for v in side['credible'])}  mean "
                         f"{side['credible_mean']:+.3f} +- {side['credible_std']:.3f} {unit}; {side['holds']} of "
                         f"{len(side['credible'])} hold")
    lines.append(f"  best minus the defaults: {check['difference']:+.3f} {unit}; higher on {check['wins']} of "
                 f"{len(check['seeds'])} seeds")
    if "credible_difference" in check:
        lines.append(f"  credibly (the lowest over the replays at other physics steps): "
                     f"{check['credible_difference']:+.3f} {unit}")
    return "\n".join(lines)


def tuning_text(summary: dict) -> str:
    """A study's trials, best first, and the line that trains with the best."""
    unit = summary.get("score_unit") or ""
    done = sorted((t for t in summary["trials"] if t["score"] is not None), key=lambda t: -t["score"])
    lines = [f"{summary['env_id']} {summary['algo'].upper()}: {summary['n_finished']} trials scored "
             f"({summary['timesteps']} steps each, training seed {summary['seed']}, episodes from seed "
             f"{summary['eval_first_seed']})"]
    for t in done:
        mark = " (the defaults)" if t["defaults"] else ""
        lines.append(f"  trial {t['number']:3d}: {t['score']:+8.3f} {unit}  {t.get('wall_time_s', 0):6.0f} s{mark}")
    failed = [t for t in summary["trials"] if t["score"] is None]
    for t in failed:
        lines.append(f"  trial {t['number']:3d}: {t['state'].lower()}{': ' + t['error'] if t.get('error') else ''}")
    best = summary.get("best")
    if best:
        import shlex
        hp = " ".join(f"--hp {shlex.quote(o)}" for o in summary["hp_overrides"])
        lines.append(f"best: trial {best['number']} ({best['score']:+.3f} {unit}); train with it:")
        lines.append(f"  trajopt rl train {summary['env_id']} --algo {summary['algo']} --n-envs {summary['n_envs']} "
                     f"--timesteps {summary['timesteps']} --vec-env dummy {hp}".rstrip())
    return "\n".join(lines)
