"""The fastest walk within the motors' limits: ``trajopt optimize ROBOT --speed max`` (issue #28 item 3).

The paper fixes the cycle (72 steps, 2.4 s) by hand; the fastest gait under the motors' limits
(the torque-speed line, :mod:`trajopt.optim.motor_torque`, by default; the speed limit alone,
:mod:`trajopt.optim.motor_limit`, with ``motor_model="speed"``) needs a shorter one. :func:`fastest_gait` searches the
cycle length and the keyframe count discretely, with several starts, coarse to fine:

1. **coarse**: every candidate ``(n_cycle, n_keyframes)`` of :class:`SearchSettings`
   (shortest cycles first, then fewer keyframes first) gets ``coarse_iterations`` Gauss-Newton
   iterations from the best of its starts: the previous candidate's keyframes (keyframes are
   phases of the cycle, so a gait at one cycle length is a start at its neighbour; resampled
   at the new phases for another keyframe count, :func:`keyframes_at`) and
   ``param.seeds(seeds)`` (screened by cheap rollouts without sensitivities);
2. **revisit** (``revisit``, default on): the coarse chain starts its shortest cycle from the
   seeds alone and walks from short to long, so a short cycle never sees the keyframes of a
   better gait found later. Every candidate with a shorter cycle than the fastest upright
   coarse gait runs again, ``coarse_iterations`` iterations warm-started from that gait's
   keyframes (at the same phases: a faster stride frequency). Measured under the Coulomb law
   without a budget: on the shipped Puppy the 16-step cycle with 8 keyframes reached 19.8 BL/min
   from the shorter cycle's gait and 30.2 revisited from the 24-step gait, and the search's
   result rose from 28.3 to 30.9 BL/min; on a co-designed Tripod (docs/codesign.md) the 8-step
   cycle reached 4.9 from the seeds and 30.9 revisited, and the result rose from 26.1 to 31.5.
   On the shipped Tripod the fastest coarse gait is the shortest cycle (nothing to revisit);
   within one PPO seed's budget (the RL comparison) the Puppy's revisits do not fit;
3. **fine**: the ``n_fine`` fastest upright candidates continue for ``fine_iterations``
   iterations from where they stopped.

Under the motors' torque-speed line (the default model) the coarse and revisit stages explore
under the speed limit alone and the fine stage tightens their fastest gaits to the line
(``explore_under_speed``, a continuation): started from the seeds under the line, the short
cycles end in gaits that lean rather than walk (measured on the shipped Tripod, Coulomb law: the
8-step cycle at 0.01 BL/min after its coarse iterations, the search's best a 36-step gait at
14.7 BL/min), while the speed limit's 8-step gait moved into the line and refined walks at
20.8 BL/min. The result is the fastest upright run made under the search's own model.

Every optimisation tracks a straight line (the walk's objective, paper eq. 5-7) at a target
speed chosen above the fastest gait found so far: ``max(min_target, target_margin * best)``
BL/min, so that the target always asks for more than is known to be possible. The keyframes
are interpolated by straight lines (``GaitSpec(interpolation="linear")``, the
``interpolation`` setting): the paper's zero-tangent spline peaks at 1.5 times its mean slope,
so under the limit its cables average at most 2/3 of the motors' speed. The horizon holds at
least ``min_horizon_steps`` cycle steps (two cycles at least), so a short cycle is tracked
over several strides, not only its prep phase.

Each candidate is evaluated with :func:`trajopt.evaluation.evaluate_controls` over
``eval_cycles`` cycles (10) after the prep phase; the result is the fastest upright one.
Every simulation step is counted: the optimisations' (``sim_steps`` of
:class:`trajopt.optim.optimize.GaitProblem`: rollouts with and without sensitivities,
line-search trials, seed screening) and the evaluations'; the total is in
``result.evaluation["search_sim_steps"]`` and the table. :func:`write_search_table` writes the
table beside the result (``NAME.search.csv`` and ``.md``).

A search is resumable (:class:`SearchCheckpoint`, ``trajopt optimize --speed max --resume``):
after every optimisation its row and result go to a folder (``NAME.search.partial/``); a search
interrupted (Ctrl-C, SIGTERM, SIGHUP, a kill) continues after its last finished optimisation,
the finished ones replayed from their files (the search is deterministic given them, so it ends
where an uninterrupted search ends).
"""
from __future__ import annotations

