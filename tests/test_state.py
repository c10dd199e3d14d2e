"""The simulation state (issue #27 item 1): one frozen :class:`State`, one loop body.

* The rest-anchor trap, under both contact laws: ``sim.rollout(u, x0=sim.rest_state())`` is
  ``sim.rollout(u)`` bit for bit (a 24 mm Coulomb cube on a 20-degree slope, which does not
  creep from there; the same cube under the paper's law), and a bare array ``x0`` is the body at
  rest there with its anchors where it stands, as documented.
* ``State`` is immutable; ``Simulator.step(state, u)`` chained K times is the rollout bit for
  bit; the environments' step is the same loop (bit for bit too); the deprecated positions form
  of ``step`` still works.
* The adjoint re-walks the states from the rollout's start (a moving start included).
* dt has one home: the solver's; the defaults come from ``soft_envs.sim.timing``.
"""
from __future__ import annotations

import dataclasses
import pickle

import meshio
import numpy as np
import pytest

from soft_envs.sim import (DEFAULT_DT, GAIT_CYCLE_STEPS, ContactParams, FactorCache, Robot, Simulator, State,
                           incline_gravity, load_robot)
from soft_envs.sim.meshgen import voxel_tet_mesh

from .conftest import small_robot

SECONDS = 3.0


def cube(model: str, size: float = 0.024, mu: float = 0.5) -> Robot:
    """A soft cube (as tests/test_coulomb.py builds them) with contact law ``model``."""
    xs = np.linspace(0.0, size, 3)
    p, t = voxel_tet_mesh(xs, xs, xs, np.ones((2, 2, 2), bool))
    contact = ContactParams(model=model, friction_coefficient=mu) if model == "coulomb" else ContactParams()
    return Robot.from_mesh(meshio.Mesh(p, [("tetra", t)]), youngs_modulus=1e5, poisson_ratio=0.3,
                           density=200.0, contact=contact)


def on_slope(model: str) -> Simulator:
    return Simulator(cube(model), gravity=incline_gravity(20.0, uphill=(-1.0, 0.0)))


