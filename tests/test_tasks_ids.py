"""The benchmark's tasks as registered Gymnasium ids (issue #39 item 2): every id makes, resets,
steps, renders and passes Gymnasium's and Stable-Baselines3's checkers; each task's difficulty,
reward terms and termination; the health check on ground that is not flat; the robot ids
unchanged."""
from __future__ import annotations

import inspect
import math
import re
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import soft_envs
from soft_envs.envs import SoftTripodEnv
from soft_envs.envs.ground_reference import GroundReference
from soft_envs.envs.tasks import LEVELS, TASK_CLASSES
from soft_envs.sim import HeightField
from soft_envs.sim.kinematics import tilt_deg_of

from .test_envs import _expected

TASK_IDS = sorted(soft_envs.TASK_ENV_IDS)
REWARD_TERMS = ("reward_forward", "reward_ctrl", "reward_survive", "reward_success")


def test_the_ids_are_registered_and_the_robot_ids_kept():
    assert len(TASK_IDS) == 20 and len(TASK_CLASSES) == 10
    for task, by_robot in soft_envs.TASK_IDS_BY_TASK.items():
        for robot, env_id in by_robot.items():
            spec = gym.spec(env_id)
            assert spec.kwargs == {"robot": robot} and spec.max_episode_steps == soft_envs.MAX_EPISODE_STEPS
            assert re.fullmatch(r"Soft(Tripod|Puppy)[A-Z]\w+-v0", env_id)
            assert spec.entry_point.endswith(TASK_CLASSES[task].__name__)
    assert sorted(soft_envs.ENV_IDS) == sorted([*(f"Soft{r}-v{v}" for r in ("Tripod", "Puppy") for v in range(3)),
                                                "SoftHexapod-v2", "SoftInchworm-v2"])
    for env_id, kwargs in soft_envs.ENV_KWARGS.items():
        assert gym.spec(env_id).kwargs == kwargs


@pytest.mark.parametrize("env_id", TASK_IDS)
def test_every_id_makes_steps_renders_and_passes_both_checkers(env_id):
    from stable_baselines3.common.env_checker import check_env as sb3_check_env
    env = gym.make(env_id, render_mode="rgb_array", width=96, height=72)
    u = env.unwrapped
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(u)
        sb3_check_env(gym.make(env_id).unwrapped)
    unexpected = [str(w.message) for w in caught if not _expected(str(w.message))]
    assert not unexpected, unexpected
    obs, info = env.reset(seed=3)
    assert obs.shape == u.observation_space.shape == (sum(u.observation_structure.values()),)
    assert info["is_success"] is False
    rng = np.random.default_rng(0)
    for _ in range(3):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(-1, 1, u.action_space.shape))
        assert u.observation_space.contains(obs) and not truncated
        assert reward == pytest.approx(sum(info[k] for k in REWARD_TERMS), rel=1e-12, abs=1e-12)
    frame = env.render()
    assert frame.shape == (72, 96, 3) and frame.dtype == np.uint8 and frame.std() > 0
    # the class docstring is the task's specification, with the id's own sizes
    doc = inspect.getdoc(type(u))
    for section in ("## Description", "## Action Space", "## Observation Space", "## Rewards", "## Starting State",
                    "## Episode End", "## Arguments", "## Version History"):
        assert section in doc, section
    assert f"`{env_id}`" in doc and f"n = {obs.size} for the {u.robot.name.capitalize()}" in " ".join(doc.split())
    for part in u.observation_structure:
        assert f"`{part}`" in doc, part


@pytest.mark.parametrize("task", sorted(TASK_CLASSES))
@pytest.mark.parametrize("bad", ["extreme", 1, None, "Easy"])
def test_a_bad_difficulty_names_the_keyword_and_value(task, bad):
    with pytest.raises(ValueError, match=rf"difficulty must be one of 'easy', 'medium', 'hard', got {bad!r}"):
        TASK_CLASSES[task]("tripod", difficulty=bad)


@pytest.mark.parametrize("task", sorted(TASK_CLASSES))
def test_keywords_the_task_sets_are_refused(task):
    cls = TASK_CLASSES[task]
    key = cls.owned[-1]
    with pytest.raises(ValueError, match=rf"^{key} is set by the task"):
        cls("tripod", **{key: 0.0})
    doc = inspect.getdoc(cls)
    assert all(f"`{k}`" in doc for k in cls.owned) and "`difficulty`" in doc


