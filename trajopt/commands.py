"""What ``trajopt optimize`` and ``trajopt evaluate`` do (argument parsing lives in
:mod:`trajopt.cli`; render, export and plot in :mod:`trajopt.output_commands`; the library
functions they call in :mod:`trajopt.optimize`, :mod:`trajopt.evaluation` and :mod:`trajopt.replay`).

``trajopt optimize ... --name NAME`` writes ``OUT/NAME.npz`` (+ ``.json``) only when the run
finishes; until then its checkpoints (one per Gauss-Newton iteration, and the last iterate on
Ctrl-C) go to ``OUT/NAME.partial.npz``, which ``--resume`` continues and a finished run removes.
A finished result, or an interrupted run's checkpoint, is never replaced without ``--overwrite``,
and while a run lives its name is reserved (``OUT/NAME.lock``, :mod:`trajopt.reservation`): a
second run of the same name and folder is refused at once.
"""
from __future__ import annotations

import json

import sys
import time
from pathlib import Path

from soft_envs.envs import compile_ahead, make_gradient_env

from .evaluation import evaluate_result
from .files import RESULTS_DIR
from .gait import GaitSpec
from .gauss_newton import GaussNewtonOptions
from .optimize import TASK_CONTACT, optimize_gait
from .progress import IterationProgress
from .reservation import lock_path, reserve
from .results import Result, partial_path, result_path

__all__ = ["run_optimize", "run_evaluate", "STATUS_MEANING", "evaluation_rows"]

#: What the ``status`` of a result means (Gauss-Newton's stopping criteria, and checkpoints).
STATUS_MEANING = {
    "max_iter": "ran all the Gauss-Newton iterations asked for (--iterations); not a failure: the gait "
                "is usable, and more iterations may still improve it",
    "ftol": "converged: the last step lowered the objective by less than 1e-4 of it",
    "gtol": "converged: the objective's projected gradient vanished",
    "xtol": "converged: the last accepted step was negligible",
    "stalled": "stopped: three iterations in a row found no lower objective (a local minimum)",
    "callback": "stopped by its callback",
    "running": "a checkpoint of a run in progress (or killed): continue it with --resume",
    "interrupted": "a checkpoint of an interrupted run: continue it with --resume",
}


def _print_table(rows: list[tuple[str, str]]) -> None:
    w = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"  {k.ljust(w)}  {v}")


def evaluation_rows(ev: dict, task: str = "walk") -> list[tuple[str, str]]:
    """The rows of an evaluation (speed, per cycle, heading, tilt, upright), or the simulation
    failure's reason when the replay failed. The heading is the yaw of the best-fit rotation of
    all nodes. A turn's speed is along its COM path sampled once per cycle (along a fixed
    direction it averages out; every step's path adds the sway within a stride); a turn also
    shows its heading per cycle and over the optimised horizon, with the COM's RMS distance from
    the quarter circle."""
    if "sim_failure" in ev:
        return [("simulation", f"FAILED: {ev['sim_failure']}"), ("upright", "False (the simulation failed)")]
    nan = float("nan")
    if task != "turn":
        rows = [("speed", f"{ev['speed_bl_per_min']:.3f} BL/min over {ev['cycles']} cycles"),
                ("per cycle", " ".join(f"{v:.2f}" for v in ev.get("speed_per_cycle_bl_per_min", []))),
                ("heading change", f"{ev.get('heading_change_deg', nan):+.1f} deg over {ev['cycles']} cycles")]
    else:
        rows = [("speed", f"{ev.get('cycle_path_speed_bl_per_min', nan):.2f} BL/min along the COM path "
                          f"(cycle to cycle) over {ev['cycles']} cycles"),
                ("heading change", f"{ev.get('heading_change_deg', nan):+.1f} deg over {ev['cycles']} cycles"),
                ("heading per cycle", " ".join(f"{v:+.1f}" for v in ev.get("heading_per_cycle_deg", [])))]
        if "horizon_heading_change_deg" in ev:
            rows.append(("heading, horizon", f"{ev['horizon_heading_change_deg']:+.1f} deg over the optimised "
                                             f"{ev['horizon_steps']} steps; COM {ev['horizon_rms_to_target_bl']:.3f} "
                                             "BL RMS from the target"))
    return rows + [("max tilt", f"{ev.get('max_tilt_deg', nan):.1f} deg"),
                   ("upright", "yes" if ev["upright"] else "NO: it fell (tilt over 60 deg or COM below half its height)")]


