"""The fastest walk within the motors' limits: ``trajopt optimize ROBOT --speed max``.

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
3. **fine**: the ``n_fine`` (3) fastest upright candidates continue for ``fine_iterations``
   iterations from where they stopped. Three, not two: which coarse gaits come first moves with
   the Gauss-Newton path (a Newton tolerance of 1e-6 m instead of 1e-7 per physics step took
   the Tripod's first coarse candidate from 14.5 to 12.5 BL/min), and at 1e-6 neither of the
   Tripod's two fastest refined gaits held (docs/fidelity.md, "Cost");
4. **hold**: each refined gait is replayed with half, twice and four times its physics steps per
   control step (``hold_factors``, :mod:`trajopt.search.hold`), and the search returns the one
   whose speed holds within ``max_spread`` (5 %) at all of them with the highest slowest speed.
   Measured on the shipped Tripod (Coulomb law, 8.25 ms): the fastest refined gait (8-step cycle,
   20.5 BL/min) walks 18.1-21.6 at 16.5-2.06 ms (19 %), the other (12-step cycle, 16.5 BL/min)
   16.2-16.7 (3.0 %): the search returns the latter. When none holds it returns the fastest
   upright gait and says so. In a budgeted search the replays' steps are reserved before the
   fine stage.

Under the motors' torque-speed line (the default model) the coarse and revisit stages explore
under the speed limit alone and the fine stage tightens their fastest gaits to the line
(``explore_under_speed``, a continuation): started from the seeds under the line, the short
cycles end in gaits that lean rather than walk (measured on the shipped Tripod, Coulomb law: the
8-step cycle at 0.01 BL/min after its coarse iterations, the search's best a 36-step gait at
14.7 BL/min), while the speed limit's 8-step gait moved into the line and refined walks at
20.8 BL/min. The result is made under the search's own model (stage 4 says which).

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

This module runs the search; its parts live in :mod:`trajopt.search`: the settings
(:mod:`~trajopt.search.settings`), the table (:mod:`~trajopt.search.table`) and the checkpoint
(:mod:`~trajopt.search.checkpoint`), re-exported here.
"""
from __future__ import annotations

import math

import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from soft_envs.envs import SimulationError, as_gradient_env

from .hardware.signals import Terminated
from .optim.gait import GaitSpec
from .optim.gauss_newton import GaussNewtonOptions
from .optim.ensemble import ensemble_substeps
from .optim.motor_limit import IDEAL, SPEED, TORQUE_SPEED, choose_motor_model
from .optim.optimize import optimize_gait
from .optim.parameterization import GaitParameterization
from .results.result import Result
from .search.checkpoint import SearchCheckpoint, finish_search, search_checkpoint_dir, search_identity
from .search.hold import FASTEST_HELD, SLOWEST_BEST, choose_gait, hold_cost, hold_stage
from .search.settings import SEARCH_EVAL_CYCLES, SearchSettings
from .search.table import TABLE_COLUMNS, search_table_paths, table_row, write_search_table

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
    if "evaluation_sim_steps" in res.evaluation:            # an ensemble's: every member's, in default steps
        return int(round(res.evaluation["evaluation_sim_steps"]))
    return int(s["n_prep"]) + int(s["eval_cycles"]) * int(s["n_cycle"])



