"""trajopt: parameterisation, targets, objective Jacobian through rollouts, Gauss-Newton,
results files, resume."""
from __future__ import annotations

import json

import numpy as np
import pytest

from soft_envs.envs import as_gradient_env, make_gradient_env
from soft_envs.sim import NewtonOptions
from trajopt import GaitParameterization, GaitSpec, GaussNewtonOptions, ObjectiveWeights, Result, optimize_gait
from trajopt.evaluation import zero_slack_controls
from trajopt.optim.optimize import GaitProblem
from trajopt.optim.parameterization import hermite_cycle_basis
from trajopt.tasks.targets import quarter_circle, straight_line

from .conftest import shipped


def puppy_param(symmetry=True, **kw):
    robot = shipped("puppy")[0]
    return robot, GaitParameterization.for_robot(robot, GaitSpec(symmetry=symmetry, **kw))


def test_spline_is_periodic_zero_tangent_and_bounded():
    B = hermite_cycle_basis(72, 4)
    assert np.allclose(B.sum(axis=1), 1.0) and (B >= 0).all()
    kf = np.array([0.0, 1.0, 0.3, 0.7])
    u = B @ kf
    assert np.allclose(u[::18], kf)                        # passes through the keyframes
    assert u.min() >= kf.min() and u.max() <= kf.max()     # never leaves their range
    # zero tangent at keyframes (one-sided differences vanish to second order)
    for j in range(4):
        i = 18 * j
        assert abs(u[(i + 1) % 72] - u[i]) < 0.02 and abs(u[i - 1] - u[i]) < 0.02


def test_dudz_matches_finite_differences_and_layout():
    robot, p = puppy_param()
    assert p.nz == 16 and p.dudz().shape == (168, 8, 16)    # paper: 16 with symmetry
    assert puppy_param(symmetry=False)[1].nz == 32           # and 32 without
    rng = np.random.default_rng(0)
    z = p.initial_z(0.5, rng, noise=0.4)
    d = rng.normal(size=p.nz)
    h = 1e-6
    fd = (p.controls(z + h * d) - p.controls(z - h * d)) / (2 * h)
    assert np.allclose(fd, p.dudz() @ d, rtol=1e-8, atol=1e-12)
    u = p.controls(z)
    assert np.allclose(u[0], 0.0, atol=1e-12) or np.abs(u[0]).max() < 0.01 * np.abs(u).max()
    assert np.allclose(u[p.n_prep - 1], u[p.n_prep])        # prep ends at the cycle's start
    assert np.allclose(u[p.n_prep:p.n_prep + 72], u[p.n_prep + 72:])   # two identical cycles


def test_symmetry_is_half_period_shift_of_mirror_motor():
    robot, p = puppy_param()
    z = p.initial_z(0.5, np.random.default_rng(1), noise=0.4)
    u = p.controls(z)[p.n_prep:p.n_prep + 72]
    for m, mm in enumerate(robot.mirror_map):
        assert np.allclose(u[:, mm], np.roll(u[:, m], -36))
    kf = p.keyframes(z)
    lo, hi = p.bounds()
    assert np.allclose(p.z_from_keyframes(kf), z)
    assert (lo == 0).all() and np.allclose(hi, robot.u_bounds[p.free_motors, 1].repeat(4))


def test_targets():
    line = straight_line([0.0, 0.0], 10, 0.1, 0.5, heading_deg=90.0)
    assert np.allclose(line[-1], [0.0, 0.5])
    arc = quarter_circle([0.0, 0.0], 100, 0.05, 0.2, direction="right")
    R = 2 * 0.2 * 5.0 / np.pi
    assert np.allclose(arc[-1], [R, R])                     # a quarter circle towards +z (right)
    assert np.allclose(np.linalg.norm(np.diff(arc, axis=0), axis=1).sum(), 1.0, rtol=1e-3)
    with pytest.raises(ValueError, match="direction"):
        quarter_circle([0, 0], 10, 0.1, 0.1, direction="up")