# ---------------------------------------------------------------------- optimize: files
def _refuse(path: Path, what: str, advice: str) -> None:
    raise ValueError(f"{path}: {what}; {advice}")


def _plan(out: Path, partial: Path, args) -> tuple[Result | None, bool]:
    """``(resume, done)``: the interrupted run to continue (or None), and whether there is
    nothing to do (``--resume`` of a finished result). Refuses (ValueError, nothing written) to
    replace a finished result or an interrupted run's checkpoint without ``--overwrite``."""
    for p in (out, partial):
        if p.exists() and not p.is_file():
            _refuse(p, "exists and is not a file", "choose another --name or --out")
    if args.resume:
        if partial.is_file():
            if out.is_file() and not args.overwrite:
                _refuse(out, "a finished result of this name exists", f"resuming {partial} would replace it when "
                        "it finishes: add --overwrite, or resume under another --name after renaming the checkpoint")
            return _load_checkpoint(partial), False
        if out.is_file():
            prev = Result.load(out)
            if prev.status in ("running", "interrupted"):     # a checkpoint of an older version
                return _load_checkpoint(out), False
            print(f"{out} is finished ({prev.status}); nothing to resume. {prev.summary()}")
            return None, True
        print(f"no interrupted run to resume ({partial} not found): starting afresh", file=sys.stderr)
        return None, False
    if partial.is_file() and not args.overwrite:
        _refuse(partial, "holds the checkpoint of an interrupted run of this name",
                "continue it with --resume, or start afresh with --overwrite")
    if out.is_file() and not args.overwrite:
        status = _status_of(out)
        _refuse(out, f"a result of this name exists ({status})",
                "pass --overwrite to replace it when the new run finishes, or choose another --name")
    return None, False


def _status_of(path: Path) -> str:
    try:
        return f"status {Result.load(path).status}"
    except ValueError:
        return "not a readable result"


def _load_checkpoint(path: Path) -> Result:
    prev = Result.load(path)
    print(f"resuming {path} after iteration {len(prev.history)}")
    prev.settings["source"] = str(path)          # named by the settings check's error
    return prev


def _gait(args) -> GaitSpec:
    try:
        return GaitSpec.for_task(args.task, symmetry=args.symmetry, n_prep=args.prep_steps,
                                 n_cycle=args.cycle_steps, n_keyframes=args.keyframes)
    except ValueError:
        raise ValueError(f"--keyframes {args.keyframes} must be at most --cycle-steps {args.cycle_steps}") from None


def _finish_files(res: Result, out: Path, partial: Path) -> Path:
    """Save the finished result and remove the checkpoint (the other way round never)."""
    path = res.save(out)
    for p in (partial, partial.with_suffix(".json")):
        p.unlink(missing_ok=True)
    return path


# ---------------------------------------------------------------------- optimize
def run_optimize(args) -> int:
    task = args.task
    name = args.name or f"{Path(args.robot).stem if args.robot.endswith('.toml') else args.robot}_{task}"
    out = result_path(args.out / name)
    partial = partial_path(out)
    incline = args.angle if task == "incline" else 0.0
    gait = _gait(args)
    with reserve(lock_path(out), f"result {out.name}"):   # a second run of this name is refused
        return _optimize_reserved(args, task, out, partial, incline, gait)


