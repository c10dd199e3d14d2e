"""``trajopt codesign ROBOT --vary routing,stiffness,legs --out DIR``: one co-design run into files.

The steps (each file written atomically; ``DIR`` is created only once every input has been
checked, and reserved while the run lives: ``DIR/codesign.lock``, :mod:`trajopt.results.reservation`):

1. **baseline**: the shipped design's fastest gait within the motors' limit, as ``trajopt
   optimize ROBOT --speed max`` finds it (:func:`trajopt.fastest.fastest_gait`), or a given one
   (``baseline=``, made by ``--speed max`` on the same robot and law): ``DIR/baseline_walk.npz``;
2. **screening** of designs a finite step away (:mod:`trajopt.codesign.screen`), its candidates
   scored in ``workers`` processes, then **joint optimisation** of the keyframes and the design
   parameters ``vary`` declares (:mod:`trajopt.codesign.joint`); checkpointed to
   ``DIR/codesign.partial.json`` after every screening round and every Gauss-Newton iteration;
   ``resume`` continues an interrupted run from there;
3. **the designed robot**: ``DIR/robot.toml`` (and ``DIR/mesh.vtu`` when the legs changed),
   written by :func:`soft_envs.envs.design.write_designed_robot`, a robot folder every command
   loads unchanged, checked independently of the optimiser (:mod:`trajopt.codesign.checks`);
4. **its gait**: ``DIR/NAME_walk.npz``, the co-designed keyframes on the robot reloaded from
   ``DIR/robot.toml`` (a few more Gauss-Newton iterations there, kept when faster), tied to the
   written robot (its fingerprint: the shipped robot refuses it);
5. **re-optimised from scratch** (``reoptimise``): ``--speed max`` on the reloaded robot,
   ``DIR/NAME_walk_reoptimised.npz``: the gain belongs to the design, not to a lucky gait;
6. **the report**: ``DIR/codesign.md`` (speeds before and after, every design change, the
   constraint checks) and ``DIR/codesign.png`` (the shipped and the designed robot side by side,
   tendons drawn), and ``DIR/codesign.json`` (the figures).
"""
from __future__ import annotations

import json
import os
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from soft_envs.envs import make_gradient_env
from soft_envs.envs.design import KINDS, load_design, write_designed_robot

from ..fastest import SearchSettings, fastest_gait, search_table_paths, write_search_table
from ..results.files import atomic_write_bytes
from ..results.reservation import reserve
from ..optim.gait import GaitSpec
from ..optim.gauss_newton import GaussNewtonOptions
from ..optim.motor_limit import SPEED, TORQUE_SPEED, max_step_of_env
from ..optim.optimize import optimize_gait
from ..results.result import Result
from ..results.robot_match import robot_reference
from .inputs import check_baseline, check_design, read_summary
from .joint import JointSettings, JointState, optimise_jointly, replay_path
from .partial import check_partial_sizes, read_partial
from .problem import CodesignProblem, CodesignWeights
from .screen import ScreenProgress, ScreenSettings, screen_designs
from ..search.hold import credible_rank
from .summary import credible_check, describe_credible, summarise, write_report

__all__ = ["CodesignRun", "CodesignOutcome", "run_codesign", "design_changes", "check_baseline"]

PARTIAL = "codesign.partial.json"
#: what the screening's and the joint stage's scores are, in a checkpoint's settings: a checkpoint
#: without it was made when they were the speeds at the own physics alone, and is refused
SCORES = "credible: (holds, slowest) over the hold replays"   # the screening's order: ScreenSettings.rank


