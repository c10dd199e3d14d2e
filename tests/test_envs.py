"""Gymnasium environments SoftTripod-v1 / SoftPuppy-v1: API conformance, determinism, action
handling, gradient hooks, failure handling, pickling, vectorisation and rendering."""
from __future__ import annotations

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import soft_envs  # noqa: F401  (registers the ids)
from soft_envs.envs import GradientEnv, SoftPuppyEnv, SoftTripodEnv
from soft_envs.sim import SimulationError, incline_gravity

IDS = ["SoftTripod-v1", "SoftPuppy-v1"]

# Gymnasium's own whitelist (tests/envs/test_envs.py, CHECK_ENV_IGNORE_WARNINGS)
GYM_WHITELIST = [
    f"\x1b[33mWARN: {m}\x1b[0m" for m in [
        "A Box observation space minimum value is -infinity. This is probably too low.",
        "A Box observation space maximum value is infinity. This is probably too high.",
        "For Box action spaces, we recommend using a symmetric and normalized space (range=[-1, 1] or "
        "[0, 1]). See https://stable-baselines3.readthedocs.io/en/master/guide/rl_tips.html for more "
        "information.",
    ]
]


def _expected(message: str) -> bool:
    if message in GYM_WHITELIST:
        return True
    # check_env renders every declared mode; on a headless test machine "human" cannot open a
    # window and the environment says so (documented, once per process).
    import matplotlib
    return (matplotlib.get_backend().lower() == "agg"
            and "render_mode='human'" in message and "cannot open a window" in message)


def _run(env, actions):
    out = []
    for a in actions:
        obs, rew, term, trunc, info = env.step(a)
        out.append((obs, rew, term, trunc))
    return out


def _same(run1, run2) -> bool:
    return len(run1) == len(run2) and all(
        np.array_equal(o1, o2) and r1 == r2 and t1 == t2 and u1 == u2
        for (o1, r1, t1, u1), (o2, r2, t2, u2) in zip(run1, run2))


def _actions(env, n, seed=0):
    env.action_space.seed(seed)
    return [env.action_space.sample() for _ in range(n)]


# ---------------------------------------------------------------------------- registration, API
def test_registration():
    for env_id in IDS:
        spec = gym.spec(env_id)
        assert spec.max_episode_steps == 300
    env = gym.make("soft_envs:SoftPuppy-v1")
    assert isinstance(env.unwrapped, SoftPuppyEnv)
    assert isinstance(gym.make("SoftTripod-v1").unwrapped, SoftTripodEnv)
    env = gym.make("SoftTripod-v1", max_episode_steps=3)
    env.reset(seed=0)
    truncs = [env.step(env.action_space.sample())[3] for _ in range(3)]
    assert truncs == [False, False, True]


VARIANT = dict(frame_skip=2, observe_nodes=True, task="turn", incline_deg=5.0,
               domain_randomization={"friction": (0.7, 1.3), "youngs_modulus": (0.8, 1.2)})


@pytest.mark.parametrize("env_id, kwargs", [(i, {}) for i in IDS] + [("SoftTripod-v1", VARIANT)],
                         ids=IDS + ["SoftTripod-v1-variant"])
def test_check_env_gymnasium_and_sb3(env_id, kwargs):
    from stable_baselines3.common.env_checker import check_env as sb3_check_env
    env = gym.make(env_id, **kwargs)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
        sb3_check_env(env.unwrapped)
    unexpected = [str(w.message) for w in caught if not _expected(str(w.message))]
    assert not unexpected, unexpected
    assert isinstance(env.unwrapped, GradientEnv)


