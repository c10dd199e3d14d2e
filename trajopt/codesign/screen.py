"""Design screening: the coarse stage of co-design, before joint Gauss-Newton (issue #29 item 3).

Gauss-Newton is local, and a walking gait under the Coulomb law is a rugged function of the
design: feet that stick or slip one step earlier change the stride, and a gait tuned to one
design can barely walk on a neighbour (measured on the Tripod's fastest gait: the middle leg
twice as stiff walks at 0.45 BL/min with the shipped design's keyframes, and at 32.6 once the
keyframes follow for 5 Gauss-Newton iterations; the shipped design: 26.8). So co-design first
screens designs a finite step away in a few directions, each with its gait re-optimised
(:func:`trajopt.optimize.optimize_gait`, warm-started from the current keyframes, the motors'
limit on), and keeps the fastest upright one; then :mod:`trajopt.codesign.joint` refines gait
and design together from there.

The candidates around the current design theta (:func:`candidates`):

* each region's modulus times ``modulus_factors`` (0.5x, 2x; clipped to the bounds);
* each leg (or mirror pair of legs) ``leg_step`` longer and shorter;
* the via points moved along the steepest descent of the co-design objective
  (:class:`~trajopt.codesign.problem.CodesignProblem`, one rollout with sensitivities) restricted
  to the routing, scaled so the largest coordinate moves ``routing_steps`` (1 and 2 mm).

Candidates that break the clearance or mass constraints are skipped (listed). Greedy rounds:
each round screens the candidates around the best design so far, and the next round starts from
the round's winner; it stops after ``rounds`` rounds or a round without a faster design.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from soft_envs.envs import SimulationError

from ..gauss_newton import GaussNewtonOptions
from ..optimize import optimize_gait
from .problem import CodesignProblem, InfeasibleDesign

__all__ = ["ScreenSettings", "candidates", "screen_designs"]


@dataclass(frozen=True)
class ScreenSettings:
    """What :func:`screen_designs` tries (module docstring); ``rounds=0``: no screening."""

    rounds: int = 2
    iterations: int = 5
    modulus_factors: tuple[float, ...] = (0.5, 2.0)
    leg_step: float = 3e-3
    routing_steps: tuple[float, ...] = (1e-3, 2e-3)
    eval_cycles: int = 10

    @classmethod
    def quick(cls) -> "ScreenSettings":
        return cls(rounds=1, iterations=1, modulus_factors=(2.0,), routing_steps=(), eval_cycles=2)


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
            for step in settings.routing_steps:
                add(f"via points {1e3 * step:g} mm along the steepest descent", theta + step * d)
    return out


def screen_designs(problem: CodesignProblem, theta: np.ndarray, z: np.ndarray, speed: float, target: float,
                   settings: ScreenSettings = ScreenSettings(), *, log: Callable[[str], Any] = lambda t: None,
                   done: Callable[[dict], None] | None = None) -> tuple[np.ndarray, np.ndarray, float, list[dict]]:
    """``(theta, z, speed, rows)``: the fastest upright design and gait found (``theta, z,
    speed`` as given when none is faster) and one row per candidate. ``target``: the gaits'
    tracking target [BL/min]; ``done(row)`` after each candidate (progress, checkpoints)."""
    best_theta, best_z, best = np.asarray(theta, dtype=np.float64), np.asarray(z, dtype=np.float64), float(speed)
    rows: list[dict] = []
    gait = problem.gait
    for rnd in range(1, settings.rounds + 1):
        start_theta, start_z, winner = best_theta, best_z, None
        problem.move_to(start_theta)
        for label, th in candidates(problem, start_theta, start_z, settings):
            row = {"round": rnd, "candidate": label, "speed_bl_per_min": float("nan"), "upright": False,
                   "status": "", "sim_steps": 0}
            try:
                robot = problem.robot_at(th)
                why = problem.design_violation(robot)
                if why is not None:
                    raise InfeasibleDesign(why)
                res = optimize_gait(problem.env_of(robot), "walk", gait=gait, speed_bl_per_min=target, z0=start_z,
                                    n_seeds=0, options=GaussNewtonOptions(max_iter=settings.iterations),
                                    eval_cycles=settings.eval_cycles)
            except InfeasibleDesign as err:
                row["status"] = f"skipped: {err}"
            except SimulationError as err:
                row["status"] = f"failed: {err}"
            else:
                ev = res.evaluation
                steps = int(ev.get("optimization_sim_steps", 0)) + gait.n_prep + settings.eval_cycles * gait.n_cycle
                problem.sim_steps += steps
                row.update(speed_bl_per_min=float(ev["speed_bl_per_min"]), upright=bool(ev["upright"]),
                           status=res.status, sim_steps=steps)
                if row["upright"] and row["speed_bl_per_min"] > best:
                    best, best_theta, best_z, winner = row["speed_bl_per_min"], th, np.asarray(res.z), label
            rows.append(row)
            log(f"  screen round {rnd}: {label}: {row['speed_bl_per_min']:.2f} BL/min"
                f"{'' if row['upright'] else ' (not upright)'} {row['status']}")
            if done is not None:
                done(row)
        log(f"screen round {rnd}: {'best ' + winner if winner else 'no faster design'} ({best:.2f} BL/min)")
        if winner is None:
            break
    return best_theta, best_z, best, rows
