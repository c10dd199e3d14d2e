"""One run of a sweep, as a Ray task executes it (or in-process with ``--serial``).

:func:`execute` calls the library function of the run's kind (:mod:`trajopt.sweep.kinds`:
:func:`~trajopt.optimize_run.run_optimization`, :func:`~trajopt.rl.options.train_with_options`,
:func:`~trajopt.evaluation.evaluate_result`, :func:`~trajopt.rl.evaluate.evaluate_policy_metric`)
with the run's arguments and ``DIR/<run>`` as its folder, its output going to
``DIR/<run>/log.txt``, and keeps ``DIR/<run>/status.json`` (atomic writes) up to date:
``running`` when it starts, then ``done``, ``failed`` (with the reason) or ``interrupted``.
The figures of a finished run are read from the files it wrote (a :class:`~trajopt.results.Result`,
the RL run's config, ``evaluation.json``). A rerun of an interrupted optimisation continues
from its last Gauss-Newton checkpoint (``resume``); an interrupted RL training starts again.
"""
from __future__ import annotations

import contextlib
import json
import os
import platform
import signal
import sys
import time
import traceback
from pathlib import Path
from typing import Any

from ..optim.gait import DEFAULT_EVAL_CYCLES
from ..results.result import Result, atomic_write_bytes, partial_path
from .spec import Run

__all__ = ["execute", "read_status", "write_status", "recover_status", "result_present", "check_run", "resumes",
           "STATUS_NAME", "LOG_NAME", "result_path"]

STATUS_NAME = "status.json"
SWEEP_LOCK = "sweep.lock"            # in the sweep folder while a sweep runs there
LOG_NAME = "log.txt"
POLICY_RESULT = "policy.npz"          # rl-train: the policy exported as a trajopt Result
CURVE_NAME = "curve.json"             # rl-train with evaluate_checkpoints: [[steps, BL/min], ...]
EVALUATION_NAME = "evaluation.json"   # evaluate / rl-evaluate
TASK_SCORE_NAME = "task_score.json"   # task_score = true: the run on its task's id (trajopt.tasks.play)


def read_status(run_dir: Path) -> dict[str, Any] | None:
    """The run's status.json, or None when there is none (or it cannot be read: see
    :func:`recover_status`)."""
    path = Path(run_dir) / STATUS_NAME
    try:
        st = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return st if isinstance(st, dict) else None


def write_status(run_dir: Path, status: dict[str, Any]) -> None:
    atomic_write_bytes(Path(run_dir) / STATUS_NAME, json.dumps(status, indent=1, default=str).encode())


def result_path(run: Run, run_dir: Path) -> Path:
    """The file the run's main figure is read from."""
    if run.kind == "optimize":
        return run_dir / f"{run.name}.npz"
    if run.kind == "rl-train":
        return run_dir / POLICY_RESULT
    return run_dir / EVALUATION_NAME


def result_present(run: Run, run_dir: Path) -> bool:
    """Whether the files a finished run wrote are still there (a "done" run whose result was
    deleted is run again)."""
    if run.kind == "rl-train":
        from ..rl.training import MODEL_NAME
        return (run_dir / MODEL_NAME).is_file() and (not run.options.get("export", True)
                                                    or (run_dir / POLICY_RESULT).is_file())
    return result_path(run, run_dir).is_file()


def recover_status(run: Run, run_dir: Path) -> dict[str, Any] | None:
    """The status of a run whose status.json exists but cannot be read (cut, overwritten),
    rebuilt from its result files: "done" with its metrics when they hold a finished run,
    otherwise None (the run is started again)."""
    if not (run_dir / STATUS_NAME).exists() or read_status(run_dir) is not None or not result_present(run, run_dir):
        return None
    try:
        if run.kind == "optimize":
            res = Result.load(result_path(run, run_dir))
            if res.status in ("running", "interrupted"):
                return None
            metrics = _metrics(run, run_dir)
        elif run.kind == "rl-train":
            from ..rl.training import CONFIG_NAME
            cfg = json.loads((run_dir / CONFIG_NAME).read_text())
            if cfg.get("status") in ("running", "interrupted"):
                return None
            metrics = {"timesteps": cfg.get("timesteps_done"), "sim_steps": cfg.get("sim_steps"),
                       "result_status": cfg.get("status")}
            if (run_dir / POLICY_RESULT).is_file():
                ev = Result.load(run_dir / POLICY_RESULT).evaluation
                metrics.update(speed_bl_per_min=ev.get("speed_bl_per_min"), upright=ev.get("upright"),
                               result=str(run_dir / POLICY_RESULT))
        else:
            ev = json.loads((run_dir / EVALUATION_NAME).read_text())
            metrics = {"speed_bl_per_min": ev.get("speed_bl_per_min"), "upright": ev.get("upright")}
    except (OSError, ValueError, KeyError, AttributeError):
        return None
    return {"run": run.name, "kind": run.kind, "params": run.params, "cpus": run.cpus, "options": run.options,
            "status": "done", "metrics": metrics, "wall_time_s": 0.0,
            "recovered": f"{STATUS_NAME} was unreadable; rebuilt from {result_path(run, run_dir).name}"}