import csv
import io
import json
import math
import shutil
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from soft_envs.envs import SimulationError, as_gradient_env

from .hardware.signals import Terminated
from .results.files import atomic_write_bytes
from .optim.gait import GaitSpec
from .optim.gauss_newton import GaussNewtonOptions
from .optim.motor_limit import IDEAL, SPEED, TORQUE_SPEED, choose_motor_model
from .optim.optimize import optimize_gait
from .optim.parameterization import GaitParameterization
from .results.result import Result

__all__ = [
    "SEARCH_EVAL_CYCLES",
    "TABLE_COLUMNS",
    "SearchCheckpoint",
    "SearchSettings",
    "fastest_gait",
    "keyframes_at",
    "finish_search",
    "search_checkpoint_dir",
    "search_identity",
    "search_table_paths",
    "write_search_table",
]

#: cycles played after the prep phase when a candidate is evaluated (the issue's "10 cycles")
SEARCH_EVAL_CYCLES = 10


@dataclass(frozen=True)
class SearchSettings:
    """What :func:`fastest_gait` searches (module docstring). ``cycle_steps``: the cycle lengths
    [simulation steps]; ``keyframes``: keyframe counts per cycle (a count is tried on a cycle of
    at least ``min_steps_per_keyframe`` steps per keyframe); ``seeds``: random starts screened
    besides the mid-range and square-wave starts; Gauss-Newton iterations per stage;
    ``n_fine``: candidates refined; the target speed rule; the interpolation of the keyframes; bilateral symmetry;
    ``revisit``: the shorter cycles again from the fastest coarse gait (module docstring).
    ``explore_under_speed``: under the torque-speed model, the coarse and revisit stages run
    under the speed limit alone and the fine stage tightens them to the line (module docstring).
    ``max_sim_steps``: a budget of simulation steps (None: none) the search never exceeds: the
    coarse stage keeps within ``coarse_share`` of it, the fine stage within all of it; a run
    that would not fit is skipped (listed in the table), and one that runs stops early rather
    than risk its next iteration and evaluation passing the budget."""

    cycle_steps: tuple[int, ...] = (8, 12, 16, 24, 36, 72)
    keyframes: tuple[int, ...] = (4, 8)
    min_steps_per_keyframe: int = 2
    seeds: int = 1
    coarse_iterations: int = 3
    fine_iterations: int = 6
    n_fine: int = 2
    min_target: float = 20.0
    target_margin: float = 1.25
    min_horizon_steps: int = 48
    n_prep: int = 24
    interpolation: str = "linear"
    symmetry: bool = True
    eval_cycles: int = SEARCH_EVAL_CYCLES
    max_sim_steps: int | None = None
    coarse_share: float = 0.75
    revisit: bool = True
    explore_under_speed: bool = True

    @classmethod
    def quick(cls) -> SearchSettings:
        """A search small enough for tests and CI (a few seconds)."""
        return cls(cycle_steps=(8, 12), keyframes=(4,), seeds=0, coarse_iterations=1, fine_iterations=1,
                   n_fine=1, min_horizon_steps=16, n_prep=4, eval_cycles=2)

    def candidates(self, cycle_steps: int | None = None) -> list[tuple[int, int]]:
        """``(n_cycle, n_keyframes)`` in search order: shortest cycle first, fewer keyframes first
        (``cycle_steps``: that cycle only)."""
        cycles = (int(cycle_steps),) if cycle_steps is not None else self.cycle_steps
        out = [(c, k) for c in sorted(cycles) for k in sorted(self.keyframes) if c >= self.min_steps_per_keyframe * k]
        if not out:
            raise ValueError(f"no (cycle, keyframes) candidate: cycles {cycles} are shorter than "
                             f"{self.min_steps_per_keyframe} steps per keyframe for keyframes {self.keyframes}")
        return out

    def gait(self, n_cycle: int, n_keyframes: int) -> GaitSpec:
        """The gait of a candidate: horizon of at least ``min_horizon_steps`` cycle steps."""
        n_cycles = max(2, math.ceil(self.min_horizon_steps / n_cycle))
        return GaitSpec(n_prep=self.n_prep, n_cycle=n_cycle, n_cycles=n_cycles, n_keyframes=n_keyframes,
                        symmetry=self.symmetry, interpolation=self.interpolation)

    def target(self, best: float) -> float:
        """The tracking target [BL/min] when the fastest upright gait so far makes ``best``."""
        return max(self.min_target, self.target_margin * best)