def test_objective_jacobian_matches_finite_differences_of_rollouts():
    """The residual Jacobian (COM tracking, slack eating with active cables, regularisers) equals
    central differences of whole rollouts."""
    robot = shipped("tripod")[0]
    env = make_gradient_env(robot)
    env.simulator.newton.options = NewtonOptions(tol=1e-12)
    p = GaitParameterization.for_robot(robot, GaitSpec(n_prep=6, n_cycle=16))
    x0, _ = env.reset_state()
    target = straight_line(robot.com(x0)[[0, 2]], p.n_steps(), env.timestep, 0.02)
    weights = ObjectiveWeights(slack=1.0, slack_eps=2e-4)
    prob = GaitProblem(env, p, target, weights)
    z = p.initial_z(0.5, np.random.default_rng(2), noise=0.45)
    r, J, terms = prob(z)
    assert terms["terms"]["slack"] > 0 and terms["terms"]["com"] > 0
    rng = np.random.default_rng(3)
    for _ in range(2):
        d = rng.normal(size=p.nz)
        d /= np.linalg.norm(d)
        h = 2e-8
        fd = (prob(z + h * d, False)[0] - prob(z - h * d, False)[0]) / (2 * h)
        assert np.linalg.norm(fd - J @ d) / np.linalg.norm(fd) < 1e-4


@pytest.fixture(scope="module")
def short_walk():
    robot = shipped("tripod")[0]
    env = make_gradient_env(robot)
    res = optimize_gait(env, "walk", gait=GaitSpec(n_prep=12, n_cycle=36), options=GaussNewtonOptions(max_iter=2),
                        n_seeds=2, eval_cycles=3, robot_spec="tripod")
    return env, res


def test_slack_eating_residual_is_eq_13():
    """0.5 |r|^2 = scale^2 sum Q(eps - Gamma) with Q(s) = max(s, 0)^2 / 2 (paper eq. 13), and its
    Jacobian is -scale dGamma/dz on the cables less than eps taut, zero on the others; checked
    against central differences of Gamma(z) = Gamma0 + G z (exact for a linear map)."""
    from trajopt.optim.objectives import slack_eating_residual
    rng = np.random.default_rng(3)
    eps, scale = 5e-5, 7.0
    gamma = rng.uniform(-2e-4, 2e-4, size=(6, 4))
    G = rng.normal(size=(6, 4, 3)) * 1e-3
    r, J = slack_eating_residual(gamma, G, eps, scale)
    Q = 0.5 * np.maximum(eps - gamma, 0.0) ** 2
    assert np.isclose(0.5 * r @ r, scale ** 2 * Q.sum(), rtol=1e-14)
    assert (r >= 0).all() and (r[(gamma >= eps).ravel()] == 0).all() and (r > 0).any()
    d, h = rng.normal(size=3), 1e-9
    plus = slack_eating_residual(gamma + h * (G @ d), None, eps, scale)[0]
    minus = slack_eating_residual(gamma - h * (G @ d), None, eps, scale)[0]
    assert np.linalg.norm((plus - minus) / (2 * h) - J @ d) <= 1e-6 * np.linalg.norm(J @ d)
    assert slack_eating_residual(gamma, None, eps, scale)[1] is None


def test_short_optimisation_lowers_objective_and_walks_forward(short_walk):
    hooks, res = short_walk
    hist = res.history
    assert hist and hist[-1]["objective_after"] <= hist[0]["objective"]
    ev = res.evaluation
    assert ev["speed_bl_per_min"] > 0.5 and ev["upright"]
    assert res.u.shape == (12 + 2 * 36, 2) and res.com.shape == (85, 3)
    assert (res.u_post >= res.u - 1e-15).all()              # post-processing only reels in slack


def test_zero_slack_post_processing():
    u = np.zeros((3, 2))
    gamma = np.array([[0, 0, 0, 0], [-0.002, -0.001, 0.001, -0.003], [0.0, 0.0, -0.001, -0.001],
                      [-0.004, -0.004, 0.0, 0.0]], float)
    tm = np.array([0, 0, 1, 1])
    out = zero_slack_controls(u, gamma, tm, np.array([[0, 0.003], [0, 0.003]]))
    assert np.allclose(out, [[0.001, 0.0], [0.0, 0.001], [0.003, 0.0]])   # min slack of the pair, clipped