@pytest.mark.parametrize("env_id", IDS)
def test_observation_layout_at_rest(env_id):
    env = gym.make(env_id, reset_noise_scale=0.0)
    obs, info = env.reset(seed=0)
    u = env.unwrapped
    s = u.observation_structure
    assert obs.shape == (sum(s.values()),) and obs.dtype == np.float64
    np.testing.assert_allclose(obs[[0, 2]], 0.0, atol=1e-12)               # COM relative to start
    assert obs[1] == pytest.approx(u.com()[1])                            # COM height
    np.testing.assert_allclose(obs[3:6], 0.0, atol=1e-12)                 # at rest
    np.testing.assert_allclose(obs[6:9], [1, 0, 0], atol=1e-9)            # forward vector
    np.testing.assert_allclose(obs[9:12], [0, 1, 0], atol=1e-9)           # up vector
    i = 12 + s["cable_deformation"]
    np.testing.assert_allclose(obs[i:i + s["contraction"]], -1.0)        # no contraction
    np.testing.assert_allclose(obs[-2:], [0.0, 1.0])                      # gait phase 0
    big = gym.make(env_id, observe_nodes=True, reset_noise_scale=0.0)
    obs_n, _ = big.reset(seed=0)
    n = big.unwrapped.robot.mesh.n_nodes
    assert obs_n.shape == (obs.size + 3 * n,)
    np.testing.assert_allclose(obs_n[:obs.size], obs)
    nodes = obs_n[obs.size:].reshape(n, 3)
    np.testing.assert_allclose(big.unwrapped.robot.node_masses @ nodes, 0.0, atol=1e-12)


# ---------------------------------------------------------------------------- determinism, seeding
def test_seeded_determinism_and_fresh_observations():
    env = gym.make("SoftTripod-v1")
    acts = _actions(env, 8)
    env.reset(seed=3)
    run1 = _run(env, acts)
    env.reset(seed=3)
    run2 = _run(env, acts)
    other = gym.make("SoftTripod-v1")
    other.reset(seed=3)
    assert _same(run1, run2) and _same(run1, _run(other, acts))
    # observations never share memory between steps (nor with the environment)
    for (o1, *_), (o2, *_) in zip(run1, run1[1:]):
        assert not np.shares_memory(o1, o2)
    state = env.unwrapped.get_state()
    run2[-1][0][:] = 1e6                              # scribbling on an observation ...
    after = env.unwrapped.get_state()                 # ... does not touch the environment
    assert all(np.array_equal(state[k], after[k]) for k in ("x", "x_prev", "u", "com_start"))


def test_custom_robot_object():
    from soft_envs.envs import SoftRobotEnv
    from tests.conftest import small_robot
    env = SoftRobotEnv(small_robot(), reset_noise_scale=0.0)
    obs, _ = env.reset(seed=0)
    assert env.action_space.shape == (1,) and obs.shape == (3 + 3 + 6 + 1 + 1 + 2,)
    obs, *_ = env.step(np.ones(1, np.float32))
    assert np.isfinite(obs).all()


def test_reset_noise_follows_the_seed():
    env = gym.make("SoftPuppy-v1", reset_noise_scale=1e-4)
    a, _ = env.reset(seed=1)
    b, _ = env.reset(seed=1)
    c, _ = env.reset(seed=2)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    x0, xm1 = env.unwrapped.reset_state()
    rest = env.unwrapped.simulator.rest_positions()
    assert 0 < np.abs(x0 - rest).max() <= 1e-4 and 0 < np.abs(xm1 - x0).max() <= 1e-4
    quiet = gym.make("SoftPuppy-v1", reset_noise_scale=0.0)
    quiet.reset(seed=1)
    np.testing.assert_array_equal(quiet.unwrapped.reset_state()[0], rest)