#: the columns of the search table (one row per optimisation)
TABLE_COLUMNS = ("stage", "motor_model", "n_cycle", "n_keyframes", "horizon_cycles", "start", "target_bl_per_min", "iterations",
                 "status", "speed_bl_per_min", "upright", "max_tilt_deg", "optimization_sim_steps",
                 "evaluation_sim_steps", "total_sim_steps", "wall_time_s", "chosen")


class _KeyframeStart:
    """A warm start for :func:`trajopt.optim.optimize.choose_start`: only its keyframes are read."""

    def __init__(self, keyframes: np.ndarray, source: str):
        self.settings = {"keyframes": np.asarray(keyframes).tolist(), "source": source}


def keyframes_at(keyframes: np.ndarray, n_keyframes: int) -> np.ndarray:
    """Keyframes (M, k) of a cycle as ``n_keyframes`` keyframes at the same phases of the cycle:
    the periodic piecewise-linear cycle through them sampled at the new keyframes' phases (the
    same cycle when k divides ``n_keyframes`` and the keyframes are joined by straight lines)."""
    kf = np.asarray(keyframes, dtype=np.float64)
    k = kf.shape[1]
    phase = np.arange(n_keyframes) * k / n_keyframes
    return np.array([np.interp(phase, np.arange(k + 1), np.append(row, row[0])) for row in kf])


def _evaluation_steps(res: Result) -> int:
    """The steps of a result's evaluation (prep + its cycles; a failed one counted in full)."""
    s = res.settings
    return int(s["n_prep"]) + int(s["eval_cycles"]) * int(s["n_cycle"])


def _row(stage: str, res: Result | None, gait: GaitSpec, start: str, target: float, opt_steps: int,
         eval_steps: int, total: int, seconds: float, failure: str = "", motor_model: str = "") -> dict[str, Any]:
    ev = res.evaluation if res is not None else {}
    return {"stage": stage, "motor_model": motor_model, "n_cycle": gait.n_cycle, "n_keyframes": gait.n_keyframes,
            "horizon_cycles": gait.n_cycles, "start": start, "target_bl_per_min": round(target, 3),
            "iterations": len(res.history) if res is not None else 0,
            "status": res.status if res is not None else failure,
            "speed_bl_per_min": float(ev.get("speed_bl_per_min", float("nan"))),
            "upright": bool(ev.get("upright", False)), "max_tilt_deg": float(ev.get("max_tilt_deg", float("nan"))),
            "optimization_sim_steps": opt_steps, "evaluation_sim_steps": eval_steps, "total_sim_steps": total,
            "wall_time_s": round(seconds, 2), "chosen": False}


def _progress(total: int, quiet: bool):
    if quiet:
        return None
    from tqdm.auto import tqdm
    return tqdm(total=total, desc="--speed max", unit="run", leave=True)


def search_checkpoint_dir(result_file: str | Path) -> Path:
    """``NAME.search.partial/`` beside the result ``NAME.npz``: an unfinished search's runs."""
    p = Path(result_file)
    return p.with_name(p.name.removesuffix(".npz") + ".search.partial")