def same_rollout(a, b) -> None:
    for name in ("x", "com", "cable_deformation", "newton_iterations"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


# ------------------------------------------------------------------ the rest-anchor trap
def test_coulomb_cube_from_its_rest_state_is_the_default_rollout_and_stays_put():
    sim = on_slope("coulomb")
    u = np.zeros((int(round(SECONDS / sim.dt)), 0))
    default, from_rest = sim.rollout(u), sim.rollout(u, x0=sim.rest_state())
    same_rollout(default, from_rest)
    moved = np.abs(from_rest.x - from_rest.x[0]).max()
    assert moved < 1e-7, f"crept {1e3 * moved:.2e} mm in {SECONDS} s"       # < 1e-4 mm


def test_paper_law_cube_from_its_rest_state_is_the_default_rollout():
    sim = on_slope("paper")
    u = np.zeros((int(round(SECONDS / sim.dt)), 0))
    same_rollout(sim.rollout(u), sim.rollout(u, x0=sim.rest_state()))


def test_a_bare_array_x0_is_the_body_at_rest_there_with_fresh_anchors():
    """As the docstring says: positions alone are the body at rest there, its anchors where the
    nodes stand (unloaded), not the rest state's loaded ones; so for the Coulomb law the rest
    positions alone are a different start from the rest state (which a user passes as the State)."""
    sim = on_slope("coulomb")
    u = np.zeros((30, 0))
    rest = sim.rest_state()
    bare = sim.rollout(u, x0=np.array(rest.x))
    same_rollout(bare, sim.rollout(u, x0=sim.state_at_rest(rest.x)))
    assert not np.array_equal(bare.x, sim.rollout(u).x)
    i = sim.system.terms.index(sim.system.contact)
    np.testing.assert_array_equal(sim.state_at_rest(rest.x).history[i], sim.initial_history(rest.x)[i])
    # a State carries its own x_prev and history: giving them again is refused, not merged
    with pytest.raises(ValueError, match="x0 is a State"):
        sim.rollout(u, x0=rest, history0=rest.history)
    with pytest.raises(ValueError, match="x_prev0"):
        sim.rollout(u, x0=rest, x_prev0=rest.x)
    # functions that take positions refuse a State instead of reading it as an array
    with pytest.raises(ValueError, match="got a State"):
        sim.initial_history(rest)


def test_rest_positions_and_history_are_the_rest_states():
    sim = on_slope("coulomb")
    rest = sim.rest_state()
    pos = sim.rest_positions()
    np.testing.assert_array_equal(pos, rest.x)
    assert pos.flags.writeable and pos is not rest.x
    assert sim.rest_history() is rest.history
    assert rest.k == 0 and rest.x_prev is rest.x and rest.x_prev2 is rest.x


# ------------------------------------------------------------------ the State
def test_state_is_immutable_and_copies_what_it_is_given():
    x = np.zeros((4, 3))
    hist = (None, np.ones((2, 2)))
    s = State(x, x + 1.0, None, hist, 3)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.x = x
    for a in (s.x, s.x_prev, s.history[1]):
        assert not a.flags.writeable
        with pytest.raises(ValueError):
            a[0, 0] = 7.0
    x[0, 0] = 5.0                                   # the caller's arrays stay theirs
    hist[1][0, 0] = 5.0
    assert s.x[0, 0] == 0.0 and s.history[1][0, 0] == 1.0 and x.flags.writeable
    assert isinstance(s.history, tuple)
    back = pickle.loads(pickle.dumps(s))
    assert not back.x.flags.writeable and back.k == 3 and back.x_prev2 is None
    np.testing.assert_array_equal(back.x_prev, s.x_prev)


@pytest.mark.parametrize("bad, match", [
    (dict(x=np.zeros((4, 2))), r"State.x must have shape \(n, 3\)"),
    (dict(x_prev=np.zeros((5, 3))), "State.x_prev must have the shape"),
    (dict(x_prev2=np.zeros((3, 3))), "State.x_prev2 must have the shape"),
    (dict(history=None), "State.history must be a tuple"),
    (dict(k=-1), "State.k must be an integer >= 0"),
    (dict(k=1.5), "State.k must be an integer >= 0"),
])
def test_bad_states_are_refused_naming_the_field(bad, match):
    fields = dict(x=np.zeros((4, 3)), x_prev=np.zeros((4, 3)), x_prev2=None, history=(None,), k=0)
    with pytest.raises(ValueError, match=match):
        State(**{**fields, **bad})


def test_the_simulator_checks_a_state_against_its_robot():
    sim = on_slope("coulomb")
    rest = sim.rest_state()
    with pytest.raises(ValueError, match=r"state.x must have shape"):
        sim.step(State.at_rest(rest.x[:5], rest.history), np.zeros(0))
    with pytest.raises(ValueError, match=r"state.history\[2\] must be a finite array"):
        sim.step(rest.replace(history=tuple(None if h is None else h[:3] for h in rest.history)), np.zeros(0))
    with pytest.raises(ValueError, match=r"x0 must have shape \(27, 3\)"):
        sim.rollout(np.zeros((2, 0)), x0=(rest.x, rest.x))          # neither a State nor positions


# ------------------------------------------------------------------ one loop body
def _chained(sim, state, u):
    cache = FactorCache()
    xs = [state.x]
    for k in range(len(u)):
        state = sim.step(state, u[k], factor_cache=cache)
        xs.append(state.x)
    return state, np.array(xs)


@pytest.mark.parametrize("model", ["coulomb", "paper"])
def test_chained_steps_are_the_rollout_bit_for_bit(model):
    sim = on_slope(model)
    u = np.zeros((40, 0))
    traj = sim.rollout(u)
    end, xs = _chained(sim, sim.rest_state(), u)
    np.testing.assert_array_equal(xs, traj.x)
    assert end.k == 40
    fin = traj.info["state"]
    np.testing.assert_array_equal(fin.x, end.x)
    for a, b in zip(fin.history, end.history):
        assert (a is None and b is None) or np.array_equal(a, b)
    # continuing from the final state: the chained steps from there (a fresh factorisation
    # cache, so the longer rollout only to within the Newton tolerance)
    more = sim.rollout(np.zeros((10, 0)), x0=fin)
    np.testing.assert_array_equal(more.x, _chained(sim, fin, np.zeros((10, 0)))[1])
    tol = sim.newton.options.tol
    np.testing.assert_allclose(more.x, sim.rollout(np.zeros((50, 0))).x[40:], rtol=0, atol=tol)


def test_chained_steps_of_a_shipped_robot_are_its_rollout():
    robot = load_robot("tripod")
    sim = Simulator(robot)
    t = np.arange(12) * sim.dt
    lo, hi = robot.u_bounds[:, 0], robot.u_bounds[:, 1]
    u = lo + (hi - lo) * 0.5 * (1 - np.cos(2 * np.pi * t[:, None] / 1.2 + np.arange(robot.n_motors)))
    traj = sim.rollout(u)
    np.testing.assert_array_equal(_chained(sim, sim.rest_state(), u)[1], traj.x)


def test_the_deprecated_positions_step_is_the_state_step():
    sim = on_slope("coulomb")
    rest = sim.rest_state()
    with pytest.warns(DeprecationWarning, match="pass a State"):
        x = sim.step(rest.x, rest.x, np.zeros(0), history=rest.history, x_prev3=rest.x)
    np.testing.assert_array_equal(x, sim.step(rest, np.zeros(0)).x)
    assert x.flags.writeable
    np.testing.assert_array_equal(sim.step(rest, u=np.zeros(0)).x, x)
    with pytest.raises(TypeError, match="takes the State"):
        sim.step(rest, np.zeros(0), 3)


@pytest.mark.filterwarnings("ignore:.*SoftTripod-v0 is out of date:DeprecationWarning")   # -v0 on purpose: both laws
@pytest.mark.parametrize("env_id", ["SoftTripod-v0", "SoftTripod-v1"])
def test_the_environment_steps_through_the_same_loop(env_id):
    gym = pytest.importorskip("gymnasium")
    import soft_envs  # noqa: F401  (registers the environments)
    env = gym.make(env_id, reset_noise_scale=0.0, frame_skip=2)
    env.reset(seed=0)
    e = env.unwrapped
    sim = e.simulator
    state = sim.rest_state(e.robot.u_rest)
    actions = np.random.default_rng(0).uniform(-1, 1, size=(4, e.robot.n_motors)).astype(np.float32)
    for a in actions:
        info = env.step(a)[4]
        cache = FactorCache()                       # one per environment step, as the env does
        for u in info["u_substeps"]:
            state = sim.step(state, u, factor_cache=cache)
        got = e.get_state()
        np.testing.assert_array_equal(got["x"], state.x)
        np.testing.assert_array_equal(got["x_prev"], state.x_prev)
        assert got["sim_steps"] == state.k
    # env.rollout starts from the reset state: the simulator's default rollout
    u = np.tile(e.robot.u_rest, (5, 1))
    np.testing.assert_array_equal(e.rollout(u).x, sim.rollout(u, x0=sim.rest_state(e.robot.u_rest)).x)


# ------------------------------------------------------------------ the adjoint re-walks the states
@pytest.mark.parametrize("moving", [False, True])
def test_adjoint_from_a_state_matches_the_forward_sensitivities(moving):
    """The adjoint and the forward recurrence (whose central-difference checks are in
    tests/test_sensitivity.py) agree for a Coulomb bar from its rest state (loaded anchors) and
    from a state that is not at rest (x_prev != x) with other anchors: the adjoint re-walks the
    rollout from the State it started from (``traj.info["start"]``)."""
    sim = Simulator(small_robot(contact=ContactParams(model="coulomb", friction_coefficient=0.5)),
                    gravity=incline_gravity(20.0, uphill=(-1.0, 0.0)))
    K = 12
    start = sim.rest_state()
    if moving:          # and re-anchored where it stands: not the rest state's anchors
        start = sim.state_at_rest(start.x).replace(x_prev=start.x - np.array([1e-3, 0.0, 0.0]) * sim.dt,
                                                   x_prev2=None)
    rng = np.random.default_rng(3)
    u = np.linspace(0.0, 0.003, K)[:, None]
    dudz = rng.normal(size=(K, 1, 3)) * 1e-3
    w = rng.normal(size=(K + 1, sim.n_nodes, 3))
    traj = sim.rollout(u, x0=start, dudz=dudz, store_dxdz=True)
    assert traj.info["start"] is start
    forward = np.einsum("kd,kdz->z", w.reshape(K + 1, -1)[1:], traj.dxdz[1:])
    adjoint = sim.rollout_gradient(u, w, dudz=dudz, traj=traj)
    np.testing.assert_allclose(adjoint, forward, rtol=1e-6)
    np.testing.assert_allclose(sim.rollout_gradient(u, w, x0=start, dudz=dudz), forward, rtol=1e-4)   # re-simulated


# ------------------------------------------------------------------ dt in one place
def test_dt_has_one_home():
    assert DEFAULT_DT == 0.033 and GAIT_CYCLE_STEPS == 72
    sim = Simulator(cube("paper"))
    assert sim.dt == DEFAULT_DT == sim.newton.dt
    with pytest.raises(AttributeError):
        sim.dt = 0.01
    with pytest.raises(AttributeError):
        sim.newton.dt = 0.01
    np.testing.assert_array_equal(sim.newton.inertia, sim.system.mass / DEFAULT_DT**2)
    other = Simulator(cube("paper"), dt=0.0165)
    assert other.dt == 0.0165 and pickle.loads(pickle.dumps(other)).dt == 0.0165


def test_the_environments_and_trajopt_read_the_one_time_step():
    pytest.importorskip("gymnasium")
    from soft_envs.envs import PAPER_GAIT_PERIOD, PAPER_TIMESTEP, SoftRobotEnv
    from trajopt import GaitSpec
    assert PAPER_TIMESTEP == DEFAULT_DT and PAPER_GAIT_PERIOD == GAIT_CYCLE_STEPS * DEFAULT_DT
    # trajopt cannot import soft_envs where GaitSpec lives (its command line must stay light)
    assert GaitSpec().n_cycle == GAIT_CYCLE_STEPS
    env = SoftRobotEnv("tripod", timestep=0.02, frame_skip=3, reset_noise_scale=0.0)
    assert env.timestep == env.simulator.dt == 0.02 and env.dt == 3 * 0.02
    np.testing.assert_array_equal(env._actuation.du_max, env.motor_speed * env.simulator.dt)
    env.reset(seed=0)
    info = env.step(np.zeros(env.robot.n_motors, np.float32))[4]
    assert info["time"] == 3 * env.simulator.dt


@pytest.mark.parametrize("model", ["coulomb", "paper"])
def test_the_terms_are_handed_read_only_positions(model):
    """The system hands every term its positions read-only, the Newton iterates as the states'
    (``soft_envs.sim.terms.readonly``): numba compiles a kernel once per argument type, and a
    writeable array is another type, so a kernel met by both would be compiled twice."""
    robot = load_robot("tripod")
    robot = dataclasses.replace(robot, contact=dataclasses.replace(robot.contact, model=model))
    sim = Simulator(robot)
    seen = []
    names = ("energy", "assemble", "assemble_projected", "add_control_jacobian", "add_prev_product",
             "add_prev_product_T", "add_history_product", "add_history_product_T", "next_history",
             "history_tangent", "history_tangent_T", "initial_history")
    for term in sim.system.terms:
        for name in names:
            method = getattr(term, name, None)
            if method is None:
                continue

            def spy(*args, _method=method, _where=f"{term.name}.{name}", **kwargs):
                seen.append((_where, [a.flags.writeable for a in args[:2] if isinstance(a, np.ndarray)]))
                return _method(*args, **kwargs)
            setattr(term, name, spy)
    u = np.tile(robot.u_rest, (3, 1)) + 1e-3
    traj = sim.rollout(u, dudz=np.full((3, robot.n_motors, 1), 1e-3))
    sim.rollout_gradient(u, np.ones_like(traj.x), dudz=np.full((3, robot.n_motors, 1), 1e-3), traj=traj)
    where = {w for w, _ in seen}
    assert {"elastic.assemble", "cables.assemble", "contact.assemble", "contact.add_prev_product",
            "contact.add_prev_product_T", "elastic.add_control_jacobian"} <= where, where
    writeable = sorted({w for w, flags in seen if any(flags)})
    assert not writeable, f"handed writeable positions: {writeable}"