def check_run(run: Run) -> None:
    """What a run's start would refuse, checked without running it (``--dry-run``): an unknown
    or unreadable robot, contact parameters out of range (``contact_stiffness = -1``). A
    ValueError naming the run."""
    if "robot" not in run.params or run.kind not in ("optimize", "rl-train"):
        return
    import dataclasses
    from soft_envs.envs import load_robot
    from ..rl.envs import robot_name, task_of
    try:
        robot = load_robot(robot_name(str(run.params["robot"])) if task_of(str(run.params["robot"]))
                           else str(run.params["robot"]))
        contact = run.contact()
        if contact:
            dataclasses.replace(robot.contact, **{k: (v if k == "model" else float(v)) for k, v in contact.items()})
    except (ValueError, TypeError, OSError) as exc:
        raise ValueError(f"{run.source} (run {run.name!r}): {str(exc).strip().splitlines()[0]}") from None


def _derived_robot(run: Run, run_dir: Path) -> Path:
    """A copy of the run's robot.toml with its [contact] fields replaced (mesh path made
    absolute), written to ``run_dir/robot.toml``."""
    import tomllib
    import tomli_w
    robot = str(run.params["robot"])
    if robot.endswith(".toml"):
        src = Path(robot)
    else:                                   # where load_robot finds shipped robots, in its order
        import soft_envs
        from importlib.resources import files
        src = Path(soft_envs.__file__).resolve().parents[1] / "assets" / robot / "robot.toml"
        if not src.is_file():
            src = Path(str(files("soft_envs.assets") / robot / "robot.toml"))
    if not src.is_file():
        raise ValueError(f"robot {robot!r}: robot file {src} not found")
    doc = tomllib.loads(src.read_text())
    doc.setdefault("robot", {})
    if "mesh" in doc["robot"]:
        doc["robot"]["mesh"] = str((src.parent / doc["robot"]["mesh"]).resolve())
    doc.setdefault("contact", {}).update(run.contact())
    path = run_dir / "robot.toml"
    atomic_write_bytes(path, tomli_w.dumps(doc).encode())
    return path


def resumes(run: Run, run_dir: Path) -> bool:
    """Whether ``run`` continues from a checkpoint in ``run_dir`` (an interrupted or killed
    optimisation left its ``NAME.partial.npz``, a ``--speed max`` search its
    ``NAME.search.partial/``)."""
    if run.kind != "optimize":
        return False
    from ..search.checkpoint import search_checkpoint_dir
    out = result_path(run, run_dir)
    return _resumable(partial_path(out)) or (search_checkpoint_dir(out) / "state.json").is_file()


def _resumable(path: Path) -> bool:
    """An optimisation checkpoint (``NAME.partial.npz``) left by an interrupted or killed run."""
    meta = path.with_suffix(".json")
    try:
        return path.is_file() and json.loads(meta.read_text()).get("status") in ("running", "interrupted")
    except (OSError, ValueError):
        return False


