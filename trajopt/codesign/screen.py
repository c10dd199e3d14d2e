"""Design screening: the coarse stage of co-design, before joint Gauss-Newton.

Gauss-Newton is local, and a walking gait under the Coulomb law is a rugged function of the
design: feet that stick or slip one step earlier change the stride, and a gait tuned to one
design can barely walk on a neighbour (measured on the Tripod's fastest gait: the middle leg
twice as stiff walks at 0.45 BL/min with the shipped design's keyframes, and at 32.6 once the
keyframes follow for 5 Gauss-Newton iterations; the shipped design: 26.8). So co-design first
screens designs a finite step away in a few directions and keeps the best; then
:mod:`trajopt.codesign.joint` refines gait and design together from there.

A design is scored by the *credible speed* of a gait for it (``ScreenSettings.score`` says how
the gait is found, below), the protocol of ``--speed max``'s hold stage
(:func:`trajopt.search.hold.hold_check`): the gait, upright over 10 cycles with the motors' limit on
at its own physics (4 steps of 8.25 ms per 33-ms control step), replayed with ``hold_factors``
times its physics steps (default half, twice and four times: 16.5, 4.125 and 2.06 ms), gives the
speeds ``v_n`` at n = 2, 4, 8, 16 steps per control step and

    slowest = min_n v_n,    spread = (max_n v_n - slowest) / slowest,    holds = spread <= 5 %.

Candidates rank by the slowest speed, the credible speed (``rank="slowest"``, the default:
:func:`~trajopt.search.hold.slowest_rank`): a design is kept for what its gait walks at the least
favourable physics step, which is a speed of the design, not of the step, whether or not the gait
spreads more than 5 % (the joint stage and the report ask that of the co-designed gait). A gait that
falls at any step or walks backwards is never better (the rank of not upright). ``rank="holds-first"``
ranks by ``(holds, slowest)`` (:func:`~trajopt.search.hold.credible_rank`, the rule until
2026-12-07): a gait that holds beats every gait that does not, whatever their speeds. Measured on
the Tripod (docs/codesign.md): holding first, its screening stopped at 16.62 BL/min at the slowest
step, a flat neighbourhood of designs whose gaits hold; by the slowest speed, round 2 kept a design
whose gait spread 6.2 % (17.23 at its slowest), and from there rounds 3 and 4 found designs whose
gaits hold again at 17.51 and 17.87. ``hold_factors=()`` scores on the own physics alone (the
slowest is then the speed and every upright forward gait holds).

How the gait is found:

* ``"warm"`` (default): ``iterations`` Gauss-Newton iterations warm-started from the current
  keyframes. The gait follows the design step by step, so the pair found is fast, but the gait
  is the end of a chain of warm starts: on the Tripod (Coulomb) the co-designed robot and gait
  reach 1.40x the shipped design's fastest gait, while ``--speed max`` on the written robot from
  scratch finds 1.05x;
* ``"scratch"``: as ``trajopt optimize --speed max`` finds a gait on the baseline's cycle and
  keyframe count (the search pinned there: the same two runs, coarse from the seeds and fine,
  as that candidate's in the full search): the design's merit for that search. The ``warm``
  best-scored candidates also get a warm-started gait, and keep the faster one.

The candidates around the current design theta (:func:`candidates`):

* each region's modulus times ``modulus_factors`` (0.5x, 2x; clipped to the bounds);
* each leg (or mirror pair of legs) ``leg_step`` longer and shorter;
* the via points moved along the steepest descent of the co-design objective
  (:class:`~trajopt.codesign.problem.CodesignProblem`, one rollout with sensitivities) restricted
  to the routing, scaled so the largest coordinate moves ``routing_steps`` (1 and 2 mm), then
  projected onto the linearised clearance (a point on a face slides along it).

Candidates that break the clearance or mass constraints are skipped (listed). Greedy rounds:
each round scores the current design and the candidates around it, the best-scored candidate
that beats the current design wins, and the next round starts from it; it stops after
``rounds`` rounds or a round without a better design.

A round's scores are independent of each other: with ``workers`` > 1 they run in that many
processes (:class:`concurrent.futures.ProcessPoolExecutor`, started by ``spawn``, one compute
thread each), and the rows, the winner and every figure are the same as one after another in
this process (``tests/test_codesign_screen.py``). After each round ``round_done`` receives where
the screening stands (:class:`ScreenProgress`); a run interrupted between rounds continues from
it (``resume``).

The workers end with the screening however it ends: on an exception, Ctrl-C, SIGTERM or SIGHUP
(raised as exceptions by the command line) they are terminated; a worker whose parent is gone
(killed by SIGKILL) ends itself (:mod:`trajopt.workers`: ``PR_SET_PDEATHSIG`` on Linux, and a
thread that watches its parent everywhere, started before the worker imports the work), so that
no worker outlives the run and holds its stdout. A worker that dies
(the out-of-memory killer, ``kill -9``) ends the screening with :class:`WorkerDied`. The scoring
and its processes: :mod:`trajopt.codesign.score`.
"""
from __future__ import annotations

