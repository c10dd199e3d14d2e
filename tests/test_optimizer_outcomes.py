"""The optimiser's outcomes against known minimisers (not only "the objective did not grow").

Projected Gauss-Newton (``trajopt.optim.gauss_newton``) on small problems whose bound-constrained
minimiser is known in closed form or from an independent solver (scipy's ``lsq_linear``):
it must reach it to a stated tolerance, lower the objective on its first step, decrease it
on every accepted step, and end with exactly the expected variables at their bounds (the KKT
signs: a variable at its lower bound has a gradient pushing outwards, g > 0; at its upper
bound g < 0; a free variable has g = 0). Then ``optimize_gait`` on a short horizon, with a
custom target.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from soft_envs.envs import make_gradient_env
from trajopt import GaitSpec, GaussNewtonOptions, optimize_gait
from trajopt.optim.gauss_newton import gauss_newton

#: options that stop only on the projected gradient (or stalling at machine precision)
PRECISE = GaussNewtonOptions(max_iter=100, ftol=0.0, xtol=0.0, gtol=1e-13)


def linear(A, b):
    """``fun(z, need_jac)`` of the residual ``r = A z - b``."""
    A, b = np.asarray(A, float), np.asarray(b, float)
    return lambda z, need_jac: (A @ z - b, A if need_jac else None, {})


def rosenbrock(z, need_jac):
    """``0.5 |r|^2`` with ``r = (10 (z1 - z0^2), 1 - z0)``: the Rosenbrock function / 2,
    minimiser (1, 1)."""
    r = np.array([10.0 * (z[1] - z[0] ** 2), 1.0 - z[0]])
    J = np.array([[-20.0 * z[0], 10.0], [-1.0, 0.0]]) if need_jac else None
    return r, J, {}


def check_descent(res):
    """First step accepted and strictly lowering O; no step raises O (at the minimiser an
    accepted step may leave it unchanged in floating point); a rejected step keeps it."""
    h = res.history
    assert h, "no iteration was made"
    assert h[0]["accepted"] and h[0]["objective_after"] < h[0]["objective"], h[0]
    for e in h:
        if e["accepted"]:
            assert e["objective_after"] <= e["objective"], e
        else:
            assert e["objective_after"] == e["objective"], e
    assert res.objective < h[0]["objective"]
    after = [e["objective_after"] for e in h]
    assert all(b <= a for a, b in zip(after, after[1:]))


def kkt_active_sets(z, g, lower, upper, tol=1e-9):
    """(at lower, at upper) as index sets, checking the KKT signs of the gradient g."""
    at_lo = set(np.flatnonzero(z <= lower).tolist())
    at_hi = set(np.flatnonzero(z >= upper).tolist())
    for i in range(len(z)):
        if i in at_lo:
            assert g[i] > 0, f"z[{i}] sits at its lower bound but the gradient {g[i]:.3g} points inwards"
        elif i in at_hi:
            assert g[i] < 0, f"z[{i}] sits at its upper bound but the gradient {g[i]:.3g} points inwards"
        else:
            assert abs(g[i]) < tol, f"free z[{i}] has gradient {g[i]:.3g}"
    return at_lo, at_hi


def test_separable_bounded_least_squares_is_solved_exactly():
    """``r = z - b`` in a box: the minimiser is ``clip(b, lower, upper)`` (closed form). Starting
    at the lower corner, z1 must leave its bound (its gradient points inwards), z0 must
    cross to its upper bound, z2 stays at its lower bound."""
    b = np.array([2.0, 0.3, -1.0, 0.7])
    lower, upper = np.zeros(4), np.ones(4)
    res = gauss_newton(linear(np.eye(4), b), lower.copy(), lower, upper, PRECISE)
    check_descent(res)
    expected = np.clip(b, lower, upper)                     # (1, 0.3, 0, 0.7)
    assert np.abs(res.z - expected).max() < 1e-10, res.z
    g = res.z - b
    assert kkt_active_sets(res.z, g, lower, upper) == ({2}, {0})
    assert res.z[0] == 1.0 and res.z[2] == 0.0               # exactly on the bounds, not near them
    assert res.status == "gtol"


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_coupled_bounded_least_squares_matches_scipy(seed):
    """A coupled over-determined problem whose unconstrained minimiser violates the box:
    Gauss-Newton reaches scipy's ``lsq_linear`` solution to 1e-9 with the same active bounds."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(12, 6))
    z_free = rng.normal(scale=2.0, size=6)                   # outside the box in several entries
    b = A @ z_free + 0.1 * rng.normal(size=12)
    lower, upper = -np.ones(6), np.ones(6)
    ref = lsq_linear(A, b, bounds=(lower, upper), method="bvls", tol=1e-14)
    expected_lo = set(np.flatnonzero(ref.active_mask == -1).tolist())
    expected_hi = set(np.flatnonzero(ref.active_mask == 1).tolist())
    assert expected_lo | expected_hi, f"seed {seed}: the test problem has no active bound"
    assert len(expected_lo | expected_hi) < 6, f"seed {seed}: every bound active, nothing to solve"
    res = gauss_newton(linear(A, b), lower.copy(), lower, upper, PRECISE)   # from the lower corner
    check_descent(res)
    assert np.abs(res.z - ref.x).max() < 1e-9, f"seed {seed}: {res.z} vs scipy {ref.x}"
    active = kkt_active_sets(res.z, A.T @ (A @ res.z - b), lower, upper, tol=1e-8)
    assert active == (expected_lo, expected_hi), f"seed {seed}"
    assert res.objective == pytest.approx(0.5 * np.sum((A @ ref.x - b) ** 2), rel=1e-12, abs=1e-14)