@dataclass
class CodesignRun:
    """The options of one ``trajopt codesign`` run (the command line's, module docstring)."""

    robot: str
    out: Path
    vary: tuple[str, ...] = KINDS
    contact: str | None = None
    baseline: Path | None = None
    joint: JointSettings = JointSettings()
    screen: ScreenSettings = ScreenSettings()
    search: SearchSettings = SearchSettings()
    weights: CodesignWeights = CodesignWeights()
    polish_iterations: int = 3
    reoptimise: bool = True
    resume: bool = False
    overwrite: bool = False
    quiet: bool = False
    name: str | None = None
    workers: int | None = 1             # processes scoring the screening's candidates (None: one per core;
                                        # > 1 from a script: run it under `if __name__ == "__main__":`)
    motor_model: str = "torque-speed"   # the motors' law every gait obeys ("torque-speed" or "speed")

    def __post_init__(self):
        if self.workers is not None and int(self.workers) < 1:
            raise ValueError(f"workers must be >= 1, got {self.workers}")
        if self.motor_model not in (TORQUE_SPEED, SPEED):
            raise ValueError(f"motor_model must be {TORQUE_SPEED!r} or {SPEED!r} (co-design needs the motors' "
                             f"limits), got {self.motor_model!r}")

    def n_workers(self) -> int:
        return int(self.workers) if self.workers is not None else max(1, os.cpu_count() or 1)

    @classmethod
    def quick(cls, robot: str, out: Path, **kw) -> "CodesignRun":
        """Small enough for tests and CI (a minute or two)."""
        return cls(robot, Path(out), joint=JointSettings.quick(), search=SearchSettings.quick(),
                   screen=ScreenSettings.quick(), polish_iterations=1, **kw)


@dataclass
class CodesignOutcome:
    """Where a co-design's files are and its figures; ``finished``: it was finished before
    (``resume`` had nothing to do)."""

    robot_file: Path
    result_file: Path
    report_file: Path
    summary: dict[str, Any] = field(default_factory=dict)
    finished: bool = False


def design_changes(design, before: np.ndarray, after: np.ndarray) -> list[dict]:
    """Every design parameter that changed (by more than a millionth of its value, or of a
    millimetre): name, before, after, unit (and a description when the design gives one)."""
    before, after = np.asarray(before, dtype=np.float64), np.asarray(after, dtype=np.float64)
    moved = np.abs(after - before) > 1e-6 * np.maximum(np.abs(before), 1e-3)
    if hasattr(design, "describe_changes"):
        keep = {n for n, m in zip(design.names, moved) if m}
        return [c for c in design.describe_changes(before, after) if c["name"] in keep]
    return [{"name": n, "before": float(b), "after": float(a), "unit": "Pa" if n.startswith("stiffness:") else "m"}
            for n, b, a, m in zip(design.names, before, after, moved) if m]


def _say(run: CodesignRun):
    return (lambda text: None) if run.quiet else (lambda text: print(text, file=sys.stderr, flush=True))


#: the lock reserving a co-design's folder while a run lives (:mod:`trajopt.results.reservation`)
LOCK = "codesign.lock"
#: the summary of a finished co-design
SUMMARY = "codesign.json"


def _check_out(run: CodesignRun, name: str) -> CodesignOutcome | None:
    """What ``--out`` holds decides (inside the folder's reservation): an interrupted run is
    continued only with ``resume`` (or replaced with ``overwrite``), a finished one is replaced
    only with ``overwrite``; ``resume`` of a finished one has nothing to do (its outcome is
    returned), and one made with another ``--vary`` is refused."""
    out = run.out
    partial, robot_file, summary = out / PARTIAL, out / "robot.toml", out / SUMMARY
    for p in (partial, robot_file, summary):
        if p.exists() and not p.is_file():
            raise ValueError(f"{p}: exists and is not a file; choose another --out")
    if partial.is_file():
        if not (run.resume or run.overwrite):
            raise ValueError(f"{partial} holds an interrupted co-design run: continue it with --resume, "
                             "or start afresh with --overwrite")
        return None
    if not robot_file.is_file():
        return None
    if run.resume:
        if not summary.is_file():
            raise ValueError(f"{out}: holds a robot.toml but no {SUMMARY}: not a co-design to resume; choose "
                             "another --out, or replace it with --overwrite (without --resume)")
        done = read_summary(summary)
        vary = done.get("vary")
        if isinstance(vary, list) and list(vary) != list(run.vary):
            raise ValueError(f"{summary}: the finished co-design in {out} varied {','.join(map(str, vary))}, not "
                             f"--vary {','.join(run.vary)}: nothing of it can be resumed; replace it with "
                             "--overwrite (without --resume), or choose another --out")
        return CodesignOutcome(robot_file, out / f"{name}.npz", out / "codesign.md", done, finished=True)
    if not run.overwrite:
        raise ValueError(f"{robot_file} exists: a finished co-design is never replaced without "
                         "--overwrite (or choose another --out)")
    return None