# ---------------------------------------------------------------------------- actions
def test_action_validation_clipping_and_mapping():
    env = gym.make("SoftTripod-v1", motor_speed_rpm=None)
    u = env.unwrapped
    env.reset(seed=0)
    for bad in ([np.nan, 0.0], [0.0, np.inf], [-np.inf, 0.0]):
        with pytest.raises(ValueError, match="NaN or inf"):
            env.step(np.array(bad, dtype=np.float32))
    for shape in [(3,), (1, 2), ()]:
        with pytest.raises(ValueError, match="shape"):
            env.step(np.zeros(shape, dtype=np.float32))
    lo, hi = u.robot.u_bounds.T
    np.testing.assert_allclose(u.action_to_control([-1, 1]), [lo[0], hi[1]])
    np.testing.assert_allclose(u.action_to_control([5, -7]), [hi[0], lo[1]])   # clipped
    np.testing.assert_allclose(u.control_to_action(u.action_to_control([0.25, -0.5])), [0.25, -0.5])
    # out-of-range actions act exactly like the clipped ones
    env.reset(seed=0)
    r1 = _run(env, [np.array([3.0, -2.0], np.float32)] * 2)
    env.reset(seed=0)
    r2 = _run(env, [np.array([1.0, -1.0], np.float32)] * 2)
    assert _same(r1, r2)
    assert env.unwrapped.get_state()["u"].tolist() == [hi[0], lo[1]]          # no speed limit


def test_motor_speed_limit():
    env = gym.make("SoftTripod-v1")
    env.reset(seed=0)
    v = 100 / 60 * 2 * np.pi * 0.005                # 100 rpm on a 5 mm spool [m/s]
    assert env.unwrapped.motor_speed == pytest.approx([v, v])
    u_max = env.unwrapped.robot.u_bounds[0, 1]
    n = int(np.ceil(u_max / (v * 0.033)))             # steps to the end of the stroke
    us = [env.step(np.array([1.0, -1.0], np.float32))[4]["u"][0] for _ in range(n + 1)]
    np.testing.assert_allclose(us[:n - 1], v * 0.033 * np.arange(1, n))
    assert us[n - 1] == us[n] == u_max
    skip = gym.make("SoftTripod-v1", frame_skip=2)
    skip.reset(seed=0)
    info = skip.step(np.array([1.0, 1.0], np.float32))[4]
    np.testing.assert_allclose(info["u_substeps"][:, 0], [v * 0.033, 2 * v * 0.033])


