"""Scoring the screening's candidates (:mod:`trajopt.codesign.screen`): one design's gait and its
credible speed, in this process or in worker processes.

:func:`score_gait` finds a gait for a design (warm-started Gauss-Newton, or ``--speed max`` pinned to
the current cycle and keyframes) and replays it at the hold stage's other physics steps
(:func:`trajopt.search.hold.hold_check`); the screening ranks its :class:`Score` by
:meth:`ScreenSettings.rank_of <trajopt.codesign.screen.ScreenSettings.rank_of>`. :class:`Scorer` maps :func:`score_job` over a round's
jobs (:class:`ScoreJob`, picklable) in this process or in a pool of ``spawn``-started processes, one
compute thread each, in order, so that every figure is the same for any number of workers; it
terminates its workers however the screening ends, and a worker that dies ends it with
:class:`WorkerDied`.
"""
from __future__ import annotations

import signal
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from typing import Any, Iterator

import numpy as np

from soft_envs.envs import SimulationError
from soft_envs.envs.threads import limit_threads

from ..fastest import SearchSettings, fastest_gait
from ..optim.gauss_newton import GaussNewtonOptions
from ..optim.optimize import optimize_gait
from ..search.hold import hold_check
from ..workers import worker_pool
from .problem import design_env

__all__ = ["Score", "ScoreJob", "Scorer", "WorkerDied", "score_gait", "score_job"]


@dataclass(frozen=True)
class Score:
    """A candidate's gait and its credible speed (module docstring): ``own`` its speed at the own
    physics, ``hold`` the replays (:func:`~trajopt.search.hold.hold_check`: ``speeds``,
    ``slowest``, ``spread``, ``holds``; None when nothing upright was found), ``z`` its keyframes,
    ``steps`` the simulation steps it took (the replays included) and ``status`` the optimiser's."""

    own: float
    hold: dict | None
    z: np.ndarray | None
    steps: int
    status: str

    @property
    def slowest(self) -> float:
        return float("nan") if self.hold is None else float(self.hold["slowest"])

    def row(self) -> dict:
        """The screening row's fields of this score."""
        h = self.hold or {}
        return {"own_bl_per_min": self.own, "slowest_bl_per_min": self.slowest,
                "spread": float(h.get("spread", float("nan"))), "holds": bool(h.get("holds", False))}


def score_gait(env, gait, target: float, settings: Any, z0: np.ndarray | None, search: SearchSettings
          ) -> Score:
    """The :class:`Score` of a gait on ``env``'s robot (``settings``: a
    :class:`~trajopt.codesign.screen.ScreenSettings`): ``settings.iterations`` Gauss-Newton
    iterations from ``z0`` (warm), or (``z0`` None) from scratch as ``--speed max`` finds it on the
    current cycle and keyframes (``search`` pinned to them: the same runs as that candidate's in
    the full search, its hold stage's replays reused when they were made over
    ``settings.eval_cycles`` cycles at ``settings.hold_factors``); then replayed at the other physics
    steps (:func:`~trajopt.search.hold.hold_check`). Not upright: ``own`` nan, ``hold`` None."""
    reuse = False
    if z0 is None:
        pinned = replace(search, keyframes=(gait.n_keyframes,), max_sim_steps=None)
        try:
            res, _ = fastest_gait(env, settings=pinned, cycle_steps=gait.n_cycle, quiet=True)
        except SimulationError as err:            # nothing upright: never better
            return Score(float("nan"), None, None, 0, f"no upright gait ({err})")
        steps = int(res.evaluation["search_sim_steps"])
        reuse = (int(res.settings["eval_cycles"]) == settings.eval_cycles
                 and tuple(pinned.hold_factors) == tuple(settings.hold_factors)
                 and float(pinned.max_spread) == float(settings.max_spread))
    else:
        res = optimize_gait(env, "walk", gait=gait, speed_bl_per_min=target, z0=z0, n_seeds=0,
                            options=GaussNewtonOptions(max_iter=settings.iterations), eval_cycles=settings.eval_cycles)
        steps = int(res.evaluation.get("optimization_sim_steps", 0)) + gait.n_prep + settings.eval_cycles * gait.n_cycle
    ev = res.evaluation
    if not ev.get("upright"):
        return Score(float("nan"), None, np.asarray(res.z), steps, res.status)
    hold = ev.get("hold") if reuse else None
    if hold is None:
        hold = hold_check(env, res, factors=settings.hold_factors, max_spread=settings.max_spread,
                          n_cycles=settings.eval_cycles)
        steps += hold["steps"]
    return Score(float(ev["speed_bl_per_min"]), hold, np.asarray(res.z), steps, res.status)


