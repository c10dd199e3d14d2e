"""Study: why chord iterations fail, i.e. what a reused factorisation misses (issue: simulator core).

Whenever the Newton solver refreshes a stale factorisation (factorised at x0) at the current
iterate x, this script compares three directions for the same gradient g:
  * exact:  H(x)^{-1} g (a fresh Newton step),
  * chord:  H(x0)^{-1} g (what the stale factorisation gives),
  * hybrid: the Hessian with the FEM part taken at x0 but the cable and contact parts (and
    inertia) at x, i.e. what a low-rank (Woodbury) correction of the stale factorisation for
    the changed cables and contacts only could give.
It prints the median relative error of chord and hybrid against exact, for the gait rollout of
bench_sim.py and for random env actions, and how many contacts and tendons changed stiffness.
Measured (2026-11-22): chord 0.51 / hybrid 0.008 (Puppy gait), 0.52 / 0.03 (Tripod gait),
0.92 / 0.04 (Puppy, random actions): the chord failures come from cables and contacts switching,
not from the elastic nonlinearity. But 5-8 contacts and 2 (Tripod) to 10-13 (Puppy) tendons
change at a refresh, so a Woodbury correction needs ~10-30 columns; at 30-44 us per solved
column through cvxopt that is about the cost of the refactorisation it would replace
(0.65 ms). A rank update of the factor (CHOLMOD's updown, not exposed by cvxopt) would be
the tool to try.
Run: python benchmarks/study_chord_directions.py
"""
from __future__ import annotations

import gymnasium as gym
import numpy as np

import soft_envs  # noqa: F401  (registers the ids)
import soft_envs.sim.integrator as integrator
from common import gait_controls, report
from soft_envs.sim import Simulator, load_robot
from soft_envs.sim.cables import cable_assemble, d2Q
from soft_envs.sim.contact import contact_assemble
from soft_envs.sim.linsolve import CholmodSolver
from soft_envs.sim.materials import fem_assemble


def hybrid_hessian(newton, x0, x, x_prev, u) -> np.ndarray:
    """Hessian values with the FEM part at x0 and cables, contacts and inertia at x."""
    s = newton.system
    grad = np.zeros(s.n_dof)
    h = np.zeros(s.pattern.nnz + 1)
    fem_assemble(x0, s.tets, s.dN, s.vol, s.mu, s.lam, grad, h, s.fem_map, True)
    rest, tension = s.tendon_controls(u)
    cable_assemble(x, s.pt_nodes, s.pt_w, s.ptr, rest, s.k_cable, s.eps_cable, s.mode, tension,
                   grad, h, s.cable_map, s.cable_hptr, True)
    contact_assemble(x, x_prev, s.contact_nodes, s.k_n, s.eps_n, s.mu_f, grad, h, s.contact_diag, True)
    h[s.pattern.diag] += newton._diag_inertia
    return h


def changed_terms(newton, x0, x, u) -> tuple[int, int]:
    """Contact nodes whose normal stiffness Q_n'' and tendons whose Q'' changed by more than 1 %
    of the full stiffness between x0 and x: the rank a Woodbury correction would need
    (friction stiffness is constant within a step and not counted)."""
    s = newton.system
    kn = np.array([d2Q(-x[n, 1], s.k_n, s.eps_n) - d2Q(-x0[n, 1], s.k_n, s.eps_n) for n in s.contact_nodes])
    g, g0 = s.cable_deformation(x, u), s.cable_deformation(x0, u)
    kc = np.array([d2Q(a, k, s.eps_cable) - d2Q(b, k, s.eps_cable) for a, b, k in zip(g, g0, s.k_cable)])
    return int((np.abs(kn) > 0.01 * s.k_n).sum()), int((np.abs(kc) > 0.01 * s.k_cable).sum())


def directions_at_refreshes(run) -> np.ndarray:
    """(events, 4): relative errors of the chord and hybrid directions at every refresh, and
    the numbers of changed contacts and tendons."""
    errors = []
    last_point = {}
    original = integrator.NewtonSolver._refactor

    def refactor(self, x, xt, x_prev, u, *args):
        x0 = last_point.get(id(self))
        if x0 is not None and self._have_factor:
            aux = CholmodSolver(self.system.pattern)
            free = self.system.free
            g = self.phi_assemble(x, xt, x_prev, u, want_hess=False)[1][free]
            d_chord = -self.solver.solve(g)
            _, _, h_exact = self.phi_assemble(x, xt, x_prev, u)
            if aux.factorize(h_exact):
                d_exact = -aux.solve(g)
                if aux.factorize(hybrid_hessian(self, x0, x, x_prev, u)):
                    n = np.linalg.norm(d_exact)
                    errors.append((np.linalg.norm(d_chord - d_exact) / n,
                                   np.linalg.norm(-aux.solve(g) - d_exact) / n,
                                   *changed_terms(self, x0, x, u)))
        last_point[id(self)] = x.copy()
        return original(self, x, xt, x_prev, u, *args)

    integrator.NewtonSolver._refactor = refactor
    try:
        run()
    finally:
        integrator.NewtonSolver._refactor = original
    return np.array(errors)


def gait(name: str):
    def run():
        robot = load_robot(name)
        sim = Simulator(robot)
        sim.rollout(gait_controls(robot), x0=sim.rest_state())
    return run


def random_env(env_id: str, steps: int = 100):
    def run():
        env = gym.make(env_id)
        env.reset(seed=0)
        env.action_space.seed(0)
        for _ in range(steps):
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            if terminated or truncated:
                env.reset()
    return run


def main() -> None:
    rows = []
    for label, run in (("tripod gait", gait("tripod")), ("puppy gait", gait("puppy")),
                       ("SoftTripod-v0 random", random_env("SoftTripod-v0")),
                       ("SoftPuppy-v0 random", random_env("SoftPuppy-v0"))):
        e = directions_at_refreshes(run)
        rows.append({"case": label, "refreshes": len(e),
                     "chord_rel_error_median": float(np.median(e[:, 0])),
                     "hybrid_rel_error_median": float(np.median(e[:, 1])),
                     "chord_within_0.3": float((e[:, 0] < 0.3).mean()),
                     "hybrid_within_0.3": float((e[:, 1] < 0.3).mean()),
                     "changed_contacts_median": float(np.median(e[:, 2])),
                     "changed_tendons_median": float(np.median(e[:, 3]))})
    report("directions at factorisation refreshes: stale (chord) vs cables+contacts updated (hybrid)", rows)


if __name__ == "__main__":
    main()