from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from soft_envs.envs import SimulationError

from ..fastest import SearchSettings
from ..optim.qp import QPError, nearest_feasible
from ..search.hold import HOLD_FACTORS, MAX_SPREAD, credible_rank, slowest_rank
from .problem import CodesignProblem
from .score import Score, ScoreJob, Scorer, WorkerDied, score_gait

__all__ = ["ScreenSettings", "ScreenProgress", "Score", "candidates", "screen_designs", "SCORES", "WorkerDied"]

#: how a candidate design is scored (module docstring)
SCORES = ("warm", "scratch")
#: how the scored candidates are ranked (module docstring)
RANKS = ("slowest", "holds-first")


@dataclass(frozen=True)
class ScreenSettings:
    """What :func:`screen_designs` tries (module docstring); ``rounds=0``: no screening."""

    rounds: int = 4
    iterations: int = 5
    modulus_factors: tuple[float, ...] = (0.5, 2.0)
    leg_step: float = 3e-3
    routing_steps: tuple[float, ...] = (1e-3, 2e-3)
    eval_cycles: int = 10
    warm: int = 2
    score: str = "warm"
    hold_factors: tuple[float, ...] = HOLD_FACTORS
    max_spread: float = MAX_SPREAD
    rank: str = "slowest"

    def __post_init__(self):
        if self.score not in SCORES:
            raise ValueError(f"screening score must be one of {', '.join(SCORES)}, got {self.score!r}")
        if self.rank not in RANKS:
            raise ValueError(f"screening rank must be one of {', '.join(RANKS)}, got {self.rank!r}")

    def rank_of(self, score: Score | None) -> tuple[int, float]:
        """``score``'s place in this screening's order (None: not scored, never better)."""
        check = None if score is None else score.hold
        return slowest_rank(check) if self.rank == "slowest" else credible_rank(check)

    @classmethod
    def quick(cls) -> "ScreenSettings":
        return cls(rounds=1, iterations=1, modulus_factors=(2.0,), routing_steps=(), eval_cycles=2, warm=1,
                   hold_factors=(0.5,))


def candidates(problem: CodesignProblem, theta: np.ndarray, z: np.ndarray, settings: ScreenSettings
               ) -> list[tuple[str, np.ndarray]]:
    """``(label, theta)`` of the designs a round screens around ``theta`` (module docstring)."""
    names = problem.block.names
    lo, hi = problem.shipped.bounds[:, 0], problem.shipped.bounds[:, 1]
    out: list[tuple[str, np.ndarray]] = []

    def add(label: str, th: np.ndarray) -> None:
        th = np.clip(th, lo, hi)
        if not np.array_equal(th, theta):
            out.append((label, th))

    for i, n in enumerate(names):
        kind, what = n.split(":", 1)
        if kind == "stiffness":
            for f in settings.modulus_factors:
                th = theta.copy()
                th[i] *= f
                add(f"{what} modulus x{f:g}", th)
        elif kind == "legs":
            for s in (settings.leg_step, -settings.leg_step):
                th = theta.copy()
                th[i] += s
                add(f"{what} {1e3 * s:+g} mm", th)
    routing = np.array([n.startswith("routing:") for n in names])
    if routing.any() and settings.routing_steps:
        w = np.concatenate([z, theta])
        r, J, _ = problem(w, True)                     # linearises at theta
        g = (J.T @ r)[problem.nz:]
        d = np.where(routing, -g * problem.theta_range ** 2, 0.0)
        if np.abs(d).max() > 0:
            d /= np.abs(d).max()
            lin = problem.linearised_constraints(w, trust=False)    # clearance kept: points on a face slide along it
            for step in settings.routing_steps:
                try:
                    moved = nearest_feasible(np.concatenate([z, theta + step * d]), lin, anchor=w)
                except QPError:
                    continue
                add(f"via points {1e3 * step:g} mm along the steepest descent", moved[problem.nz:])
    return out


