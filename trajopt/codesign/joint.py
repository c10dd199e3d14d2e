"""Gauss-Newton on gait and design together, in stages with a rising target.

:func:`optimise_jointly` runs :func:`trajopt.optim.gauss_newton.gauss_newton` on a
:class:`~trajopt.codesign.problem.CodesignProblem` in ``stages``: each stage tracks a straight
line at ``max(min_target, target_margin * best)`` BL/min, where ``best`` is the fastest upright
gait found so far (the shipped design's fastest gait at first: co-design asks for more than is
known to be possible, as ``--speed max`` does), for at most ``iterations`` iterations under the
motors' limit, the bounds and the linearised clearance and mass constraints. After each stage the
gait on the current design is evaluated (:func:`trajopt.evaluation.evaluate_controls`, 10 cycles
after the prep phase, upright required) and replayed at the hold stage's other physics steps
(``hold_factors``, :func:`trajopt.search.hold.hold_replays`: 16.5, 4.125 and 2.06 ms around the
default 8.25 ms). A stage is accepted only when its credible rank improves,

    (holds, slowest)_stage > (holds, slowest)_best    (:func:`trajopt.search.hold.credible_rank`),

a gait that holds within ``max_spread`` beating every one that does not, the slowest speed
deciding among gaits alike; the next stage starts from the best accepted point. The search stops
after ``stages`` stages, when a stage is not accepted, or when it gains less than ``min_gain``
(relative, in the slowest speed) without changing whether the gait holds.

``ensemble``: physics steps per control step of further members; Gauss-Newton minimises the
members' mean objective, :class:`~trajopt.codesign.ensemble.CodesignEnsemble`. Default
:data:`~trajopt.optim.ensemble.DEFAULT_ENSEMBLE`, ``(2, 8)``: 2x coarser and 2x finer steps than
the default 4, as ``trajopt optimize --ensemble``; ``()``: the default physics alone. Chosen by
measurement (docs/codesign.md, "On the converged physics"): the screened Puppy's stages, refused
on the default physics alone and with ``(8,)``, were all accepted with ``(2, 8)``, +12 % at the
slowest step; the Tripod's were refused by all three (measured before the joint step's QP was
solved in Jacobi-scaled variables, :func:`trajopt.optim.qp.solve_qp`: until then no Tripod step was
accepted at all; since, its four stages are, +6.8 % at the slowest step, docs/codesign.md).

Resumable: the :class:`JointState` (JSON) is handed to ``checkpoint`` after every iteration. It
holds the designs Gauss-Newton linearised at, in order (``path``): a design block's derivatives
hold at its own robot and :meth:`DesignParameters.moved_to` rebuilds the block at the next one,
so replaying the path (:func:`replay_path`) rebuilds the exact block of the interrupted run.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import Any, Callable

import numpy as np

from soft_envs.envs import SimulationError

from ..evaluation import evaluate_controls
from ..search.hold import HOLD_FACTORS, MAX_SPREAD, credible_rank, describe_hold, hold_replays
from ..search.settings import SEARCH_EVAL_CYCLES
from ..optim.ensemble import DEFAULT_ENSEMBLE
from ..optim.gauss_newton import GaussNewtonOptions, gauss_newton
from .ensemble import CodesignEnsemble
from .problem import CodesignProblem

__all__ = ["JointSettings", "JointState", "optimise_jointly", "replay_path", "evaluate_design"]


@dataclass(frozen=True)
class JointSettings:
    """The stages of :func:`optimise_jointly` (module docstring). ``max_rejections``: rejected
    Gauss-Newton steps in a row before a stage stalls; each multiplies the damping by 10, so 6
    take it from 1e-4 to 100. The joint objective is rugged in the gait: on the screened Tripod
    the first accepted step came at a damping of 1 (the 5th try), which the default 3 never
    reached."""

    stages: int = 4
    iterations: int = 6
    target_margin: float = 1.1
    min_target: float = 20.0
    min_gain: float = 0.01
    eval_cycles: int = SEARCH_EVAL_CYCLES
    hold_factors: tuple[float, ...] = HOLD_FACTORS
    max_spread: float = MAX_SPREAD
    ensemble: tuple[int, ...] = DEFAULT_ENSEMBLE
    max_rejections: int = 6

    def target(self, best: float) -> float:
        return max(self.min_target, self.target_margin * best)

    @classmethod
    def quick(cls) -> "JointSettings":
        """Small enough for tests and CI."""
        return cls(stages=1, iterations=2, min_target=0.0, eval_cycles=2, hold_factors=(0.5,))


@dataclass
class JointState:
    """Where a joint optimisation stands (JSON-able: :meth:`to_dict` / :meth:`from_dict`)."""

    w: list[float]
    stage: int = 0
    iteration: int = 0                       # Gauss-Newton iterations done in this stage
    lam: float | None = None
    rejections: int = 0
    path: list[list[float]] = field(default_factory=list)     # designs linearised at, in order
    best_speed: float = 0.0                  # the best point's credible speed: its slowest over the hold replays
    best_holds: bool = False                 # and whether its speed holds (trajopt.search.hold.credible_rank)
    best_w: list[float] | None = None
    best_evaluation: dict[str, Any] | None = None
    best_path_len: int = 0                   # the best point's design is path[:best_path_len]'s last
    stage_rows: list[dict] = field(default_factory=list)
    history: list[dict] = field(default_factory=list)
    sim_steps: int = 0
    wall_time_s: float = 0.0
    done: bool = False
    screened: bool = False                   # the screening stage (trajopt.codesign.screen) is done
    screen_rows: list[dict] = field(default_factory=list)
    screen_progress: dict | None = None      # an unfinished screening after its last round (ScreenProgress)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "JointState":
        return cls(**d)


def replay_path(problem: CodesignProblem, path: list[list[float]]):
    """``(block, anchor)`` at the end of ``path`` (the designs an interrupted run linearised at),
    moved there from the shipped design one design at a time, as the run did."""
    block, anchor = problem.shipped, problem.shipped.values.copy()
    for theta in path:
        block, anchor = problem.moved(block, anchor, theta)
    return block, anchor


def evaluate_design(problem: CodesignProblem, w: np.ndarray, eval_cycles: int, hold_factors=HOLD_FACTORS,
                    max_spread: float = MAX_SPREAD) -> dict[str, Any]:
    """The gait ``w``'s keyframes on ``w``'s design, played for ``eval_cycles`` cycles after the
    prep phase (:func:`trajopt.evaluation.evaluate_controls`) and, when upright, replayed at the
    other physics steps of ``hold_factors`` (``ev["hold"]``, :func:`~trajopt.search.hold.hold_replays`);
    counts the simulation steps."""
    z, theta = problem.split(w)
    env = problem.env_of(problem.robot_at(theta))
    u = problem.controls(z, eval_cycles)
    gait = problem.gait
    try:
        ev = evaluate_controls(env, u, n_prep=gait.n_prep, n_cycle=gait.n_cycle)
    except SimulationError as err:
        ev = {"speed_bl_per_min": float("nan"), "upright": False, "sim_failure": str(err)}
    problem.sim_steps += len(u)
    if ev.get("upright") and "sim_failure" not in ev:
        ev["hold"] = hold_replays(env, u, gait.n_prep, gait.n_cycle, ev, factors=hold_factors, max_spread=max_spread)
        problem.sim_steps += ev["hold"]["steps"]
    return ev


def _json_entry(entry: dict) -> dict:
    out = {}
    for k, v in entry.items():
        if k in ("z", "lam"):
            continue
        if isinstance(v, (np.floating, np.integer, np.bool_)):
            v = v.item()
        out[k] = v
    return out


def optimise_jointly(problem: CodesignProblem, state: JointState, settings: JointSettings = JointSettings(), *,
                     checkpoint: Callable[[JointState], None] | None = None,
                     progress: Callable[[dict], None] | None = None,
                     log: Callable[[str], Any] = lambda text: None) -> JointState:
    """Run (or continue) the stages from ``state`` (a fresh one: ``JointState(w=list(w0),
    best_speed=credible speed of the start, best_holds=whether it holds)``); returns the final
    state, ``best_w`` the best-ranked point (module docstring). ``checkpoint(state)`` after every iteration and stage; ``progress(entry)`` after
    every iteration."""
    t0 = time.perf_counter() - state.wall_time_s
    steps0 = problem.sim_steps - state.sim_steps
    lo, hi = problem.bounds()
    if state.best_w is None:
        state.best_w, state.best_path_len = list(state.w), len(state.path)
    problem.block, problem.anchor = replay_path(problem, state.path)
    best_block = replay_path(problem, state.path[:state.best_path_len])
    gn_problem = CodesignEnsemble(problem, settings.ensemble) if settings.ensemble else problem

    def sync() -> None:
        state.sim_steps = problem.sim_steps - steps0
        state.wall_time_s = time.perf_counter() - t0

    def moved() -> None:
        theta = problem.anchor.tolist()
        if not state.path or state.path[-1] != theta:
            state.path.append(theta)

    while state.stage < settings.stages and not state.done:
        target = settings.target(state.best_speed)
        problem.set_target(target)
        remaining = settings.iterations - state.iteration

        def on_iteration(entry: dict) -> bool | None:
            state.w = [float(v) for v in entry["z"]]
            state.lam, state.iteration = float(entry["lam"]), state.iteration + 1
            state.rejections = 0 if entry["accepted"] else state.rejections + 1
            state.history.append(_json_entry({**entry, "stage": state.stage, "target_bl_per_min": target}))
            moved()
            sync()
            if progress is not None:
                progress(entry)
            if checkpoint is not None:
                checkpoint(state)
            return None

        if remaining > 0:
            gn = gauss_newton(gn_problem, np.asarray(state.w), lo, hi,
                              GaussNewtonOptions(max_iter=remaining, max_rejections=settings.max_rejections),
                              callback=on_iteration, lam=state.lam, first_iteration=state.iteration + 1,
                              rejections=state.rejections, constraints=gn_problem.linearised_constraints)
            moved()
            state.w = gn.z.tolist()
            status = gn.status
        else:
            status = "resumed"
        w = np.asarray(state.w)
        ev = evaluate_design(problem, w, settings.eval_cycles, settings.hold_factors, settings.max_spread)
        speed, upright = float(ev.get("speed_bl_per_min", float("nan"))), bool(ev.get("upright", False))
        hold = ev.get("hold")
        rank, best_rank = credible_rank(hold), (int(state.best_holds), state.best_speed)
        gain = (rank[1] - state.best_speed) / max(state.best_speed, 1e-12) if np.isfinite(rank[1]) else float("nan")
        row = {"stage": state.stage + 1, "target_bl_per_min": target, "iterations": state.iteration,
               "status": status, "speed_bl_per_min": speed, "upright": upright,
               "slowest_bl_per_min": float("nan") if hold is None else hold["slowest"],
               "spread": float("nan") if hold is None else hold["spread"],
               "holds": bool(hold and hold["holds"]), "gain": gain}
        state.stage_rows.append(row)
        improved = rank > best_rank
        row["accepted"] = improved
        if improved:
            state.best_speed, state.best_holds, state.best_w, state.best_evaluation = rank[1], bool(rank[0]), list(state.w), ev
            state.best_path_len, best_block = len(state.path), (problem.block, problem.anchor)
        else:                                    # the next stage starts from the best point
            state.w, state.path = list(state.best_w), state.path[:state.best_path_len]
            problem.block, problem.anchor = best_block
        log(f"co-design stage {state.stage + 1}/{settings.stages}: tracking target {target:.1f} BL/min (not enforced), "
            f"{state.iteration} iterations ({status}): {speed:.2f} BL/min"
            f"{'; ' + describe_hold(hold) if hold else ' (fell over)'}; {'accepted' if improved else 'not accepted'}, "
            f"best so far {state.best_speed:.2f} at the slowest step ({'holds' if state.best_holds else 'does not hold'})")
        state.stage += 1
        state.iteration, state.lam, state.rejections = 0, None, 0
        if not improved or (rank[0] == best_rank[0] and gain < settings.min_gain):
            state.done = True
        sync()
        if checkpoint is not None:
            checkpoint(state)
    state.done = True
    sync()
    return state
