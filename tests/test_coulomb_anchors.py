"""The Coulomb law's stick anchors against hand values (soft_envs.sim.coulomb).

``tests/test_physics_magnitudes.py`` checks the Coulomb friction force of a node slid from
where it was (the law's entry in ``FRICTION_LAWS``) and that energy is never created; here the
anchors themselves: the force of a node at a chosen distance from its anchor (exactly mu N
beyond the slip distance, whatever the slip), the anchor update after a step (stick, drag,
re-anchor), a rollout carrying its anchors from step to step (a sliding bar stops where
mu g says and stays there) and starting from the rest state's anchors.
"""
from __future__ import annotations

import numpy as np
import pytest

from soft_envs.sim import NewtonOptions, Robot, Simulator, State, incline_gravity

from .test_physics_magnitudes import G, block, coulomb_friction_force, documented_normal_force


def coulomb_block(mu: float = 0.8, slip_distance: float = 1.5e-4, **kw) -> tuple[Robot, Simulator]:
    robot = block({"model": "coulomb", "friction_coefficient": mu, "slip_distance": slip_distance})
    return robot, Simulator(robot, **kw)


def with_anchors(sim: Simulator, x: np.ndarray, anchors: np.ndarray) -> tuple:
    """The history of ``sim`` at rest at ``x`` with the contact term's anchors replaced."""
    history = list(sim.initial_history(x))
    history[sim.system.terms.index(sim.system.contact)] = np.ascontiguousarray(anchors, dtype=np.float64)
    return tuple(history)


def test_coulomb_force_is_mu_N_beyond_the_slip_distance_whatever_the_slip():
    """The bar pressed 1 mm into the ground, still (x_prev = x); its 8 bottom nodes tied to
    anchors at 0 to 1000 slip distances r_s, in seeded random directions. The friction force
    (dE/dx_t with the anchors minus without friction) is ``mu N (2 rho - rho^2)`` inside r_s and
    exactly ``mu N`` beyond (to 1e-12), against the slip (it points from the node to its
    anchor); a node on its anchor feels none."""
    seed = 7
    robot, sim = coulomb_block()
    c = robot.contact
    X = np.array(robot.mesh.points)
    x = X - [0.0, 1e-3, 0.0]
    nodes = sim.system.contact.nodes
    bottom = X[nodes, 1] < 1e-12
    assert bottom.sum() == 8
    rho = np.array([0.0, 0.3, 0.7, 0.999, 1.001, 2.0, 10.0, 1000.0])
    angle = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, size=8)
    offset = np.zeros((len(nodes), 2))
    offset[bottom] = (rho * c.slip_distance)[:, None] * np.c_[np.cos(angle), np.sin(angle)]
    history = with_anchors(sim, x, x[nodes][:, [0, 2]] - offset)
    u = np.zeros(0)
    no_friction = sim.gradient(x, x + [0.0, 1.0, 0.0], u)
    friction = (sim.gradient(x, x, u, history=history) - no_friction)[nodes]
    N = documented_normal_force(np.full(len(nodes), 1e-3) * bottom, c)
    assert np.all(N[bottom] > 0) and np.all(N[~bottom] == 0)
    expected = coulomb_friction_force(N, offset, c, sim.dt)
    msg = f"seed {seed}"
    np.testing.assert_allclose(friction[:, [0, 2]], expected, rtol=1e-10, atol=1e-13 * N.max(), err_msg=msg)
    magnitude = np.linalg.norm(friction[:, [0, 2]], axis=1)[bottom]
    bound = c.friction_coefficient * N[bottom]
    np.testing.assert_allclose(magnitude[rho > 1], bound[rho > 1], rtol=1e-12, err_msg=msg)   # exactly mu N
    assert np.all(magnitude[rho < 1] < bound[rho < 1]) and magnitude[0] == 0.0, msg
    # dE/dx along the offset: the force -dE/dx points back to the anchor, against the slip
    along = np.sum(friction[:, [0, 2]][bottom] * offset[bottom], axis=1)
    assert np.all(along[1:] > 0), msg


def test_coulomb_anchor_update_by_hand():
    """``next_history`` (soft_envs.sim.coulomb): a node within r_s of its anchor sticks (the
    anchor stays); a node beyond it slides and drags its anchor to exactly r_s behind it, on the
    line to the node; a node without normal force in the step (x_prev above the ground) is
    re-anchored where it is."""
    seed = 11
    robot, sim = coulomb_block()
    rs = robot.contact.slip_distance
    X = np.array(robot.mesh.points)
    nodes = sim.system.contact.nodes
    bottom = np.flatnonzero(X[nodes, 1] < 1e-12)
    x_prev = X - [0.0, 1e-3, 0.0]
    lifted = bottom[-1]                                     # this one had no normal force
    x_prev[nodes[lifted], 1] = 2e-3
    rng = np.random.default_rng(seed)
    x = x_prev + np.c_[rng.normal(scale=1e-3, size=len(X)), np.zeros(len(X)), rng.normal(scale=1e-3, size=len(X))]
    rho = np.array([0.0, 0.5, 0.999, 1.001, 1.5, 3.0, 100.0, 2.0])
    angle = rng.uniform(0.0, 2.0 * np.pi, size=len(bottom))
    t = x[nodes][:, [0, 2]]
    anchors = t + rng.normal(scale=1e-3, size=t.shape)      # nodes above the ground: anywhere
    anchors[bottom] = t[bottom] - (rho * rs)[:, None] * np.c_[np.cos(angle), np.sin(angle)]
    history = with_anchors(sim, x_prev, anchors)
    new = sim.next_history(x, x_prev, history)[sim.system.terms.index(sim.system.contact)]
    expected = t.copy()                                     # no normal force: re-anchored at the node
    for i, r in zip(bottom[:-1], rho[:-1]):
        d = t[i] - anchors[i]
        expected[i] = anchors[i] if r <= 1.0 else t[i] - rs * d / np.linalg.norm(d)
    np.testing.assert_allclose(new, expected, rtol=0, atol=1e-15, err_msg=f"seed {seed}")
    dist = np.linalg.norm(t[bottom[:-1]] - new[bottom[:-1]], axis=1)
    np.testing.assert_allclose(dist, np.minimum(rho[:-1], 1.0) * rs, rtol=1e-9, err_msg=f"seed {seed}")
    assert np.array_equal(anchors[bottom], t[bottom] - (rho * rs)[:, None] * np.c_[np.cos(angle), np.sin(angle)])