def _optimize_reserved(args, task: str, out: Path, partial: Path, incline: float, gait: GaitSpec) -> int:
    resume, done = _plan(out, partial, args)
    if done:
        return 0
    warm = Result.load(args.warm_start) if args.warm_start else None
    if warm is not None:
        warm.settings["source"] = str(args.warm_start)
    contact = args.contact or TASK_CONTACT.get(task)          # the turn pivots on feet that stick
    with compile_ahead(args.robot):            # first run on a machine: numba compiles meanwhile
        env = make_gradient_env(args.robot, incline_deg=incline, heading_deg=args.heading, contact=contact)
    print(f"{env.robot.summary()}; task {task}; {env.contact_model} contact law"
          + (f" (the {task}'s default; --contact paper for the paper's)" if contact and not args.contact else "")
          + (f", slope {incline:g} deg" if incline else ""))
    print(f"writes {out} (+ .json) when it finishes; checkpoints in {partial} until then")
    done_before = len(resume.history) if resume else 0
    progress = None if args.quiet else IterationProgress(args.iterations, first=done_before + 1)
    latest: dict = {}

    def checkpoint(entry: dict, partial_result: Result) -> None:
        latest["result"] = partial_result
        partial_result.save(partial)           # atomic: a crash leaves the previous checkpoint
        if progress is not None:
            progress.update(entry)

    options = GaussNewtonOptions(max_iter=max(args.iterations - done_before, 0))
    t0 = time.perf_counter()
    try:
        res = optimize_gait(env, task, gait=gait, speed_bl_per_min=args.speed, heading_deg=args.heading,
                            turn=args.turn, options=options, warm_start=warm, n_seeds=args.seeds,
                            eval_cycles=args.cycles, robot_spec=args.robot, callback=checkpoint, resume=resume,
                            motor_limit=not getattr(args, "no_motor_limit", False))
    except KeyboardInterrupt:
        if progress is not None:
            progress.close()
        if "result" in latest:
            latest["result"].status = "interrupted"
            latest["result"].save(partial)
            print(f"\ninterrupted: iteration {len(latest['result'].history)} saved to {partial}"
                  f"{f'; {out} is untouched' if out.is_file() else ''}; continue with the same command "
                  "and --resume", file=sys.stderr)
        else:
            print("\ninterrupted before the first iteration: nothing saved", file=sys.stderr)
        return 130
    finally:
        if progress is not None:
            progress.close()
    path = _finish_files(res, out, partial)
    _report(res, path, time.perf_counter() - t0)
    return 0


def _report(res: Result, path: Path, seconds: float) -> None:
    ev = res.evaluation
    print(f"\nsaved {path} and {path.with_suffix('.json')} ({seconds:.1f} s)")
    rows = [("status", f"{res.status}: {STATUS_MEANING.get(res.status, '')}"),
            ("iterations", str(len(res.history))),
            ("objective", f"{ev['objective']:.5g}"),
            ("target speed", f"{res.settings['speed_bl_per_min']:g} BL/min")]
    rows += evaluation_rows(ev, res.task)
    rows.append(("simulation steps", str(ev["optimization_sim_steps"])))
    _print_table(rows)
    print(f"\nnext:\n  trajopt render {path}      # animation: {RESULTS_DIR / (path.stem + '.gif')}\n"
          f"  trajopt plot {path}        # COM path, controls, convergence: {RESULTS_DIR / 'plots'}/\n"
          f"  trajopt evaluate {path} --cycles 10")


def run_evaluate(args) -> int:
    res = Result.load(args.result)
    ev = evaluate_result(res, args.cycles, ignore_robot_mismatch=args.ignore_robot_mismatch)
    if getattr(args, "json", False):
        print(json.dumps({k: v for k, v in ev.items() if k != "com"}, allow_nan=True))
    else:
        print(res.summary())
        _print_table(evaluation_rows(ev, res.task))
    return 0 if ev["upright"] else 1