def test_result_round_trip_and_bad_files(short_walk, tmp_path):
    _, res = short_walk
    path = res.save(tmp_path / "walk")
    assert path.suffix == ".npz" and path.with_suffix(".json").is_file()
    back = Result.load(path)
    for key in ("z", "u", "u_post", "target", "com"):
        assert np.array_equal(getattr(back, key), getattr(res, key))
    assert back.settings == json.loads(json.dumps(res.settings))
    assert back.evaluation["speed_bl_per_min"] == res.evaluation["speed_bl_per_min"]
    assert not list(tmp_path.glob("*.tmp"))
    with pytest.raises(ValueError, match="not found"):
        Result.load(tmp_path / "nope.npz")
    (tmp_path / "junk.npz").write_bytes(b"junk")
    with pytest.raises(ValueError, match=r"junk\.npz.*not a readable"):
        Result.load(tmp_path / "junk.npz")
    import io
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files if k not in ("u_post", "content_sha256")}  # edited files
    old_meta = {k: v for k, v in json.loads(str(arrays["meta"])).items() if k != "robot_fingerprint"}
    arrays["meta"] = np.array(json.dumps({**old_meta, "format_version": 1}))      # as version 1 wrote, before hashes
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    (tmp_path / "missing.npz").write_bytes(buf.getvalue())
    with pytest.raises(ValueError, match=r"missing\.npz: field 'u_post' is missing"):
        Result.load(tmp_path / "missing.npz")
    arrays["u_post"] = np.full_like(res.u, np.nan)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    (tmp_path / "nan.npz").write_bytes(buf.getvalue())
    with pytest.raises(ValueError, match=r"field 'u_post' contains NaN"):
        Result.load(tmp_path / "nan.npz")


def test_resume_continues_from_saved_iterate(tmp_path):
    """An optimisation stopped after one iteration (as by Ctrl-C, which saves first) and resumed
    ends where an uninterrupted run ends."""
    robot = shipped("tripod")[0]
    env = make_gradient_env(robot)
    kw = dict(gait=GaitSpec(n_prep=4, n_cycle=12), n_seeds=1, eval_cycles=1, robot_spec="tripod")
    full = optimize_gait(env, "walk", options=GaussNewtonOptions(max_iter=3, ftol=0), **kw)
    saved = {}

    def stop_after_first(entry, partial):
        partial.save(tmp_path / "ckpt")
        saved["n"] = entry["iteration"]
        return True
    optimize_gait(env, "walk", options=GaussNewtonOptions(max_iter=3, ftol=0), callback=stop_after_first, **kw)
    part = Result.load(tmp_path / "ckpt.npz")
    assert saved["n"] == 1 and len(part.history) == 1 and part.status == "running"
    resumed = optimize_gait(env, "walk", options=GaussNewtonOptions(max_iter=2, ftol=0), resume=part, **kw)
    assert [h["iteration"] for h in resumed.history] == [h["iteration"] for h in full.history]
    assert np.allclose(resumed.z, full.z, atol=1e-10)


def test_as_gradient_env_rejects_objects_without_hooks():
    with pytest.raises(TypeError, match="gradient hook"):
        as_gradient_env(object())


def test_results_reject_malformed_metadata(short_walk, tmp_path):
    import io
    _, res = short_walk
    path = res.save(tmp_path / "ok")
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files if k != "content_sha256"}   # as an older version wrote
    meta = {k: v for k, v in json.loads(str(arrays["meta"])).items() if k != "robot_fingerprint"}
    meta["format_version"] = 1                                      # version 1, before hashes and fingerprints
    cases = {"dt": None, "settings": [], "format_version": "1"}
    for key, bad in cases.items():
        m = dict(meta)
        m[key] = bad
        buf = io.BytesIO()
        np.savez(buf, **{**arrays, "meta": np.array(json.dumps(m))})
        p = tmp_path / f"bad_{key}.npz"
        p.write_bytes(buf.getvalue())
        with pytest.raises(ValueError, match=rf"bad_{key}\.npz: metadata field '{key}' has the wrong type"):
            Result.load(p)
    m = dict(meta)
    m["settings"] = {**meta["settings"], "keyframes": [[0.0]]}
    buf = io.BytesIO()
    np.savez(buf, **{**arrays, "meta": np.array(json.dumps(m))})
    (tmp_path / "kf.npz").write_bytes(buf.getvalue())
    with pytest.raises(ValueError, match=r"settings field 'keyframes' must have shape"):
        Result.load(tmp_path / "kf.npz")


