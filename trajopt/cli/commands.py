"""What ``trajopt optimize`` and ``trajopt evaluate`` do (argument parsing lives in
:mod:`trajopt.cli`; render, export and plot in :mod:`trajopt.cli.output_commands`; the library
functions they call in :mod:`trajopt.optimize_run` (the run's files, checkpoints and resume),
:mod:`trajopt.optim.optimize`, :mod:`trajopt.evaluation` and :mod:`trajopt.replay`).
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from ..evaluation import evaluate_result
from ..hardware.signals import Terminated
from ..results.files import RESULTS_DIR
from ..optimize_run import OptimizeRun, run_optimization
from ..progress import IterationProgress
from ..results.result import Result
from ..tasks.registry import speed_along_path
from .table import print_table

__all__ = ["run_optimize", "run_evaluate", "STATUS_MEANING", "evaluation_rows", "motor_limit_row"]


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


def evaluation_rows(ev: dict, task: str = "walk") -> list[tuple[str, str]]:
    """The rows of an evaluation (speed, per cycle, heading, tilt, upright), or the simulation
    failure's reason when the replay failed. The heading is the yaw of the best-fit rotation of
    all nodes. The speed of a task with a curved target (the turn,
    :attr:`~trajopt.tasks.Task.speed_along_path`) is along its COM path sampled once per cycle (along a fixed
    direction it averages out; every step's path adds the sway within a stride); a turn also
    shows its heading per cycle and over the optimised horizon, with the COM's RMS distance from
    the quarter circle."""
    if "sim_failure" in ev:
        return [("simulation", f"FAILED: {ev['sim_failure']}"), ("upright", "False (the simulation failed)")]
    nan = float("nan")
    if not speed_along_path(task):
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
    if "ensemble" in ev:
        rows.append(("credible speed", f"{ev.get('credible_bl_per_min', nan):.3f} BL/min, the slowest of the "
                                       "ensemble's physics: " + ", ".join(
                                           f"{m['speed_bl_per_min']:.2f} at {m['substeps']} steps per control step"
                                           f"{'' if m['upright'] else ' (fell)'}" for m in ev["ensemble"])))
    return rows + [("max tilt", f"{ev.get('max_tilt_deg', nan):.1f} deg"),
                   ("upright", "yes" if ev["upright"] else "NO: it fell (tilt over 60 deg or COM below half its height)")]


# ---------------------------------------------------------------------- optimize
def run_optimize(args) -> int:
    run = OptimizeRun.from_mapping(vars(args))
    t0 = time.perf_counter()
    try:
        done = run_optimization(run, None if run.quiet else
                                (lambda first: IterationProgress(run.iterations, first=first)))
    except KeyboardInterrupt:              # the checkpoint is saved and the way on printed
        return 130
    except Terminated as exc:              # SIGTERM, SIGHUP: as Ctrl-C
        return 128 + exc.signum
    if done is not None:
        _report(*done, time.perf_counter() - t0)
    return 0


def _report(res: Result, path: Path, seconds: float) -> None:
    ev = res.evaluation
    print(f"\nsaved {path} and {path.with_suffix('.json')} ({seconds:.1f} s)")
    rows = [("status", f"{res.status}: {STATUS_MEANING.get(res.status, '')}"),
            ("iterations", str(len(res.history))),
            ("objective", f"{ev['objective']:.5g}"),
            ("tracking target", f"{res.settings['speed_bl_per_min']:g} BL/min: the speed of the target COM path the "
                                "optimiser tracks, not enforced (the gait's speed is below)")]
    rows += evaluation_rows(ev, res.task)
    rows.append(("simulation steps", str(ev["optimization_sim_steps"])))
    if "search_sim_steps" in ev:          # --speed max: the whole search's
        rows.append(("search", f"cycle {res.settings['n_cycle']} steps, {res.settings['n_keyframes']} keyframes "
                               f"chosen of {res.settings['search']['runs']} optimisations; "
                               f"{ev['search_sim_steps']:,} simulation steps in total, "
                               f"{ev['search_wall_time_s']:.0f} s"))
        rows.append(("chosen as", res.settings["search"].get("chosen_by", "the fastest upright gait")))
        if "hold" in ev:                  # its speed replayed at other physics steps
            h = ev["hold"]
            fell = [f"{1e3 * res.dt / n:.3g} ms" for n, v in zip(h["substeps"], h["speeds"]) if v != v]
            rows.append(("other steps", ", ".join("fell" if v != v else f"{v:.2f}" for v in h["speeds"])
                         + " BL/min at " + ", ".join(f"{1e3 * res.dt / n:.3g}" for n in h["substeps"])
                         + " ms physics steps: " + (f"fell at {', '.join(fell)}" if fell else
                                                    f"slowest {h['slowest']:.2f}, spread {100 * h['spread']:.1f} %")))
    print_table(rows)
    print(f"\nnext:\n  trajopt render {path}      # animation: {RESULTS_DIR / (path.stem + '.gif')}\n"
          f"  trajopt plot {path}        # COM path, controls, convergence: {RESULTS_DIR / 'plots'}/\n"
          f"  trajopt evaluate {path} --cycles 10")


def motor_limit_row(res: Result) -> tuple[str, str] | None:
    """The row saying that a gait was optimised without the motors' speed limit
    (``--no-motor-limit``, or made before the limit existed), with its largest steps against
    it; None for a gait made within the limit (or not by the optimiser)."""
    if res.task == "rl" or res.settings.get("motor_limit"):
        return None
    from ..optim.motor_limit import playback_note
    note = playback_note(res)
    return ("motor limit", "made without it (--no-motor-limit): the motors may not follow this gait"
            + (f"; {note.removeprefix('warning: ')}" if note else ""))


def run_evaluate(args) -> int:
    res = Result.load(args.result)
    ev = evaluate_result(res, args.cycles, ignore_robot_mismatch=args.ignore_robot_mismatch)
    limit = motor_limit_row(res)
    fid = None
    if getattr(args, "fidelity", False):
        from ..fidelity import fidelity
        fid = fidelity(res, n_cycles=args.cycles, reference=ev, ignore_robot_mismatch=args.ignore_robot_mismatch)
    if getattr(args, "json", False):
        print(json.dumps({**{k: v for k, v in ev.items() if k != "com"}, "within_motor_limit": limit is None}
                         | ({"fidelity": fid} if fid else {}), allow_nan=True))
    else:
        print(res.summary())
        print_table(evaluation_rows(ev, res.task) + ([limit] if limit else []))
        if fid is not None:
            print(fidelity_text(fid))
    return 0 if ev["upright"] else 1


def task_hold_text(hold: dict, control_dt_ms: float) -> str:
    """The table of ``trajopt rl evaluate --task --fidelity`` (:func:`trajopt.tasks.play.task_hold`)."""
    unit = hold["score_unit"]
    lines = [f"\nthe same policy at other physics steps (control step {control_dt_ms:g} ms):"]
    for n, dt, v in zip(hold["substeps"], hold["physics_dt_ms"], hold["scores"]):
        own = " (its own)" if n == hold["own_substeps"] else ""
        lines.append(f"  {dt:7.3f} ms{own:<10} " + (f"{v:+9.3f} {unit}" if np.isfinite(v) else "   failed"))
    verdict = "holds" if hold["holds"] else "does not hold"
    if not np.isfinite(hold["slowest"]):
        lines.append(f"  a simulation failed: {verdict}")
    else:
        lines.append(f"  credible {hold['slowest']:+.3f} {unit} (the lowest), spread {100 * hold['spread']:.2f} % of it: "
                     f"{verdict} (within {100 * hold['max_spread']:g} %, above 0)")
    return "\n".join(lines)


def fidelity_text(fid: dict) -> str:
    """The table of ``trajopt evaluate --fidelity`` (:func:`trajopt.fidelity.fidelity`)."""
    lines = [f"\nthe same controls at finer physics steps (control step {fid['control_dt_ms']:g} ms):",
             "  physics step        speed [BL/min]   vs its own physics"]
    for r in fid["rows"]:
        own = " (its own)" if r["factor"] == 1 else ""
        speed = f"{r['speed_bl_per_min']:8.3f}" if np.isfinite(r["speed_bl_per_min"]) else "  failed"
        fell = "" if r["upright"] else "  fell"
        dev = "" if r["factor"] == 1 else f"{100 * r['deviation']:+7.2f} %"
        lines.append(f"  {r['physics_dt_ms']:7.3f} ms{own:<10} {speed}         {dev}{fell}")
    lines.append(f"  spread            {100 * fid['spread']:.2f} % of its speed (max - min); the converged-physics "
                 "bar: within 3 % at 4x finer steps")
    return "\n".join(lines)