def _better(a: Score, b: Score | None, settings: ScreenSettings) -> bool:
    """``a`` ranks above ``b`` in the screening's order (``settings.rank``; None: not scored)."""
    return settings.rank_of(a) > settings.rank_of(b)


@dataclass
class ScreenProgress:
    """Where a screening stands after a round (JSON-able through :func:`dataclasses.asdict`):
    the rounds done, the designs it moved to (in order: the path a resumed run replays), the best
    design, its gait and that gait's credible speed so far (``speed``: the slowest over the hold
    replays; ``holds``: whether it holds; ``own``: its speed at the own physics), the rows, and
    whether it has ended."""

    rounds_done: int
    theta: list[float]
    z: list[float]
    speed: float
    path: list[list[float]] = field(default_factory=list)
    rows: list[dict] = field(default_factory=list)
    finished: bool = False
    holds: bool = False
    own: float = float("nan")


def screen_designs(problem: CodesignProblem, theta: np.ndarray, z: np.ndarray, speed: float, target: float,
                   settings: ScreenSettings = ScreenSettings(), *, search: SearchSettings = SearchSettings(),
                   workers: int = 1, resume: ScreenProgress | None = None,
                   log: Callable[[str], Any] = lambda t: None, done: Callable[[dict], None] | None = None,
                   round_done: Callable[[ScreenProgress], None] | None = None, holds: bool = False) -> ScreenProgress:
    """Where the screening ends (:class:`ScreenProgress`): the design chosen, its best-ranked
    gait found and that gait's credible speed (``theta, z, speed`` as given when no candidate is better),
    the designs moved to, and one row per run. ``target``: the gaits' tracking target [BL/min];
    ``done(row)`` after each candidate, ``round_done(progress)`` after each round; ``workers``:
    processes scoring a round's candidates (module docstring); ``resume``: continue from a
    ``round_done`` progress (``problem`` must stand at its last design: :meth:`CodesignProblem.move_to`
    along its path); ``speed`` and ``holds``: the given gait's credible speed and whether it holds.

    A candidate's score (module docstring) is the credible rank of its gait warm-started from the
    current keyframes, or found from scratch as ``--speed max`` (``search``) finds it on the
    current cycle and keyframe count (``settings.score``); the current design is scored the same
    way. With scratch scores the ``warm`` best-ranked candidates also get a gait warm-started
    from the current keyframes, and keep the better-ranked."""
    if resume is None:
        state = ScreenProgress(0, np.asarray(theta, dtype=np.float64).tolist(),
                               np.asarray(z, dtype=np.float64).tolist(), float(speed), holds=bool(holds))
    else:
        state = resume
    scorer = Scorer(workers)
    try:
        while not state.finished and state.rounds_done < settings.rounds:
            _screen_round(problem, state, target, settings, search, scorer, log, done)
            if round_done is not None:
                round_done(state)
    except BrokenProcessPool:
        how = scorer.how_they_died()
        scorer.close(terminate=True)
        raise WorkerDied(how, state.rounds_done, settings.rounds) from None
    except BaseException:
        scorer.close(terminate=True)
        raise
    scorer.close()
    return state