def test_nan_is_written_as_null_and_resume_checks_settings(short_walk, tmp_path):
    env, res = short_walk
    res.evaluation = {**res.evaluation, "speed_bl_per_min": float("nan")}
    path = res.save(tmp_path / "nan")
    assert json.loads(path.with_suffix(".json").read_text())["evaluation"]["speed_bl_per_min"] is None
    with pytest.raises(ValueError, match="cannot resume"):
        optimize_gait(env, "walk", gait=GaitSpec(n_prep=12, n_cycle=24), resume=res, robot_spec="tripod")
    with pytest.raises(ValueError, match="eval_cycles"):
        optimize_gait(env, "walk", eval_cycles=0)


def test_the_newton_tolerance_is_recorded_and_checked_on_resume(short_walk, tmp_path):
    """A result says which Newton tolerance solved its physics steps (``settings["newton_tol"]``);
    resuming it at another tolerance is refused naming the field, a result made before the field
    existed resumes at today's; a search checkpoint's identity carries it too."""
    from dataclasses import replace

    from trajopt.search.checkpoint import search_identity
    from trajopt.search.settings import SearchSettings
    env, res = short_walk
    assert res.settings["newton_tol"] == env.simulator.newton.options.tol == 1e-6       # sub-stepped: 1e-6 m
    one = make_gradient_env("tripod", substeps=1)
    assert search_identity(one, SearchSettings(), None, 0.0)["newton_tol"] == NewtonOptions().tol == 1e-8
    tight = make_gradient_env(shipped("tripod")[0])
    tight.simulator.newton.options = replace(tight.simulator.newton.options, tol=1e-7)
    kw = dict(gait=GaitSpec(n_prep=12, n_cycle=36), options=GaussNewtonOptions(max_iter=0), robot_spec="tripod",
              eval_cycles=1)
    with pytest.raises(ValueError, match=r"cannot resume: .*'newton_tol': \(1e-06, 1e-07\)"):
        optimize_gait(tight, "walk", resume=res, **kw)
    older = Result.load(res.save(tmp_path / "older"))
    del older.settings["newton_tol"]
    assert optimize_gait(tight, "walk", resume=older, **kw).settings["newton_tol"] == 1e-7


def test_incline_is_recorded_from_the_environment():
    env = make_gradient_env("tripod", incline_deg=15.0)
    assert env.incline_deg == 15.0 and env.simulator.gravity[0] < 0 and env.gravity[0] < 0


def test_symmetric_keyframes_respect_both_mirror_ranges():
    bounds = np.array([[0.0, 0.01], [0.0, 0.006]])
    p = GaitParameterization(bounds, np.array([1, 0]), np.zeros(2), GaitSpec(n_prep=4, n_cycle=8))
    lo, hi = p.bounds()
    assert np.allclose(hi, 0.006) and np.allclose(lo, 0.0)
    u = p.controls(hi)
    assert u.max() <= 0.006 + 1e-15
    assert all(np.all(z <= hi + 1e-15) for z in p.seeds(3))


def test_prep_eases_from_the_rest_contraction_when_u_min_is_positive():
    """A motor whose range excludes 0 (pre-tensioned cable) starts its prep at u_min, not at 0:
    every control of every step stays in range, and the controls stay affine with the same
    exact dudz (the offset is the z-independent part)."""
    bounds = np.array([[0.004, 0.012], [0.004, 0.012], [-0.002, 0.01]])
    u_rest = np.array([0.004, 0.004, 0.0])            # robot.u_rest: 0 clipped into each range
    p = GaitParameterization(bounds, np.array([1, 0, 2]), u_rest, GaitSpec(n_prep=6, n_cycle=8))
    lo, hi = p.bounds()
    rng = np.random.default_rng(3)
    for z in [lo, hi, *p.seeds(4, rng), lo + rng.uniform(size=p.nz) * (hi - lo)]:
        u = p.controls(z)
        assert (u >= bounds[:, 0] - 1e-15).all() and (u <= bounds[:, 1] + 1e-15).all()
        assert np.allclose(u, p.offset() + p.dudz() @ z, atol=1e-15)
    u = p.controls(hi)
    ease0 = float(1 - (1 / 6) ** 2 * (3 - 2 / 6))           # weight of u_rest at prep step 0
    assert np.allclose(u[0, :2], ease0 * 0.004 + (1 - ease0) * 0.012)
    assert np.allclose(p.offset()[p.n_prep:], 0.0) and np.allclose(p.offset()[:, 2], 0.0)


