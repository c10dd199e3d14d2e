"""A second body (soft_envs.sim.box, issue #39's carry and push tasks): the box's model, its
contact with the robot (soft_envs.sim.contact.box_contact) against central finite differences,
its ground contact under both laws, friction that holds a payload on a tilt and lets it slide
beyond, a push, the sensitivities (every product and whole rollouts against central
differences), and nothing changed for a robot without a box."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from soft_envs.sim import Box, NewtonOptions, SimulationError, Simulator, incline_gravity, with_box
from soft_envs.sim.box import BOX_FACES, BOX_TETS, MAX_OVERLAP
from soft_envs.sim.contact.box_contact import BoxContact
from soft_envs.sim.contact.box_geometry import face_geometry
from soft_envs.sim.parameters import node_mass_jacobian

from .conftest import small_robot
from .gradcheck import rollout_jacobian_errors
from .test_energy_derivatives import check_every_term

RTOL = 1e-6          # the project's bound on every derivative against central differences
H = 1e-7             # the finite-difference step [m]


def _robot(law="coulomb", mu_box=0.8, mass=0.01, press=1e-4, blend=5e-4):
    """The 6 x 2 x 2 cm foam bar of the tests with a 3 x 1 x 3 cm box pressed ``press`` into its top."""
    r = small_robot()
    r = r.replace(contact=dataclasses.replace(r.contact, model=law))
    top = float(r.mesh.points[:, 1].max())
    box = Box(size=(0.03, 0.01, 0.03), center=(0.03, top + 0.005 - press, 0.01), mass=mass,
              friction_coefficient=mu_box, blend=blend)
    return with_box(r, box)


def _fd_errors(term, x, x_prev, hist, rng, n_dirs=6):
    """Largest relative errors of the gradient (vs differences of the energy) and of the Hessian
    (vs differences of the gradient) over random unit directions."""
    sim_pattern = term._pattern
    def grad(y):
        g, hd = np.zeros(y.size), np.zeros(sim_pattern.nnz + 1)
        term.assemble(y.reshape(-1, 3), x_prev, None, hist, g, hd, True)
        return g, hd
    y = x.ravel()
    g, hd = grad(y)
    Hm = sim_pattern.full(hd)
    free = term._free
    eg = eh = 0.0
    for _ in range(n_dirs):
        d = rng.normal(size=y.size)
        d /= np.linalg.norm(d)
        fd = (term.energy((y + H * d).reshape(-1, 3), x_prev, None, hist)
              - term.energy((y - H * d).reshape(-1, 3), x_prev, None, hist)) / (2 * H)
        eg = max(eg, abs(fd - g @ d) / abs(fd))
        fdg = ((grad(y + H * d)[0] - grad(y - H * d)[0]) / (2 * H))[free]
        eh = max(eh, np.linalg.norm(fdg - Hm @ d[free]) / np.linalg.norm(fdg))
    return eg, eh


def _pressed_state(robot, rng, depth, blend_case=False):
    """Positions with the box pressed ``depth`` into the bar's top, everything jittered."""
    x = np.array(robot.mesh.points)
    box = robot.box_nodes
    x[box, 1] -= depth
    x[box] += rng.normal(scale=1e-4, size=(8, 3))         # a slightly warped, turned box
    n = robot.n_robot_nodes
    x[:n] += rng.normal(scale=2e-5 if blend_case else 5e-5, size=(n, 3))
    return x


@pytest.mark.parametrize("case", ["quadratic", "blend", "stick", "slide", "half_quadratic"])
def test_box_contact_gradient_and_hessian_match_central_differences(case):
    """The box term alone: the penalty in its quadratic part and in its C2 blend, friction with
    the anchors within the slip distance (sticking) and beyond (sliding), and the half-quadratic
    (blend 0). Relative errors <= 1e-6 (h = 1e-7 m, random unit directions); measured 3e-10 -
    3e-8."""
    rng = np.random.default_rng(["quadratic", "blend", "stick", "slide", "half_quadratic"].index(case))
    robot = _robot(blend=0.0 if case == "half_quadratic" else 5e-4)
    sim = Simulator(robot)
    term = sim.system.terms[-1]
    assert isinstance(term, BoxContact)
    term._pattern, term._free = sim.system.pattern, sim.system.free
    depth = 3e-4 if case == "blend" else 1.5e-3
    x = _pressed_state(robot, rng, depth, blend_case=case == "blend")
    x_prev = x.copy()
    x_prev[robot.box_nodes, 1] += 2e-4                     # the lagged normal force is the step before's
    hist = term.initial_history(x_prev)
    anchored = hist[:, 0] >= 0
    assert anchored.sum() >= 3
    s, _ = term.depths(x, x_prev)
    if case == "blend":
        assert ((s > 0) & (s < 5e-4)).sum() >= 3
    # anchors moved on the faces (3 cm): 0.06 mm (r < r_s), 0.2 mm (stick) or 6 cm (slide); not at
    # r = 0, where G ~ r^3 makes the differences of the Hessian inexact (an O(h / r_s) error)
    shift = {"stick": 2e-4, "slide": 2e-3}.get(case, 6e-5) / 0.03
    hist[anchored, 1] += shift * rng.choice([-1.0, 1.0], size=anchored.sum())
    eg, eh = _fd_errors(term, x, x_prev, hist, rng)
    assert eg <= RTOL and eh <= RTOL, (case, eg, eh)


