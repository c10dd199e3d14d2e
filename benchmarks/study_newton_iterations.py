"""Study: why a step takes 7-13 Newton iterations, whatever the contact law (issue: contact).

The contact issue's speed targets (a gait step <= 4 CHOLMOD factorisations' worth of time, a
random-action step <= 1.5x MuJoCo's standing step) need a step that converges in about one
factorisation. This script measures where the iterations come from, on the shipped robots:

  1. ground vs air: the same controls with contact and gravity, and with neither (the robot
     lifted 5 cm, gravity 0: only elasticity, cables and inertia are left);
  2. cable stiffness (the paper's "stiff unilateral springs"), in the air;
  3. contact and cable laws on the ground: the shipped Coulomb law, a half-quadratic contact
     with a 1 um cable blend (equilibria on the quadratic branches), no friction, a 1 mm slip
     distance, the paper's law;
  4. Newton from a guess near the solution: steps of a converged rollout solved again from the
     solution plus per-node noise (1, 10, 100 um) or a rigid horizontal shift (0.1, 1 mm);
  5. a linearly implicit step (MuJoCo's scheme: one or two Newton iterations from the guess,
     no convergence test) against the converged rollout.

Measured (2026-12-01, 120 steps; Tripod / Puppy):
  1. ground: gait 8.1 / 7.7 iterations (3.0 / 2.4 factorisations), random 13.0 / 13.1 (7.8 /
     7.8); in the air: gait 7.1 / 5.7, random 14.0 / 13.9. Contact is not where they come from;
  2. in the air, random controls: cable stiffness 1e3 / 1e4 / 1e5 (shipped) / 1e6 N/m give
     8.6 / 10.9 / 14.0 / 18.5 (Tripod) and 8.5 / 10.9 / 13.9 / 17.0 (Puppy) iterations;
  3. every contact and cable law variant: 7.5-8.1 (gait) and 11.7-13.2 (random) iterations,
     the paper's law lowest on random controls (no exact line search);
  4. from the solution + 1 um noise: 3 iterations, 1 factorisation (Newton's quadratic
     regime); + 10 um: 5.4 / 5.9 iterations (1.2 / 1.6 factorisations); + 100 um: 7.7 / 8.7
     (3.4 / 4.3); + a 0.1 mm rigid shift: 6.0 / 6.4 (2.3 / 2.2); + 1 mm: 7.6 / 8.1 (3.8).
     The model's nonlinearity (springs engaging, slip anchors, cable kinks, the rotations of
     a floating body) lives at the 0.01-0.1 mm scale, while a step moves the body by
     millimetres: even a predictor accurate to 10 um leaves 5-6 iterations;
  5. linearly implicit: with one iteration per step the robots fall through the ground (the
     penalty contact linearised where a foot is above the ground has no stiffness; the
     deepest penetration grows to kilometres within 120 steps); 2 and 5 iterations leave the
     COM 0.05-2.4 m off the converged motion, 10 iterations 3-8 mm (Tripod) and 0.2-3.3 mm
     (Puppy): not a cheaper step.
Run: python benchmarks/study_newton_iterations.py [--robots tripod puppy] [--steps 120]
"""
from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from common import gait_controls, random_controls, report

from soft_envs.sim import Simulator, load_robot
from soft_envs.sim.integrator import NewtonSolver, SimulationError, StepInfo, _Inputs
from soft_envs.sim.line_search import backtracking

AIR_LIFT = np.array([0.0, 0.05, 0.0])


def with_contact(robot, **changes):
    return robot.replace(contact=dataclasses.replace(robot.contact, **changes))


def with_cable_stiffness(robot, k: float):
    return robot.replace(tendons=tuple(dataclasses.replace(t, stiffness=k) for t in robot.tendons))


