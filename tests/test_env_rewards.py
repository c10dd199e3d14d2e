"""Environment outputs against hand-computed values for a known motion.

The robot is put in the air (1 m above the ground) moving at a known velocity: no contact, no
friction, and internal forces (elastic, cables) do not move the centre of mass, so implicit
Euler moves the COM exactly by ``v dt`` horizontally and by ``-g dt^2`` vertically (from zero
vertical velocity) in one step, up to the Newton tolerance (1e-8 m). Rewards, observations and
the effect of domain randomisation are then checked against numbers computed here from the
documented formulas (class docstrings of SoftTripodEnv / SoftPuppyEnv).
"""
from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils import seeding

import soft_envs  # noqa: F401  (registers the ids)

G = 9.81
DT = 0.033
NEWTON_TOL = 1e-8


def flying(env_id: str, velocity, *, yaw_rate: float = 0.0, **kw):
    """An env whose state is its rest shape lifted by 1 m, moving at ``velocity`` (3,) [m/s]
    horizontally and yawing at ``yaw_rate`` [rad/s] (from +x towards +z) about its COM; the
    applied contractions are the rest ones."""
    env = gym.make(env_id, reset_noise_scale=0.0, **kw)
    env.reset(seed=0)
    u = env.unwrapped
    x = u.get_state()["x"] + [0.0, 1.0, 0.0]
    c = u.robot.com(x)
    h = u.timestep                                         # one simulation step (u.dt is an env step)
    a = -yaw_rate * h                                      # the previous state: rotated back, moved back
    rot = np.array([[math.cos(a), 0.0, -math.sin(a)], [0.0, 1.0, 0.0], [math.sin(a), 0.0, math.cos(a)]])
    x_prev = (x - c) @ rot.T + c - np.asarray(velocity, float) * h
    u.set_state({"x": x, "x_prev": x_prev, "sim_steps": 0})
    return env


def expected_ctrl_cost(action, weight=0.01) -> float:
    """``w_control sum(((a + 1) / 2)^2)``."""
    a = np.asarray(action, dtype=np.float64)
    return weight * float(np.sum(((a + 1.0) / 2.0) ** 2))


@pytest.mark.parametrize("frame_skip", [1, 3])
@pytest.mark.parametrize("env_id, length", [("SoftTripod-v1", 0.14), ("SoftPuppy-v1", 0.13)])
def test_walk_reward_terms_for_a_known_motion(env_id, length, frame_skip):
    """3 cm/s forward: forward reward 10 * 0.03 / L per step, healthy reward 0.1, control cost
    0.01 * sum(((a + 1) / 2)^2) of the commanded action, total their sum. With ``frame_skip``
    n the COM moves n v h in the n simulation steps of an env step of ``env.dt = n h``: the
    velocity (and so the reward) is the same, and ``env.dt`` is n times the simulation step."""
    v = 0.03
    env = flying(env_id, [v, 0.0, 0.0], frame_skip=frame_skip)
    assert env.unwrapped.dt == pytest.approx(frame_skip * DT, rel=1e-15) and env.unwrapped.timestep == DT
    n = env.action_space.shape[0]
    action = np.linspace(-1.0, 1.0, n).astype(np.float32)
    obs, reward, terminated, truncated, info = env.step(action)
    assert env.unwrapped.robot.body_length == length
    assert info["forward_velocity"] == pytest.approx(v / length, rel=NEWTON_TOL / (v * DT))
    assert info["reward_forward"] == pytest.approx(10.0 * v / length, rel=NEWTON_TOL / (v * DT))
    assert info["reward_survive"] == 0.1 and info["is_healthy"] and not terminated
    assert info["reward_ctrl"] == pytest.approx(-expected_ctrl_cost(action), rel=1e-6)   # float32 action
    assert reward == pytest.approx(info["reward_forward"] + 0.1 + info["reward_ctrl"], rel=1e-12)


@pytest.mark.parametrize("heading, velocity, expected", [
    (90.0, [0.0, 0.0, 0.02], 0.02), (90.0, [0.02, 0.0, 0.0], 0.0), (180.0, [0.02, 0.0, 0.0], -0.02),
    (45.0, [0.02, 0.0, 0.02], 0.02 * math.sqrt(2.0))])