def _call(run: Run, out: Path, run_dir: Path, robot_file: Path | None = None) -> None:
    """Run ``run`` through the library function of its kind; its files go to ``run_dir``
    (an RL run's to ``out/<run>``, the same folder). ``robot_file`` replaces the robot (the
    copy with the run's contact parameters, :func:`_derived_robot`)."""
    args = run.arguments()
    if robot_file is not None:
        args["robot"] = str(robot_file)
    if run.kind == "optimize":
        from ..optimize_run import OptimizeRun, run_optimization
        run_optimization(OptimizeRun.from_mapping({**args, "out": run_dir, "name": run.name, "quiet": True,
                                                   "resume": resumes(run, run_dir)}))
    elif run.kind == "rl-train":
        from ..rl.options import train_with_options
        args.setdefault("n_envs", run.cpus)
        train_run = train_with_options(args.pop("robot"), **{**args, "out": out, "name": run.name,
                                                             "no_progress": True, "overwrite": True})
        if train_run.status == "interrupted":      # as the signal that stopped it (Ctrl-C, SIGTERM)
            from ..hardware.signals import interruption
            raise interruption(train_run.signal or signal.SIGINT)
    elif run.kind == "rl-evaluate" and args.get("task", False):        # the task's own score (trajopt.tasks.play)
        from ..rl.evaluate import load_policy
        from ..tasks.play import policy_on_task, policy_task_hold
        unused = sorted(k for k in ("cycles", "seed", "reset_noise") if k in args)
        if unused:
            raise ValueError(f"task = true scores the task's own episodes: {', '.join(unused)} does not apply")
        policy = load_policy(args["model"])
        ev = policy_on_task(policy)
        if args.get("fidelity", False):
            ev["hold"] = policy_task_hold(policy, reference=ev)
        _write_evaluation(run_dir, ev)
    elif run.kind == "rl-evaluate":
        from ..rl.evaluate import evaluate_policy_metric, load_policy
        policy = load_policy(args["model"])
        n_cycles, seed = args.get("cycles", DEFAULT_EVAL_CYCLES), args.get("seed", 0)
        ev = evaluate_policy_metric(policy, n_cycles=n_cycles, seed=seed,
                                    reset_noise_scale=args.get("reset_noise", 0.0))
        if args.get("fidelity", False):
            from ..rl.evaluate import policy_fidelity
            ev["fidelity"] = policy_fidelity(policy, n_cycles=n_cycles, seed=seed,
                                             reference=None if args.get("reset_noise", 0.0) else ev)
        _write_evaluation(run_dir, ev)
    else:
        from ..evaluation import evaluate_result
        res = Result.load(args["result"])
        ignore = args.get("ignore_robot_mismatch", False)
        ev = evaluate_result(res, args.get("cycles"), ignore_robot_mismatch=ignore)
        if args.get("fidelity", False):
            from ..fidelity import fidelity
            ev["fidelity"] = fidelity(res, n_cycles=args.get("cycles"), reference=ev, ignore_robot_mismatch=ignore)
        _write_evaluation(run_dir, ev)


def _write_evaluation(run_dir: Path, ev: dict[str, Any]) -> None:
    """An evaluation as ``evaluation.json`` (what ``--json`` prints: all but the COM path)."""
    text = json.dumps({k: v for k, v in ev.items() if k != "com"}, indent=1, allow_nan=True)
    atomic_write_bytes(run_dir / EVALUATION_NAME, text.encode())


def _metrics(run: Run, run_dir: Path) -> dict[str, Any]:
    """The figures the summary shows, read from the files the run wrote."""
    m: dict[str, Any] = {}
    if run.kind == "optimize":
        res = Result.load(result_path(run, run_dir))
        ev = res.evaluation
        m.update(speed_bl_per_min=ev.get("speed_bl_per_min"), upright=ev.get("upright"),
                 target_bl_per_min=res.settings.get("speed_bl_per_min"), objective=ev.get("objective"),
                 gn_iterations=len(res.history), result_status=res.status,
                 # a --speed max search: every step of it, not only the chosen gait's optimisation
                 sim_steps=ev.get("search_sim_steps", ev.get("optimization_sim_steps")),
                 result=str(result_path(run, run_dir)))
    elif run.kind == "rl-train":
        from ..rl.training import CONFIG_NAME
        cfg = json.loads((run_dir / CONFIG_NAME).read_text())
        m.update(timesteps=cfg.get("timesteps_done"), sim_steps=cfg.get("sim_steps"),
                 train_wall_time_s=cfg.get("wall_time_s"), result_status=cfg.get("status"))
        if run.options.get("export", True):
            from ..rl.evaluate import export_result
            ev = export_result(run_dir, run_dir / POLICY_RESULT).evaluation
            m.update(speed_bl_per_min=ev.get("speed_bl_per_min"), upright=ev.get("upright"),
                     result=str(run_dir / POLICY_RESULT))
        if run.options.get("evaluate_checkpoints"):
            m["curve"] = _checkpoint_curve(run_dir, int(cfg["env"]["frame_skip"]))
    else:                                                  # evaluate, rl-evaluate: evaluation.json
        ev = json.loads((run_dir / EVALUATION_NAME).read_text())
        m.update(speed_bl_per_min=ev.get("speed_bl_per_min"), upright=ev.get("upright"))
        if "score_name" in ev:                             # rl-evaluate with task = true: the task's score
            m["task"] = {k: v for k, v in ev.items() if k not in ("episodes", "hold")}
            if "hold" in ev:
                m["task"].update(credible=ev["hold"]["slowest"], holds=ev["hold"]["holds"])
    if run.options.get("task_score"):
        m["task"] = _task_score(run, run_dir)
    return m


