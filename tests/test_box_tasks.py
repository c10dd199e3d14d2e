"""The tasks with a second body (issue #39): carry a payload (SoftTripodCarry-v0, SoftPuppyCarry-v0)
and push a box (SoftTripodPushBox-v0, SoftPuppyPushBox-v0). Both checkers, reset / step / render
and the docstrings run for every id in tests/test_tasks_ids.py; here: the box's observation
parts, a payload that falls ends the episode with its penalty, the box's speed as the push
reward and the push's success, the levels, determinism and the gradient hooks."""
from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import soft_envs  # noqa: F401  (registers the ids)
from soft_envs.envs.tasks import CarryEnv, LEVELS, PushBoxEnv
from soft_envs.envs.tasks.box_task import BOX_PARTS

BOX_IDS = ["SoftTripodCarry-v0", "SoftPuppyCarry-v0", "SoftTripodPushBox-v0", "SoftPuppyPushBox-v0"]


def _gait(env, k):
    """A travelling wave over the motors (a walk for the Tripod)."""
    n = env.action_space.shape[0]
    return np.sin(2 * np.pi * k / 20 + np.arange(n))


@pytest.mark.parametrize("env_id", BOX_IDS)
def test_the_box_is_in_the_observation_and_the_robot_measures_leave_it_out(env_id):
    u = gym.make(env_id, reset_noise_scale=0.0).unwrapped
    obs, info = u.reset(seed=0)
    s, robot = u.observation_structure, u.robot
    assert list(s)[-3:] == list(BOX_PARTS) and obs.size == sum(s.values())
    at = sum(s.values()) - sum(BOX_PARTS.values())
    box = u.box_center()
    np.testing.assert_allclose(obs[at:at + 3], box - u.com(), atol=1e-12)
    np.testing.assert_allclose(obs[at + 3:at + 6], 0.0, atol=1e-9)                # at rest
    np.testing.assert_allclose(obs[at + 6:at + 12], [1, 0, 0, 0, 1, 0], atol=2e-2)  # upright, facing +x
    # the robot's COM, frame and health are its own: the box's nodes weigh nothing there
    n = robot.n_robot_nodes
    own = robot.node_masses[:n]
    np.testing.assert_allclose(u.com(), own @ u._x[:n] / own.sum(), rtol=1e-12)
    assert info["is_healthy"] and robot.mesh.n_nodes == n + 8
    np.testing.assert_array_equal(info["box_position"], box)
    if "Carry" in env_id:
        assert box[1] > u._x[:n, 1].max() and not info["payload_fell"]
    else:
        assert box[0] > u._x[:n, 0].max() and abs(box[1] - 0.125 * robot.body_length) < 1e-3


def test_a_payload_that_falls_ends_the_episode_with_its_penalty():
    """The payload moved down beside the robot (set_state): the next step is terminated, its
    reward holds -drop_penalty, info says it fell; the episode counts as ended."""
    env = gym.make("SoftTripodCarry-v0", drop_penalty=7.0)
    env.reset(seed=0)
    u = env.unwrapped
    obs, reward, terminated, _, info = env.step(np.zeros(2))
    assert not terminated and info["reward_drop"] == 0.0 and not info["payload_fell"]
    state = u.get_state()
    x = state["x"].copy()
    b = u.robot.box_nodes
    x[b] += np.array([0.0, u.box.size[1] / 2 + 1e-3, 0.0]) - x[b].mean(axis=0) + [0.07, 0.0, 0.1]
    u.set_state({**state, "x": x, "x_prev": x, "history": None})
    with pytest.warns(UserWarning, match="already returned terminated"):       # the state set has ended
        obs, reward, terminated, _, info = env.step(np.zeros(2))
    assert terminated and info["payload_fell"] and info["is_healthy"]
    assert info["reward_drop"] == -7.0
    assert reward == pytest.approx(sum(info[k] for k in ("reward_forward", "reward_ctrl", "reward_survive",
                                                         "reward_success", "reward_drop")), abs=1e-12)
    assert u._has_terminated()          # a further step warns as after any end of an episode


def test_a_tilted_payload_falls_too():
    env = CarryEnv("tripod", fall_tilt_deg=0.1)     # the payload at rest already tilts a little more
    env.reset(seed=0)
    assert env.payload_fell() and env.box_tilt_deg() > 0.1


def test_the_tripod_carries_the_easy_payload_while_it_walks():
    """60 steps (2 s) of a gait: the payload rides along (it moves with the COM, does not fall)."""
    env = gym.make("SoftTripodCarry-v0", difficulty="easy")
    env.reset(seed=0)
    for k in range(60):
        _, _, terminated, _, info = env.step(_gait(env, k))
        assert not terminated
    assert info["displacement"][0] > 0.01
    assert abs(info["box_displacement"][0] - info["displacement"][0]) < 5e-3 and not info["payload_fell"]