def test_forward_reward_is_the_speed_along_the_target_heading(heading, velocity, expected):
    env = flying("SoftTripod-v1", velocity, target_heading_deg=heading)
    info = env.step(-np.ones(2, np.float32))[4]
    assert info["reward_forward"] == pytest.approx(10.0 * expected / 0.14, abs=1e-6)
    assert info["reward_ctrl"] == 0.0                                          # a = -1: cables released


def test_weights_scale_the_terms():
    env = flying("SoftTripod-v1", [0.03, 0.0, 0.0], forward_reward_weight=2.5, ctrl_cost_weight=0.2,
                 healthy_reward=0.7)
    info = env.step(np.ones(2, np.float32))[4]
    assert info["reward_forward"] == pytest.approx(2.5 * 0.03 / 0.14, rel=1e-5)
    assert info["reward_ctrl"] == pytest.approx(-0.2 * 2.0, rel=1e-12)
    assert info["reward_survive"] == 0.7


@pytest.mark.parametrize("direction, sign", [("right", 1.0), ("left", -1.0)])
def test_turn_reward_for_a_known_yaw_rate(direction, sign):
    """Yawing at 0.3 rad/s towards +z (a right turn): turn reward = 10 * yaw rate * radius / L
    (radius L by default) = 3 per step for a right turn, -3 for a left one. The rotation is not
    exactly rigid over the step (implicit Euler, elastic body): 1 % tolerance."""
    env = flying("SoftTripod-v1", [0.0, 0.0, 0.0], yaw_rate=0.3, task="turn", turn_direction=direction)
    info = env.step(-np.ones(2, np.float32))[4]
    assert info["yaw_rate"] == pytest.approx(0.3, rel=1e-2)
    assert info["reward_forward"] == pytest.approx(sign * 10.0 * 0.3, rel=1e-2)
    env = flying("SoftTripod-v1", [0.0, 0.0, 0.0], yaw_rate=0.3, task="turn", turn_radius=0.07)
    assert env.step(-np.ones(2, np.float32))[4]["reward_forward"] == pytest.approx(10.0 * 0.3 * 0.5, rel=1e-2)


@pytest.mark.parametrize("frame_skip", [1, 2])
def test_observation_entries_against_the_state(frame_skip):
    """Every block of the observation (table in SoftTripodEnv's docstring) after one step of
    a known motion: COM offset and height, COM velocity over the last simulation step,
    orientation, cable deformation over the motor range, applied contraction at the speed
    limit, gait phase."""
    v = 0.03
    env = flying("SoftTripod-v1", [v, 0.0, 0.0], frame_skip=frame_skip)
    u = env.unwrapped
    c_reset = u.robot.com(u.reset_state()[0])
    action = np.array([0.0, 1.0], np.float32)
    obs = env.step(action)[0]
    assert obs.shape == (20,)
    n = frame_skip
    # COM: x moved n v dt, z did not move, height fell g dt^2 (1 + 2 + ... + n) from rest
    fall = G * DT**2 * n * (n + 1) / 2
    np.testing.assert_allclose(obs[0:3], [n * v * DT, c_reset[1] + 1.0 - fall, 0.0], rtol=0, atol=NEWTON_TOL)
    # velocity over the last simulation step: (v, -g dt n, 0)
    np.testing.assert_allclose(obs[3:6], [v, -G * DT * n, 0.0], rtol=0, atol=NEWTON_TOL / DT)
    # orientation: the body does not rotate (it relaxes its sag a little)
    np.testing.assert_allclose(obs[6:9], [1.0, 0.0, 0.0], atol=2e-3)
    np.testing.assert_allclose(obs[9:12], [0.0, 1.0, 0.0], atol=2e-3)
    state = u.get_state()
    lo, hi = u.robot.u_bounds.T
    gamma = u.simulator.cable_deformation(state["x"], state["u"])
    np.testing.assert_allclose(obs[12:16], gamma / (hi - lo)[u.robot.tendon_motor], rtol=1e-12, atol=1e-15)
    # applied contraction: towards u_cmd = (a + 1) / 2 * 20 mm at most 100 rpm * 2 pi / 60 * 5 mm per second
    step_max = 100.0 * 2.0 * math.pi / 60.0 * 0.005 * DT
    u_cmd = (action.astype(float) + 1.0) / 2.0 * 0.02
    applied = np.minimum(u_cmd, n * step_max)
    np.testing.assert_allclose(state["u"], applied, rtol=1e-12)
    np.testing.assert_allclose(obs[16:18], 2.0 * applied / 0.02 - 1.0, rtol=1e-12)
    phase = 2.0 * math.pi * n * DT / (72 * DT)
    np.testing.assert_allclose(obs[18:20], [math.sin(phase), math.cos(phase)], rtol=1e-12)