def _baseline(run: CodesignRun, env, given: Result | None, say) -> Result:
    """The shipped design's fastest gait: the given one (checked before), the resumed run's,
    or a ``--speed max`` search."""
    path = run.out / "baseline_walk.npz"
    if given is not None:
        given.save(path)
        for table in search_table_paths(path):         # an earlier search's table is not this baseline's
            table.unlink(missing_ok=True)
        return given
    if run.resume and path.is_file():
        return check_baseline(path, env, run.robot, run.motor_model)
    say(f"baseline: the shipped {env.robot.name}'s fastest gait within the motors' limit (--speed max)")
    res, rows = fastest_gait(env, settings=run.search, robot_spec=robot_reference(run.robot), quiet=run.quiet,
                             log=say)
    res.save(path)
    write_search_table(rows, path)
    return res


def _write_json(path: Path, data: dict) -> None:
    atomic_write_bytes(path, (json.dumps(data, indent=1, default=float) + "\n").encode())


def run_codesign(run: CodesignRun) -> CodesignOutcome:
    """Run the steps of the module docstring; returns where the files are and the figures.
    Every input (the robot and its [design] table, a given baseline) is checked before anything
    is created; the folder is reserved for the run's length (``DIR/codesign.lock``: a second
    co-design into it is refused); ``resume`` of a finished co-design does nothing (the outcome
    says ``finished``)."""
    t_start = time.perf_counter()
    env = make_gradient_env(run.robot, contact=run.contact, motor_model=run.motor_model)
    shipped = env.robot
    design = load_design(shipped, run.vary)
    check_design(design, run.vary, shipped.source)
    given = check_baseline(Path(run.baseline), env, run.robot, run.motor_model) if run.baseline is not None else None
    with reserve(run.out / LOCK, f"co-design folder {run.out}"):
        done = _check_out(run, run.name or f"{shipped.name}_walk")
        if done is not None:
            return done
        return _run_reserved(run, env, design, given, t_start)


def _settings_difference(saved: Any, settings: dict) -> str:
    if not isinstance(saved, dict):
        return "its settings are not an object"
    diff = [f"{k}: {_short(saved.get(k))} -> {_short(settings.get(k))}" for k in sorted(set(saved) | set(settings))
            if saved.get(k) != settings.get(k)]
    return "; ".join(diff[:3]) + (f" and {len(diff) - 3} more" if len(diff) > 3 else "")