def test_difficulty_scales_what_it_says():
    def make(task, level, **kw):
        return TASK_CLASSES[task]("tripod", difficulty=level, **kw)
    L = make("walk", "easy").robot.body_length
    assert [make("slope_up", lv).incline_deg for lv in ("easy", "medium", "hard")] == [5.0, 10.0, 15.0]
    assert [make("slope_down", lv).incline_deg for lv in ("easy", "medium", "hard")] == [-5.0, -10.0, -15.0]
    assert make("walk", "easy").domain_parameters == {}
    hard = make("turn", "hard")
    hard.reset(seed=0)
    assert set(hard.domain_parameters) == set(LEVELS["turn"]["hard"]["domain_randomization"])
    steps = [make("climb_step", lv).step_height for lv in ("easy", "medium", "hard")]
    assert steps == pytest.approx([0.03 * L, 0.06 * L, 0.1 * L]) and steps == sorted(steps)
    lengths = [make("cross_trench", lv).trench_length for lv in ("easy", "medium", "hard")]
    assert lengths == sorted(lengths) and lengths[0] == pytest.approx(0.1 * L)
    rms = []
    for lv in ("easy", "medium", "hard"):
        env = make("rough_terrain", lv, terrain_seed=1)
        xs, zs = np.meshgrid(np.linspace(-0.1, 0.3, 40), np.linspace(-0.1, 0.1, 20))
        rms.append(float(np.std(env.robot.ground.height(xs, zs))))
    assert rms == sorted(rms) and rms[2] == pytest.approx(0.021 * L, rel=0.5)
    for lv, (dist, half) in {"easy": (0.5, 30), "medium": (1.0, 90), "hard": (1.5, 180)}.items():
        env = make("reach_goal", lv)
        for seed in range(5):
            env.reset(seed=seed)
            off = env.goal - env.com()
            assert math.hypot(off[0], off[2]) == pytest.approx(dist * L, rel=1e-9)
            assert abs(math.degrees(math.atan2(off[2], off[0]))) <= half + 1e-9


def test_the_walk_task_at_easy_is_the_robot_environment_bit_for_bit():
    a = gym.make("SoftTripodWalk-v0", difficulty="easy")
    b = gym.make("SoftTripod-v2")
    oa, _ = a.reset(seed=5)
    ob, _ = b.reset(seed=5)
    assert np.array_equal(oa, ob)
    rng = np.random.default_rng(1)
    for _ in range(4):
        act = rng.uniform(-1, 1, 2)
        ra, rb = a.step(act), b.step(act)
        assert np.array_equal(ra[0], rb[0]) and ra[1] == rb[1] and ra[2] == rb[2]


def test_rough_terrain_draws_a_terrain_per_episode_from_np_random():
    env = gym.make("SoftTripodRoughTerrain-v0", difficulty="easy").unwrapped
    o1, i1 = env.reset(seed=7)
    o2, i2 = env.reset(seed=7)
    assert i1["terrain_seed"] == i2["terrain_seed"] and np.array_equal(o1, o2)
    _, i3 = env.reset(seed=8)
    assert i3["terrain_seed"] != i1["terrain_seed"]
    fixed = gym.make("SoftTripodRoughTerrain-v0", terrain_seed=4).unwrapped
    assert {fixed.reset(seed=s)[1]["terrain_seed"] for s in range(3)} == {4}
    with pytest.raises(ValueError, match="terrain_seed must be an integer >= 0 or None, got -1|terrain_seed must"):
        gym.make("SoftTripodRoughTerrain-v0", terrain_seed=-1)
    # the terrain part: the COM's height above the ground under it, the ground ahead
    obs, info = env.reset(seed=7)
    t = obs[-3:]
    assert t[0] == pytest.approx(info["height_above_ground"]) and 0.03 < t[0] < 0.07
    com = env.com()
    assert t[0] == pytest.approx(com[1] - env.robot.ground.height(com[0], com[2]), abs=1e-12)