@dataclass(frozen=True)
class ScoreJob:
    """One candidate's gait, as a worker process receives it (everything picklable)."""

    robot: Any
    contact: str
    newton: Any
    substeps: int
    gait: Any
    target: float
    settings: Any                       # trajopt.codesign.screen.ScreenSettings (which imports this module)
    z0: np.ndarray | None
    search: SearchSettings
    motor_model: str = "torque-speed"


def score_job(job: ScoreJob):
    """:func:`score_gait` of a job on a fresh environment of its robot, or ``SimulationError``'s text
    (a failed candidate, not a failed screening)."""
    env = design_env(job.robot, job.contact, job.newton, job.substeps, job.motor_model)
    try:
        return score_gait(env, job.gait, job.target, job.settings, job.z0, job.search)
    except SimulationError as err:
        return str(err)


class WorkerDied(RuntimeError):
    """A process scoring the screening's candidates died (``how``: e.g. "killed by SIGKILL", as
    the out-of-memory killer ends one), after ``rounds_done`` finished rounds of ``rounds``."""

    def __init__(self, how: str, rounds_done: int, rounds: int):
        self.how, self.rounds_done, self.rounds = how, int(rounds_done), int(rounds)
        super().__init__(
            f"a worker process scoring the screening's candidates died ({how}; the out-of-memory killer ends one "
            f"so when memory runs out) after {rounds_done} of {rounds} screening rounds. Fewer workers use less "
            "memory (workers=1 scores in this process; the result is the same); the run's checkpoint continues "
            "after the last finished round. From a script, processes are started by multiprocessing's spawn "
            "method, which imports the script again: a script that co-designs with workers > 1 must run its work "
            "under `if __name__ == \"__main__\":`")

    def command_line_text(self) -> str:
        """The advice for ``trajopt codesign`` (no script is involved there)."""
        return (f"a worker process scoring the screening's candidates died ({self.how}; the out-of-memory killer "
                f"ends one so when memory runs out) after {self.rounds_done} of {self.rounds} screening rounds: "
                "the same command with --resume continues from the last finished round; --workers 1 uses less "
                "memory (the result is the same)")


def _one_thread() -> None:
    """A scoring process computes on one thread (the workers share the cores)."""
    limit_threads(1)


class Scorer:
    """Scores jobs in order: in this process (``workers`` 1) or in a pool of ``workers`` processes,
    started on first use and terminated by :meth:`close` (also on Ctrl-C or an error)."""

    def __init__(self, workers: int):
        if int(workers) < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self.workers = int(workers)
        self.pool: ProcessPoolExecutor | None = None
        self._seen = set()                  # the worker processes (their exit codes, once dead)

    def map(self, jobs: list[ScoreJob]) -> Iterator:
        if self.workers == 1 or len(jobs) <= 1:
            return map(score_job, jobs)
        if self.pool is None:
            self.pool = worker_pool(self.workers, f"{__name__}:_one_thread")
        try:        # a worker killed while the jobs are submitted breaks the pool inside map()
            return self.pool.map(score_job, jobs)
        finally:
            self._seen.update((getattr(self.pool, "_processes", None) or {}).values())

    def how_they_died(self) -> str:
        """How the first worker that died unasked ended ("killed by SIGKILL", "exit code 1")."""
        manager = getattr(self.pool, "_executor_manager_thread", None)
        if manager is not None:             # it reaps the workers of a broken pool: let it finish first
            manager.join(timeout=5.0)
        for proc in self._seen:
            # join() again while the exit code is unknown: a wait that races the pool's manager thread
            # for the same child gets ECHILD, and multiprocessing then reports None for a dead process
            deadline = time.monotonic() + 5.0
            while proc.exitcode is None and time.monotonic() < deadline:
                proc.join(timeout=0.05)
            code = proc.exitcode
            if code is None or code == 0 or code == -signal.SIGTERM:      # alive, or terminated by the pool
                continue
            if code < 0:
                try:
                    return f"killed by {signal.Signals(-code).name}"
                except ValueError:
                    return f"killed by signal {-code}"
            return f"exit code {code}"
        return "ended abruptly"

    def close(self, terminate: bool = False) -> None:
        pool, self.pool = self.pool, None
        if pool is None:
            return
        if terminate:                       # running scores are abandoned, not waited for
            for proc in list((getattr(pool, "_processes", None) or {}).values()):
                proc.terminate()
        pool.shutdown(wait=True, cancel_futures=True)