# ---------------------------------------------------------------------------- gradient hooks
@pytest.mark.parametrize("frame_skip", [1, 2])
def test_hooks_rollout_equals_stepping(frame_skip):
    env = gym.make("SoftTripod-v1", reset_noise_scale=0.0, frame_skip=frame_skip)
    u = env.unwrapped
    env.reset(seed=0)
    states, controls = [], []
    for a in _actions(env, 12 // frame_skip):
        info = env.step(a)[4]
        controls.append(info["u_substeps"])
        states.append(u.get_state()["x"])
    before = u.get_state()
    traj = u.rollout(np.concatenate(controls))
    after = u.get_state()
    for k in ("x", "x_prev", "u"):
        np.testing.assert_array_equal(before[k], after[k])                   # state untouched
    # The same trajectory up to the Newton tolerance: each env step starts without a stored
    # factorisation while the rollout reuses one across steps (chord iterations), so the two
    # converge to within tol = 1e-8 m per step by different paths (measured: <= 1.4e-7 m).
    np.testing.assert_allclose(traj.x[frame_skip::frame_skip], np.array(states), rtol=0, atol=1e-6)
    assert traj.com.shape == (len(traj.x), 3)
    # sensitivities through the hooks
    K = len(traj.u)
    dudz = np.ones((K, u.robot.n_motors, 1))
    assert u.rollout(traj.u, dudz=dudz).dcomdz.shape == (K + 1, 3, 1)


def test_rollout_does_not_perturb_stepping():
    a, b = gym.make("SoftTripod-v1"), gym.make("SoftTripod-v1")
    acts = _actions(a, 6)
    a.reset(seed=5)
    b.reset(seed=5)
    _run(a, acts[:3]), _run(b, acts[:3])
    a.unwrapped.rollout(np.full((4, 2), 0.004))
    assert _same(_run(a, acts[3:]), _run(b, acts[3:]))


def test_get_set_state_and_hook_values():
    env = gym.make("SoftPuppy-v1")
    u = env.unwrapped
    env.reset(seed=0)
    acts = _actions(env, 4)
    _run(env, acts[:2])
    saved = u.get_state()
    run1 = _run(env, acts[2:])
    u.set_state(saved)
    assert _same(run1, _run(env, acts[2:]))
    np.testing.assert_allclose(u.com(), u.robot.com(u.get_state()["x"]))
    assert u.cable_deformation().shape == (len(u.robot.tendons),)
    with pytest.raises(ValueError, match="shape"):
        u.set_state({"x": np.zeros((3, 3))})
    assert u.dt == 0.033 and u.timestep == 0.033
    # x_prev2 (the solver's extrapolation) is part of the state; without it the next state is
    # the same to within the Newton tolerance
    assert saved["x_prev2"].shape == saved["x"].shape
    with pytest.raises(ValueError, match="x_prev2"):
        u.set_state({**saved, "x_prev2": np.full_like(saved["x"], np.nan)})
    u.set_state({k: v for k, v in saved.items() if k != "x_prev2"})
    np.testing.assert_allclose(_run(env, acts[2:3])[0][0], run1[0][0], rtol=0, atol=1e-6)


# ---------------------------------------------------------------------------- rewards, tasks, termination
def _kicked(env_id, dx=None, yaw=0.0, **kw):
    """An env whose state is the rest shape moving by ``dx`` and turning by ``yaw`` per step."""
    env = gym.make(env_id, reset_noise_scale=0.0, **kw)
    env.reset(seed=0)
    u = env.unwrapped
    x = u.simulator.rest_positions()
    c = u.robot.com(x)
    rot = np.array([[np.cos(yaw), 0, -np.sin(yaw)], [0, 1, 0], [np.sin(yaw), 0, np.cos(yaw)]])  # +x -> +z
    x_now = (x - c) @ rot.T + c + (np.zeros(3) if dx is None else dx)
    u.set_state({"x": x_now, "x_prev": x, "sim_steps": 0})
    return env


def test_walk_and_turn_rewards():
    off = -np.ones(2, np.float32)
    v = 0.002                                        # 2 mm per step along +x
    fwd = _kicked("SoftTripod-v1", dx=np.array([v, 0, 0])).step(off)[4]
    back = _kicked("SoftTripod-v1", dx=np.array([v, 0, 0]), target_heading_deg=180).step(off)[4]
    assert fwd["forward_velocity"] > 0 and fwd["reward_forward"] > 0
    assert back["reward_forward"] == pytest.approx(-fwd["reward_forward"])
    # yaw from +x towards +z (trajopt's heading convention): turning towards +z is turning right
    right = _kicked("SoftTripod-v1", yaw=0.01, task="turn", turn_direction="right").step(off)[4]
    left = _kicked("SoftTripod-v1", yaw=0.01, task="turn", turn_direction="left").step(off)[4]
    assert right["yaw_rate"] > 0 and right["reward_forward"] > 0
    assert left["reward_forward"] == pytest.approx(-right["reward_forward"])
    assert right["reward_ctrl"] == 0.0 and right["reward_survive"] == 0.1


def test_falling_over_terminates():
    env = _kicked("SoftTripod-v1")
    u = env.unwrapped
    x = u.simulator.rest_positions()
    c = u.robot.com(x)
    roll = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float)              # 90 deg about x
    on_side = (x - c) @ roll.T + c
    on_side[:, 1] -= on_side[:, 1].min()
    u.set_state({"x": on_side, "x_prev": on_side})
    _, rew, term, _, info = env.step(-np.ones(2, np.float32))
    assert term and not info["is_healthy"] and info["reward_survive"] == 0.0
    lax = gym.make("SoftTripod-v1", terminate_when_unhealthy=False)
    lax.reset(seed=0)
    lax.unwrapped.set_state({"x": on_side, "x_prev": on_side})
    assert not lax.step(-np.ones(2, np.float32))[2]


def test_incline_and_heading_rotate_gravity():
    env = gym.make("SoftPuppy-v1", incline_deg=10.0, target_heading_deg=90.0)
    g = env.unwrapped.simulator.gravity
    np.testing.assert_allclose(g, incline_gravity(10.0, uphill=(0.0, 1.0)), atol=1e-12)
    assert g[2] < 0 and abs(g[0]) < 1e-12            # uphill towards +z (the right): pulled to -z