def test_face_normal_second_derivatives_match_central_differences():
    """``d n / dy`` and ``d^2 n / dy^2`` of a warped face (the geometry every Hessian uses)."""
    rng = np.random.default_rng(5)
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float) * 0.02
    F = square + rng.normal(scale=1e-3, size=(4, 3))
    n, Dn, D2n = face_geometry(F, True)
    for _ in range(4):
        d = rng.normal(size=12)
        d /= np.linalg.norm(d)
        np_, Dp, _ = face_geometry(F + H * d.reshape(4, 3), False)
        nm, Dm, _ = face_geometry(F - H * d.reshape(4, 3), False)
        assert np.linalg.norm((np_ - nm) / (2 * H) - Dn[:, 3:] @ d) <= RTOL * np.linalg.norm(Dn[:, 3:] @ d)
        fd2 = (Dp - Dm)[:, 3:] / (2 * H)
        assert np.linalg.norm(fd2 - D2n[:, 3:, 3:] @ d) <= RTOL * np.linalg.norm(fd2)
    assert np.allclose(Dn[:, :3], 0) and np.allclose(D2n[:, :3], 0)       # the node does not move the face


@pytest.mark.parametrize("law", ["paper", "coulomb"])
def test_the_whole_energy_with_a_box_and_its_projected_hessian(law):
    """Every term together (the box's corners pressed into the ground too): gradient and Hessian
    against central differences (<= 1e-6), and the projected Hessian positive semi-definite
    with the same energy and gradient."""
    rng = np.random.default_rng(11)
    robot = _robot(law)
    sim = Simulator(robot)
    x = _pressed_state(robot, rng, 1.5e-3)
    x[:, 1] -= 3e-4                                           # everything a little into the ground
    x_prev = x + rng.normal(scale=2e-5, size=x.shape)
    hist = sim.system.initial_history(x_prev)
    system = sim.system
    e, g, hd = system.assemble(x, x_prev, np.zeros(1), history=hist)
    Hm = system.pattern.full(hd)
    for _ in range(4):
        d = rng.normal(size=x.size)
        d /= np.linalg.norm(d)
        ep = system.energy(x + H * d.reshape(-1, 3), x_prev, np.zeros(1), hist)
        em = system.energy(x - H * d.reshape(-1, 3), x_prev, np.zeros(1), hist)
        assert abs((ep - em) / (2 * H) - g @ d) <= RTOL * abs((ep - em) / (2 * H))
        gp = system.assemble(x + H * d.reshape(-1, 3), x_prev, np.zeros(1), history=hist)[1]
        gm = system.assemble(x - H * d.reshape(-1, 3), x_prev, np.zeros(1), history=hist)[1]
        fd = ((gp - gm) / (2 * H))[system.free]
        assert np.linalg.norm(fd - Hm @ d[system.free]) <= RTOL * np.linalg.norm(fd)
    term = system.terms[-1]
    g0, h0 = np.zeros(x.size), np.zeros(system.pattern.nnz + 1)
    g1, h1 = np.zeros(x.size), np.zeros(system.pattern.nnz + 1)
    e0 = term.assemble(x, x_prev, None, hist[-1], g0, h0, True)
    e1 = term.assemble_projected(x, x_prev, None, hist[-1], g1, h1)
    assert e0 == e1 and np.array_equal(g0, g1)
    w = np.linalg.eigvalsh(system.pattern.full(h1).toarray())
    assert w.min() >= -1e-9 * np.abs(w).max()