def test_node_observations_are_positions_relative_to_the_com():
    env = flying("SoftPuppy-v1", [0.01, 0.0, 0.0], observe_nodes=True)
    obs = env.step(np.zeros(8, np.float32))[0]
    u = env.unwrapped
    x = u.get_state()["x"]
    assert obs.shape == (38 + 3 * len(x),)
    np.testing.assert_allclose(obs[38:], (x - u.robot.com(x)).ravel(), rtol=0, atol=1e-15)


# ----------------------------------------------------------------------------- domain randomisation
def test_domain_randomisation_scales_mass_and_stiffness():
    """Fixed factors (low = high): the foam's node masses scale with the density, the payload
    with its own factor, and the elastic stiffness (the Hessian of the energy at the undeformed
    shape in the air, where cables and ground exert nothing) with Young's modulus."""
    f_rho, f_pay, f_E = 1.3, 0.5, 0.8
    nominal = gym.make("SoftTripod-v1", reset_noise_scale=0.0).unwrapped
    env = gym.make("SoftTripod-v1", reset_noise_scale=0.0, domain_randomization={
        "density": (f_rho, f_rho), "payload_mass": (f_pay, f_pay), "youngs_modulus": (f_E, f_E)})
    env.reset(seed=0)
    rand = env.unwrapped
    base = nominal.robot
    assert rand.domain_parameters == {"density": f_rho, "payload_mass": f_pay, "youngs_modulus": f_E}
    assert rand.robot.total_mass == pytest.approx(f_rho * base.body_mass + f_pay * base.payload_mass, rel=1e-12)
    foam = base.mesh.lumped_masses(base.density)
    payload = base.node_masses - foam
    np.testing.assert_allclose(rand.robot.node_masses, f_rho * foam + f_pay * payload, rtol=1e-12)
    # gravity pulls on the randomised masses: in the air, undeformed, the force is m_i g
    X = np.array(base.mesh.points) + [0.0, 1.0, 0.0]
    u0 = np.zeros(base.n_motors)
    weights = G * rand.robot.node_masses
    np.testing.assert_allclose(rand.simulator.gradient(X, X, u0)[:, 1], weights, rtol=0, atol=1e-9 * weights.max())
    H_nom = nominal.simulator.hessian(X, X, u0)
    H_rand = rand.simulator.hessian(X, X, u0)
    assert abs(H_nom).max() > 0
    assert abs(H_rand - f_E * H_nom).max() <= 1e-12 * abs(H_nom).max()


def test_domain_factors_are_drawn_from_the_seeded_generator():
    """One uniform draw per key in sorted key order from the generator seeded by reset(seed):
    the factors can be predicted from the seed (and so are reproducible across processes)."""
    dr = {"youngs_modulus": (0.8, 1.2), "friction": (0.7, 1.3), "density": (0.9, 1.1)}
    env = gym.make("SoftTripod-v1", domain_randomization=dr)
    base = gym.make("SoftTripod-v1").unwrapped.robot                     # the nominal robot
    for seed in (3, 11):
        env.reset(seed=seed)
        rng, _ = seeding.np_random(seed)
        expected = {k: rng.uniform(*dr[k]) for k in sorted(dr)}
        got = env.unwrapped.domain_parameters
        assert got == pytest.approx(expected, rel=1e-15), f"seed {seed}"
        r = env.unwrapped.robot
        assert r.contact.friction_coefficient == pytest.approx(base.contact.friction_coefficient * expected["friction"], rel=1e-15)
        assert r.youngs_modulus == pytest.approx(base.youngs_modulus * expected["youngs_modulus"], rel=1e-15)
        assert r.density == pytest.approx(base.density * expected["density"], rel=1e-15)
