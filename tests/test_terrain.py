"""Contact with a height field (soft_envs.sim.ground, soft_envs.sim.contact.surface and the
laws' field variants): derivatives against central finite differences, and equivalences with
the plane.

* The field itself: ``h`` interpolates the grid, its first to third derivatives match central
  differences of the one below (relative error <= 1e-6; measured ~1e-8).
* The contact energy of both laws on rough ground (RMS 3 mm, wavelength 4 cm) at the Tripod's
  contact nodes pushed 1 mm into it: gradient, Hessian, ``add_prev_product`` (+ transpose) and,
  for the Coulomb law, the anchors' ``add_history_product`` and ``history_tangent`` (+
  transposes), along random directions with h = 1e-7 m: relative error <= 1e-6 (measured: gradient
  3e-9 - 8e-9, Hessian 2e-9 - 3e-9, prev products 2e-9 - 3e-9, anchor products 1.2e-7, anchor
  tangent 6e-8).
* Their parameter Jacobians (contact stiffness, friction): <= 1e-6 (tests/test_parameter_derivatives.py).
* Rollout sensitivities on rough ground (tests/gradcheck.py, Newton at 1e-13 m, 20 steps): <= 1e-4
  for the paper's law and <= 1e-6 for the Coulomb law, as tests/test_sensitivity.py asks on the
  plane (measured 9e-9 and 1.7e-8).
* A flat field is the plane, a planar slope field is the plane rotated with gravity
  ``incline_gravity`` (a rollout from the rotated state, anchors included): within 1e-9 m
  (measured 1e-16 and 6e-15 m).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from soft_envs.sim import HeightField, NewtonOptions, Simulator, incline_gravity, load_robot

from .gradcheck import relative_error, rollout_jacobian_errors
from .test_sensitivity import gait

RTOL = 1e-6
H = 1e-7
ROUGH = HeightField.rough(0.003, 0.04, seed=2)
TIGHT = NewtonOptions(tol=1e-13)


def tripod(model: str, ground=None):
    robot = load_robot("tripod")
    return robot.replace(contact=dataclasses.replace(robot.contact, model=model), ground=ground)


def test_height_field_interpolates_and_is_differentiable():
    f = ROUGH
    i, j = 37, 21
    assert math.isclose(f.derivatives(f.origin[0] + i * f.spacing[0], f.origin[1] + j * f.spacing[1])[0],
                        f.heights[i, j], rel_tol=1e-12, abs_tol=1e-15)
    # spatial RMS of the field: the amplitude (16 waves: within sampling noise)
    assert 0.6 * 0.003 < f.heights.std() < 1.4 * 0.003
    e = 1e-6
    for x, z in [(0.3123, 0.0771), (-0.2, 0.41), (1.5063, 0.12)]:   # the last outside the grid
        d = np.array(f.derivatives(x, z))
        dx = (np.array(f.derivatives(x + e, z)) - np.array(f.derivatives(x - e, z))) / (2 * e)
        dz = (np.array(f.derivatives(x, z + e)) - np.array(f.derivatives(x, z - e))) / (2 * e)
        analytic = d[[1, 2, 3, 4, 5, 4, 6, 7, 8, 7, 8, 9]]
        numeric = np.r_[dx[0], dz[0], dx[1], dx[2], dz[2], dz[1], dx[3], dx[4], dx[5], dz[3], dz[4], dz[5]]
        assert relative_error(analytic, numeric) <= RTOL
    # constructors: flat is zero everywhere; a slope rises by tan(angle) along uphill
    assert HeightField.flat().derivatives(0.3, -2.0) == (0.0,) * 10
    h = HeightField.incline(10.0, uphill=(0.0, 1.0)).derivatives(0.3, 0.2)
    assert math.isclose(h[0], 0.2 * math.tan(math.radians(10.0))) and h[1] == 0.0
    step = HeightField.step(0.01, 0.2, width=0.01)
    assert abs(step.height(0.0, 0.0)) < 1e-12 and abs(step.height(0.5, 3.0) - 0.01) < 1e-12
    assert math.isclose(step.height(0.2, 0.0), 0.005, rel_tol=1e-9)
    trench = HeightField.trench(0.02, 0.3, 0.05)
    assert math.isclose(trench.height(0.325, 0.0), -0.02, rel_tol=1e-9) and abs(trench.height(0.6, 0.0)) < 1e-12


def _perturbed(sim, rng):
    """A state of the Tripod pressed 1 mm into the ground, moved from its previous positions and
    anchors so that nodes stick, slide and are lifted."""
    st = sim.rest_state()
    x_prev = st.x + rng.normal(scale=2e-4, size=st.x.shape)
    x = x_prev + rng.normal(scale=2e-4, size=st.x.shape)
    x[:, 1] -= 1e-3
    hist = st.history[2]
    if hist is not None:
        hist = hist + rng.normal(scale=1e-4, size=hist.shape)
    return x, x_prev, hist


def _directional(f, x, S, h=H):
    """Central differences of ``f`` along the columns of ``S``."""
    return np.stack([(f(x + h * S[:, j]) - f(x - h * S[:, j])) / (2 * h) for j in range(S.shape[1])], axis=1)


@pytest.mark.parametrize("model", ["coulomb", "paper"])
def test_field_contact_derivatives(model):
    sim = Simulator(tripod(model, ROUGH))
    c = sim.system.contact
    assert c.model == model and type(c).__name__.endswith("FieldContact")
    rng = np.random.default_rng(0)
    x, x_prev, hist = _perturbed(sim, rng)
    nd, nnz, free = x.size, sim.system.pattern.nnz, sim.system.free

    def grad(y, yp=x_prev, hh=hist, hess=False):
        g, hd = np.zeros(nd), np.zeros(nnz + 1)
        c.assemble(y.reshape(-1, 3), yp.reshape(-1, 3), None, hh if hh is None else hh.reshape(-1, 2), g, hd, hess)
        return (g, hd) if hess else g

    g, hd = grad(x.ravel(), hess=True)
    Hm = sim.system.pattern.full(hd)
    S = rng.normal(size=(nd, 3))
    S /= np.linalg.norm(S, axis=0)
    fd_e = _directional(lambda y: np.array([c.energy(y.reshape(-1, 3), x_prev, None, hist)]), x.ravel(), S)
    assert relative_error(g @ S, fd_e[0]) <= RTOL
    fd_g = _directional(grad, x.ravel(), S)
    assert relative_error(Hm @ S[free], fd_g[free]) <= RTOL
    # d(grad)/dx_prev and its transpose
    out = np.zeros_like(S)
    c.add_prev_product(x, x_prev, None, hist, S, out)
    assert relative_error(out, _directional(lambda yp: grad(x.ravel(), yp), x_prev.ravel(), S)) <= RTOL
    lam = rng.normal(size=nd)
    out_T = np.zeros(nd)
    c.add_prev_product_T(x, x_prev, None, hist, lam, out_T)
    assert relative_error(out_T @ S, lam @ out) <= 1e-12
    if model == "paper":
        return
    # the anchors: d(grad)/d anchors, d next anchors / d(x, anchors), and transposes
    moved = np.abs(c.next_history(x, x_prev, hist) - hist).max(axis=1)
    assert (moved == 0).any() and (moved > 0).any()                  # nodes stick and slide
    P = rng.normal(size=(hist.size, 3))
    out = np.zeros((nd, 3))
    c.add_history_product(x, x_prev, None, hist, P, out)
    assert relative_error(out, _directional(lambda hh: grad(x.ravel(), x_prev, hh), hist.ravel(), P)) <= RTOL
    out_T = np.zeros(hist.size)
    c.add_history_product_T(x, x_prev, None, hist, lam, out_T)
    assert relative_error(out_T @ P, lam @ out) <= 1e-12
    tangent = c.history_tangent(x, x_prev, hist, S, P)

    def nxt(v):
        return c.next_history(v[:nd].reshape(-1, 3), x_prev, v[nd:].reshape(-1, 2)).ravel()
    fd = _directional(nxt, np.r_[x.ravel(), hist.ravel()], np.r_[S, P])
    assert relative_error(tangent, fd) <= RTOL
    m = rng.normal(size=hist.size)
    ox, oh = np.zeros(nd), np.zeros(hist.size)
    c.history_tangent_T(x, x_prev, hist, m, ox, oh)
    assert relative_error(ox @ S + oh @ P, m @ tangent) <= 1e-12
    # lifted nodes are re-anchored at their feet, where the anchors of a body at rest are
    lifted = x.copy()
    lifted[:, 1] += 0.05
    assert np.allclose(c.next_history(x, lifted, hist), c.initial_history(x), atol=1e-15)


@pytest.mark.parametrize("model,tol", [("coulomb", 1e-6), ("paper", 1e-4)])
def test_rollout_sensitivities_on_rough_ground(model, tol):
    K = 20
    robot = tripod(model, ROUGH)
    sim = Simulator(robot, newton=TIGHT)
    x0 = sim.rest_state()
    u0 = gait(robot, "length", K)
    rng = np.random.default_rng(7)
    dudz = 1e-3 * rng.normal(size=(K, robot.n_motors, 4))
    traj = sim.rollout(u0, x0=x0)
    assert np.isfinite(traj.x).all() and np.abs(traj.com[-1] - traj.com[0]).max() > 1e-4
    errs = rollout_jacobian_errors(sim, u0, dudz, x0=x0, n_dirs=2, h=3e-5, rng=rng)
    assert max(errs.values()) <= tol, errs


@pytest.mark.parametrize("model", ["coulomb", "paper"])
def test_flat_field_is_the_plane(model):
    robot = tripod(model)
    u = gait(robot, "length", 30)
    plane = Simulator(robot, newton=NewtonOptions(tol=1e-12))
    flat = Simulator(robot.replace(ground=HeightField.flat()), newton=NewtonOptions(tol=1e-12))
    start = plane.rest_state()
    a, b = plane.rollout(u, x0=start), flat.rollout(u, x0=start)
    assert np.abs(a.com[-1] - a.com[0]).max() > 1e-3                   # it walks
    assert np.abs(a.x - b.x).max() <= 1e-9
    assert np.abs(flat.rest_state().x - start.x).max() <= 1e-9


@pytest.mark.parametrize("model", ["coulomb", "paper"])
def test_planar_slope_field_is_the_rotated_incline(model):
    """The Tripod on the plane with gravity ``incline_gravity(12)`` and on the field
    ``HeightField.incline(12)`` with gravity -y, started from the rotated state: the same
    rollout, rotated (``R`` maps the plane's frame to the world: ``R e_y`` is the slope's normal)."""
    angle = 12.0
    robot = tripod(model)
    u = gait(robot, "length", 30)
    inclined = Simulator(robot, gravity=incline_gravity(angle), newton=NewtonOptions(tol=1e-12))
    field = Simulator(robot.replace(ground=HeightField.incline(angle)), newton=NewtonOptions(tol=1e-12))
    ca, sa = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    R = np.array([[ca, -sa, 0.0], [sa, ca, 0.0], [0.0, 0.0, 1.0]])
    start = inclined.rest_state()
    history = list(start.history)
    if history[2] is not None:                 # anchors (x, z) on the plane -> (x, z) of the rotated points
        p = np.stack([history[2][:, 0], np.zeros(len(history[2])), history[2][:, 1]], axis=1) @ R.T
        history[2] = np.ascontiguousarray(p[:, [0, 2]])
    a = inclined.rollout(u, x0=start)
    b = field.rollout(u, x0=field.state_at_rest(start.x @ R.T, tuple(history)))
    assert np.abs(a.com[-1] - a.com[0]).max() > 5e-4
    assert np.abs(a.x @ R.T - b.x).max() <= 1e-9


@pytest.mark.parametrize("model", ["coulomb", "paper"])
def test_field_contact_parameter_jacobians(model):
    """``add_parameter_jacobian`` of every term on rough ground (contact stiffness and the law's
    friction parameter for the contact term) against central differences of the gradient
    (tests/test_parameter_derivatives.py's check, relative error <= 1e-6)."""
    from .test_parameter_derivatives import check_term_parameter_jacobians
    sim = Simulator(tripod(model, ROUGH))
    x, x_prev, hist = _perturbed(sim, np.random.default_rng(1))
    history = list(sim.system.initial_history(x_prev))
    history[sim.system.terms.index(sim.system.contact)] = hist
    check_term_parameter_jacobians(sim, x, x_prev, np.full(sim.robot.n_motors, 0.004), tuple(history))


def test_the_rest_states_leg_derivative_is_refused_on_a_relief():
    """On a relief the initial anchors are the nodes' feet on the surface (not linear in the
    positions): the derivative with respect to the leg morph is refused, naming the ground."""
    from soft_envs.sim.design import DesignParameters, LegMorph, legs_below
    robot = load_robot("tripod").replace(ground=HeightField.step(0.004, 0.3))
    design = DesignParameters(robot, [LegMorph(robot, legs_below(robot, 0.03), 0.03)])
    with pytest.raises(ValueError, match="leg morph\\) is not available on step of 0.004 m"):
        Simulator(robot).rest_sensitivity(design)
