"""One optimisation run into files: ``OUT/NAME.npz`` (+ ``.json``), with checkpoints and resume.

What ``trajopt optimize`` does and a sweep's ``optimize`` runs do (:mod:`trajopt.sweep.task`),
as a library function: :func:`run_optimization` of an :class:`OptimizeRun` (the run's options,
named as the command's). It writes ``OUT/NAME.npz`` only when the run finishes; until then its
checkpoints (one per Gauss-Newton iteration, and the last iterate on Ctrl-C, SIGTERM or SIGHUP) go to
``OUT/NAME.partial.npz``, which ``resume`` continues and a finished run removes. A finished
result, or an interrupted run's checkpoint, is never replaced without ``overwrite``, and while a
run lives its name is reserved (``OUT/NAME.lock``, :mod:`trajopt.results.reservation`): a second run of
the same name and folder is refused at once.
"""
from __future__ import annotations

import dataclasses
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

from soft_envs.envs import compile_ahead, make_gradient_env

from .fidelity import fidelity_record
from .hardware.signals import Terminated, signal_label
from .results.files import RESULTS_DIR
from .optim.gait import DEFAULT_EVAL_CYCLES, INTERPOLATIONS, GaitSpec
from .optim.gauss_newton import GaussNewtonOptions
from .optim.motor_limit import IDEAL, MOTOR_MODELS, TORQUE_SPEED
from .optim.optimize import optimize_gait
from .results.reservation import lock_path, reserve
from .results.robot_match import robot_reference
from .results.result import Result, partial_path, result_path, robot_file_name
from .tasks.registry import ENV_TASKS, get_task

__all__ = ["OptimizeRun", "run_optimization", "OPTIMIZE_OPTIONS"]

_PAPER = GaitSpec()


@dataclass(frozen=True)
class OptimizeRun:
    """The options of one optimisation run (``trajopt optimize ROBOT --OPTION ...``): the robot
    (shipped name or robot.toml path), the task (:data:`trajopt.tasks.TASKS`), its target speed
    [BL/min] (None: the robot's default; ``"max"``: the fastest walk within the motors' limit,
    :mod:`trajopt.fastest`, with its search table beside the result), heading [deg], turn side, slope ``angle`` [deg] (a task
    on a slope), ``difficulty`` (a benchmark task's level, :attr:`trajopt.tasks.Task.env_task`: its slope or
    ground; None: the task's default), contact law (None: the task's, else the robot file's), physics ``substeps`` per
    control step (None: the contact law's default), the ``ensemble`` of other physics the gait is
    optimised on as well (physics steps per control step, :mod:`trajopt.optim.ensemble`; an empty
    list: :data:`~trajopt.optim.ensemble.DEFAULT_ENSEMBLE`; None: none), symmetry (None: the
    task's), warm start result, the motors' law the controls obey (``motor_model``:
    ``"torque-speed"``, ``"speed"`` or ``"ideal"``, :mod:`soft_envs.sim.motors`; ``no_motor_limit``
    is ``"ideal"``, kept for scripts of before the model), Gauss-Newton iterations, keyframes and their ``interpolation`` (None: the task's; :data:`trajopt.optim.gait.INTERPOLATIONS`), cycle
    steps (None: the paper's 72; with ``speed="max"``: searched) and prep steps, random seeds, evaluation cycles,
    the ``speed="max"`` search's budget of simulation steps (``max_sim_steps``, None: none), output folder and
    result name (None:
    ``ROBOT_TASK``), resume / overwrite, and quiet (no progress)."""

    robot: str
    task: str = "walk"
    speed: float | str | None = None
    heading: float = 0.0
    turn: str = "right"
    angle: float = 20.0
    difficulty: str | None = None
    contact: str | None = None
    substeps: int | None = None
    ensemble: tuple[int, ...] | list[int] | None = None
    symmetry: bool | None = None
    warm_start: Path | None = None
    no_motor_limit: bool = False
    motor_model: str = TORQUE_SPEED
    iterations: int = 10
    keyframes: int | None = None
    interpolation: str | None = None
    cycle_steps: int | None = None
    prep_steps: int = _PAPER.n_prep
    seeds: int = 8
    cycles: int = DEFAULT_EVAL_CYCLES
    max_sim_steps: int | None = None
    out: Path = RESULTS_DIR
    name: str | None = None
    resume: bool = False
    overwrite: bool = False
    quiet: bool = False

    @classmethod
    def from_mapping(cls, options: Mapping[str, Any]) -> "OptimizeRun":
        """The run of ``options`` (a command's parsed arguments, a sweep run's parameters);
        keys that are no option are ignored."""
        return cls(**{k: v for k, v in options.items() if k in OPTIMIZE_OPTIONS})

    def model(self) -> str:
        """The motor model the run obeys (``no_motor_limit``: ``"ideal"``); ValueError for an
        unknown name or both options contradicting each other."""
        if self.motor_model not in MOTOR_MODELS:
            raise ValueError(f"--motor-model must be one of {', '.join(MOTOR_MODELS)}, got {self.motor_model!r}")
        if self.no_motor_limit and self.motor_model not in (TORQUE_SPEED, IDEAL):
            raise ValueError(f"--no-motor-limit (no limit) contradicts --motor-model {self.motor_model}")
        return IDEAL if self.no_motor_limit else self.motor_model

    def ensemble_members(self) -> tuple[int, ...]:
        """The ensemble's other physics (``--ensemble`` alone: :data:`DEFAULT_ENSEMBLE`)."""
        from .optim.ensemble import DEFAULT_ENSEMBLE
        if self.ensemble is None:
            return ()
        return tuple(self.ensemble) if len(self.ensemble) else DEFAULT_ENSEMBLE

    def result_file(self) -> Path:
        """``OUT/NAME.npz`` (NAME default ``ROBOT_TASK``, ROBOT a robot file's ``[robot] name``;
        a dot in NAME is kept)."""
        name = self.name or f"{robot_file_name(str(self.robot))}_{self.task}"
        return result_path(Path(self.out) / name)