class SearchCheckpoint:
    """The finished optimisations of a search in ``folder``: ``state.json`` (what the search
    is: its settings, pinned cycle, heading, robot and contact law; its rows; ``status``
    running or interrupted) and ``run_NNN.npz`` (+ ``.json``) per finished optimisation.
    :meth:`load` reads and checks them (ValueError naming the file and the field);
    :func:`fastest_gait` replays them and saves each new one."""

    STATE = "state.json"

    def __init__(self, folder: str | Path, identity: dict[str, Any] | None = None):
        self.folder = Path(folder)
        self.identity = identity or {}

    @property
    def state_file(self) -> Path:
        return self.folder / self.STATE

    def _run_file(self, i: int) -> Path:
        return self.folder / f"run_{i:03d}.npz"

    def _state(self, rows: list[dict], status: str) -> None:
        data = {"identity": self.identity, "status": status, "rows": rows}
        atomic_write_bytes(self.state_file, (json.dumps(data, indent=1, default=float) + "\n").encode())

    def start(self, rows: list[dict]) -> None:
        """Mark the search running (its ``rows`` replayed so far kept)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        self._state(rows, "running")

    def save_run(self, rows: list[dict], res: Result | None) -> None:
        """After optimisation ``len(rows) - 1``: its result (if any), then the rows."""
        if res is not None:
            res.save(self._run_file(len(rows) - 1))
        self._state(rows, "running")

    def mark(self, rows: list[dict], status: str) -> None:
        self._state(rows, status)

    def remove(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)

    def load(self) -> tuple[list[tuple[dict, Result | None]], str]:
        """``(finished runs, status)``: each run's row and result (None: skipped or failed), in
        the order the search made them. Refuses (ValueError naming the file and the field) a
        damaged state or one of another search (its settings, robot, contact law)."""
        path = self.state_file
        hint = "continue with the same options, or start afresh with --overwrite"
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except UnicodeDecodeError as err:
            raise ValueError(f"{path}: not UTF-8 ({err.reason} at byte {err.start}); {hint}") from None
        except json.JSONDecodeError as err:
            raise ValueError(f"{path}: not JSON ({err.msg}, line {err.lineno}); {hint}") from None
        if not isinstance(data, dict):
            raise ValueError(f"{path}: expected a JSON object, got {type(data).__name__}; {hint}")
        identity, rows, status = data.get("identity"), data.get("rows"), data.get("status")
        if not isinstance(identity, dict):
            raise ValueError(f"{path}: field 'identity' is missing or not an object; {hint}")
        if not isinstance(rows, list) or not all(isinstance(r, dict) and set(TABLE_COLUMNS) <= set(r) for r in rows):
            raise ValueError(f"{path}: field 'rows' must be a list of search-table rows ({', '.join(TABLE_COLUMNS)}); "
                             f"{hint}")
        expected = json.loads(json.dumps(self.identity, default=float))
        changed = [k for k in sorted(set(expected) | set(identity)) if expected.get(k) != identity.get(k)]
        if changed:
            what = []
            for k in changed:
                a, b = identity.get(k), expected.get(k)
                if isinstance(a, dict) and isinstance(b, dict):
                    what += [f"{k}.{f}: {a.get(f)!r} -> {b.get(f)!r}" for f in sorted(set(a) | set(b))
                             if a.get(f) != b.get(f)]
                else:
                    what.append(f"{k}: {a!r} -> {b!r}")
            raise ValueError(f"{path}: cannot resume: this search differs from the interrupted one "
                             f"({'; '.join(what[:4])}); run it with the interrupted search's options, or start afresh "
                             "with --overwrite")
        runs: list[tuple[dict, Result | None]] = []
        for i, row in enumerate(rows):
            res = None
            if not str(row.get("status", "")).startswith(("skipped", "failed")):
                file = self._run_file(i)
                if not file.is_file():
                    raise ValueError(f"{file}: missing: the checkpoint's row {i} has no result; {hint}")
                res = Result.load(file)
            runs.append((row, res))
        return runs, str(status)


class _Search:
    """The state of a search: its rows, runs, step count and the fastest upright speed so far;
    ``replay``: the finished runs of an interrupted search (:class:`SearchCheckpoint`), taken
    instead of running them again; ``checkpoint``: where each finished run goes."""

    def __init__(self, env, settings: SearchSettings, heading_deg: float, robot_spec: str | None, bar, say,
                 replay: list[tuple[dict, Result | None]] = (), checkpoint: SearchCheckpoint | None = None,
                 motor_model: str = SPEED):
        self.env, self.settings, self.heading_deg, self.robot_spec = env, settings, heading_deg, robot_spec
        self.motor_model = motor_model
        self.bar, self.say = bar, say
        self.t_start = time.perf_counter()
        self.rows: list[dict] = []
        self.runs: list[tuple[dict, Result]] = []
        self.total = 0
        self.best = 0.0
        self.replay, self.checkpoint = list(replay), checkpoint

    def _replayed(self, stage: str, gait: GaitSpec, start: str) -> tuple[bool, Result | None]:
        """The next run from the interrupted search's, when there is one left."""
        i = len(self.rows)
        if i >= len(self.replay):
            return False, None
        row, res = self.replay[i]
        if (row["stage"], int(row["n_cycle"]), int(row["n_keyframes"]), row["start"]) != \
                (stage, gait.n_cycle, gait.n_keyframes, start):
            where = self.checkpoint.state_file if self.checkpoint is not None else "the checkpoint"
            raise ValueError(f"{where}: row {i} is {row['stage']} cycle {row['n_cycle']} keyframes "
                             f"{row['n_keyframes']}, but the search now runs {stage} cycle {gait.n_cycle} keyframes "
                             f"{gait.n_keyframes}: not this search's; start afresh with --overwrite")
        self.rows.append(row)
        self.total = int(row["total_sim_steps"])
        if res is not None:
            self.runs.append((row, res))
            if row["upright"] and row["speed_bl_per_min"] > self.best:
                self.best = row["speed_bl_per_min"]
        self.say(f"{stage} cycle {gait.n_cycle} keyframes {gait.n_keyframes}: {row['speed_bl_per_min']:.2f} BL/min "
                 f"(from the checkpoint)")
        self._tick()
        return True, res

    def _cap(self, share: float) -> float:
        budget = self.settings.max_sim_steps
        return np.inf if budget is None else share * budget

    def _n_starts(self, gait: GaitSpec, warm, z0, n_seeds: int) -> int:
        """Rollouts :func:`~trajopt.optim.optimize.choose_start` screens before Gauss-Newton."""
        if z0 is not None:
            return 0
        n = (1 if warm is not None else 0) + (len(GaitParameterization.for_robot(self.env.robot, gait).seeds(n_seeds))
                                              if (n_seeds > 0 or warm is None) else 0)
        return n if n > 1 else 0

    def model_of(self, stage: str) -> str:
        """The motor model a stage's runs obey: the search's, but the speed limit alone in the
        coarse and revisit stages of a torque-speed search that explores under it."""
        if stage != "fine" and self.motor_model == TORQUE_SPEED and self.settings.explore_under_speed:
            return SPEED
        return self.motor_model

    def run(self, stage: str, gait: GaitSpec, start: str, iterations: int, share: float, *, warm=None, z0=None,
            n_seeds: int = 0) -> Result | None:
        """One optimisation and its evaluation, within ``share`` of the budget: skipped when the
        start, one iteration and the evaluation do not fit, and stopped after the iteration
        beyond which the next (its line search at most ``max_backtracks + 1`` trials and a
        Jacobian rollout) and the evaluation might not."""
        replayed, res = self._replayed(stage, gait, start)
        if replayed:
            return res
        cap, options = self._cap(share), GaussNewtonOptions(max_iter=iterations)
        horizon, eval_steps = gait.n_steps(), gait.n_prep + self.settings.eval_cycles * gait.n_cycle
        per_iteration = horizon * (options.max_backtracks + 2)
        target = self.settings.target(self.best)
        if self.total + (self._n_starts(gait, warm, z0, n_seeds) + 1) * horizon + per_iteration + eval_steps > cap:
            self.rows.append(_row(stage, None, gait, start, target, 0, 0, self.total, 0.0, "skipped: budget",
                                  self.model_of(stage)))
            if self.checkpoint is not None:
                self.checkpoint.save_run(self.rows, None)
            self._tick()
            return None

        def within_budget(entry: dict, _partial: Result) -> bool:
            return self.total + entry["sim_steps_total"] + per_iteration + eval_steps > cap

        t0 = time.perf_counter()
        res, failure = None, ""
        try:
            res = optimize_gait(self.env, "walk", gait=gait, speed_bl_per_min=target, heading_deg=self.heading_deg,
                                options=options, warm_start=warm, z0=z0, n_seeds=n_seeds,
                                eval_cycles=self.settings.eval_cycles, robot_spec=self.robot_spec,
                                callback=within_budget, motor_model=self.model_of(stage))
            opt_steps, eval_steps = int(res.evaluation["optimization_sim_steps"]), _evaluation_steps(res)
        except SimulationError as err:       # a start that cannot be simulated: the candidate fails
            failure, opt_steps, eval_steps = f"failed: {err}", 0, 0
        self.total += opt_steps + eval_steps
        row = _row(stage, res, gait, start, target, opt_steps, eval_steps, self.total, time.perf_counter() - t0,
                   failure, self.model_of(stage))
        self.rows.append(row)
        if self.checkpoint is not None:
            self.checkpoint.save_run(self.rows, res)
        if res is not None:
            self.runs.append((row, res))
            if row["upright"] and row["speed_bl_per_min"] > self.best:
                self.best = row["speed_bl_per_min"]
        self.say(f"{stage} cycle {gait.n_cycle} keyframes {gait.n_keyframes}: {row['speed_bl_per_min']:.2f} BL/min "
                 f"({'upright' if row['upright'] else 'fell'}), {self.total:,} simulation steps so far")
        self._tick()
        return res

    def _tick(self) -> None:
        if self.bar is not None:
            self.bar.set_postfix(best=f"{self.best:.2f} BL/min", steps=f"{self.total:,}")
            self.bar.update(1)