class CountingSolver(NewtonSolver):
    """The shipped solver, counting iterations and factorisations per step; ``guess`` (if
    set) replaces the initial guess of the next step (section 4)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.counts: list[tuple[int, int]] = []
        self.guess: np.ndarray | None = None

    def step(self, *args, **kwargs):
        x, info = super().step(*args, **kwargs)
        self.counts.append((info.iterations, info.factorizations))
        return x, info

    def _initial_guess(self, ctx, x_prev2, x_prev3, fixed_src):
        if self.guess is None:
            return super()._initial_guess(ctx, x_prev2, x_prev3, fixed_src)
        x = self.guess.copy()
        phi, grad, _ = self._phi_grad(x, ctx)
        return x, phi, grad


class LinearlyImplicit(NewtonSolver):
    """``iterations`` Newton iterations per step from the usual guess (fresh Hessian, Armijo
    backtracking), no convergence test: the linearly implicit scheme for 1."""

    iterations = 1

    def step(self, x_prev, x_prev2, u, k=None, x_fixed=None, need_exact=False, x_prev3=None,
             cache=None, history=None):
        ctx = _Inputs(2.0 * x_prev - x_prev2, x_prev, u, self.system.resolve_history(history, x_prev))
        free = self.system.free
        x, phi, grad = NewtonSolver._initial_guess(self, ctx, x_prev2, x_prev3, x_prev)
        for _ in range(self.iterations):
            phi, grad, hdata = self.phi_assemble(x, *ctx[:3], history=ctx.history)
            self.factorize(hdata, x, *ctx[:3], ctx.history)
            dx = -self.solver.solve(grad[free])

            def evaluate(alpha, x=x, dx=dx):
                xn = x.copy()
                self._move(xn, alpha * dx)
                phi_n, grad_n, _ = self._phi_grad(xn, ctx)
                return xn, phi_n, grad_n, float(grad_n[free] @ dx)

            found = backtracking(evaluate, phi, float(grad[free] @ dx), 1e-6, 40)
            if found is None:
                raise SimulationError("line search failed", k)
            x = found[0]
        return x, StepInfo(self.iterations, self.iterations, 0, None)


def controls(robot, kind: str, K: int) -> np.ndarray:
    return gait_controls(robot, K) if kind == "gait" else random_controls(robot, K)


def counted_rollout(robot, kind: str, K: int, air: bool = False):
    sim = Simulator(robot, gravity=(0.0, 0.0, 0.0) if air else (0.0, -9.81, 0.0))
    sim.newton = CountingSolver(sim.system, sim.newton.dt, sim.newton.options)
    x0 = sim.rest_state() + (AIR_LIFT if air else 0.0)
    traj = sim.rollout(controls(robot, kind, K), x0=x0)
    its, facts = np.mean(sim.newton.counts, axis=0)
    return sim, traj, its, facts


def coulomb(name: str):
    return with_contact(load_robot(name), model="coulomb")


def ground_vs_air(names, K) -> list[dict]:
    rows = []
    for name in names:
        for air in (False, True):
            for kind in ("gait", "random"):
                _, _, its, facts = counted_rollout(coulomb(name), kind, K, air)
                rows.append({"robot": name, "where": "air" if air else "ground", "controls": kind,
                             "newton_its": its, "factorizations": facts})
    return rows


def cable_stiffness(name, K) -> list[dict]:
    rows = []
    for k in (1e3, 1e4, 1e5, 1e6):
        _, _, its, facts = counted_rollout(with_cable_stiffness(coulomb(name), k), "random", K, air=True)
        rows.append({"robot": name, "cable_stiffness": k, "newton_its": its, "factorizations": facts})
    return rows


def laws(name, K) -> list[dict]:
    base = coulomb(name)
    variants = {
        "coulomb (shipped)": base,
        "half-quadratic contact, 1 um cable blend": with_contact(base, blend=0.0).replace(cable_blend=1e-6),
        "coulomb, mu = 0": with_contact(base, friction_coefficient=0.0),
        "coulomb, slip distance 1 mm": with_contact(base, slip_distance=1e-3),
        "paper": load_robot(name),
    }
    rows = []
    for kind in ("gait", "random"):
        for label, robot in variants.items():
            _, _, its, facts = counted_rollout(robot, kind, K)
            rows.append({"robot": name, "controls": kind, "law": label, "newton_its": its,
                         "factorizations": facts})
    return rows


def near_solution(name, K) -> list[dict]:
    robot = coulomb(name)
    sim, traj, _, _ = counted_rollout(robot, "gait", K)
    u = traj.u
    hist = [sim.system.resolve_history(None, traj.x[0])]      # as the rollout started
    for k in range(K):
        hist.append(sim.system.next_history(traj.x[k + 1], traj.x[k], hist[-1]) if sim.system.has_history else None)
    rng = np.random.default_rng(0)
    perturbations = {"noise 1 um": lambda x: x + 1e-6 * rng.standard_normal(x.shape),
                     "noise 10 um": lambda x: x + 1e-5 * rng.standard_normal(x.shape),
                     "noise 100 um": lambda x: x + 1e-4 * rng.standard_normal(x.shape),
                     "rigid shift 0.1 mm": lambda x: x + np.array([1e-4, 0.0, 1e-4]),
                     "rigid shift 1 mm": lambda x: x + np.array([1e-3, 0.0, 1e-3])}
    rows = []
    solver = sim.newton
    for label, perturb in perturbations.items():
        solver.counts.clear()
        for k in range(K // 3, K):
            solver.guess = perturb(traj.x[k + 1])
            solver.step(traj.x[k], traj.x[k - 1], u[k], k, history=hist[k])
        solver.guess = None
        its, facts = np.mean(solver.counts, axis=0)
        rows.append({"robot": name, "guess": "solution + " + label, "newton_its": its, "factorizations": facts})
    return rows


def linearly_implicit(name, K) -> list[dict]:
    rows = []
    robot = coulomb(name)
    for kind in ("gait", "random"):
        u = controls(robot, kind, K)
        ref = Simulator(robot).rollout(u)
        for n in (1, 2, 5, 10):
            sim = Simulator(robot)
            solver = LinearlyImplicit(sim.system, sim.newton.dt, sim.newton.options)
            solver.iterations = n
            sim.newton = solver
            try:
                traj = sim.rollout(u)
                dev = 1e3 * float(np.abs(traj.com - ref.com).max())
                sink = -1e3 * float(traj.x[:, :, 1].min()) if n == 1 else np.nan
            except SimulationError as e:
                dev, sink = f"failed: {e}", np.nan
            rows.append({"robot": name, "controls": kind, "iterations_per_step": n, "steps": K,
                         "max_com_deviation_mm": dev, "deepest_penetration_mm": sink})
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--robots", nargs="+", default=["tripod", "puppy"])
    p.add_argument("--steps", type=int, default=120)
    a = p.parse_args()
    report("1. ground vs air (Coulomb law)", ground_vs_air(a.robots, a.steps))
    report("2. cable stiffness, in the air, random controls",
           [r for n in a.robots for r in cable_stiffness(n, a.steps)])
    report("3. contact and cable laws, on the ground", [r for n in a.robots for r in laws(n, a.steps)])
    report("4. Newton from a guess near the solution (gait)", [r for n in a.robots for r in near_solution(n, a.steps)])
    report("5. linearly implicit steps vs the converged rollout (COM deviation)",
           [r for n in a.robots for r in linearly_implicit(n, a.steps)])


if __name__ == "__main__":
    main()
