"""The environments' keywords, domain randomisation that never makes reset() raise, and the
warning for a step after termination (issue #16 items 9 and 10)."""
from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest

import soft_envs  # noqa: F401  (registers the environments)
from soft_envs.envs import SoftTripodEnv, domain

BAD_KEYWORDS = [
    ("healthy_tilt_deg", float("nan")), ("healthy_tilt_deg", 0.0), ("healthy_tilt_deg", 200.0),
    ("healthy_height_fraction", float("nan")), ("healthy_height_fraction", 1.5),
    ("forward_reward_weight", float("inf")), ("ctrl_cost_weight", -1.0), ("ctrl_cost_weight", float("nan")),
    ("healthy_reward", float("nan")), ("turn_radius", 0.0), ("turn_radius", float("inf")),
    ("target_heading_deg", float("inf")), ("target_heading_deg", "north"), ("terminate_when_unhealthy", "yes"),
    ("frame_skip", 1.5), ("frame_skip", True), ("frame_skip", float("nan")), ("frame_skip", 0),
    ("timestep", float("nan")), ("timestep", "0.03"), ("gait_period", -1.0), ("reset_noise_scale", float("nan")),
    ("motor_speed_rpm", float("inf")), ("motor_speed_rpm", 0.0), ("incline_deg", float("nan")),
    ("observe_nodes", "no"), ("width", 0), ("height", 1e9), ("camera_config", 3), ("render_mode", "window"),
    ("robot", 3.5),
]


@pytest.mark.parametrize("key,value", BAD_KEYWORDS, ids=[f"{k}={v!r}" for k, v in BAD_KEYWORDS])
def test_every_bad_keyword_is_refused_naming_it(key, value):
    with pytest.raises(ValueError, match=rf"^{key} must be"):
        SoftTripodEnv(**{key: value})


def test_numpy_numbers_are_accepted():
    env = SoftTripodEnv(frame_skip=np.int64(2), timestep=np.float32(0.033), healthy_tilt_deg=np.float64(50.0))
    assert env.frame_skip == 2 and env.dt == pytest.approx(2 * 0.033)


# Factors at which the Tripod's rest state does not settle under the paper's contact law (soft,
# heavy foam on soft ground; the tests below name that law: Coulomb feet hold at some of them).
CANNOT_STAND = {"contact_stiffness": (5.0, 5.0), "density": (5.0, 5.0), "friction": (5.0, 5.0),
                "payload_mass": (5.0, 5.0), "youngs_modulus": (0.2, 0.2)}


def test_reset_falls_back_to_the_nominal_robot_when_no_draw_can_stand():
    env = SoftTripodEnv(domain_randomization=CANNOT_STAND, contact="paper")
    with pytest.warns(UserWarning, match=f"none of {domain.MAX_DOMAIN_DRAWS} draws could stand at rest.*nominal"):
        obs, info = env.reset(seed=0)
    assert info["domain_fallback"] and info["domain_draws"] == domain.MAX_DOMAIN_DRAWS
    assert info["domain_parameters"] == {k: 1.0 for k in CANNOT_STAND} == env.domain_parameters
    assert np.isfinite(obs).all() and env.robot.youngs_modulus == env.unwrapped._base_robot.youngs_modulus
    obs, *_ = env.step(np.zeros(2))
    assert np.isfinite(obs).all()


def test_reset_redraws_until_the_robot_stands_and_reports_the_factors():
    ranges = {**CANNOT_STAND, "youngs_modulus": (0.2, 1.0)}    # soft draws cannot stand, stiffer ones can
    env = SoftTripodEnv(domain_randomization=ranges, reset_noise_scale=0.0, contact="paper")
    draws = []
    for seed in range(3):
        with warnings.catch_warnings():
            warnings.simplefilter("error")                   # no fallback: some draw stood
            _, info = env.reset(seed=seed)
        assert not info["domain_fallback"] and info["domain_parameters"] == env.domain_parameters
        assert 0.2 <= info["domain_parameters"]["youngs_modulus"] <= 1.0
        draws.append(info["domain_draws"])
    assert max(draws) > 1                                    # a redraw happened
    _, again = env.reset(seed=int(np.argmax(draws)))         # redraws come from np_random: reproducible
    assert again["domain_draws"] == max(draws)