#: the options an optimisation run takes (a sweep file's ``optimize`` arguments)
OPTIMIZE_OPTIONS = tuple(f.name for f in dataclasses.fields(OptimizeRun))


def _physics(env) -> str:
    """``"physics: 4 steps of 8.25 ms per 33 ms control step"`` (what the run simulates)."""
    n = int(env.substeps)
    return (f"physics: {n} steps of {1e3 * env.timestep / n:g} ms per {1e3 * env.timestep:g} ms control step"
            if n > 1 else f"physics: one step of {1e3 * env.timestep:g} ms per control step")


def _refuse(path: Path, what: str, advice: str) -> None:
    raise ValueError(f"{path}: {what}; {advice}")


#: how the run's header names each motor model
_MOTOR_WORDS = {TORQUE_SPEED: "the torque-speed line and the gearbox limit", "speed": "the speed limit alone",
                IDEAL: "no limit"}


def _plan(out: Path, partial: Path, run: OptimizeRun) -> tuple[Result | None, bool]:
    """``(resume, done)``: the interrupted run to continue (or None), and whether there is
    nothing to do (``--resume`` of a finished result). Refuses (ValueError, nothing written) to
    replace a finished result or an interrupted run's checkpoint without ``--overwrite``."""
    for p in (out, partial):
        if p.exists() and not p.is_file():
            _refuse(p, "exists and is not a file", "choose another --name or --out")
    if run.resume:
        if partial.is_file():
            if out.is_file() and not run.overwrite:
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
    if partial.is_file() and not run.overwrite:
        _refuse(partial, "holds the checkpoint of an interrupted run of this name",
                "continue it with --resume, or start afresh with --overwrite")
    if out.is_file() and not run.overwrite:
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


def _gait(run: OptimizeRun) -> GaitSpec:
    n_cycle = _PAPER.n_cycle if run.cycle_steps is None else run.cycle_steps
    try:
        return GaitSpec.for_task(run.task, symmetry=run.symmetry, n_prep=run.prep_steps,
                                 n_cycle=n_cycle, n_keyframes=run.keyframes, interpolation=run.interpolation)
    except ValueError:
        if run.interpolation not in (None, *INTERPOLATIONS):
            raise ValueError(f"--interpolation must be one of {INTERPOLATIONS}, got {run.interpolation!r}") from None
        raise ValueError(f"--keyframes {run.keyframes} must be at most --cycle-steps {n_cycle}") from None