def _task_score(run: Run, run_dir: Path) -> dict[str, Any]:
    """The run on its benchmark task's id, with the task's own score (:mod:`trajopt.tasks.play`),
    written to ``task_score.json``."""
    from ..tasks.play import gait_on_task, policy_on_task
    ev = policy_on_task(run_dir) if run.kind == "rl-train" else gait_on_task(result_path(run, run_dir))
    atomic_write_bytes(run_dir / TASK_SCORE_NAME, json.dumps(ev, indent=1, default=float).encode())
    return {k: v for k, v in ev.items() if k != "episodes"}


def _checkpoint_curve(run_dir: Path, frame_skip: int) -> list[list[float]]:
    """trajopt's metric for every checkpoint of an RL run (speed vs simulation steps)."""
    from ..rl.evaluate import evaluate_policy_metric, load_policy
    from ..rl.training import checkpoint_steps
    curve = []
    for ck in sorted((run_dir / "checkpoints").glob("model_*_steps.zip"), key=checkpoint_steps):
        ev = evaluate_policy_metric(load_policy(ck))
        curve.append([checkpoint_steps(ck) * frame_skip, ev["speed_bl_per_min"]])
    atomic_write_bytes(run_dir / CURVE_NAME, json.dumps(curve).encode())
    return curve


def _reason(exc: BaseException) -> str:
    """One line: the message of a bad input (ValueError, OSError: what the command prints after
    ``trajopt: error:``), else the exception's type and first line."""
    text = str(exc).strip().splitlines()
    first = text[0] if text else ""
    if isinstance(exc, (ValueError, OSError)) and first:
        return first
    from soft_envs.envs import SimulationError
    if isinstance(exc, SimulationError):
        return f"simulation failed: {first}"
    return f"{type(exc).__name__}: {first}".strip()


def execute(run: Run, out: str | os.PathLike, threads: int | None = None) -> dict[str, Any]:
    """Run ``run`` under ``out/run.name`` and return its final status (also in status.json).
    ``threads``: cap the compute threads of this process (default: the run's CPUs)."""
    from soft_envs.envs.threads import limit_threads

    out = Path(out)
    run_dir = out / run.name
    t0, cpu0 = time.time(), time.process_time()
    status: dict[str, Any] = {"run": run.name, "kind": run.kind, "params": run.params, "cpus": run.cpus,
                              "options": run.options, "status": "running", "started": t0,
                              "host": platform.node(), "pid": os.getpid()}
    if not out.is_dir():
        status.update(status="failed", reason=f"the sweep directory {out} is not visible on host "
                      f"{platform.node()}: on a cluster, --out must be on a filesystem every node shares")
        return status
    run_dir.mkdir(parents=True, exist_ok=True)
    write_status(run_dir, status)
    limit_threads(threads or run.cpus)
    try:
        with open(run_dir / LOG_NAME, "a") as log:
            log.write(f"\n=== {time.strftime('%Y-%m-%d %H:%M:%S')} on {platform.node()} (pid {os.getpid()})\n")
            try:
                robot_file = _derived_robot(run, run_dir) if run.contact() else None
                command = ["trajopt", *run.argv(robot_file)]     # what does the same from a shell
                status["command"] = command
                log.write("$ " + " ".join(command) + "\n")
                log.flush()
                with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
                    saved_argv, sys.argv = sys.argv, command   # the command a reservation records
                    try:
                        _call(run, out, run_dir, robot_file)
                    finally:
                        sys.argv = saved_argv
                status.update(status="done", metrics=_metrics(run, run_dir))
            except KeyboardInterrupt:
                status.update(status="interrupted", reason="interrupted (Ctrl-C or cancelled)")
            except Exception as exc:                # SimulationError, bad files, bugs: recorded
                traceback.print_exc(file=log)
                status.update(status="failed", reason=_reason(exc))
    finally:
        status.update(finished=time.time(), wall_time_s=time.time() - t0,
                      cpu_time_s=time.process_time() - cpu0)     # this process (not its subprocesses)
        if status["status"] == "running":           # left by a BaseException we do not handle
            status.update(status="interrupted", reason="stopped before the run ended")
        write_status(run_dir, status)
    return status