def test_sim_failure_terminates_and_keeps_state(monkeypatch):
    env = gym.make("SoftPuppy-v1")
    u = env.unwrapped
    obs0, _ = env.reset(seed=0)
    before = u.get_state()

    def boom(*args, **kwargs):
        raise SimulationError("line search failed (test)", step=0)
    monkeypatch.setattr(u.simulator, "step", boom)
    obs, rew, term, trunc, info = env.step(np.ones(8, np.float32))
    assert term and not trunc and rew == 0.0
    assert "line search failed (test)" in info["sim_failure"]
    np.testing.assert_array_equal(obs, obs0)
    after = u.get_state()
    for k in ("x", "x_prev", "u", "com_start"):
        np.testing.assert_array_equal(before[k], after[k])
    assert after["sim_steps"] == before["sim_steps"]


def test_domain_randomization():
    dr = {"friction": (0.7, 1.3), "youngs_modulus": (0.8, 1.2), "payload_mass": (0.9, 1.1)}
    env = gym.make("SoftTripod-v1", domain_randomization=dr)
    u = env.unwrapped
    base = SoftTripodEnv().robot
    env.reset(seed=0)
    p0 = u.domain_parameters
    assert set(p0) == set(dr) and all(dr[k][0] <= p0[k] <= dr[k][1] for k in dr)
    assert u.robot.contact.friction_coefficient == pytest.approx(base.contact.friction_coefficient * p0["friction"])  # Coulomb's mu
    assert u.robot.youngs_modulus == pytest.approx(base.youngs_modulus * p0["youngs_modulus"])
    env.reset(seed=1)
    assert u.domain_parameters != p0
    env.reset(seed=0)
    assert u.domain_parameters == p0
    fixed = gym.make("SoftTripod-v1", domain_randomization={"density": (1.0, 1.0)})
    fixed.reset(seed=0)
    sim = fixed.unwrapped.simulator
    fixed.reset(seed=1)
    assert fixed.unwrapped.simulator is sim           # unchanged parameters: no rebuild
    with pytest.raises(ValueError, match="unknown key"):
        gym.make("SoftTripod-v1", domain_randomization={"gravity": (0.9, 1.1)})


# ---------------------------------------------------------------------------- pickling, vectorisation
def test_pickle_steps_identically():
    env = gym.make("SoftPuppy-v1", render_mode="rgb_array")
    env.reset(seed=4)
    acts = _actions(env, 5)
    _run(env, acts[:2])
    env.render()                                     # a live matplotlib canvas must not matter
    clone = pickle.loads(pickle.dumps(env))
    assert _same(_run(env, acts[2:]), _run(clone, acts[2:]))


def test_make_vec_async():
    envs = gym.make_vec("SoftPuppy-v1", num_envs=2, vectorization_mode="async")
    try:
        obs, _ = envs.reset(seed=0)
        assert obs.shape == (2, 38)
        assert not np.array_equal(obs[0], obs[1])     # seeds 0 and 1
        envs.action_space.seed(0)
        for _ in range(2):
            obs, rew, term, trunc, info = envs.step(envs.action_space.sample())
        assert obs.shape == (2, 38) and rew.shape == (2,) and np.isfinite(obs).all()
    finally:
        envs.close()


# ---------------------------------------------------------------------------- rendering
def test_render_rgb_array_and_human():
    env = gym.make("SoftTripod-v1", render_mode="rgb_array", width=160, height=120)
    env.reset(seed=0)
    env.step(np.ones(2, np.float32))
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.shape == (120, 160, 3)
    assert frame.reshape(-1, 3).std(axis=0).max() > 10          # not blank
    human = gym.make("SoftTripod-v1", render_mode="human", width=80, height=60)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        human.reset(seed=0)
        human.step(np.zeros(2, np.float32))
        assert human.render() is None
    human.close()
    human.close()
