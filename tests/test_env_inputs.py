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


# Factors at which the Tripod's rest state does not settle (soft, heavy foam on soft ground).
CANNOT_STAND = {"contact_stiffness": (5.0, 5.0), "density": (5.0, 5.0), "friction": (5.0, 5.0),
                "payload_mass": (5.0, 5.0), "youngs_modulus": (0.2, 0.2)}


def test_reset_falls_back_to_the_nominal_robot_when_no_draw_can_stand():
    env = SoftTripodEnv(domain_randomization=CANNOT_STAND)
    with pytest.warns(UserWarning, match=f"none of {domain.MAX_DOMAIN_DRAWS} draws could stand at rest.*nominal"):
        obs, info = env.reset(seed=0)
    assert info["domain_fallback"] and info["domain_draws"] == domain.MAX_DOMAIN_DRAWS
    assert info["domain_parameters"] == {k: 1.0 for k in CANNOT_STAND} == env.domain_parameters
    assert np.isfinite(obs).all() and env.robot.youngs_modulus == env.unwrapped._base_robot.youngs_modulus
    obs, *_ = env.step(np.zeros(2))
    assert np.isfinite(obs).all()


def test_reset_redraws_until_the_robot_stands_and_reports_the_factors():
    ranges = {**CANNOT_STAND, "youngs_modulus": (0.2, 1.0)}    # soft draws cannot stand, stiffer ones can
    env = SoftTripodEnv(domain_randomization=ranges, reset_noise_scale=0.0)
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
    env = gym.make("SoftTripod-v0", healthy_tilt_deg=1e-9, reset_noise_scale=0.0).unwrapped
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