def test_the_push_reward_is_the_box_speed_and_pushing_it_far_enough_succeeds():
    env = gym.make("SoftTripodPushBox-v0", push_distance_bl=0.05, difficulty="easy")
    _, info = env.reset(seed=0)
    u = env.unwrapped
    L = u.robot.body_length
    before = u.box_center()
    for k in range(120):
        obs, reward, terminated, _, info = env.step(_gait(env, k))
        now = u.box_center()
        assert info["reward_forward"] == pytest.approx(10.0 * (now[0] - before[0]) / u.dt / L, rel=1e-12, abs=1e-12)
        before = now
        if terminated:
            break
    assert info["is_success"] and info["reward_success"] == 10.0 and info["box_pushed"] >= 0.05 * L
    assert info["box_pushed"] == pytest.approx(info["box_displacement"][0], abs=1e-15)


def test_the_levels_set_the_box():
    L = None
    for task, cls in (("carry", CarryEnv), ("push_box", PushBoxEnv)):
        masses = []
        for lv in ("easy", "medium", "hard"):
            env = cls("tripod", difficulty=lv)
            L = env.robot.body_length
            assert env.box.mass == pytest.approx(LEVELS[task][lv]["mass_fraction"] * env.robot.total_mass)
            masses.append(env.box.mass)
            if task == "carry":
                assert env.box.friction_coefficient == LEVELS["carry"][lv]["friction_coefficient"]
        assert masses == sorted(masses)
    assert L == pytest.approx(0.14)
    with pytest.raises(ValueError, match="drop_penalty must be a finite number in \\[0, inf\\]"):
        CarryEnv("tripod", drop_penalty=-1.0)
    with pytest.raises(ValueError, match="push_distance_bl must be"):
        PushBoxEnv("tripod", push_distance_bl=0)


@pytest.mark.parametrize("env_id", ["SoftTripodCarry-v0", "SoftPuppyPushBox-v0"])
def test_a_seeded_reset_replays_bit_for_bit(env_id):
    def run():
        env = gym.make(env_id)
        obs, _ = env.reset(seed=4)
        out = [obs]
        rng = np.random.default_rng(1)
        for _ in range(4):
            out.append(env.step(rng.uniform(-1, 1, env.action_space.shape))[0])
        return np.array(out)
    np.testing.assert_array_equal(run(), run())


def test_the_gradient_hooks_give_the_rollouts_derivatives(monkeypatch):
    """``rollout`` with ``dudz`` from the reset state (the box's contact has sensitivities, checked
    exactly in tests/test_box.py): dCOM/dz and the box's dx/dz against central differences of
    the environment's own rollouts, solved to 1e-9 m per physics step here (the default, 1e-6 m,
    is the size of the difference step; the stick-slip events bound the agreement: 0.14 % and
    0.25 % at h = 1e-6 m of contraction and 1e-7 m, 5 % and 11 % at 1e-4 m)."""
    from soft_envs.sim import substeps
    monkeypatch.setattr(substeps, "SUBSTEP_TOLERANCE", 1e-9)
    env = gym.make("SoftTripodCarry-v0").unwrapped
    assert env.simulator.newton.options.tol == 1e-9
    env.reset(seed=0)
    K = 6
    u = np.outer(np.linspace(0.001, 0.01, K), [1.0, 0.5])
    dudz = np.ones((K, 2, 1))
    traj = env.rollout(u, dudz=dudz, store_dxdz=True)
    h = 1e-6
    tp, tm = env.rollout(u + h), env.rollout(u - h)
    fd_com = (tp.com - tm.com) / (2 * h)
    assert np.linalg.norm(traj.dcomdz[..., 0] - fd_com) <= 1e-2 * np.linalg.norm(fd_com)
    box = env.robot.box_nodes
    fd_box = (tp.x[:, box] - tm.x[:, box]).reshape(K + 1, -1) / (2 * h)
    an_box = traj.dxdz[:, 3 * box[0]:3 * box[-1] + 3, 0]
    assert np.linalg.norm(an_box - fd_box) <= 1e-2 * np.linalg.norm(fd_box)


def test_the_paper_law_carries_and_pushes_too():
    """Both ground laws act on the box: the ids take contact="paper"."""
    for env_id in ("SoftTripodCarry-v0", "SoftTripodPushBox-v0"):
        env = gym.make(env_id, contact="paper")
        env.reset(seed=0)
        for k in range(5):
            _, _, terminated, _, info = env.step(_gait(env, k))
            assert not terminated and "sim_failure" not in info
        assert env.unwrapped.contact_model == "paper"


