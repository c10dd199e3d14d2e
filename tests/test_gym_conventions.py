"""Gymnasium conventions of SoftTripod-v1 / SoftPuppy-v1, as in Gymnasium's MuJoCo v5
environments: ``env.dt`` is the duration of one ``env.step`` (frame_skip x simulation step),
every keyword is documented in the class docstring's Arguments table, ``domain_randomization``
accepts ``True``, and the episode length is one documented number. trajopt measures with the
simulation step whatever the frame skip."""
from __future__ import annotations

import inspect
import re
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import soft_envs
from soft_envs.envs import DEFAULT_DOMAIN_RANDOMIZATION, SoftPuppyEnv, SoftRobotEnv, SoftTripodEnv
from trajopt.evaluation import evaluate_controls

IDS = ["SoftTripod-v1", "SoftPuppy-v1"]


@pytest.mark.parametrize("frame_skip, timestep", [(1, 0.033), (2, 0.033), (3, 0.02)])
def test_dt_is_the_duration_of_an_env_step(frame_skip, timestep):
    env = gym.make("SoftTripod-v1", frame_skip=frame_skip, timestep=timestep, reset_noise_scale=0.0)
    u = env.unwrapped
    assert u.dt == pytest.approx(frame_skip * timestep, rel=1e-15)
    assert u.timestep == u.simulator.dt == timestep                # the simulation step
    assert u.metadata["render_fps"] == round(1.0 / u.dt)
    env.reset(seed=0)
    com_before = env.unwrapped.com()
    obs, reward, _, _, info = env.step(np.array([1.0, -1.0], np.float32))
    assert len(info["u_substeps"]) == frame_skip
    assert info["time"] == pytest.approx(u.dt)
    # the forward reward divides the step's displacement by env.dt (in body lengths per second)
    expected = (info["com"] - com_before)[0] / u.dt / u.robot.body_length
    assert info["forward_velocity"] == pytest.approx(expected, rel=1e-12)
    assert info["reward_forward"] == pytest.approx(10.0 * expected, rel=1e-12)


def test_trajopt_uses_the_simulation_step_whatever_the_frame_skip():
    """A rollout has one row of controls per simulation step, and the gait's speed is measured
    with ``timestep``: the same controls give the same figures at any frame skip."""
    u = np.tile(np.linspace(0.0, 0.01, 8)[:, None], (2, 2))          # 16 steps: prep 4 + 1 cycle of 12
    evs = []
    for fs in (1, 2):
        env = gym.make("SoftTripod-v1", frame_skip=fs, reset_noise_scale=0.0)
        env.reset(seed=0)
        assert env.unwrapped.timestep == 0.033
        evs.append(evaluate_controls(env.unwrapped, u, n_prep=4, n_cycle=12))
    assert evs[0]["sim_steps"] == 16 and evs[0]["speed_bl_per_min"] == evs[1]["speed_bl_per_min"]


def _arguments_section(cls) -> str:
    doc = inspect.getdoc(cls)
    return doc[doc.index("## Arguments"):doc.index("## Version History")]


@pytest.mark.parametrize("cls", [SoftTripodEnv, SoftPuppyEnv])
def test_every_keyword_is_in_the_arguments_table(cls):
    section = _arguments_section(cls)
    rows = [line for line in section.splitlines() if line.startswith("|")]
    documented = {name for row in rows for name in re.findall(r"`(\w+)`", row.split("|")[1])}
    keywords = [p for p in inspect.signature(SoftRobotEnv.__init__).parameters if p != "self"]
    assert keywords and set(keywords) <= documented, sorted(set(keywords) - documented)
    assert "max_episode_steps" in section and "True" in section          # gym.make's keyword; the default set
    doc = inspect.getdoc(cls)
    assert f"max_episode_steps` = {soft_envs.MAX_EPISODE_STEPS}" in doc


def test_max_episode_steps_is_one_documented_number():
    for env_id in IDS:
        assert gym.spec(env_id).max_episode_steps == soft_envs.MAX_EPISODE_STEPS == 300
    from trajopt.optim.gait import GaitSpec
    from trajopt.rl.envs import TRAIN_HORIZON, make_env
    assert TRAIN_HORIZON == GaitSpec().n_steps() == 24 + 2 * 72          # the RL baseline: trajopt's horizon
    env = make_env("tripod")
    assert env.spec.max_episode_steps == TRAIN_HORIZON


def test_domain_randomization_true_uses_the_documented_ranges():
    env = gym.make("SoftTripod-v1", domain_randomization=True)
    u = env.unwrapped
    env.reset(seed=0)
    p0 = u.domain_parameters
    assert set(p0) == set(DEFAULT_DOMAIN_RANDOMIZATION)
    assert all(lo <= p0[k] <= hi for k, (lo, hi) in DEFAULT_DOMAIN_RANDOMIZATION.items())
    assert any(p0[k] != 1.0 for k in p0)
    env.reset(seed=1)
    assert u.domain_parameters != p0
    same = gym.make("SoftTripod-v1", domain_randomization=dict(DEFAULT_DOMAIN_RANDOMIZATION))
    same.reset(seed=0)
    assert same.unwrapped.domain_parameters == p0                      # True means exactly these ranges
    off = gym.make("SoftTripod-v1", domain_randomization=False)
    off.reset(seed=0)
    assert off.unwrapped.domain_parameters == {}
    with pytest.raises(TypeError, match="True"):
        gym.make("SoftTripod-v1", domain_randomization=1.2)


def test_check_env_with_default_domain_randomization():
    from .test_envs import _expected
    env = gym.make("SoftTripod-v1", domain_randomization=True, frame_skip=2)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    unexpected = [str(w.message) for w in caught if not _expected(str(w.message))]
    assert not unexpected, unexpected


@pytest.mark.parametrize("env_id", IDS)
def test_spec_tables_match_the_environment(env_id):
    """The class docstring (built by soft_envs.envs.env_docs for both robots) gives the
    environment's own sizes: the observation rows start where ``observation_structure``'s parts
    do, the action rows are the robot's motors, and the listed gradient hooks are the protocol's."""
    from soft_envs.envs.protocol import GRADIENT_ENV_MEMBERS
    u = gym.make(env_id).unwrapped
    doc = inspect.getdoc(type(u))
    rows = lambda a, b: [r.split("|")[1:-1] for r in doc[doc.index(a):doc.index(b)].splitlines()  # noqa: E731
                         if re.match(r"\| \d", r)]
    starts, i = [], 0
    for size in u.observation_structure.values():
        starts.append(i)
        i += size
    obs_rows = rows("## Observation Space", "## Rewards")
    assert [int(re.match(r"\s*(\d+)", r[0]).group(1)) for r in obs_rows] == sorted({*starts, 1, 2})
    assert f"Box(low, high, ({u.observation_space.shape[0]},), float64)" in doc
    action_rows = rows("## Action Space", "## Observation Space")
    assert [r[4].strip() for r in action_rows] == list(u.robot.motor_names)
    motor = u.robot.motors[0]                 # the no-load speed the spec states is the robot file's
    v_max = motor.max_speed_rpm * 2 * np.pi / 60 * motor.spool_radius
    assert f"{motor.max_speed_rpm:g} rpm" in doc and f"{1e3 * v_max:.0f} mm/s, {1e3 * v_max * 0.033:.2f} mm per" in doc
    assert f"Box(-1, 1, ({u.action_space.shape[0]},), float32)" in doc
    hooks = doc[doc.index("Gradient hooks"):doc.index("## Version History")]
    assert all(f"`{m}" in hooks for m in GRADIENT_ENV_MEMBERS)