def _progress(total: int, quiet: bool, per_item: bool = True):
    """A bar on a terminal; plain lines otherwise (one per run unless ``per_item`` is False, as
    when a log prints each run already) and a heartbeat after 30 s without one."""
    if quiet:
        return None
    from .progress import Progress
    return Progress(total, "--speed max", "run", per_item=per_item)



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
        self.reserve = 0                 # steps kept for the hold stage's replays
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
        row.setdefault("credible_bl_per_min", row["speed_bl_per_min"])      # checkpoints of before ensembles
        for key, value in (("slowest_bl_per_min", float("nan")), ("spread", float("nan")), ("holds", ""),
                           ("hold_sim_steps", 0)):
            row.setdefault(key, value)                                        # checkpoints of before hold checks
        self.rows.append(row)
        self.total = int(row["total_sim_steps"])
        if res is not None:
            self.runs.append((row, res))
            if row["upright"] and row["credible_bl_per_min"] > self.best:
                self.best = row["credible_bl_per_min"]
        self.say(f"{stage} cycle {gait.n_cycle} keyframes {gait.n_keyframes}: {row['speed_bl_per_min']:.2f} BL/min "
                 f"(from the checkpoint)")
        self._tick()
        return True, res

    def cap(self, share: float) -> float:
        budget = self.settings.max_sim_steps
        return np.inf if budget is None else share * budget - self.reserve

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

    def costs(self, gait: GaitSpec, options: GaussNewtonOptions = GaussNewtonOptions()) -> tuple[int, int, int]:
        """``(horizon, one iteration, evaluation)``: the simulation steps of a rollout of ``gait``'s
        horizon, of one Gauss-Newton iteration at most (its line search and a Jacobian rollout) and
        of its evaluation, in steps of the default physics (an ensemble's members weighted)."""
        weight = sum(ensemble_substeps(self.env, self.settings.ensemble)) / int(self.env.substeps)
        horizon = int(math.ceil(weight * gait.n_steps()))
        eval_steps = int(math.ceil(weight * (gait.n_prep + self.settings.eval_cycles * gait.n_cycle)))
        return horizon, horizon * (options.max_backtracks + 2), eval_steps

    def run(self, stage: str, gait: GaitSpec, start: str, iterations: int, share: float, *, warm=None, z0=None,
            n_seeds: int = 0) -> Result | None:
        """One optimisation and its evaluation, within ``share`` of the budget: skipped when the
        start, one iteration and the evaluation do not fit, and stopped after the iteration
        beyond which the next (its line search at most ``max_backtracks + 1`` trials and a
        Jacobian rollout) and the evaluation might not."""
        replayed, res = self._replayed(stage, gait, start)
        if replayed:
            return res
        cap, options = self.cap(share), GaussNewtonOptions(max_iter=iterations)
        horizon, per_iteration, eval_steps = self.costs(gait, options)
        target = self.settings.target(self.best)
        if self.total + (self._n_starts(gait, warm, z0, n_seeds) + 1) * horizon + per_iteration + eval_steps > cap:
            self.rows.append(table_row(stage, None, gait, start, target, 0, 0, self.total, 0.0, "skipped: budget",
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
                                callback=within_budget, motor_model=self.model_of(stage),
                                ensemble=self.settings.ensemble)
            opt_steps, eval_steps = int(res.evaluation["optimization_sim_steps"]), _evaluation_steps(res)
        except SimulationError as err:       # a start that cannot be simulated: the candidate fails
            failure, opt_steps, eval_steps = f"failed: {err}", 0, 0
        self.total += opt_steps + eval_steps
        row = table_row(stage, res, gait, start, target, opt_steps, eval_steps, self.total, time.perf_counter() - t0,
                   failure, self.model_of(stage))
        self.rows.append(row)
        if self.checkpoint is not None:
            self.checkpoint.save_run(self.rows, res)
        if res is not None:
            self.runs.append((row, res))
            if row["upright"] and row["credible_bl_per_min"] > self.best:
                self.best = row["credible_bl_per_min"]
        credible = (f", credible {row['credible_bl_per_min']:.2f}" if self.settings.ensemble else "")
        self.say(f"{stage} cycle {gait.n_cycle} keyframes {gait.n_keyframes}: {row['speed_bl_per_min']:.2f} BL/min"
                 f"{credible} ({'upright' if row['upright'] else 'fell'}), {self.total:,} simulation steps so far")
        self._tick()
        return res

    def _tick(self) -> None:
        if self.bar is not None:
            self.bar.set_postfix(best=f"{self.best:.2f} BL/min", steps=f"{self.total:,}")
            self.bar.update(1)


def _hold_reserve(search: _Search, settings: SearchSettings, fine: list[Result]) -> int:
    """The steps a budgeted search keeps for the hold stage's replays of the gaits to refine,
    when the budget left then still fits a refinement of each (its start, one iteration and its
    evaluation); else none (a refined gait matters more than its check)."""
    if settings.max_sim_steps is None or not fine:
        return 0
    reserve = sum(hold_cost(search.env, settings, res.settings) for res in fine)
    need = 0
    for res in fine:
        horizon, per_iteration, eval_steps = search.costs(GaitSpec.from_settings(res.settings))
        need += horizon + per_iteration + eval_steps
    return reserve if search.total + need + reserve <= settings.max_sim_steps else 0


def _revisit(search: _Search, settings: SearchSettings, candidates: list[tuple[int, int]]) -> None:
    """The coarse candidates with a shorter cycle than the fastest upright one, again, each
    warm-started from that gait's keyframes (the coarse chain starts the shortest cycle from the
    seeds alone, and walks from short to long)."""
    upright = [(row, res) for row, res in search.runs if row["upright"]]
    if not upright:
        return
    row, best = max(upright, key=lambda p: p[0]["credible_bl_per_min"])
    source = f"cycle {row['n_cycle']}, {row['n_keyframes']} keyframes"
    shorter = [(n_cycle, n_kf) for n_cycle, n_kf in candidates if n_cycle < row["n_cycle"]]
    if search.bar is not None:                # the revisits were not known in advance
        search.bar.total = len(search.rows) + len(shorter) + settings.n_fine
        search.bar.refresh()
    for n_cycle, n_kf in shorter:
        warm = _KeyframeStart(keyframes_at(np.asarray(best.settings["keyframes"]), n_kf), source)
        search.run("revisit", settings.gait(n_cycle, n_kf), source, settings.coarse_iterations,
                   settings.coarse_share, warm=warm, n_seeds=0)



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
    bar = _progress(len(candidates) + settings.n_fine, quiet, per_item=log is None)
    search = _Search(env, settings, heading_deg, robot_spec, bar,
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
        upright = sorted((p for p in search.runs if p[0]["upright"]), key=lambda p: -p[0]["credible_bl_per_min"])
        search.reserve = _hold_reserve(search, settings, [res for _, res in upright[:settings.n_fine]])
        for row, res in upright[:settings.n_fine]:
            gait = GaitSpec.from_settings(res.settings)
            search.run("fine", gait, f"coarse cycle {gait.n_cycle}, {gait.n_keyframes} keyframes",
                       settings.fine_iterations, 1.0, z0=res.z)
        search.reserve = 0
        hold_stage(search, settings, model)
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
    row, res, chosen_by = choose_gait(upright, settings.max_spread)
    if chosen_by != FASTEST_HELD and any(isinstance(r["holds"], bool) for r, _ in upright):
        spread = (f", spread {100 * row['spread']:.1f} %" if isinstance(row["holds"], bool) and np.isfinite(row["spread"])
                  else ", it fell at another physics step" if isinstance(row["holds"], bool) else "")
        which = ("the one with the highest slowest speed" if chosen_by.startswith(SLOWEST_BEST)
                 else "the fastest upright one")
        search.say(f"no refined gait holds its speed within {100 * settings.max_spread:g} % at other physics "
                   f"steps: returning {which} ({row['speed_bl_per_min']:.2f} BL/min{spread})")
    row["chosen"] = True
    res.settings["search"] = {"settings": asdict(settings), "cycle_steps_pinned": cycle_steps, "runs": len(rows),
                              "sim_steps": total, "wall_time_s": time.perf_counter() - search.t_start,
                              "chosen_by": chosen_by}
    res.evaluation["search_sim_steps"] = total
    res.evaluation["search_wall_time_s"] = time.perf_counter() - search.t_start
    return res, rows