def test_step_after_terminated_warns_like_gymnasium():
    env = gym.make("SoftTripod-v1", healthy_tilt_deg=1e-9, reset_noise_scale=0.0).unwrapped
    env.reset(seed=0)
    _, _, terminated, _, _ = env.step(np.ones(2))
    assert terminated
    with pytest.warns(UserWarning, match="already returned terminated = True"):
        env.step(np.ones(2))
    with warnings.catch_warnings():
        warnings.simplefilter("error")                       # once per episode, and not after a reset
        env.step(np.ones(2))
        env.reset(seed=1)
        env.step(np.zeros(2))


def _state(env):
    e = env.unwrapped
    return (e._x.copy(), e._x_prev.copy(), e._u.copy(), e._n_sub, e.np_random.bit_generator.state)


def _assert_same_state(a, b):
    assert all(np.array_equal(x, y) for x, y in zip(a[:3], b[:3])) and a[3:] == b[3:]


@pytest.fixture(scope="module")
def stepped_env():
    env = SoftTripodEnv(reset_noise_scale=1e-4)
    env.reset(seed=3)
    env.step(np.full(env.action_space.shape, 0.5))
    return env


BAD_OPTIONS = [("a string", "reset options must be a dict or None, got str"),
               ([("speed", 1)], "reset options must be a dict or None, got list"),
               ({"speed": 1.0}, r"unknown reset option 'speed' \(this environment's reset options: none\)"),
               ({1: 2}, "unknown reset option 1 ")]


@pytest.mark.parametrize("options,message", BAD_OPTIONS, ids=[repr(o) for o, _ in BAD_OPTIONS])
def test_unknown_or_non_dict_reset_options_are_refused_with_the_state_untouched(stepped_env, options, message):
    """Issue #26 item 7: ``reset(options=...)`` was silently ignored; now refused before the seed,
    the random generator or the state change. ``None`` and ``{}`` are accepted."""
    before = _state(stepped_env)
    with pytest.raises(ValueError, match=message):
        stepped_env.reset(seed=99, options=options)
    _assert_same_state(_state(stepped_env), before)


def test_empty_reset_options_are_accepted():
    env = SoftTripodEnv(reset_noise_scale=1e-4)
    obs_none, _ = env.reset(seed=4, options=None)
    obs_empty, _ = env.reset(seed=4, options={})
    assert np.array_equal(obs_none, obs_empty)


def _bad_actions(m):
    return [(np.full(m, 0.5 + 0.0j), "action must be real, got complex dtype complex128"),
            (np.full(m, 0.5, dtype=np.complex64) + 1j, "action must be real, got complex dtype complex64"),
            ([0.5 + 1j] * m, "action must be real"),
            ({f"m{i}": 0.5 for i in range(m)}, rf"action must be an array of {m} numbers .* got a dict \(keys \['m0'"),
            ({}, "got a dict")]


def test_complex_and_dict_actions_are_refused_with_the_state_untouched(stepped_env):
    """A complex action lost its imaginary part silently (numpy's cast) and a dict failed on its
    shape; both are refused by step() and action_to_control(), and nothing moves."""
    m = stepped_env.action_space.shape[0]
    before = _state(stepped_env)
    for action, message in _bad_actions(m):
        with pytest.raises(ValueError, match=message):
            stepped_env.step(action)
        with pytest.raises(ValueError, match=message):
            stepped_env.action_to_control(action)
        _assert_same_state(_state(stepped_env), before)
    assert np.allclose(stepped_env.action_to_control(np.full(m, 0.5)),          # real arrays still work
                       stepped_env.action_to_control(np.full(m, 0.5, dtype=np.float32)))