def _check_speed_max(run: OptimizeRun) -> None:
    """``--speed max`` searches a walk within the motors' limit from scratch: other tasks, and
    the options it cannot honour, are refused (ValueError, nothing written)."""
    if run.task != "walk":
        raise ValueError(f"--speed max finds the fastest walk: it needs --task walk, got --task {run.task}")
    refused = [flag for flag, on in (("--no-motor-limit", run.no_motor_limit),
                                     ("--motor-model ideal", run.motor_model == IDEAL),
                                     ("--warm-start", run.warm_start is not None)) if on]
    if refused:
        raise ValueError(f"--speed max cannot be combined with {', '.join(refused)}: the search starts from its "
                         "own seeds within the motors' speed limit (run it again with --overwrite to replace its "
                         "result)")


def _plan_search(out: Path, partial: Path, run: OptimizeRun) -> tuple[Path, bool, bool]:
    """``(checkpoint folder, resume it, nothing to do)`` of a ``--speed max`` run: the search
    interrupted in ``NAME.search.partial/`` is continued with ``resume`` (refused without it or
    ``overwrite``), a finished result is never replaced without ``overwrite``."""
    from .search.checkpoint import search_checkpoint_dir
    folder = search_checkpoint_dir(out)
    state = folder / "state.json"
    if out.exists() and not out.is_file():
        _refuse(out, "exists and is not a file", "choose another --name or --out")
    if folder.exists() and not folder.is_dir():
        _refuse(folder, "exists and is not a folder", "remove it, or choose another --name or --out")
    if partial.is_file() and not run.overwrite:       # a plain run's: the finished search would remove it
        _refuse(partial, "holds the checkpoint of an interrupted run of this name (not a --speed max search)",
                "continue it without --speed max and with --resume, or start afresh with --overwrite")
    if run.resume:
        if state.is_file():
            if out.is_file() and not run.overwrite:
                _refuse(out, "a finished result of this name exists", f"resuming the search in {folder} would "
                        "replace it when it finishes: add --overwrite, or choose another --name")
            return folder, True, False
        if out.is_file():
            print(f"{out} is finished; nothing to resume. {Result.load(out).summary()}")
            return folder, False, True
        print(f"no interrupted search to resume ({state} not found): starting afresh", file=sys.stderr)
        return folder, False, False
    if state.is_file() and not run.overwrite:
        _refuse(folder, "holds the finished optimisations of an interrupted --speed max search of this name",
                "continue it with --resume, or start afresh with --overwrite")
    if out.is_file() and not run.overwrite:
        _refuse(out, f"a result of this name exists ({_status_of(out)})",
                "pass --overwrite to replace it when the new run finishes, or choose another --name")
    return folder, False, False


def _finish_files(res: Result, out: Path, partial: Path) -> Path:
    """Record how the result's speed holds at finer physics steps (:func:`~trajopt.fidelity.fidelity_record`),
    save the finished result and remove the checkpoint (the other way round never)."""
    if res.evaluation.get("upright") and "fidelity" not in res.evaluation:
        res.evaluation["fidelity"] = fidelity_record(res)
    path = res.save(out)
    for p in (partial, partial.with_suffix(".json")):
        p.unlink(missing_ok=True)
    return path


def run_optimization(run: OptimizeRun, progress: Callable[[int], Any] | None = None) -> tuple[Result, Path] | None:
    """Optimise as ``run`` says and save the result (see the module docstring): ``(result,
    its file)``, or None when there is nothing to do (``resume`` of a finished result).
    ``progress(first_iteration)``: makes an object whose ``update(entry)`` sees every
    Gauss-Newton iteration and whose ``close()`` ends it (a progress bar). Bad options, files
    or robots: ValueError, nothing written. Ctrl-C, or SIGTERM / SIGHUP (raised as
    :class:`~trajopt.hardware.signals.Terminated` by the command line): the last iterate is saved
    as an "interrupted" checkpoint (continue with ``resume``) and the exception raised again."""
    get_task(run.task)
    run.model()                    # an unknown or contradicting motor model: refused before anything is written
    out = run.result_file()
    partial = partial_path(out)
    if run.speed == "max":
        _check_speed_max(run)
        with reserve(lock_path(out), f"result {out.name}"):
            return _fastest_reserved(run, out, partial)
    if run.max_sim_steps is not None:
        raise ValueError(f"--max-sim-steps {run.max_sim_steps} is the budget of the --speed max search: without "
                         "--speed max it would do nothing (add --speed max, or leave it out)")
    gait = _gait(run)
    with reserve(lock_path(out), f"result {out.name}"):   # a second run of this name is refused
        return _optimize_reserved(run, out, partial, gait, progress)