def test_coulomb_rollout_carries_the_anchors_and_slides_to_a_stop():
    """A bar at rest (with its rest anchors) given 0.3 m/s along +x: every contact node slides
    and feels mu N against the motion, so the bar decelerates at mu g and stops after
    v^2 / (2 mu g) = 7.6 mm; implicit Euler with h = 2 ms: h sum_j max(v - j mu g h, 0) =
    7.348 mm (measured 7.3478 mm; 1 % allowed). Then it stays where it stopped, its anchors
    having come along: the bristles unload and the bar relaxes its shear, springing back by
    less than 2 r_s (measured 1.5 r_s), and it settles (< 2 um over the last 10 steps). The
    rollout is the documented step-by-step recurrence: ``step`` of a State carrying the history
    (``next_history`` after each step)."""
    mu, v0, h = 0.6, 0.3, 0.002
    robot, sim = coulomb_block(mu, dt=h, newton=NewtonOptions(tol=1e-12))
    x0, h0 = sim.rest_positions(), sim.rest_history()
    K = 75                                                   # 0.15 s: stops after ~0.05 s
    xm1 = x0 - np.array([v0, 0.0, 0.0]) * h
    traj = sim.rollout(np.zeros((K, 0)), x0=x0, x_prev0=xm1, history0=h0)
    state = State(x0, xm1, None, h0)
    for k in range(K):
        prev = state
        state = sim.step(state, np.zeros(0))
        hist = sim.next_history(state.x, prev.x, prev.history)
        assert all(a is b is None or np.array_equal(a, b) for a, b in zip(state.history, hist))
        np.testing.assert_allclose(traj.x[k + 1], state.x, rtol=0, atol=1e-9, err_msg=f"step {k + 1}")
    i = sim.system.terms.index(sim.system.contact)
    np.testing.assert_allclose(traj.info["history"][i], hist[i], rtol=0, atol=1e-9)
    a = mu * G
    j = np.arange(1, int(v0 / (a * h)) + 1)
    expected = h * np.sum(v0 - j * a * h)
    travel = traj.com[:, 0] - traj.com[0, 0]
    stopped = int(travel.argmax())
    assert travel[stopped] == pytest.approx(expected, rel=0.01), (travel[stopped], expected)
    assert 0 < stopped < K // 2
    back = travel[stopped] - travel[stopped:].min()
    assert back < 2 * robot.contact.slip_distance, f"slid back {1e3 * back:.3f} mm after stopping"
    assert np.ptp(travel[-10:]) < 2e-6, "still moving at the end"
    anchors = traj.info["history"][i]
    t = traj.x[-1][sim.system.contact.nodes][:, [0, 2]]
    touching = traj.x[-1][sim.system.contact.nodes, 1] < 0
    assert touching.sum() >= 8
    assert np.linalg.norm(t - anchors, axis=1)[touching].max() <= robot.contact.slip_distance * (1 + 1e-9)
    assert np.abs(anchors - h0[i]).max() > 5e-3                                # dragged along


def test_rollout_from_the_rest_state_starts_with_the_rest_anchors():
    """On a 20-degree slope (mu = 0.8 > tan 20) the rest state holds with loaded bristles
    (nodes up to 40 um from their anchors, ``Simulator.rest_history``). A rollout from the
    rest state starts with those anchors and so does not move (measured 4e-12 m in 30 steps;
    < 1e-9 m asserted); had it re-anchored the nodes where they stand, the bar would slip by
    the bristles' deflection (measured 40 um)."""
    robot, sim = coulomb_block(gravity=incline_gravity(20.0, uphill=(-1.0, 0.0)))
    x0, h0 = sim.rest_positions(), sim.rest_history()
    i = sim.system.terms.index(sim.system.contact)
    nodes = sim.system.contact.nodes
    deflection = np.linalg.norm(x0[nodes][:, [0, 2]] - h0[i], axis=1)
    assert 1e-6 < deflection.max() < robot.contact.slip_distance, deflection.max()
    traj = sim.rollout(np.zeros((30, 0)))
    assert np.abs(traj.x - x0).max() < 1e-9, f"moved {np.abs(traj.x - x0).max():.3e} m from rest"
    same = sim.rollout(np.zeros((30, 0)), x0=x0, history0=h0)
    assert np.array_equal(same.x, traj.x)