def test_rosenbrock_reaches_the_minimiser():
    """From the classic start (-1.2, 1) inside a box that does not bind: z = (1, 1) to 1e-8
    and O < 1e-20."""
    lower, upper = np.array([-2.0, -2.0]), np.array([2.0, 2.0])
    res = gauss_newton(rosenbrock, np.array([-1.2, 1.0]), lower, upper, PRECISE)
    check_descent(res)
    assert np.abs(res.z - 1.0).max() < 1e-8, res.z
    assert res.objective < 1e-20
    assert len(res.history) < 60
    kkt_active_sets(res.z, rosenbrock(res.z, True)[1].T @ rosenbrock(res.z, True)[0], lower, upper)


def test_rosenbrock_with_an_active_upper_bound():
    """With z0 <= 0.5 the minimiser is (0.5, 0.25): z1 = z0^2 zeroes the first residual and
    (1 - z0)^2 decreases up to the bound. Exactly z0 is at its upper bound, z1 is free."""
    lower, upper = np.array([-2.0, -2.0]), np.array([0.5, 2.0])
    res = gauss_newton(rosenbrock, np.array([-1.2, 1.0]), lower, upper, PRECISE)
    check_descent(res)
    assert np.abs(res.z - [0.5, 0.25]).max() < 1e-8, res.z
    assert res.objective == pytest.approx(0.5 * 0.25, rel=1e-10)
    r, J, _ = rosenbrock(res.z, True)
    assert kkt_active_sets(res.z, J.T @ r, lower, upper) == (set(), {0})


def test_damping_starts_at_lambda0_and_drops_after_full_steps():
    """Levenberg-Marquardt bookkeeping on a linear problem: the first iteration uses lambda0,
    a full step (alpha = 1) multiplies lambda by lambda_decrease."""
    opts = GaussNewtonOptions(max_iter=3, ftol=0.0, xtol=0.0, gtol=0.0, lambda0=1e-2, lambda_decrease=0.3)
    res = gauss_newton(linear(np.diag([1.0, 2.0]), [0.5, 0.5]), np.zeros(2), -np.ones(2), np.ones(2), opts)
    lams = [e["lambda"] for e in res.history]
    assert lams[0] == 1e-2
    for e, nxt in zip(res.history, lams[1:]):
        assert e["accepted"] and e["alpha"] == 1.0
        assert nxt == pytest.approx(0.3 * e["lambda"], rel=1e-15)


# ----------------------------------------------------------------------------- optimize_gait
SHORT = GaitSpec(n_prep=4, n_cycle=12)          # 4 + 2 x 12 steps


@pytest.fixture(scope="module")
def tripod_env():
    """The Tripod at one physics step per control step (``-v1``'s physics): the optimiser's
    outcomes, fast; the physics' own tests are elsewhere."""
    return make_gradient_env("tripod", substeps=1)


def test_optimize_gait_short_horizon_accepts_a_step_and_strictly_decreases(tripod_env):
    """Two Gauss-Newton iterations on a 4 + 2 x 12 step horizon: at least one accepted step,
    each accepted step strictly lowers the objective, and the final objective is below the
    starting one."""
    res = optimize_gait(tripod_env, "walk", gait=SHORT, n_seeds=1, eval_cycles=1,
                        options=GaussNewtonOptions(max_iter=2, ftol=0.0), robot_spec="tripod")
    h = res.history
    assert len(h) == 2 and any(e["accepted"] for e in h), h
    for e in h:
        if e["accepted"]:
            assert e["objective_after"] < e["objective"]
    assert res.evaluation["objective"] < h[0]["objective"]
    assert res.evaluation["objective"] == h[-1]["objective_after"]
    assert [e["iteration"] for e in h] == [1, 2]
    assert h[-1]["sim_steps_total"] >= 2 * (4 + 2 * 12)       # at least one rollout per iteration


def test_custom_target_is_used_as_given(tripod_env):
    """task="custom": the target array is the objective's target, unchanged, and one accepted
    step brings the COM path closer to it (the COM term drops). Without the motors' limit: 3
    steps per keyframe bind it hard, and the constrained step lowers the objective, not
    necessarily its COM term (tests/test_motor_limit.py tests the limit)."""
    K = SHORT.n_steps()
    x0, _ = tripod_env.reset_state()
    start = tripod_env.robot.com(x0)[[0, 2]]
    t = np.arange(K + 1) * tripod_env.timestep
    target = start + np.outer(t, [0.0, 0.01])                 # 1 cm/s to the right (+z)
    res = optimize_gait(tripod_env, "custom", target=target, gait=SHORT, n_seeds=1, motor_limit=False,
                        eval_cycles=1, options=GaussNewtonOptions(max_iter=2, ftol=0.0), robot_spec="tripod")
    assert res.task == "custom"
    np.testing.assert_array_equal(res.target, target)
    accepted = [e for e in res.history if e["accepted"]]
    assert accepted, res.history
    assert accepted[0]["terms_after"]["com"] < accepted[0]["terms"]["com"]
    with pytest.raises(ValueError, match="target"):
        optimize_gait(tripod_env, "custom", gait=SHORT)
    with pytest.raises(ValueError, match=r"shape \(29, 2\)"):
        optimize_gait(tripod_env, "custom", target=target[:-1], gait=SHORT)