def _fastest_reserved(run: OptimizeRun, out: Path, partial: Path) -> tuple[Result, Path] | None:
    """``--speed max`` (:func:`trajopt.fastest.fastest_gait`): the search's default settings
    (``SOFT_ENVS_QUICK=1``: its quick ones), the cycle pinned by ``cycle_steps``, the keyframe
    count by ``keyframes``, the interpolation by ``interpolation`` (default the search's, linear); ``iterations`` and ``seeds`` cap each run's Gauss-Newton iterations
    and random starts, ``cycles`` raises the evaluation's 10 cycles; the result and its table
    (``NAME.search.csv`` / ``.md``) written when it finishes."""
    from .fastest import SearchSettings, fastest_gait, finish_search, write_search_table
    folder, resume, done = _plan_search(out, partial, run)
    if done:
        return None
    quick = os.environ.get("SOFT_ENVS_QUICK", "") not in ("", "0")
    settings = SearchSettings.quick() if quick else SearchSettings()
    settings = dataclasses.replace(            # the options cap the search's effort
        settings, coarse_iterations=min(settings.coarse_iterations, run.iterations),
        fine_iterations=min(settings.fine_iterations, run.iterations), seeds=min(settings.seeds, run.seeds),
        eval_cycles=max(settings.eval_cycles, run.cycles) if not quick else settings.eval_cycles,
        n_prep=run.prep_steps if not quick else settings.n_prep,
        keyframes=(run.keyframes,) if run.keyframes is not None else settings.keyframes,
        symmetry=settings.symmetry if run.symmetry is None else run.symmetry,
        interpolation=settings.interpolation if run.interpolation is None else run.interpolation,
        max_sim_steps=run.max_sim_steps, ensemble=run.ensemble_members())
    with compile_ahead(run.robot):
        env = make_gradient_env(run.robot, heading_deg=run.heading, contact=run.contact, substeps=run.substeps)
    print(f"{env.robot.summary()}; task walk at the highest speed within the motors' limits ({run.model()} "
          f"model); {env.contact_model} contact law; {_physics(env)}"
          f"{'; quick search (SOFT_ENVS_QUICK)' if quick else ''}")
    if resume:
        print(f"resuming the --speed max search in {folder}")
    try:
        res, rows = fastest_gait(env, settings=settings, cycle_steps=run.cycle_steps, heading_deg=run.heading,
                                 robot_spec=robot_reference(run.robot), quiet=run.quiet, checkpoint=folder, resume=resume,
                                 motor_model=run.model())
    except (KeyboardInterrupt, Terminated) as exc:
        by = "" if isinstance(exc, KeyboardInterrupt) else f" by {signal_label(exc.signum)}"
        n = _finished_runs(folder)
        print(f"\ninterrupted{by}: {n} finished optimisation{'s' * (n != 1)} of the search saved in {folder}"
              f"{f'; {out} is untouched' if out.is_file() else ''}; continue with the same command and --resume",
              file=sys.stderr)
        raise
    path = _finish_files(res, out, partial)
    csv_path, md_path = write_search_table(rows, out)
    finish_search(folder)
    print(f"search: {len(rows)} optimisations, {res.evaluation['search_sim_steps']:,} simulation steps in total "
          f"(optimisations and evaluations); table {csv_path} and {md_path.name}")
    return res, path


def _finished_runs(folder: Path) -> int:
    import json
    try:
        return len(json.loads((folder / "state.json").read_text()).get("rows", []))
    except (OSError, ValueError, AttributeError):
        return 0


