"""Newton's rescue (soft_envs/sim/integrator.py, NewtonOptions.rescue_doublings): a step that
runs out of iterations is solved again, afresh, with a line search that may lengthen a step
that still descends steeply.

``tests/data/creep_step.npz`` is a real failure of the benchmark (issue #39): the Tripod's PPO
policy of seed 2 on ``SoftTripodClimbStep-v0`` (medium, Coulomb law, 4 physics steps of 8.25
ms per control step), evaluation episode 1, the third physics step of control step 141, a foot
pressed on the convex edge of the step. There Phi curves downwards: the modified Hessian's
Newton steps grow from 1.3e-6 to 6.2e-6 m over 45 iterations, and 50 did not converge.
(Recorded by the step's inputs: x_{k-1}, x_{k-2}, x_{k-3}, the controls and the energy terms'
history, whose third entry is the friction anchors.)
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import soft_envs  # noqa: F401  (registers the ids)
from soft_envs.sim import NewtonOptions, SimulationError
from soft_envs.sim.line_search import bracketing

DATA = Path(__file__).parent / "data" / "creep_step.npz"


def _creep_step():
    """The solver of the recorded step's environment, and the step's inputs."""
    env = gym.make("SoftTripodClimbStep-v0", contact="coulomb", substeps=4)
    solver = env.unwrapped._sim.newton
    d = np.load(DATA)
    history = (None, None, d["history2"], None)
    inputs = dict(x_prev=d["x_prev"], x_prev2=d["x_prev2"], u=d["u"], k=int(d["k"]), x_prev3=d["x_prev3"],
                  history=history)
    return env, solver, inputs


def test_the_recorded_creeping_step_fails_without_the_rescue_and_converges_with_it():
    env, solver, inputs = _creep_step()
    try:
        assert solver.dt == pytest.approx(0.033 / 4) and solver.options.rescue_doublings == 30
        plain = dataclasses.replace(solver.options, rescue_doublings=0)
        solver.options, default = plain, solver.options
        with pytest.raises(SimulationError, match="did not converge in 50 iterations"):
            solver.step(**inputs)
        solver.options = default
        x, info = solver.step(**inputs)
        assert 50 < info.iterations <= 100                        # the failed solve's 50 count too
        # a minimiser of Phi: the gradient on the free dofs is small (the last Newton step was
        # below the sub-steps' tolerance, times the Hessian's stiffness)...
        xt = 2.0 * inputs["x_prev"] - inputs["x_prev2"]
        phi, grad, _ = solver.phi_assemble(x, xt, inputs["x_prev"], inputs["u"], want_hess=False,
                                           history=solver.system.resolve_history(inputs["history"], inputs["x_prev"]))
        free = solver.system.free if len(solver.system.free) < solver.system.n_dof else slice(None)
        assert np.abs(grad[free]).max() < 1e-4
        # ... and the inputs untouched
        assert np.isfinite(phi) and np.all(np.isfinite(x))
        d = np.load(DATA)
        assert np.array_equal(inputs["x_prev"], d["x_prev"]) and np.array_equal(inputs["history"][2], d["history2"])
    finally:
        env.close()


def test_a_step_that_fails_both_times_says_so_with_both_reasons():
    env, solver, inputs = _creep_step()
    try:
        solver.options = dataclasses.replace(solver.options, max_iter=3)
        with pytest.raises(SimulationError) as err:
            solver.step(**inputs)
        assert err.value.step == inputs["k"]
        assert "did not converge in 3 iterations" in err.value.reason
        assert "solved again with longer line searches: Newton did not converge in 3" in err.value.reason
        second = err.value.__cause__                    # the traceback has both solves' failures
        first = second.__context__
        assert isinstance(second, SimulationError) and isinstance(first, SimulationError)
        assert first is not second and first.__traceback__ is not None and second.__traceback__ is not None
        assert err.value.reason == f"{first.reason}; solved again with longer line searches: {second.reason}"
    finally:
        env.close()


def test_steps_that_converge_are_the_same_bit_for_bit_with_or_without_the_rescue():
    """A control step of the same environment from its reset, with the rescue and without it."""
    out = []
    for doublings in (30, 0):
        env = gym.make("SoftTripodClimbStep-v0", contact="coulomb", substeps=4)
        sim = env.unwrapped._sim
        sim.newton.options = dataclasses.replace(sim.newton.options, rescue_doublings=doublings)
        env.reset(seed=0)
        for _ in range(3):
            env.step(np.array([0.8, -0.5], dtype=np.float32))
        out.append(env.unwrapped._state.x.copy())
        env.close()
    assert np.array_equal(out[0], out[1])


def _concave_then_convex(alpha_min: float):
    """Phi along a step: falls like -alpha^2 near 0 (a negative curvature), then rises, its
    minimum at ``alpha_min``; ``evaluate(alpha) -> (x, Phi, grad, dPhi/dalpha)``."""
    def phi(a):
        return -(a ** 2) + a ** 4 / (2.0 * alpha_min ** 2) - 0.01 * a

    def dphi(a):
        return -2.0 * a + 2.0 * a ** 3 / alpha_min ** 2 - 0.01

    return (lambda a: (np.array([a]), phi(a), None, dphi(a))), phi(0.0), dphi(0.0)


def test_bracketing_doubles_a_step_that_still_descends_steeply_only_when_asked():
    evaluate, phi0, slope = _concave_then_convex(40.0)
    kept = bracketing(evaluate, phi0, slope, 1e-6, 0.1, 8, 40)
    assert kept[3] == 1.0                                     # the full step, as before
    x, phi, _, alpha = bracketing(evaluate, phi0, slope, 1e-6, 0.1, 8, 40, max_doublings=30)
    # doubled to 64, past the minimum at 40, then bracketed there: its derivative within
    # wolfe = 0.1 times the initial one
    assert alpha == pytest.approx(40.0, rel=1e-3) and phi < kept[1] and abs(evaluate(alpha)[3]) <= 0.1 * abs(slope)
    capped = bracketing(evaluate, phi0, slope, 1e-6, 0.1, 8, 40, max_doublings=2)
    assert capped[3] == 4.0                                   # 1 -> 2 -> 4, still descending


def test_the_doubled_search_returns_its_lowest_point():
    """Phi steep at alpha = 1 and 2 but higher at 2 (a bump in between): the lower point is kept."""
    def evaluate(a):
        phi = {1.0: -1.0, 2.0: -0.8}.get(a, -0.8 + (a - 2.0) ** 2 if a > 2.0 else -a)
        return np.array([a]), phi, None, (-5.0 if a <= 2.0 else 2.0 * (a - 2.0))

    x, phi, _, alpha = bracketing(evaluate, 0.0, -1.0, 1e-6, 0.1, 8, 40, max_doublings=30)
    assert (alpha, phi) == (1.0, -1.0)


def test_rescue_doublings_is_validated():
    with pytest.raises(ValueError, match="rescue_doublings"):
        NewtonOptions(rescue_doublings=-1)
    assert NewtonOptions(rescue_doublings=0).rescue_doublings == 0