def _revisit(search: _Search, settings: SearchSettings, candidates: list[tuple[int, int]]) -> None:
    """The coarse candidates with a shorter cycle than the fastest upright one, again, each
    warm-started from that gait's keyframes (the coarse chain starts the shortest cycle from the
    seeds alone, and walks from short to long)."""
    upright = [(row, res) for row, res in search.runs if row["upright"]]
    if not upright:
        return
    row, best = max(upright, key=lambda p: p[0]["speed_bl_per_min"])
    source = f"cycle {row['n_cycle']}, {row['n_keyframes']} keyframes"
    for n_cycle, n_kf in candidates:
        if n_cycle >= row["n_cycle"]:
            continue
        warm = _KeyframeStart(keyframes_at(np.asarray(best.settings["keyframes"]), n_kf), source)
        search.run("revisit", settings.gait(n_cycle, n_kf), source, settings.coarse_iterations,
                   settings.coarse_share, warm=warm, n_seeds=0)


def search_identity(env: Any, settings: SearchSettings, cycle_steps: int | None, heading_deg: float,
                    motor_model: str = SPEED) -> dict:
    """What a search checkpoint must match to be resumed: the settings, the pinned cycle, the
    heading, the robot (its fingerprint), the contact law, the physics steps per control step and
    the motor model."""
    from soft_envs.envs import robot_fingerprint
    fp = robot_fingerprint(env.robot) or {}
    return json.loads(json.dumps({"settings": asdict(settings), "cycle_steps": cycle_steps,
                                  "heading_deg": float(heading_deg), "robot": fp.get("sha256", env.robot.name),
                                  "contact": env.contact_model, "substeps": int(env.substeps),
                                  "motor_model": motor_model}, default=float))