def test_reach_goal_reward_is_progress_and_reaching_it_ends_the_episode():
    env = gym.make("SoftPuppyReachGoal-v0", difficulty="easy").unwrapped
    env.reset(seed=0)
    rng = np.random.default_rng(2)
    for _ in range(3):
        d0 = env.goal_distance()
        obs, reward, terminated, _, info = env.step(rng.uniform(-1, 1, 8))
        progress = (d0 - info["goal_distance"]) / env.dt / env.robot.body_length
        assert info["reward_forward"] == pytest.approx(10.0 * progress, rel=1e-9, abs=1e-12)
        assert np.allclose(obs[-2:], (env.goal - env.com())[[0, 2]]) and not terminated
    env._goal = env.com() + np.array([0.01 * env.robot.body_length, 0.0, 0.0])   # the goal next to the COM
    obs, reward, terminated, _, info = env.step(np.full(8, -1.0))
    assert info["is_success"] and terminated and info["reward_success"] == 10.0
    # without terminating, the success reward comes once
    env = gym.make("SoftPuppyReachGoal-v0", terminate_on_success=False, success_reward=3.0).unwrapped
    env.reset(seed=0)
    env._goal = env.com().copy()
    r = [env.step(np.full(8, -1.0)) for _ in range(2)]
    assert [x[4]["reward_success"] for x in r] == [3.0, 0.0] and not any(x[2] for x in r)
    with pytest.raises(ValueError, match="goal_radius_bl must be a positive number"):
        gym.make("SoftPuppyReachGoal-v0", goal_radius_bl=0)


@pytest.mark.parametrize("env_id", ["SoftTripodClimbStep-v0", "SoftPuppyCrossTrench-v0"])
def test_passing_the_obstacle_is_a_success(env_id):
    env = gym.make(env_id).unwrapped
    env.reset(seed=0)
    _, _, terminated, _, info = env.step(np.zeros(env.action_space.shape))
    assert not info["is_success"] and not terminated and info["reward_success"] == 0.0
    assert env.finish_x > env.com()[0] + 0.5 * env.robot.body_length
    env.finish_x = env.com()[0] - 1.0                # as if the COM were past it
    _, reward, terminated, _, info = env.step(np.zeros(env.action_space.shape))
    assert info["is_success"] and terminated and info["reward_success"] == 10.0


def test_the_robot_on_top_of_the_step_is_healthy_and_sees_the_step():
    env = gym.make("SoftTripodClimbStep-v0", difficulty="hard", reset_noise_scale=0.0).unwrapped
    obs, info = env.reset(seed=0)
    rest_height = obs[-3]
    assert obs[-1] == pytest.approx(env.step_height, rel=1e-6)          # the step one body length ahead
    x = env.get_state()["x"] + np.array([env.finish_x + 0.1, env.step_height, 0.0])   # lifted onto it
    env.set_state({"x": x})
    assert env.is_healthy
    obs = env._get_obs()
    assert obs[-3] == pytest.approx(rest_height, abs=1e-9) and obs[-2] == pytest.approx(0.0, abs=1e-9)


def test_an_unhealthy_robot_terminates_on_every_kind_of_ground():
    for env_id in ("SoftTripodRoughTerrain-v0", "SoftTripodSlopeDown-v0", "SoftTripodWalk-v0"):
        env = gym.make(env_id).unwrapped
        env.reset(seed=0)
        x = env.get_state()["x"]
        com = env.com()
        flipped = com + (x - com) * np.array([1.0, -1.0, -1.0])          # upside down (180 deg about x)
        env.set_state({"x": flipped})
        assert not env.is_healthy
        _, _, terminated, _, info = env.step(np.zeros(env.action_space.shape))
        assert terminated and not info["is_healthy"]


# ---------------------------------------------------------------------- the health check on a slope
def _on_slope(angle_deg: float, **kw) -> SoftTripodEnv:
    env = SoftTripodEnv(ground=HeightField.incline(angle_deg), reset_noise_scale=0.0, **kw)
    env.reset(seed=0)
    return env


def test_walking_down_a_sloped_field_is_not_falling():
    """A robot carried 0.3 m down a 20-degree field slope, along it, is healthy: its COM is far
    below y = 0 (the old rule, COM y against half its rest y, would end the episode) but at its
    rest height above the ground under it."""
    env = _on_slope(-20.0)
    a = math.radians(-20.0)
    x = env.get_state()["x"] + 0.3 * np.array([math.cos(a), math.sin(a), 0.0])
    env.set_state({"x": x})
    com = env.com()
    assert com[1] < 0 < 0.5 * env._rest_com_height                      # the old rule: fallen
    assert env.is_healthy
    above = com[1] - env.robot.ground.height(com[0], com[2])
    assert above == pytest.approx(env._rest_com_height, rel=1e-9)
    x2 = x - np.array([0.0, 0.6 * above, 0.0])                          # sunk to 0.4 of its height
    env.set_state({"x": x2})
    assert not env.is_healthy