def test_a_box_task_pickles_and_steps_as_the_original():
    import pickle
    env = gym.make("SoftPuppyCarry-v0").unwrapped
    env.reset(seed=2)
    env.step(np.full(8, 0.5))
    copy = pickle.loads(pickle.dumps(env))
    a = np.linspace(-1, 1, 8)
    np.testing.assert_array_equal(env.step(a)[0], copy.step(a)[0])
    assert copy.robot.box == env.robot.box


def test_domain_randomisation_scales_the_robot_and_keeps_the_box_mass():
    env = gym.make("SoftTripodPushBox-v0", domain_randomization={"youngs_modulus": (0.8, 0.8), "density": (1.2, 1.2)})
    env.reset(seed=0)
    robot = env.unwrapped.robot
    box = robot.box_nodes
    np.testing.assert_allclose(robot.node_masses[box], env.unwrapped.box.mass / 8, rtol=1e-15)
    E_box = robot.youngs_modulus * robot.element_modulus_scale[-5:]
    np.testing.assert_allclose(E_box, 0.8 * env.unwrapped.box.youngs_modulus, rtol=1e-12)
    assert not env.step(np.zeros(2))[2]


def test_frames_draw_the_box_in_its_own_colour():
    from soft_envs.envs.viewer import BOX_COLOUR
    env = gym.make("SoftTripodCarry-v0", render_mode="rgb_array", width=240, height=180)
    try:
        env.reset(seed=0)
        frame = env.render().astype(int)
        colours = np.asarray(env.unwrapped._viewer.renderer.color)
        box = np.isin(env.unwrapped._base_robot.mesh.surface, env.unwrapped._base_robot.box_nodes).all(axis=1)
        assert box.any() and np.allclose(colours[box], BOX_COLOUR) and not np.allclose(colours[~box], BOX_COLOUR)
        orange = (frame[..., 0] > frame[..., 2] + 60) & (frame[..., 1] > frame[..., 2] + 20)
        assert orange.sum() > 200                    # the plate on the robot's top is seen
    finally:
        env.close()


def test_trajopt_optimises_with_the_box_and_its_result_replays_and_scores_with_it(tmp_path):
    """``trajopt optimize tripod --task push_box``: the walk's objective on the robot with the
    task's box (soft_envs.envs.tasks.task_keywords); the result replays with the same box (its
    robot fingerprint, box nodes included, matches) and is scored on SoftTripodPushBox-v0 by the
    box's displacement."""
    from soft_envs.envs.tasks import task_keywords
    from trajopt.optimize_run import OptimizeRun, run_optimization
    from trajopt.replay import env_for_result, result_box
    from trajopt.results.result import Result
    from trajopt.tasks.play import gait_on_task
    run_optimization(OptimizeRun("tripod", task="push_box", difficulty="easy", iterations=1, seeds=0, cycle_steps=12,
                                 prep_steps=6, cycles=1, out=tmp_path, quiet=True))
    res = Result.load(tmp_path / "tripod_push_box.npz")
    assert res.settings["env_task"] == "push_box" and res.settings["difficulty"] == "easy"
    box = task_keywords("push_box", "tripod", "easy")["box"]
    assert result_box(res, "tripod") == box
    env = env_for_result(res)                     # the fingerprint of the robot with its box
    assert env.robot.box == box and env.robot.mesh.n_nodes == gym.make("SoftTripodPushBox-v0").unwrapped.robot.mesh.n_nodes
    x0, _ = env.reset_state()
    traj = env.rollout(res.u)
    moved = float(traj.x[-1][env.robot.box_nodes][:, 0].mean() - x0[env.robot.box_nodes][:, 0].mean())
    ev = gait_on_task(res, episodes=1)
    assert ev["env_id"] == "SoftTripodPushBox-v0" and ev["score_name"] == "pushed" and ev["score_unit"] == "BL"
    assert np.isfinite(ev["score"]) and (moved > 0.0) == (ev["score"] > 0.0)
    from trajopt.robustness.report import robustness_jobs     # a robustness study replays it with its box
    from trajopt.robustness.study import run_sample
    nominal, perturbed = robustness_jobs(res, 1, 1, 0)
    assert nominal.box == box and perturbed[0].box == box
    assert np.isfinite(run_sample(nominal)["speed_bl_per_min"])
    with pytest.raises(ValueError, match="--heading applies to the walk, the turn and reach_goal, not to --task carry"):
        run_optimization(OptimizeRun("tripod", task="carry", heading=90.0, out=tmp_path, quiet=True))
    with pytest.raises(ValueError, match="task 'carry' adds its own box; robot 'tripod' has one already"):
        task_keywords("carry", gym.make("SoftTripodCarry-v0").unwrapped.robot, "medium")