def fastest_gait(env: Any, *, settings: SearchSettings = SearchSettings(), cycle_steps: int | None = None,
                 contact: str | None = None, heading_deg: float = 0.0, robot_spec: str | None = None,
                 quiet: bool = False, log: Callable[[str], Any] | None = None,
                 checkpoint: str | Path | None = None, resume: bool = False,
                 motor_model: str | None = None) -> tuple[Result, list[dict]]:
    """The fastest upright walk within the motors' limits (module docstring): ``(result,
    table)``. ``env``: a Gymnasium env offering :class:`~soft_envs.envs.GradientEnv`, or a robot
    / name / robot.toml path (``contact``: its contact law). ``cycle_steps``: pin the cycle
    (search keyframes and starts only). ``quiet``: no progress bar. ``motor_model``: the motors'
    law every candidate obeys (``"torque-speed"`` or ``"speed"``, :func:`trajopt.optimize_gait`;
    None: the environment's; ``"ideal"`` is refused: without a limit there is no fastest gait). The result is the chosen
    run's :class:`Result` (evaluated over ``settings.eval_cycles`` cycles); its
    ``settings["search"]`` and ``evaluation["search_sim_steps"]`` record the search; the table
    has one row per optimisation (:data:`TABLE_COLUMNS`), the chosen one marked. Raises
    :class:`~soft_envs.envs.SimulationError` when no candidate can be simulated or none stays
    upright, ValueError when the budget fits none. ``checkpoint``: a folder
    (:func:`search_checkpoint_dir`) that keeps every finished optimisation; ``resume``: continue
    the search interrupted there (:class:`SearchCheckpoint`; without ``resume`` an old one is
    discarded). An interrupted search (Ctrl-C, SIGTERM, SIGHUP) marks it ``interrupted``; a
    finished one removes it."""
    env = as_gradient_env(env, contact=contact)
    model = choose_motor_model(env, motor_model)
    if model == IDEAL:
        raise ValueError("--speed max needs the motors' limits: motor_model 'ideal' has none")
    candidates = settings.candidates(cycle_steps)
    store, replay = None, []
    if checkpoint is not None:
        store = SearchCheckpoint(checkpoint, search_identity(env, settings, cycle_steps, heading_deg, model))
        if resume and store.state_file.is_file():
            replay, _ = store.load()
        elif store.folder.exists():
            store.remove()
        store.start([row for row, _ in replay])
    search = _Search(env, settings, heading_deg, robot_spec, _progress(len(candidates) + settings.n_fine, quiet),
                     log or (lambda text: None), replay, store, model)
    try:
        previous: Result | None = None          # the last candidate's result: the next one's warm start
        for n_cycle, n_kf in candidates:
            warm = None
            if previous is not None:
                warm = _KeyframeStart(keyframes_at(np.asarray(previous.settings["keyframes"]), n_kf),
                                      f"cycle {previous.settings['n_cycle']}, "
                                      f"{previous.settings['n_keyframes']} keyframes")
            res = search.run("coarse", settings.gait(n_cycle, n_kf), warm.settings["source"] if warm else "seeds",
                             settings.coarse_iterations, settings.coarse_share, warm=warm,
                             n_seeds=settings.seeds if warm is not None else max(settings.seeds, 1))
            previous = res if res is not None else previous
        if settings.revisit:
            _revisit(search, settings, candidates)
            if search.bar is not None:                    # the revisits were not known in advance
                search.bar.total = len(search.rows) + settings.n_fine
                search.bar.refresh()
        upright = sorted((p for p in search.runs if p[0]["upright"]), key=lambda p: -p[0]["speed_bl_per_min"])
        for row, res in upright[:settings.n_fine]:
            gait = GaitSpec.from_settings(res.settings)
            search.run("fine", gait, f"coarse cycle {gait.n_cycle}, {gait.n_keyframes} keyframes",
                       settings.fine_iterations, 1.0, z0=res.z)
    except (KeyboardInterrupt, Terminated):
        if store is not None:
            store.mark(search.rows, "interrupted")
        raise
    finally:
        if search.bar is not None:
            search.bar.close()
    rows, total = search.rows, search.total
    runs = [p for p in search.runs if p[0]["motor_model"] == model]       # the result obeys the search's model
    upright = [p for p in runs if p[0]["upright"]]
    if not runs:
        failed = [r["status"] for r in rows if str(r["status"]).startswith("failed")]
        if failed or settings.max_sim_steps is None:
            raise SimulationError(f"--speed max: no candidate could be simulated ({len(failed)} of the {len(rows)} "
                                  f"tried failed{'; the first ' + failed[0] if failed else ''})")
        raise ValueError(f"--speed max: a budget of {settings.max_sim_steps:,} simulation steps fits none of the "
                         f"{len(rows)} candidates (a start, one Gauss-Newton iteration and the evaluation)")
    if not upright:
        raise SimulationError(f"--speed max: none of the {len(rows)} gaits tried stayed upright over "
                              f"{settings.eval_cycles} cycles ({total:,} simulation steps)")
    row, res = max(upright, key=lambda p: p[0]["speed_bl_per_min"])
    row["chosen"] = True
    res.settings["search"] = {"settings": asdict(settings), "cycle_steps_pinned": cycle_steps, "runs": len(rows),
                              "sim_steps": total, "wall_time_s": time.perf_counter() - search.t_start}
    res.evaluation["search_sim_steps"] = total
    res.evaluation["search_wall_time_s"] = time.perf_counter() - search.t_start
    return res, rows


