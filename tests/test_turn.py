"""The turn (paper IV-B): the heading measure and its exact derivative, the heading term of the
objective through whole rollouts, the turn's target headings and horizon figures; a short
turn optimisation (slow)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from soft_envs.envs import make_gradient_env
from soft_envs.sim import NewtonOptions
from trajopt import GaitParameterization, GaitSpec, GaussNewtonOptions, ObjectiveWeights, Result, optimize_gait
from trajopt.evaluation import measure_gait
from trajopt.optim.gait import TURN_KEYFRAMES
from trajopt.optim.heading import HeadingMeasure
from trajopt.optim.objectives import HeadingTarget
from trajopt.optim.optimize import TASK_CONTACT, GaitProblem
from trajopt.tasks.targets import quarter_circle, quarter_circle_heading, straight_line
from trajopt.tasks.registry import TURN_INTERPOLATION

from .conftest import shipped


def yaw_rotation(a: float) -> np.ndarray:
    """Rotation about +y by ``a`` that turns +x towards +z (a right turn by ``a``)."""
    return np.array([[np.cos(a), 0.0, -np.sin(a)], [0.0, 1.0, 0.0], [np.sin(a), 0.0, np.cos(a)]])


def tilt_rotation(a: float) -> np.ndarray:
    """Rotation about +x by ``a`` (a roll)."""
    return np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)], [0.0, np.sin(a), np.cos(a)]])


def test_heading_of_a_rigid_rotation_is_its_yaw():
    robot, _, x0 = shipped("puppy")
    measure = HeadingMeasure(x0, robot.node_masses)
    for a in (0.3, -1.2, 2.9):
        assert np.isclose(measure.yaw((x0 - 0.05) @ yaw_rotation(a).T + [0.1, 0.0, -0.2]), a, atol=1e-12)
    xs = np.stack([x0 @ yaw_rotation(a).T for a in np.linspace(0.0, 7.0, 50)])
    assert np.allclose(measure.yaws(xs), np.linspace(0.0, 7.0, 50))          # unwrapped past pi


@pytest.mark.parametrize("yaw, roll", [(0.0, 0.0), (0.8, 0.3), (-2.5, -0.6)])
def test_heading_gradient_matches_central_differences(yaw, roll):
    """d yaw / dx of the best-fit rotation (polar-decomposition derivative) against central
    differences along random directions, on deformed, tilted and turned states."""
    robot, _, x0 = shipped("puppy")
    measure = HeadingMeasure(x0, robot.node_masses)
    rng = np.random.default_rng(7)
    x = (x0 + 0.004 * rng.normal(size=x0.shape)) @ (yaw_rotation(yaw) @ tilt_rotation(roll)).T + 0.3
    value, grad = measure.yaw_and_gradient(x)
    assert np.isclose(value, measure.yaw(x))
    for _ in range(4):
        d = rng.normal(size=x.shape)
        h = 1e-6
        fd = (measure.yaw(x + h * d) - measure.yaw(x - h * d)) / (2 * h)
        assert abs(fd - float(np.sum(grad * d))) <= 1e-7 * max(abs(fd), 1e-3)


def test_target_heading_is_the_tangent_of_the_quarter_circle():
    for direction, sign in (("right", 1.0), ("left", -1.0)):
        arc = quarter_circle([0.0, 0.0], 400, 0.01, 0.1, heading_deg=20.0, direction=direction)
        yaw = quarter_circle_heading(400, 0.01, 0.1, heading_deg=20.0, direction=direction)
        mid = 0.5 * (yaw[1:] + yaw[:-1])
        step = np.diff(arc, axis=0)
        assert np.allclose(np.arctan2(step[:, 1], step[:, 0]), mid, atol=1e-9)
        assert np.isclose(yaw[-1] - yaw[0], sign * np.pi / 2)


def test_heading_term_jacobian_matches_finite_differences_of_rollouts():
    """The heading residual's Jacobian through the rollout sensitivities dx/dz (and the COM
    term beside it) equals central differences of whole rollouts (tight Newton tolerance),
    along random directions; the heading rows to 1e-6 relative."""
    robot = shipped("puppy")[0]                # the Tripod's cables lie in its sagittal plane: no yaw
    env = make_gradient_env(robot)
    env.simulator.newton.options = NewtonOptions(tol=1e-12)
    p = GaitParameterization.for_robot(robot, GaitSpec(n_prep=4, n_cycle=8, symmetry=False))
    x0, _ = env.reset_state()
    K = p.n_steps()
    target = straight_line(robot.com(x0)[[0, 2]], K, env.timestep, 0.02)
    heading = HeadingTarget(HeadingMeasure(x0, robot.node_masses), np.linspace(0.0, 0.1, K + 1))
    prob = GaitProblem(env, p, target, ObjectiveWeights(heading=1.0), heading)
    z = p.initial_z(0.5, np.random.default_rng(4), noise=0.45)
    r, J, info = prob(z)
    assert info["terms"]["heading"] > 0
    rows = slice(2 * K, 3 * K)                                  # the heading residuals follow the COM's
    rng = np.random.default_rng(5)
    for _ in range(2):
        d = rng.normal(size=p.nz)
        d /= np.linalg.norm(d)
        h = 2e-8
        fd = (prob(z + h * d, False)[0] - prob(z - h * d, False)[0]) / (2 * h)
        err = np.linalg.norm(fd[rows] - (J @ d)[rows]) / np.linalg.norm(fd[rows])
        assert np.linalg.norm((J @ d)[rows]) > 1e-3 * np.linalg.norm(J @ d) and err < 1e-6, err   # measured 1e-8, 2e-9
        assert np.linalg.norm(fd - J @ d) / np.linalg.norm(fd) < 1e-4


def test_measure_gait_reports_heading_per_cycle_and_over_the_horizon():
    """A rigid body carried along a quarter circle while turning with it: the heading and
    the distance to the target are read back exactly."""
    robot, _, x0 = shipped("puppy")
    n_prep, n_cycle, dt = 4, 10, 0.033
    K = n_prep + 3 * n_cycle
    c0 = robot.com(x0)
    target = quarter_circle(c0[[0, 2]], K, dt, 0.02, direction="left")
    yaw = quarter_circle_heading(K, dt, 0.02, direction="left")
    xs = np.stack([(x0 - c0) @ yaw_rotation(a).T + [p[0], c0[1], p[1]] for a, p in zip(yaw, target)])
    traj = SimpleNamespace(x=xs, com=robot.com(xs))
    env = SimpleNamespace(robot=robot, timestep=dt)
    ev = measure_gait(traj, env, n_prep=n_prep, n_cycle=n_cycle, target=target[: n_prep + 2 * n_cycle + 1])
    assert np.isclose(ev["heading_change_deg"], -90.0)
    assert np.allclose(ev["heading_per_cycle_deg"], -90.0 * n_cycle / K)
    assert np.isclose(ev["horizon_heading_change_deg"], -90.0 * (n_prep + 2 * n_cycle) / K)
    assert ev["horizon_rms_to_target_bl"] < 1e-12 and ev["upright"]
    chords = np.linalg.norm(target[n_prep + n_cycle::n_cycle] - target[n_prep:-n_cycle:n_cycle], axis=1)
    assert np.isclose(ev["cycle_path_speed_bl_per_min"], chords.sum() / (K - n_prep) / dt * 60 / robot.body_length)
    shifted = measure_gait(traj, env, n_prep=n_prep, n_cycle=n_cycle, target=target + [0.0, 0.013])
    assert np.isclose(shifted["horizon_rms_to_target_bl"], 0.013 / robot.body_length)
    with pytest.raises(ValueError, match="target"):
        measure_gait(traj, env, n_prep=n_prep, n_cycle=n_cycle, target=np.zeros((K + 5, 2)))


def test_turn_defaults_and_warm_start_from_the_walk():
    """The walk keeps the paper's gait and objective; the turn has 12 keyframes joined by straight
    lines, no symmetry and the heading term; a 4-keyframe walk warm-starts it as three strides per
    cycle."""
    assert GaitSpec.for_task("walk") == GaitSpec() and ObjectiveWeights.for_task("walk") == ObjectiveWeights()
    turn = GaitSpec.for_task("turn", n_keyframes=None, n_prep=30)
    assert (turn.n_keyframes, turn.symmetry, turn.n_prep) == (TURN_KEYFRAMES, False, 30)
    assert turn.interpolation == TURN_INTERPOLATION == "linear" and GaitSpec().interpolation == "hermite"
    assert ObjectiveWeights.for_task("turn").heading > 0
    robot = shipped("puppy")[0]
    walk = GaitParameterization.for_robot(robot, GaitSpec(interpolation=turn.interpolation))  # same lines
    param = GaitParameterization.for_robot(robot, turn)
    kf = walk.keyframes(walk.initial_z(0.5, np.random.default_rng(1), noise=0.4))
    tiled = param.keyframes_from(kf)
    u_walk = walk.controls(walk.z_from_keyframes(kf))[walk.n_prep:]
    u_turn = param.controls(param.z_from_keyframes(tiled))[param.n_prep:]
    n = walk.n_cycle // 3                                       # one stride of the turn's cycle
    assert np.allclose(u_turn[:n], u_walk[::3][:n], atol=1e-12)
    with pytest.raises(ValueError, match="divides 12"):
        param.keyframes_from(np.zeros((robot.n_motors, 5)))


#: the Puppy's walk (keyframes [mm] of ``trajopt optimize puppy --task walk``, rounded)
PUPPY_WALK_MM = [[16, 16, 0, 1], [4, 0, 11, 16], [0, 1, 16, 16], [11, 16, 4, 0],
                 [0, 1, 16, 16], [13, 16, 16, 0], [16, 16, 0, 1], [16, 0, 13, 16]]


@pytest.mark.slow
@pytest.mark.parametrize("turn, sign", [("right", 1.0), ("left", -1.0)])
def test_short_turn_optimisation_turns_the_body(turn, sign):
    """A short turn (prep + one cycle, two Gauss-Newton iterations) warm-started from the walk,
    with the turn's defaults (12 keyframes joined by lines, heading term, Coulomb law): the body's heading
    (best-fit rotation of all nodes) turns to the asked side over the horizon and keeps turning
    at the same rate in the cycles after it. Under the motors' limit (the default) it turns
    about 26 degrees over the horizon and 25 per cycle to either side with the turn's straight
    lines (the spline: 19; without the limit over 30)."""
    env = make_gradient_env("puppy", contact=TASK_CONTACT["turn"])
    kf = np.array(PUPPY_WALK_MM) * 1e-3
    walk = Result(robot="puppy", task="walk", motor_names=env.robot.motor_names, dt=env.timestep, z=kf.ravel(),
                  u=np.zeros((1, 8)), u_post=np.zeros((1, 8)), target=np.zeros((0, 2)), com=np.zeros((0, 3)),
                  settings={"keyframes": kf.tolist()})
    res = optimize_gait(env, "turn", gait=GaitSpec.for_task("turn", n_cycles=1), turn=turn, warm_start=walk,
                        n_seeds=0, options=GaussNewtonOptions(max_iter=2), eval_cycles=3)
    ev = res.evaluation
    assert res.history[-1]["objective_after"] < res.history[0]["objective"]
    assert sign * ev["horizon_heading_change_deg"] > 20.0, ev
    per_cycle = sign * np.array(ev["heading_per_cycle_deg"])
    assert per_cycle.min() > 20.0 and np.ptp(per_cycle[1:]) < 2.0, per_cycle
    assert ev["horizon_rms_to_target_bl"] < 0.25 and ev["upright"]