def _optimize_reserved(run: OptimizeRun, out: Path, partial: Path, gait: GaitSpec,
                       make_progress: Callable[[int], Any] | None) -> tuple[Result, Path] | None:
    resume, done = _plan(out, partial, run)
    if done:
        return None
    warm = Result.load(run.warm_start) if run.warm_start else None
    if warm is not None:
        warm.settings["source"] = str(run.warm_start)
    task = get_task(run.task)
    if run.difficulty is not None and task.env_task is None:
        raise ValueError(f"--difficulty applies to the benchmark's tasks ({', '.join(ENV_TASKS.values())}), "
                         f"not to --task {task.name}")
    if task.env_task not in (None, "walk", "turn", "reach_goal") and run.heading:
        why = ("its box sits for a walk along +x" if task.env_task in ("carry", "push_box")
               else "its slope, step, trench or terrain lies along +x")
        raise ValueError(f"--heading applies to the walk, the turn and reach_goal, not to --task {task.name}: {why}, "
                         "and its id scores +x")
    where = task.environment(run.robot, run.difficulty)     # a benchmark task's slope or ground
    incline = run.angle if task.on_slope else where.get("incline_deg", 0.0)
    contact = run.contact or task.contact          # e.g. the turn pivots on feet that stick
    with compile_ahead(run.robot):            # first run on a machine: numba compiles meanwhile
        env = make_gradient_env(run.robot, incline_deg=incline, heading_deg=run.heading, contact=contact,
                                substeps=run.substeps, ground=where.get("ground"), box=where.get("box"))
    print(f"{env.robot.summary()}; task {task.name}; {env.contact_model} contact law"
          + (f" (the {task.name}'s default; --contact paper for the paper's)" if contact and not run.contact
             else " (the robot file's; --contact paper for the paper's)"
             if not run.contact and env.contact_model != "paper" else "")
          + (f", slope {incline:g} deg" if incline else "")
          + (f", the {task.env_task} task's ground ({run.difficulty or 'medium'})" if "ground" in where else "")
          + (f", the {task.env_task} task's box ({run.difficulty or 'medium'}: {where['box'].mass * 1e3:.1f} g)"
             if "box" in where else "")
          + f"; {_physics(env)}"
          + f"; motors: {_MOTOR_WORDS[run.model()]} (--motor-model {run.model()})")
    print(f"writes {out} (+ .json) when it finishes; checkpoints in {partial} until then")
    done_before = len(resume.history) if resume else 0
    progress = None if make_progress is None else make_progress(done_before + 1)
    latest: dict = {}

    def checkpoint(entry: dict, partial_result: Result) -> None:
        latest["result"] = partial_result
        partial_result.save(partial)           # atomic: a crash leaves the previous checkpoint
        if progress is not None:
            progress.update(entry)

    options = GaussNewtonOptions(max_iter=max(run.iterations - done_before, 0))
    try:
        res = optimize_gait(env, task.name, gait=gait, speed_bl_per_min=run.speed, heading_deg=run.heading,
                            turn=run.turn, options=options, warm_start=warm, n_seeds=run.seeds,
                            eval_cycles=run.cycles, robot_spec=robot_reference(run.robot), callback=checkpoint, resume=resume,
                            motor_model=run.model(), ensemble=run.ensemble_members())
    except (KeyboardInterrupt, Terminated) as exc:     # Ctrl-C, SIGTERM, SIGHUP: the same way out
        if progress is not None:
            progress.close()
            progress = None
        by = "" if isinstance(exc, KeyboardInterrupt) else f" by {signal_label(exc.signum)}"
        if "result" in latest:
            latest["result"].status = "interrupted"
            latest["result"].save(partial)
            print(f"\ninterrupted{by}: iteration {len(latest['result'].history)} saved to {partial}"
                  f"{f'; {out} is untouched' if out.is_file() else ''}; continue with the same command "
                  "and --resume", file=sys.stderr)
        else:
            print(f"\ninterrupted{by} before the first iteration: nothing saved", file=sys.stderr)
        raise
    finally:
        if progress is not None:
            progress.close()
    if task.env_task is not None:              # replays rebuild its ground (trajopt.replay)
        from soft_envs.envs.tasks import DEFAULT_DIFFICULTY
        res.settings.update(env_task=task.env_task, difficulty=run.difficulty or DEFAULT_DIFFICULTY)
    path = _finish_files(res, out, partial)
    from .search.table import search_table_paths
    for table in search_table_paths(out):      # an earlier --speed max result's: not this result's search
        table.unlink(missing_ok=True)
    return res, path