def test_gradient_env_starts_at_the_rest_contraction():
    """A bare gradient environment starts where the Gymnasium environments do: at rest with
    u = robot.u_rest (0 clipped into each motor's range), and the gait's prep phase eases from
    there."""
    import dataclasses

    from soft_envs.envs import SoftRobotEnv
    from soft_envs.sim import load_robot

    robot = load_robot("tripod")
    motors = tuple(dataclasses.replace(m, u_min=0.002) for m in robot.motors)
    robot = dataclasses.replace(robot, motors=motors)
    assert np.allclose(robot.u_rest, 0.002)
    assert np.allclose(GaitParameterization.for_robot(robot).u_rest, 0.002)
    env = make_gradient_env(robot)
    x0, _ = env.reset_state()
    assert np.allclose(x0, env.simulator.rest_positions(robot.u_rest))
    assert not np.allclose(x0, env.simulator.rest_positions())
    gym_env = SoftRobotEnv(env.robot, reset_noise_scale=0.0)
    gym_env.reset(seed=0)
    assert np.allclose(gym_env.get_state()["x"], x0, atol=1e-12)
    traj = env.rollout(np.full((3, robot.n_motors), 0.002))
    assert np.allclose(traj.cable_deformation[0], env.cable_deformation())


def test_gauss_newton_resume_keeps_the_rejection_count():
    """A run interrupted inside a streak of rejected steps resumes that streak: with
    max_rejections = 3 and 2 rejections already made, one more rejection stops it."""
    from soft_envs.sim import SimulationError
    from trajopt.optim.gauss_newton import gauss_newton

    def fun(z, need_jac):                  # minimum at z = 1, but nothing beyond 0.01 simulates
        if z[0] > 0.01:
            raise SimulationError("out of range")
        return np.array([z[0] - 1.0]), (np.ones((1, 1)) if need_jac else None), {}

    opts = GaussNewtonOptions(max_iter=10, max_rejections=3)
    fresh = gauss_newton(fun, np.zeros(1), np.array([-5.0]), np.array([5.0]), opts)
    assert fresh.status == "stalled" and len(fresh.history) == 3
    resumed = gauss_newton(fun, np.zeros(1), np.array([-5.0]), np.array([5.0]), opts,
                           first_iteration=3, rejections=2)
    assert resumed.status == "stalled" and [h["iteration"] for h in resumed.history] == [3]


def test_a_jacobian_rollout_asked_again_at_the_same_point_is_not_simulated_again():
    """The start is moved into the motors' line with rollouts with sensitivities, and
    Gauss-Newton's first evaluation is at the same point: the problem keeps the last one."""
    from trajopt.optim.optimize import build_problem
    from trajopt.optim.motor_limit import max_step_of_env

    def problem():
        env = make_gradient_env("tripod", contact="coulomb")
        return build_problem(env, "walk", GaitSpec(n_prep=4, n_cycle=8, n_cycles=1, n_keyframes=4), speed_bl_per_min=8.0,
                             heading_deg=0.0, turn="right", target=None, weights=ObjectiveWeights.for_task("walk"),
                             max_step=max_step_of_env(env), motor_model="torque-speed")
    p = problem()
    lo, hi = p.param.bounds()
    z = lo + 0.3 * (hi - lo)
    r, J, _ = p.evaluate(z, True)
    steps, rollouts = p.sim_steps, p.rollouts
    r2, J2, _ = p.evaluate(z.copy(), True)
    assert (p.sim_steps, p.rollouts) == (steps, rollouts)
    assert np.array_equal(r, r2) and np.array_equal(J, J2)
    p.evaluate(z, False, check=False)                      # a trial always simulates
    assert p.rollouts == rollouts + 1
    p.evaluate(lo + 0.31 * (hi - lo), True)                # another point: simulated
    assert p.rollouts == rollouts + 2
    fresh_r, fresh_J, _ = problem().evaluate(z, True)
    assert np.array_equal(fresh_r, r) and np.array_equal(fresh_J, J)