def _screen_round(problem: CodesignProblem, state: ScreenProgress, target: float, settings: ScreenSettings,
                  search: SearchSettings, scorer: Scorer, log, done) -> None:
    """One greedy round from ``state``'s design (module docstring); updates ``state``."""
    rnd = state.rounds_done + 1
    start_theta, start_z = np.asarray(state.theta), np.asarray(state.z)
    if not np.array_equal(start_theta, problem.anchor):
        problem.move_to(start_theta)
        state.path.append(list(state.theta))
    todo = [("current design", start_theta)] + candidates(problem, start_theta, start_z, settings)
    rows: list[dict] = []
    jobs: list[ScoreJob] = []
    for label, th in todo:
        rows.append({"round": rnd, "candidate": label, **Score(float("nan"), None, None, 0, "").row(),
                     "warm_bl_per_min": float("nan"), "status": "", "sim_steps": 0})
        try:
            robot = problem.robot_at(th)
            why = problem.design_violation(robot)
        except SimulationError as err:
            rows[-1]["status"] = f"failed: {err}"
            continue
        if why is not None:
            rows[-1]["status"] = f"skipped: {why}"
            continue
        jobs.append(ScoreJob(robot, problem.contact, problem.newton, problem.substeps, problem.gait, target, settings,
                              start_z if settings.score == "warm" else None, search, problem.motor_model))
    scores = scorer.map(jobs)                  # in the order of the rows left unscored above
    scored: list[tuple[Score, str, np.ndarray]] = []
    for row, (label, th) in zip(rows, todo):
        if row["status"] == "":
            out = next(scores)
            if isinstance(out, str):
                row["status"] = f"failed: {out}"
            else:
                problem.sim_steps += out.steps
                row.update(out.row(), sim_steps=out.steps, status=out.status)
                scored.append((out, label, th))
        state.rows.append(row)
        log(f"  screen round {rnd}: {label}: {_describe(row)} "
            f"({'warm-started' if settings.score == 'warm' else 'from scratch'}) {row['status']}")
        if done is not None:
            done(row)
    current = scored[0][0] if scored and scored[0][1] == "current design" else None
    ranked = sorted((s for s in scored if s[1] != "current design" and s[0].hold is not None),
                    key=lambda s: settings.rank_of(s[0]), reverse=True)   # stable: ties keep the candidates' order
    winner = None
    for score, label, th in ranked[:settings.warm]:
        if not _better(score, current, settings):
            break
        gait = score
        if settings.score == "scratch":       # also a gait from the current keyframes
            env = problem.env_of(problem.robot_at(th))
            warm = score_gait(env, problem.gait, target, settings, start_z, search)
            problem.sim_steps += warm.steps
            row = next(r for r in rows if r["candidate"] == label)
            row.update(warm_bl_per_min=warm.slowest, sim_steps=row["sim_steps"] + warm.steps)
            log(f"  screen round {rnd}: {label}: warm-started {_describe(warm.row())}")
            gait = warm if _better(warm, score, settings) else score
        if winner is None:
            winner = label
            state.theta, state.z = np.asarray(th).tolist(), np.asarray(gait.z).tolist()
            state.speed, state.holds, state.own = gait.slowest, bool(gait.hold["holds"]), gait.own
    best = _describe(ranked[0][0].row()) if ranked else "nothing upright"
    log(f"screen round {rnd}: {'best ' + winner if winner else 'no better design'} (best candidate {best}; the "
        f"current design's {_describe(current.row()) if current is not None else 'not upright'}; gait "
        f"{state.speed:.2f} BL/min at the slowest step)")
    state.rounds_done = rnd
    state.finished = winner is None or rnd >= settings.rounds


def _describe(row: dict) -> str:
    """A score in a line: its own speed, its slowest, spread and whether it holds."""
    if not np.isfinite(row["slowest_bl_per_min"]):
        return f"{row['own_bl_per_min']:.2f} BL/min, falls at another physics step or not upright"
    return (f"{row['own_bl_per_min']:.2f} BL/min, slowest {row['slowest_bl_per_min']:.2f}, spread "
            f"{100 * row['spread']:.1f} % ({'holds' if row['holds'] else 'does not hold'})")
