"""Study: chord iterations corrected by a low-rank (Woodbury) update (issue: simulator core).

study_chord_directions.py found that a stale factorisation's directions are poor because
cables and contacts change stiffness, while a Hessian with only those terms updated (the FEM
part stale) is within a few per cent of the exact one. This script tries the obvious solver
built on that: keep the factorisation of ``K_f = H(x_f)`` and solve, at every iterate x, with

    K_f + U D U^T            (Woodbury: y = K_f^{-1} g,  dx = -(y - W (I + D U^T W)^{-1} D U^T y))

where the columns of U are the terms whose stiffness changed since x_f: the normal direction of
every contact node whose ``Q_n''`` changed, the two tangential directions of every node whose
lagged friction stiffness changed (it changes from one step to the next), and ``dL_t/dx`` at
x_f for every tendon whose ``Q''`` changed (the cable's geometric stiffness and direction are
left at x_f). ``W = K_f^{-1} U`` is solved once per column and factorisation and cached. The
Newton loop (line search, refresh rule, stopping rule) is the production one: only
:meth:`NewtonSolver._direction` and :meth:`NewtonSolver._refactor` are overridden.

It prints, against the production solver on the same controls in the same run: Newton
iterations, factorisations, solved Woodbury columns per step and wall time.
Measured (2026-11-22): factorisations per step drop only from 2.72 to 2.58 (Tripod gait) and
2.35 to 1.95 (Puppy gait), and hardly at all with random controls, while 50-56 (gait) and
99-164 (random) Woodbury columns have to be solved per step: every step is about twice as
slow. The chord still stalls on what the model leaves at x_f (the FEM part, the cables'
geometric stiffness and directions), and the column solves cost more than the
factorisations they save. A rank-k update of the factor itself (CHOLMOD's updown, not exposed
by cvxopt) would remove the column solves but not the stalls.
Run: python benchmarks/study_lowrank_chord.py
"""
from __future__ import annotations

import time

import numpy as np

from common import gait_controls, report
from soft_envs.sim import SimulationError, Simulator, load_robot
from soft_envs.sim.cables import cable_length_gradients, cable_lengths
from soft_envs.sim.contact import normal_forces
from soft_envs.sim.integrator import NewtonSolver


def _d2q(s: np.ndarray, k, eps: float) -> np.ndarray:
    """Q''(s) of the one-sided quadratic, vectorised."""
    return np.where(s <= 0.0, 0.0, np.where(s < eps, k * s / eps, k))


class LowRankChord(NewtonSolver):
    """The production Newton loop with Woodbury-corrected chord directions (module docstring)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.columns = 0

    def _stiffnesses(self, x, x_prev, u):
        s = self.system
        rest, _ = s.tendon_controls(u)
        contact = _d2q(-x[s.contact_nodes, 1], s.k_n, s.eps_n)
        friction = 2.0 * s.mu_f * normal_forces(x_prev, s.contact_nodes, s.k_n, s.eps_n)
        cable = _d2q(cable_lengths(x, s.pt_nodes, s.pt_w, s.ptr) - rest, s.k_cable, s.eps_cable)
        return contact, friction, cable

    def _refactor(self, x, xt, x_prev, u):
        result = super()._refactor(x, xt, x_prev, u)
        s = self.system
        self._base = self._stiffnesses(x, x_prev, u)
        self._dL = cable_length_gradients(x, s.pt_nodes, s.pt_w, s.ptr, s.n_dof)[:, s.free]
        self._cols: dict = {}
        return result

    def _column(self, key):
        if key not in self._cols:
            kind, j = key
            if kind == "cable":
                v = self._dL[j].copy()
            else:
                full = np.zeros(self.system.n_dof)
                full[3 * self.system.contact_nodes[j] + {"normal": 1, "fx": 0, "fz": 2}[kind]] = 1.0
                v = full[self.system.free]
            self._cols[key] = (v, self.solver.solve(v))
            self.columns += 1
        return self._cols[key]

    def _direction(self, g, x, x_prev, u):
        y = self.solver.solve(g)
        contact, friction, cable = self._stiffnesses(x, x_prev, u)
        c0, f0, k0 = self._base
        keys, d = [], []
        for j in np.flatnonzero(contact != c0):
            keys.append(("normal", j))
            d.append(contact[j] - c0[j])
        for j in np.flatnonzero(friction != f0):
            keys += [("fx", j), ("fz", j)]
            d += [friction[j] - f0[j]] * 2
        for j in np.flatnonzero(cable != k0):
            keys.append(("cable", j))
            d.append(cable[j] - k0[j])
        if not keys:
            return y
        cols = [self._column(k) for k in keys]
        U = np.array([c[0] for c in cols]).T
        W = np.array([c[1] for c in cols]).T
        D = np.array(d)
        z = np.linalg.solve(np.eye(len(D)) + D[:, None] * (U.T @ W), D * (U.T @ y))
        return y - W @ z


def run(sim: Simulator, u: np.ndarray, solver: NewtonSolver) -> dict:
    """Step through controls ``u`` from rest with ``solver``; counts per step and wall time."""
    x0 = sim.rest_state()
    prev3 = prev2 = prev = x0
    its = facts = 0
    t0 = time.perf_counter()
    try:
        for k in range(len(u)):
            x, info = solver.step(prev, prev2, u[k], k, x_prev3=prev3)
            its += info.iterations
            facts += info.factorizations
            prev3, prev2, prev = prev2, prev, x
        failed = ""
    except SimulationError as exc:
        failed = str(exc)
        u = u[:k] if k else u[:1]
    wall = time.perf_counter() - t0
    K = len(u)
    return {"its": its / K, "facts": facts / K, "ms": 1e3 * wall / K, "failed": failed, "steps": K}


def random_controls(robot, K: int, seed: int = 0, rate: float = 0.15) -> np.ndarray:
    """Random targets with a speed limit of ``rate`` times the range per step."""
    rng = np.random.default_rng(seed)
    lo, hi = robot.u_bounds[:, 0], robot.u_bounds[:, 1]
    u = [lo.copy()]
    for _ in range(K - 1):
        u.append(u[-1] + np.clip(rng.uniform(lo, hi) - u[-1], -rate * (hi - lo), rate * (hi - lo)))
    return np.array(u)


def main(K: int = 168) -> None:
    rows = []
    for name in ("tripod", "puppy"):
        robot = load_robot(name)
        sim = Simulator(robot)
        for kind, u in (("gait", gait_controls(robot, K=K, dt=sim.dt)), ("random", random_controls(robot, K))):
            plain = run(sim, u, NewtonSolver(sim.system, sim.dt, sim.newton.options))
            lowrank_solver = LowRankChord(sim.system, sim.dt, sim.newton.options)
            lowrank = run(sim, u, lowrank_solver)
            rows.append({"robot": name, "controls": kind,
                         "newton_its": plain["its"], "lowrank_its": lowrank["its"],
                         "factorizations": plain["facts"], "lowrank_factorizations": lowrank["facts"],
                         "lowrank_columns_per_step": lowrank_solver.columns / lowrank["steps"],
                         "ms_per_step": plain["ms"], "lowrank_ms_per_step": lowrank["ms"],
                         "lowrank_failure": lowrank["failed"][:60] or "-"})
    report("chord iterations with Woodbury-corrected cables and contacts vs the production solver", rows)


if __name__ == "__main__":
    main()
