"""SoftTripod-v1 / SoftPuppy-v1: the environments with the Coulomb contact law, whose stick
anchors are part of the state (stepping, rollouts from the reset state, get/set_state)."""
from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import soft_envs  # noqa: F401


def actions(env, n, seed=3):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1, 1, size=(n,) + env.action_space.shape).astype(np.float32)


@pytest.mark.parametrize("env_id", ["SoftTripod-v1", "SoftPuppy-v1"])
@pytest.mark.filterwarnings("ignore:.*Soft(Tripod|Puppy)-v0 is out of date:DeprecationWarning")   # -v0 on purpose
def test_v1_uses_the_coulomb_law_and_passes_gymnasiums_checker(env_id):
    """-v1 (the latest, the default) runs the Coulomb law, the shipped robot files' own; the
    paper's is ``contact="paper"`` on it, and -v0 keeps the paper's law whatever the file says."""
    env = gym.make(env_id)
    u = env.unwrapped
    assert u.contact_model == "coulomb" and u.simulator.has_history
    assert u.robot.contact.model == "coulomb"          # the robot file's law
    assert gym.make(env_id, contact="paper").unwrapped.contact_model == "paper"
    assert gym.make(env_id.replace("-v1", "-v0")).unwrapped.contact_model == "paper"
    check_env(u, skip_render_check=True)


def test_stepping_equals_the_rollout_hook_with_anchors_carried():
    """The environment carries the stick anchors from step to step exactly as a rollout does
    (re-anchoring every step instead would let the feet creep: the difference would be far
    above the Newton tolerance)."""
    env = gym.make("SoftTripod-v1", reset_noise_scale=0.0)
    u = env.unwrapped
    env.reset(seed=0)
    states, controls = [], []
    for a in actions(env, 15):
        info = env.step(a)[4]
        controls.append(info["u_substeps"])
        states.append(u.get_state()["x"])
    traj = u.rollout(np.concatenate(controls))
    np.testing.assert_allclose(traj.x[1:], np.array(states), rtol=0, atol=1e-6)
    final = u.get_state()["history"]
    c = [h for h in final if h is not None][0]
    assert np.abs(c - [h for h in traj.info["history"] if h is not None][0]).max() < 1e-6


def test_state_round_trip_includes_the_anchors():
    env = gym.make("SoftPuppy-v1")
    u = env.unwrapped
    env.reset(seed=1)
    acts = actions(env, 5)
    for a in acts[:2]:
        env.step(a)
    saved = u.get_state()
    run1 = [env.step(a)[0] for a in acts[2:]]
    u.set_state(saved)
    run2 = [env.step(a)[0] for a in acts[2:]]
    np.testing.assert_array_equal(np.array(run1), np.array(run2))
    anchors = [h for h in saved["history"] if h is not None][0]
    bad = [None if h is None else np.full_like(h, np.nan) for h in saved["history"]]
    with pytest.raises(ValueError, match="history"):
        u.set_state({**saved, "history": bad})
    assert anchors.shape == (len(u.simulator.system.contact.nodes), 2)


def test_optimize_gait_under_the_coulomb_law_records_it():
    from trajopt import GaitSpec, GaussNewtonOptions, optimize_gait
    from trajopt.replay import env_for_result
    env = soft_envs.envs.make_gradient_env("tripod", contact="coulomb")
    res = optimize_gait(env, task="walk", gait=GaitSpec(n_prep=6, n_cycle=12, n_keyframes=4),
                        options=GaussNewtonOptions(max_iter=1), n_seeds=1, eval_cycles=1)
    assert res.settings["contact"] == "coulomb"
    assert env_for_result(res).contact_model == "coulomb"