def test_turning_on_a_sloped_field_is_not_tilting():
    """Turned 180 degrees about the slope's normal, a robot on a 20-degree field stands as it did:
    tilt 0 from the normal (its up vector is 40 degrees from +y, which the old rule measured)."""
    env = _on_slope(20.0, healthy_tilt_deg=30.0)
    n = GroundReference(env.robot.ground).normal
    R = 2.0 * np.outer(n, n) - np.eye(3)                               # 180 degrees about n
    x = env.get_state()["x"]
    com = env.com()
    env.set_state({"x": com + (x - com) @ R.T})
    assert tilt_deg_of(env._rot) == pytest.approx(40.0, abs=0.5)
    assert env._tilt == pytest.approx(0.0, abs=0.5) and env.is_healthy


def test_the_ground_reference_is_the_old_rule_on_the_plane():
    ref = GroundReference(None)
    rng = np.random.default_rng(0)
    for _ in range(5):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        assert ref.tilt_deg(q) == tilt_deg_of(q)
        assert ref.height_under(rng.normal(size=3)) == 0.0
    flat_rough = GroundReference(HeightField.step(0.01, 0.5))
    assert not flat_rough.tilted and flat_rough.height_under(np.array([1.0, 0.0, 0.0])) == pytest.approx(0.01)


@pytest.mark.parametrize("env_id", ["SoftTripodRoughTerrain-v0", "SoftPuppyReachGoal-v0"])
def test_a_task_pickles_and_resets_without_a_seed(env_id):
    import pickle
    env = gym.make(env_id).unwrapped
    env.reset()                                    # np_random seeded by the OS
    env.reset(seed=2)
    copy = pickle.loads(pickle.dumps(env))
    a = np.full(env.action_space.shape, 0.5)
    r1, r2 = env.step(a), copy.step(a)
    assert np.array_equal(r1[0], r2[0]) and r1[1] == r2[1]


def test_a_terrain_the_robot_cannot_rest_on_is_redrawn(monkeypatch):
    from soft_envs.envs.tasks.base import TaskEnv
    from soft_envs.sim import SimulationError
    env = gym.make("SoftTripodRoughTerrain-v0").unwrapped
    calls = []
    real = TaskEnv._set_ground

    def flaky(self, ground):
        calls.append(ground)
        if len(calls) == 1:
            raise SimulationError("rest_state failed")
        real(self, ground)
    monkeypatch.setattr(TaskEnv, "_set_ground", flaky)
    obs, info = env.reset(seed=0)
    assert info["terrain_draws"] == 2 and len(calls) == 2 and env.robot.ground is calls[1]
    assert env.observation_space.contains(obs)
    # a failed draw changes nothing
    monkeypatch.setattr(TaskEnv, "_set_ground", real)
    sim, robot, ref = env.simulator, env._base_robot, env._ground_ref

    def cannot_rest(self, factors, dt=None):
        raise SimulationError("rest_state failed")
    monkeypatch.setattr(TaskEnv, "_set_domain", cannot_rest)
    with pytest.raises(SimulationError):
        env._set_ground(HeightField.flat(0.01))
    assert env.simulator is sim and env._base_robot is robot and env._ground_ref is ref


@pytest.mark.parametrize("env_id", TASK_IDS)
def test_every_level_of_every_id_resets_and_steps(env_id):
    for level in ("easy", "medium", "hard"):
        env = gym.make(env_id, difficulty=level)
        obs, info = env.reset(seed=1)
        obs, reward, terminated, _, info = env.step(np.zeros(env.action_space.shape))
        assert env.observation_space.contains(obs) and np.isfinite(reward) and not terminated
        assert env.unwrapped.difficulty == level and info["is_healthy"]


def test_a_reset_whose_every_terrain_fails_keeps_the_terrain_and_its_seed(monkeypatch):
    from soft_envs.envs.tasks.base import TaskEnv
    from soft_envs.sim import SimulationError
    env = gym.make("SoftTripodRoughTerrain-v0").unwrapped
    env.reset(seed=0)
    seed, ground = env._episode_seed, env.robot.ground

    def never(self, ground):
        raise SimulationError("rest_state failed")
    monkeypatch.setattr(TaskEnv, "_set_ground", never)
    with pytest.raises(SimulationError):
        env.reset(seed=1)
    assert env._episode_seed == seed and env.robot.ground is ground