def test_the_box_model():
    """Mass on its corners, the robot's COM and mass without it, its tets positive, its faces
    outward, the checks of with_box and Box."""
    r = small_robot()
    rb = _robot(mass=0.012)
    assert rb.mesh.n_nodes == r.mesh.n_nodes + 8 and rb.mesh.n_tets == r.mesh.n_tets + len(BOX_TETS)
    assert rb.mesh.bodies == 2 and np.all(rb.mesh.volumes[-5:] > 0)
    np.testing.assert_array_equal(rb.node_masses[rb.box_nodes], 0.012 / 8)
    np.testing.assert_array_equal(rb.node_masses[:r.mesh.n_nodes], r.node_masses)
    assert rb.total_mass == r.total_mass and rb.body_mass == pytest.approx(r.body_mass, rel=1e-15)
    x = np.array(rb.mesh.points)
    np.testing.assert_allclose(rb.com(x), r.com(r.mesh.points), rtol=1e-15)
    assert np.all(node_mass_jacobian(rb, ["density"])[rb.box_nodes] == 0)
    np.testing.assert_allclose(rb.element_modulus_scale[-5:], 2e6 / r.youngs_modulus)
    c = rb.box.corners()
    for f in BOX_FACES:                                     # (c - a) x (d - b) points out of the box
        a, b, cc, d = c[f]
        assert np.cross(cc - a, d - b) @ (c[f].mean(axis=0) - c.mean(axis=0)) > 0
    with pytest.raises(ValueError, match="has a box already"):
        with_box(rb, rb.box)
    with pytest.raises(ValueError, match="overlaps the robot"):
        with_box(r, rb.box.moved((0.03, 0.012, 0.01)))
    assert MAX_OVERLAP == 1e-3
    for bad in (dict(mass=0.0), dict(size=(0.01, -0.01, 0.01)), dict(friction_coefficient=-1.0),
                dict(center=(0.0, np.nan, 0.0)), dict(slip_distance=0.0)):
        with pytest.raises(ValueError, match="box."):
            Box(**{**dict(size=(0.01, 0.01, 0.01), center=(0, 0, 0), mass=0.01), **bad})
    with pytest.raises(ValueError, match="needs a box"):
        r.replace(mesh=rb.mesh)


def test_without_a_box_the_terms_and_the_masses_are_the_old_ones():
    """No box: the four terms of before, the same mass arrays (the very objects), a 1-body mesh."""
    r = small_robot()
    sim = Simulator(r)
    assert [t.name for t in sim.system.terms] == ["elastic", "cables", "contact", "gravity"]
    assert r.body_node_masses is r.node_masses and r.box is None and r.box_nodes.size == 0
    rb = _robot()
    assert [t.name for t in Simulator(rb).system.terms][-1] == "box_contact"


@pytest.mark.parametrize("law", ["paper", "coulomb"])
def test_a_box_falls_onto_the_ground_and_rests_on_it(law):
    """A box released 5 mm above the ground beside the bar: gravity, the ground law on its
    corners; after 1 s it rests on the ground (centre at half its height, to the penetration)."""
    r = small_robot()
    r = r.replace(contact=dataclasses.replace(r.contact, model=law))
    rb = with_box(r, Box(size=(0.02, 0.01, 0.02), center=(0.09, 0.01, 0.01), mass=0.01))
    sim = Simulator(rb, substeps=4)
    state = sim.state_at_rest(np.array(rb.mesh.points))
    for _ in range(30):
        state = sim.step(state, np.zeros(1))
    c = state.x[rb.box_nodes].mean(axis=0)
    assert abs(c[1] - 0.005) < 5e-4 and abs(c[0] - 0.09) < 1e-4
    assert np.abs(state.x[rb.box_nodes] - state.x_prev[rb.box_nodes]).max() < 1e-6


def _tilted(mu_box, angle=20.0, steps=30):
    """The bar with its box at rest on flat ground, then gravity tilted by ``angle`` degrees (a
    slope along +x) for ``steps`` control steps of 33 ms: the box's slip along x relative to the
    bar's top nodes after each step [m]."""
    robot = _robot(mu_box=mu_box)
    state = Simulator(robot, substeps=4).rest_state()
    sim = Simulator(robot, substeps=4, gravity=incline_gravity(angle))
    n = robot.n_robot_nodes
    top = np.flatnonzero(robot.mesh.points[:n, 1] >= robot.mesh.points[:n, 1].max() - 1e-9)
    def offset(x):
        return x[robot.box_nodes, 0].mean() - x[top, 0].mean()
    start, slip = offset(state.x), []
    for _ in range(steps):
        state = sim.step(state, np.zeros(1))
        slip.append(offset(state.x) - start)
    return np.array(slip)


def test_friction_holds_the_payload_on_a_tilt_and_lets_it_slide_beyond():
    """On 20 degrees (tan = 0.36): with mu_b = 0.8 the box holds on the bar's top (it deflects
    0.1 mm within its slip distance, then no creep: < 0.01 mm from 0.1 s to 1 s); with mu_b =
    0.2 it slides down at g (sin a - mu_b cos a): 20.2 mm against 20.6 mm in closed form after
    5 steps (0.165 s; within 10 %)."""
    held = _tilted(0.8)
    assert np.abs(held).max() < 3e-4 and np.abs(held[2:] - held[2]).max() < 1e-5
    a = 9.81 * (np.sin(np.radians(20.0)) - 0.2 * np.cos(np.radians(20.0)))
    slid = _tilted(0.2, steps=5)
    assert slid[-1] == pytest.approx(-0.5 * a * (5 * 0.033) ** 2, rel=0.1)