def _short(v: Any) -> str:
    text = ",".join(map(str, v)) if isinstance(v, list) and all(isinstance(x, str) for x in v) else repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def _run_reserved(run: CodesignRun, env, design, given: Result | None, t_start: float) -> CodesignOutcome:
    say = _say(run)
    shipped = env.robot
    partial = run.out / PARTIAL
    saved = read_partial(partial) if run.resume and partial.is_file() else None   # before any work
    if saved is not None and saved[0].get("scores") != SCORES:
        raise ValueError(f"{partial}: cannot resume: the interrupted run was made before co-design scored designs "
                         "by credible speeds (the slowest over the hold stage's physics steps), and its screening "
                         "and stages ranked designs by the speed at the own physics; start afresh with --overwrite")
    baseline = _baseline(run, env, given, say)
    gait = GaitSpec.from_settings(baseline.settings)
    base_speed = float(baseline.evaluation["speed_bl_per_min"])
    base_hold = credible_check(env, baseline, run.screen)
    settings = {"scores": SCORES, "robot": run.robot, "vary": list(run.vary), "contact": env.contact_model,
                "gait": gait.to_settings(),
                "motor_model": run.motor_model,
                "joint": asdict(run.joint), "screen": asdict(run.screen), "weights": run.weights.to_dict(), "parameters": list(design.names),
                "baseline_speed_bl_per_min": base_speed}
    problem = CodesignProblem(env, design, gait, run.joint.target(base_speed), run.weights, max_step_of_env(env),
                              motor_model=run.motor_model)
    state = None
    if saved is not None:
        expected = json.loads(json.dumps(settings, default=float))
        if saved[0] != expected:
            raise ValueError(f"{partial}: cannot resume: the settings differ from the interrupted run's "
                             f"({_settings_difference(saved[0], expected)}); resume with its options, or start "
                             "afresh with --overwrite")
        state = saved[1]
        check_partial_sizes(partial, state, problem.nz, len(design))
        say(f"resuming {partial}: stage {state.stage + 1}, iteration {state.iteration}")
    if state is None:
        state = JointState(w=problem.start(baseline.z).tolist(), best_speed=credible_rank(base_hold)[1],
                           best_holds=bool(credible_rank(base_hold)[0]))

    def checkpoint(s: JointState) -> None:
        _write_json(partial, {"settings": settings, "state": s.to_dict()})

    if not state.screened:                   # the coarse stage, resumed after its last finished round
        _screen(run, problem, state, baseline, checkpoint, say)

    total = run.joint.stages * run.joint.iterations
    bar = None
    if not run.quiet:
        from ..progress import IterationProgress
        bar = IterationProgress(total, first=state.stage * run.joint.iterations + state.iteration + 1)
    try:
        state = optimise_jointly(problem, state, run.joint, checkpoint=checkpoint,
                                 progress=None if bar is None else bar.update, log=say)
    finally:
        if bar is not None:
            bar.close()
    block = problem.block
    z_best, theta_best = problem.split(np.asarray(state.best_w))
    if not np.array_equal(theta_best, problem.anchor):
        raise RuntimeError("co-design: the best design's block was lost (a bug)")
    robot_file = write_designed_robot(block, block.values, run.out)
    say(f"wrote the designed robot {robot_file}")
    from .checks import check_designed_robot, format_checks
    checks = check_designed_robot(shipped.source, robot_file)
    new_env = make_gradient_env(str(robot_file), contact=env.contact_model, substeps=env.substeps,
                                motor_model=run.motor_model)
    name = run.name or f"{shipped.name}_walk"
    result = _gait_on_written_robot(run, new_env, gait, z_best, state, robot_file)
    result_file = run.out / f"{name}.npz"
    result.save(result_file)
    reopt = None
    reopt_file = run.out / f"{name}_reoptimised.npz"
    if run.reoptimise:
        say(f"re-optimising the gait of {robot_file} from scratch (--speed max)")
        reopt, rows = fastest_gait(new_env, settings=run.search, robot_spec=robot_reference(robot_file),
                                   quiet=run.quiet, log=say)
        reopt.save(reopt_file)
        write_search_table(rows, reopt_file)
    else:                                    # a replaced co-design's: not this design's gait
        for stale in (reopt_file, reopt_file.with_suffix(".json"), *search_table_paths(reopt_file)):
            stale.unlink(missing_ok=True)
    changes = design_changes(design, design.values, block.values)
    holds = {"before": base_hold, "after": result.evaluation.get("hold"),
             "reoptimised": credible_check(new_env, reopt, run.screen)
             if reopt is not None and reopt.evaluation.get("upright") else None}
    summary = summarise(run, env, baseline, result, reopt, state, changes, checks, time.perf_counter() - t_start, holds)
    report_file = write_report(run, shipped, new_env.robot, summary, changes, checks, settings)
    _write_json(run.out / SUMMARY, summary)
    partial.unlink(missing_ok=True)
    say(f"co-design: {describe_credible(summary)}; {summary['iterations']} Gauss-Newton iterations, "
        f"{summary['wall_time_s']:.0f} s; report {report_file}")
    failed = [c for c in checks if not c.passed]
    if failed:
        raise ValueError(f"{robot_file}: the designed robot breaks its constraints:\n{format_checks(checks)}")
    return CodesignOutcome(robot_file, result_file, report_file, summary)


