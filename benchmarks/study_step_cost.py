"""Study: what a simulation step costs, in factorisations, and why (issue: simulator core).

The issue's target is a step of at most 2.5 factorisations' worth of time. For the 168-step gait
of bench_sim.py and for speed-limited random controls, this script prints
  1. where a step's time goes, each part in units of one numeric factorisation of that robot's
     Hessian: factorisations, Hessian assemblies, gradient evaluations, solves, and the rest
     (Python, line-search bookkeeping; "energy" counts energy-only evaluations, which the
     solver needs only rarely; failed Cholesky attempts count as factorisations). It also prints the cost of an
     ideal step, one factorisation with its Hessian plus three gradients and three solves (a
     Newton step from a perfect prediction, as a linear problem would need), with this
     machine's kernels;
  2. the regime the one-sided springs work in: the share of taut cable steps and of
     penetrating contact nodes inside the C2 blend of Q (0 < s < eps), where Q'' rises from 0
     (the force grows like s^2 and Newton on it converges slowly, halving from above);
  3. a sweep of the blend widths (cables, contact): Newton iterations and factorisations per
     step, and the distance the gait moves the body (the physics changes with the blend).
Measured (2026-11-22): on the gait a step costs 8.3-9.4 (Tripod) and 6.5-7.0 (Puppy)
factorisations, of which the 2.4-2.8 factorisations themselves are 2.5-3.7; with random
controls 16-22. The ideal step costs 2.2-2.7: the target leaves no room for a second
factorisation or for the line search. 62-98 % of the taut cable steps and 83-100 % of the
contacts are in the blend. Blend widths from 0.1x to 5x give 1.8-3.0 factorisations per step.
Run: python benchmarks/study_step_cost.py
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

import soft_envs.sim.integrator as integrator
import soft_envs.sim.linsolve as linsolve
from common import best_of, gait_controls, random_controls, report
from soft_envs.sim import Simulator, load_robot


def timed_parts(sim: Simulator, u: np.ndarray) -> dict:
    """Seconds and calls per step of factorize / Hessian assembly / gradient / solve, and the
    whole step, for one rollout of ``u`` (methods wrapped with timers)."""
    parts: dict[str, list[float]] = {}
    newton = sim.newton
    originals = {}

    def wrap(obj, name, key_of):
        f = getattr(obj, name)
        originals[(obj, name)] = f

        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return f(*args, **kwargs)
            finally:
                p = parts.setdefault(key_of(args, kwargs), [0.0, 0])
                p[0] += time.perf_counter() - t0
                p[1] += 1
        setattr(obj, name, timed)

    wrap(newton.solver, "factorize", lambda a, k: "factorize")
    wrap(newton.solver, "solve", lambda a, k: "solve")
    wrap(newton, "phi_assemble",
         lambda a, k: "hessian" if k.get("want_hess", True) else "gradient")
    wrap(newton, "phi", lambda a, k: "energy")       # energy-only evaluations
    t0 = time.perf_counter()
    sim.rollout(u, x0=sim.rest_state())
    wall = time.perf_counter() - t0
    for (obj, name) in originals:
        delattr(obj, name)                           # back to the class's methods
    K = len(u)
    out = {k: (v[0] / K, v[1] / K) for k, v in parts.items()}
    out["step"] = (wall / K, 1.0)
    return out


def factorize_time(sim: Simulator) -> float:
    """Seconds of one numeric factorisation of the Hessian at rest (best of several)."""
    x = sim.rest_positions()
    u = np.zeros(sim.n_motors)
    _, _, h = sim.newton.phi_assemble(x, x, x, u)
    solver = linsolve.make_solver(sim.system.pattern)
    return best_of(lambda: solver.factorize(h), repeat=7, number=20)


def cost_rows(name: str, kind: str, sim: Simulator, u: np.ndarray) -> dict:
    sim.rollout(u[:5], x0=sim.rest_state())          # compile and warm up
    p = timed_parts(sim, u)
    tf = factorize_time(sim)
    unit = {k: v[0] / tf for k, v in p.items()}
    per_call = {k: v[0] / max(v[1], 1e-12) / tf for k, v in p.items()}
    known = sum(unit.get(k, 0.0) for k in ("factorize", "hessian", "gradient", "energy", "solve"))
    ideal = 1.0 + per_call.get("hessian", 0.0) + 3 * per_call.get("gradient", 0.0) + 3 * per_call.get("solve", 0.0)
    return {"robot": name, "controls": kind, "step": unit["step"],
            "factorize": unit.get("factorize", 0.0), "hessian": unit.get("hessian", 0.0),
            "gradient": unit.get("gradient", 0.0), "energy": unit.get("energy", 0.0),
            "solve": unit.get("solve", 0.0), "rest": unit["step"] - known,
            "factorize_calls_per_step": p.get("factorize", (0, 0))[1],      # failed ones included
            "ideal_step": ideal, "factorize_ms": 1e3 * tf}


def regime_row(name: str, sim: Simulator, u: np.ndarray) -> dict:
    cables, contact = sim.system.cables, sim.system.contact
    traj = sim.rollout(u, x0=sim.rest_state())
    gam = traj.cable_deformation[1:]
    taut = gam > 0
    pen = -traj.x[1:, contact.nodes, 1]
    touching = pen > 0
    return {"robot": name, "taut_cable_steps": float(taut.mean()),
            "taut_in_blend": float((taut & (gam < cables.blend)).sum() / max(taut.sum(), 1)),
            "contacts_per_step": float(touching.sum(1).mean()),
            "contacts_in_blend": float((touching & (pen < contact.eps_n)).sum() / max(touching.sum(), 1)),
            "cable_blend_mm": 1e3 * cables.blend, "contact_blend_mm": 1e3 * contact.eps_n}


def blend_rows(name: str, u: np.ndarray) -> list[dict]:
    rows = []
    counts: list[tuple[int, int]] = []
    original = integrator.NewtonSolver.step

    def counting(self, *args, **kwargs):
        x, info = original(self, *args, **kwargs)
        counts.append((info.iterations, info.factorizations))
        return x, info

    for scale in (0.1, 1.0, 5.0):
        robot = load_robot(name)
        robot = dataclasses.replace(robot, cable_blend=robot.cable_blend * scale,
                                    contact=dataclasses.replace(robot.contact, blend=robot.contact.blend * scale))
        sim = Simulator(robot)
        x0 = sim.rest_state()
        counts.clear()
        integrator.NewtonSolver.step = counting
        try:
            traj = sim.rollout(u, x0=x0)
        finally:
            integrator.NewtonSolver.step = original
        its, facts = np.mean(counts, axis=0)
        rows.append({"robot": name, "blend_scale": scale, "newton_its": its, "factorizations": facts,
                     "com_dx_mm": 1e3 * (traj.com[-1, 0] - traj.com[0, 0])})
    return rows


def main(K: int = 168) -> None:
    cost, regimes, blends = [], [], []
    for name in ("tripod", "puppy"):
        robot = load_robot(name)
        sim = Simulator(robot)
        gait = gait_controls(robot, K=K, dt=sim.dt)
        cost.append(cost_rows(name, "gait", sim, gait))
        cost.append(cost_rows(name, "random", sim, random_controls(robot, K)))
        regimes.append(regime_row(name, sim, gait))
        blends += blend_rows(name, gait)
    report("a step's time in factorisations (target: step <= 2.5)", cost)
    report("operating regime of the one-sided springs (gait)", regimes)
    report("blend width sweep (gait; 1.0 = the shipped robots)", blends)


if __name__ == "__main__":
    main()