def test_a_moving_robot_pushes_the_box():
    """The bar thrown at 0.3 m/s towards a box on the ground 2 mm ahead: the box moves along +x
    (the robot's nodes push its -x face); without the bar's push it stays."""
    r = small_robot()
    rb = with_box(r, Box(size=(0.02, 0.015, 0.03), center=(0.072, 0.0075, 0.01), mass=0.005))
    sim = Simulator(rb, substeps=4)
    x = np.array(rb.mesh.points)
    x_prev = x.copy()
    x_prev[:rb.n_robot_nodes, 0] -= 0.3 * sim.physics_dt
    from soft_envs.sim import State
    state = State(x, x_prev, None, sim.initial_history(x), 0)
    for _ in range(10):
        state = sim.step(state, np.zeros(1))
    moved = state.x[rb.box_nodes, 0].mean() - 0.072
    assert moved > 1e-3


@pytest.mark.parametrize("case", ["stick", "slide", "fresh"])
def test_every_derivative_of_the_box_term_matches_central_differences(case):
    """The project's check of every term (tests/test_energy_derivatives.py: gradient, Hessian,
    d grad / d x_prev and d grad / d anchors with their transposes, the anchors' update and its
    transpose; relative error <= 1e-6, h = 1e-7) at a state with the box pressed into the bar:
    anchors sticking (0.2 mm from the nodes), sliding (6 cm) and fresh (the nodes re-anchored
    at their projections on the faces)."""
    rng = np.random.default_rng(3)
    robot = _robot()
    sim = Simulator(robot)
    x = _pressed_state(robot, rng, 1.5e-3)
    x_prev = x + rng.normal(scale=1e-4, size=x.shape)
    x_prev[robot.box_nodes, 1] += 2e-4
    history = list(sim.system.initial_history(x_prev))
    h = history[-1].copy()
    anchored = h[:, 0] >= 0
    h[anchored, 1] += {"stick": 2e-4, "slide": 2e-3, "fresh": 0.0}[case] / 0.03 * rng.choice([-1.0, 1.0],
                                                                                           size=anchored.sum())
    if case == "fresh":
        h[:, 0] = -1.0
    history[-1] = h
    term = sim.system.terms[-1]
    new = term.next_history(x, x_prev, h)
    kept = np.all(new[anchored] == h[anchored], axis=1)
    assert anchored.sum() >= 3 and {"stick": kept.sum() >= 2, "slide": not kept.any(),
                                     "fresh": (new[:, 0] >= 0).sum() >= 3}[case]
    check_every_term(sim, x, x_prev, np.zeros(1), rng, tuple(history))


@pytest.mark.parametrize("law", ["coulomb", "paper"])
def test_rollout_jacobians_with_a_box_match_central_differences(law):
    """12 steps of the bar's cable lifting its box (the box held by friction, moving 0.07-0.4
    mm): dx/dz, dCOM/dz and dGamma/dz against central differences (h = 1e-7; measured <= 4e-7)
    and the adjoint gradient of the box's position against forward mode (measured 3e-10 -
    3e-8)."""
    robot = _robot(law)
    sim = Simulator(robot, newton=NewtonOptions(tol=1e-11))
    K = 12
    t = np.arange(K) * sim.dt
    u0 = (0.004 * (1 - np.cos(2 * np.pi * t / 0.4)))[:, None]
    dudz = np.stack([np.ones(K), np.sin(10 * t), t], axis=1)[:, None, :]
    err = rollout_jacobian_errors(sim, u0, dudz, n_dirs=2, h=1e-7)
    assert max(err.values()) <= 1e-6, err
    traj = sim.rollout(u0, dudz=dudz, store_dxdz=True)
    assert (traj.info["history"][-1][:, 0] >= 0).sum() >= 3
    w = np.zeros(traj.x.shape)
    w[1:, robot.box_nodes, 0], w[1:, robot.box_nodes, 1] = 1.0, 0.5
    forward = np.einsum("ki,kiz->z", w.reshape(K + 1, -1), traj.dxdz)
    adjoint = sim.rollout_gradient(u0, w, dudz=dudz, traj=traj)
    assert np.linalg.norm(adjoint - forward) <= 1e-7 * np.linalg.norm(forward)


def test_a_failed_step_is_a_simulation_error():
    rb = _robot()
    stiff = Simulator(rb, newton=NewtonOptions(max_iter=1))
    state = stiff.rest_state()
    with pytest.raises(SimulationError):
        stiff.step(state, np.array([0.01]))