def finish_search(checkpoint: str | Path) -> None:
    """Remove a finished search's checkpoint folder (after its result and table are written)."""
    SearchCheckpoint(checkpoint).remove()


def search_table_paths(result_file: str | Path) -> tuple[Path, Path]:
    """``(NAME.search.csv, NAME.search.md)`` beside the result ``NAME.npz``."""
    p = Path(result_file)
    stem = p.name.removesuffix(".npz")
    return p.with_name(stem + ".search.csv"), p.with_name(stem + ".search.md")


def _cell(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.3f}" if np.isfinite(v) else "nan"
    return str(v)


def write_search_table(rows: list[dict], result_file: str | Path) -> tuple[Path, Path]:
    """Write the search table beside ``result_file`` as CSV and Markdown (atomically); the paths."""
    csv_path, md_path = search_table_paths(result_file)
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=TABLE_COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    atomic_write_bytes(csv_path, buf.getvalue().encode())
    lines = ["| " + " | ".join(TABLE_COLUMNS) + " |", "|" + "---|" * len(TABLE_COLUMNS)]
    lines += ["| " + " | ".join(_cell(r[c]) for c in TABLE_COLUMNS) + " |" for r in rows]
    atomic_write_bytes(md_path, ("\n".join(lines) + "\n").encode())
    return csv_path, md_path
