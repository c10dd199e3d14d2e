"""The observation space's bounds (``soft_envs.envs.observation``): the parts with a physical
bound (the forward and up vectors, the applied contraction, the gait phase) have it in the Box,
Gymnasium's checker finds nothing to warn about in them, the Min and Max columns of the
specification are the Box's, and observations stay within the bounds through random episodes
(why the other parts are unbounded: the Observation Space section of the specification)."""
from __future__ import annotations

import inspect
import re
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env, check_space_limit

import soft_envs  # noqa: F401  (registers the ids)
from soft_envs.envs.observation import BOUNDED_PARTS

from .test_envs import _expected


def _bounded_indices(env) -> np.ndarray:
    """The observation entries of the parts in BOUNDED_PARTS."""
    out, i = [], 0
    for name, size in env.unwrapped.observation_structure.items():
        if name in BOUNDED_PARTS:
            out += range(i, i + size)
        i += size
    return np.array(out, dtype=int)


@pytest.mark.parametrize("env_id, kwargs", [("SoftTripod-v2", {}), ("SoftPuppy-v2", {}),
                                            ("SoftTripod-v2", {"observe_nodes": True})],
                         ids=["tripod", "puppy", "tripod-nodes"])
def test_bounded_parts_are_finite_and_the_checker_does_not_warn_about_them(env_id, kwargs):
    env = gym.make(env_id, **kwargs)
    box = env.unwrapped.observation_space
    idx = _bounded_indices(env)
    assert len(idx) == 3 + 3 + env.unwrapped.robot.n_motors + 2
    np.testing.assert_array_equal(box.low[idx], -1.0)
    np.testing.assert_array_equal(box.high[idx], 1.0)
    rest = np.setdiff1d(np.arange(box.shape[0]), idx)
    assert np.isneginf(box.low[rest]).all() and np.isposinf(box.high[rest]).all()
    with warnings.catch_warnings(record=True) as caught:            # the bounded parts alone
        warnings.simplefilter("always")
        check_space_limit(spaces.Box(box.low[idx], box.high[idx], dtype=np.float64), "observation")
    assert [str(w.message) for w in caught] == []
    with warnings.catch_warnings(record=True) as caught:            # the whole environment
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)
    messages = [str(w.message) for w in caught]
    assert not [m for m in messages if not _expected(m)], messages
    assert not [m for m in messages if "bounds" in m or "not within the observation space" in m]


@pytest.mark.parametrize("env_id", ["SoftTripod-v2", "SoftPuppy-v2"])
def test_the_specification_states_the_bounds_of_the_box(env_id):
    """Each row of the Observation Space table: its Min and Max are the Box's over its entries."""
    env = gym.make(env_id, observe_nodes=True)
    box = env.unwrapped.observation_space
    doc = inspect.getdoc(type(env.unwrapped))
    section = doc[doc.index("## Observation Space"):doc.index("## Rewards")]
    rows = [[c.strip() for c in r.split("|")[1:-1]] for r in section.splitlines() if re.match(r"\| \d", r)]
    for num, _, lo, hi, _ in rows:
        a, _, b = num.partition("-")
        entries = slice(int(a), None if b == "..." else (int(b) if b else int(a)) + 1)
        np.testing.assert_array_equal(box.low[entries], float(lo), err_msg=num)
        np.testing.assert_array_equal(box.high[entries], float(hi), err_msg=num)


@pytest.mark.parametrize("env_id, kwargs", [
    ("SoftTripod-v2", {"domain_randomization": True, "terminate_when_unhealthy": False}),
    ("SoftPuppy-v2", {"motor_model": "ideal", "frame_skip": 2}),
    ("SoftTripod-v2", {"reset_noise_scale": 0.0}),
    ("SoftTripod-v0", {"reset_noise_scale": 0.0}),
], ids=["tripod-randomised", "puppy-ideal-motors", "tripod-no-noise", "tripod-v0-no-noise"])
@pytest.mark.filterwarnings("ignore:.*SoftTripod-v0 is out of date:DeprecationWarning")
def test_observations_of_random_episodes_stay_within_the_bounds(env_id, kwargs):
    """Random actions from seeded resets (without noise too: at rest an entry of the rotation is
    1 + 2e-16 before clipping), any motor law: every observation is in the space."""
    env = gym.make(env_id, max_episode_steps=25, **kwargs)
    box = env.observation_space
    env.action_space.seed(0)
    idx = _bounded_indices(env)
    n = 0
    for seed in (0, 1):
        obs, _ = env.reset(seed=seed)
        done = False
        while True:
            assert box.contains(obs), (n, obs[idx])
            n += 1
            if done:
                break
            obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
            done = terminated or truncated
    assert n >= 20