def _screen(run: CodesignRun, problem: CodesignProblem, state: JointState, baseline: Result, checkpoint, say) -> None:
    """The screening stage into ``state`` (:func:`~trajopt.codesign.screen.screen_designs`),
    checkpointed after every round; an interrupted one continues after its last round."""
    t0, wall0 = time.perf_counter(), state.wall_time_s
    theta0 = problem.anchor.copy()
    progress = None
    if state.screen_progress is not None:
        progress = ScreenProgress(**state.screen_progress)
        problem.block, problem.anchor = replay_path(problem, progress.path)
        problem.sim_steps = state.sim_steps
        say(f"resuming the screening after round {progress.rounds_done} of {run.screen.rounds}")
    else:
        say(f"screening designs around the shipped one ({run.screen.rounds} rounds at most, "
            f"{run.n_workers()} worker{'s' if run.n_workers() > 1 else ''})")

    from ..progress import Progress             # a heartbeat: a round's searches take minutes
    beat = Progress(run.screen.rounds, "co-design screening", "round", tty=False, per_item=False,
                    initial=progress.rounds_done if progress else 0, interval=None if run.quiet else "default")

    def round_done(p: ScreenProgress) -> None:
        state.screen_progress = asdict(p)
        state.sim_steps, state.wall_time_s = problem.sim_steps, wall0 + time.perf_counter() - t0
        checkpoint(state)
        beat.update(1)

    with beat:
        p = screen_designs(problem, theta0, np.asarray(baseline.z), state.best_speed,
                           run.search.target(float(baseline.evaluation["speed_bl_per_min"])), run.screen,
                           search=run.search, workers=run.n_workers(), resume=progress, log=say,
                           round_done=round_done, holds=state.best_holds)
    theta = np.asarray(p.theta)
    state.path = list(p.path)
    if not np.array_equal(theta, problem.anchor):
        problem.move_to(theta)
        state.path.append(theta.tolist())
    state.w = state.best_w = np.concatenate([np.asarray(p.z), theta]).tolist()
    state.best_speed, state.best_holds, state.best_path_len = p.speed, p.holds, len(state.path)
    state.screen_rows, state.screened, state.screen_progress = p.rows, True, None
    state.sim_steps, state.wall_time_s = problem.sim_steps, wall0 + time.perf_counter() - t0
    checkpoint(state)


def _gait_on_written_robot(run: CodesignRun, env, gait: GaitSpec, z: np.ndarray, state: JointState,
                           robot_file: Path) -> Result:
    """The co-designed keyframes on the reloaded robot: ``polish_iterations`` more Gauss-Newton
    iterations of the walk there (the motors' limit on), kept when their credible rank is higher
    than none's (:func:`~trajopt.search.hold.credible_rank`); the replays in ``evaluation["hold"]``."""
    target = run.joint.target(state.best_speed)
    kw = dict(gait=gait, speed_bl_per_min=target, z0=z, n_seeds=0, eval_cycles=run.joint.eval_cycles,
              robot_spec=robot_reference(robot_file))
    plain = optimize_gait(env, "walk", options=GaussNewtonOptions(max_iter=0), **kw)
    gaits = [plain]
    if run.polish_iterations > 0:
        gaits.append(optimize_gait(env, "walk", options=GaussNewtonOptions(max_iter=run.polish_iterations), **kw))
    for res in gaits:
        if res.evaluation.get("upright"):
            res.evaluation["hold"] = credible_check(env, res, run.screen)
    return max(gaits, key=lambda r: credible_rank(r.evaluation.get("hold")))     # the first of equals: plain
