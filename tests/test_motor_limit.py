"""The motors' speed limit in the robot (issue #27 item 3, #28 item 1): ``[[motors]] max_speed_rpm``
in robot.toml, one home in the code (:attr:`Robot.max_contraction_speed`), read by the
environments (``motor_speed_rpm`` stays an override) and by robustness."""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import soft_envs  # noqa: F401  (registers the environments)
from soft_envs.sim import load_robot
from soft_envs.sim.robot import DEFAULT_MAX_SPEED_RPM
from soft_envs.sim.fingerprint import robot_fingerprint
from soft_envs.sim.robot_file import asset_path

from .conftest import small_robot


def copy_robot(name: str, directory: Path, rpm_line: str | None = None) -> Path:
    """The shipped robot's files in ``directory``; ``rpm_line`` replaces every motor's
    ``max_speed_rpm`` line (``""``: removes it)."""
    src = asset_path(name)
    directory.mkdir(parents=True, exist_ok=True)
    for p in src.parent.glob(f"{name}.vtu"):
        shutil.copy(p, directory / p.name)
    text = src.read_text()
    if rpm_line is not None:
        text = "\n".join(rpm_line if line.startswith("max_speed_rpm") else line for line in text.splitlines())
    (directory / "robot.toml").write_text(text)
    return directory / "robot.toml"


def test_a_motors_contraction_speed_is_its_rpm_on_its_spool():
    """100 rpm on a 5 mm spool: 100 / 60 turns per second of 2 pi 5 mm = 52.36 mm/s, 1.728 mm per
    paper time step (0.033 s)."""
    robot = small_robot(motors=[dict(name="m0", tendons=["t0"], u_max=0.01, max_speed_rpm=100.0)])
    assert robot.motors[0].max_contraction_speed == pytest.approx(0.0523598776, rel=1e-9)
    assert robot.max_contraction_speed == pytest.approx([0.0523598776], rel=1e-9)
    assert robot.max_contraction_step(0.033) == pytest.approx([0.00172787596], rel=1e-9)
    slow = small_robot(motors=[dict(name="m0", tendons=["t0"], u_max=0.01, max_speed_rpm=30.0, spool_radius=0.01)])
    assert slow.max_contraction_speed == pytest.approx([30 / 60 * 2 * math.pi * 0.01], rel=1e-12)


@pytest.mark.parametrize("name", ["tripod", "puppy"])
def test_the_shipped_robots_declare_the_pololu_no_load_speed(name):
    robot = load_robot(name)
    assert DEFAULT_MAX_SPEED_RPM == 100.0
    assert [m.max_speed_rpm for m in robot.motors] == [100.0] * robot.n_motors
    assert asset_path(name).read_text().count("max_speed_rpm = 100.0") == robot.n_motors


def test_max_speed_rpm_is_read_and_defaults_to_100(tmp_path):
    assert [m.max_speed_rpm for m in load_robot(copy_robot("tripod", tmp_path / "a", "max_speed_rpm = 50"))
            .motors] == [50.0, 50.0]
    assert [m.max_speed_rpm for m in load_robot(copy_robot("tripod", tmp_path / "b", "")).motors] == [100.0, 100.0]


def test_writing_out_the_default_keeps_the_fingerprint(tmp_path):
    """Results made before the field existed still match the shipped robots: an absent
    ``max_speed_rpm`` and the default written out are the same robot; another value is not."""
    absent = robot_fingerprint(copy_robot("tripod", tmp_path / "a", ""))
    default = robot_fingerprint(copy_robot("tripod", tmp_path / "b", "max_speed_rpm = 100"))
    slower = robot_fingerprint(copy_robot("tripod", tmp_path / "c", "max_speed_rpm = 50"))
    assert absent["sha256"] == default["sha256"] != slower["sha256"]


@pytest.mark.parametrize("value, message", [
    ("0", r"motors\[0\] \('front'\)\.max_speed_rpm must be a finite positive number \[rpm\], got 0\.0"),
    ("-20.0", r"motors\[0\] \('front'\)\.max_speed_rpm must be a finite positive number \[rpm\], got -20\.0"),
    ("inf", r"motors\[0\]\.max_speed_rpm must be a finite number, got inf"),
    ("nan", r"motors\[0\]\.max_speed_rpm must be a finite number, got nan"),
    ('"fast"', r"motors\[0\]\.max_speed_rpm has the wrong type \(str\)"),
    ("true", r"motors\[0\]\.max_speed_rpm has the wrong type \(bool\)"),
])
def test_a_bad_max_speed_rpm_names_file_motor_and_field(tmp_path, value, message):
    path = copy_robot("tripod", tmp_path, f"max_speed_rpm = {value}")
    with pytest.raises(ValueError, match=message) as err:
        load_robot(path)
    assert str(err.value).startswith(str(path))


@pytest.mark.parametrize("rpm", [0.0, -1.0, float("nan"), float("inf")])
def test_a_bad_max_speed_rpm_is_refused_in_python_too(rpm):
    with pytest.raises(ValueError, match=r"motors\[0\] \('m0'\)\.max_speed_rpm must be a finite positive number"):
        small_robot(motors=[dict(name="m0", tendons=["t0"], u_max=0.01, max_speed_rpm=rpm)])


def _first_step_u(env) -> np.ndarray:
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.ones(env.action_space.shape))
    return info["u"]


def test_the_environment_follows_the_robots_motors_and_the_override(tmp_path):
    """A robot whose motors do 50 rpm moves half as far in a step from rest as the shipped one;
    ``motor_speed_rpm`` overrides it for every motor, None lifts the limit."""
    slow = copy_robot("tripod", tmp_path, "max_speed_rpm = 50")
    step = 100 * 2 * math.pi / 60 * 0.005 * 0.033          # [m] 100 rpm, 5 mm spool, one paper step
    kw = dict(reset_noise_scale=0.0)
    shipped = gym.make("SoftTripod-v1", **kw).unwrapped
    assert shipped.motor_speed == pytest.approx([step / 0.033] * 2, rel=1e-12)
    assert _first_step_u(shipped) == pytest.approx([step] * 2, rel=1e-12)
    env = gym.make("SoftTripod-v1", robot=str(slow), **kw).unwrapped
    assert env.motor_speed == pytest.approx([step / 0.033 / 2] * 2, rel=1e-12)
    assert _first_step_u(env) == pytest.approx([step / 2] * 2, rel=1e-12)
    override = gym.make("SoftTripod-v1", robot=str(slow), motor_speed_rpm=100, **kw).unwrapped
    assert _first_step_u(override) == pytest.approx([step] * 2, rel=1e-12)
    unlimited = gym.make("SoftTripod-v1", robot=str(slow), motor_speed_rpm=None, **kw).unwrapped
    assert _first_step_u(unlimited) == pytest.approx([0.02, 0.02], rel=1e-12)


@pytest.mark.parametrize("bad", ["fast", "Robot", 0, -5.0, float("inf"), True])
def test_a_bad_motor_speed_rpm_keyword_is_refused(bad):
    with pytest.raises(ValueError, match="motor_speed_rpm must be \"robot\""):
        gym.make("SoftTripod-v1", motor_speed_rpm=bad)


def test_robustness_scales_the_robots_own_motor_speed(tmp_path):
    """The ``motor_speed`` perturbation is a factor of each motor's limit: a 50 rpm robot's
    motors at factor 1 do 50 rpm."""
    from trajopt.robustness.study import applied_controls
    robot = load_robot(copy_robot("tripod", tmp_path, "max_speed_rpm = 50"))
    u = np.full((3, 2), 0.01)
    p = {"timing_jitter_s": 0.0, "motor_lag_s": 0.0, "motor_speed": 1.0}
    out = applied_controls(u, 0.033, robot.u_rest, robot.u_bounds, robot.max_contraction_speed, p,
                           np.random.default_rng(0))
    assert out[0] == pytest.approx(robot.max_contraction_step(0.033), rel=1e-12)
    assert out[0, 0] == pytest.approx(50 * 2 * math.pi / 60 * 0.005 * 0.033, rel=1e-12)


# ---------------------------------------------------------------------- optimised controls obey it (#28 item 2)
from trajopt import GaitSpec, optimize_gait  # noqa: E402
from trajopt.cli import main  # noqa: E402
from trajopt.optim.gauss_newton import GaussNewtonOptions, _constrained_direction, gauss_newton  # noqa: E402
from trajopt.optim.motor_limit import played_steps, speed_limit_constraints, worst_step  # noqa: E402
from trajopt.optim.parameterization import GaitParameterization  # noqa: E402
from trajopt.optim.qp import LinearConstraints  # noqa: E402
from trajopt.results.result import Result  # noqa: E402

STEP = 100 * 2 * math.pi / 60 * 0.005 * 0.033          # [m] the shipped motors' step limit
QUICK = GaitSpec(n_prep=6, n_cycle=24, n_cycles=2, n_keyframes=4)    # 6 steps per keyframe: the limit binds
SUM_AT_MOST_ONE = LinearConstraints(np.array([[1.0, 1.0]]), np.array([1.0]))


def _residual(a):
    return lambda z, need_jac=True: (z - a, np.eye(len(z)), {})


def test_the_constrained_step_is_the_kkt_point_of_the_damped_subproblem():
    """From z = 0 with r = z - (2, 2): the damped subproblem 0.5 c |dz|^2 + g.dz, c = 1 + 2 lambda
    (J'J = I: diagonal 1, mean 1), g = -(2, 2), under dz0 + dz1 <= 1. Unconstrained dz = (2/c, 2/c)
    breaks it; the KKT point is (0.5, 0.5) with multiplier 2 - c/2 > 0."""
    lam = 1e-3
    dz = _constrained_direction(np.eye(2), np.array([-2.0, -2.0]), np.zeros(2), lam, np.full(2, -10.0),
                                np.full(2, 10.0), SUM_AT_MOST_ONE)
    assert dz == pytest.approx([0.5, 0.5], abs=1e-7)      # the QP's rows are tightened by a relative 1e-9
    assert SUM_AT_MOST_ONE.feasible(dz)
    c = 1 + 2 * lam
    assert 2 - c * 0.5 > 0          # the multiplier of the active constraint (-g - c dz = mu (1, 1))


def test_a_badly_scaled_qp_is_solved_in_jacobi_variables():
    """Variables of very different units (co-design: keyframes in metres, a modulus in pascals,
    whose damped Hessian entry is 1e12 times the others'): min 0.5 x'Px + q'x with P = diag(1, 2,
    3, 5e12), q = -(1, 1, 1, 0), under x0 + x1 + x2 <= 1 and |x3| <= 1. The KKT point is x_i =
    (1 / d_i) / (11/6) for the first three. Scaled by the bounds' ranges alone, the solver's
    tolerances, relative to the largest entry, lost the small ones: it answered "optimal" at
    (0.086, 0.043, 0.029), 0.46 off."""
    from trajopt.optim.qp import MAX_DIAGONAL_SPREAD, solve_qp
    P = np.diag([1.0, 2.0, 3.0, 5e12])
    assert 5e12 / 3.0 > MAX_DIAGONAL_SPREAD
    G = np.array([[1.0, 1.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, -1.0]])
    x = solve_qp(P, np.array([-1.0, -1.0, -1.0, 0.0]), LinearConstraints(G, np.ones(3)), scale=np.full(4, 2.0))
    assert x[:3] == pytest.approx(np.array([1.0, 1 / 2, 1 / 3]) * 6 / 11, abs=1e-8)
    assert abs(x[3]) <= 1e-12 and LinearConstraints(G, np.ones(3)).feasible(x)


@pytest.mark.parametrize("a, upper, expected", [
    ((2.0, 2.0), (10.0, 10.0), (0.5, 0.5)),      # the limit active: the projection of a onto z0 + z1 = 1
    ((2.0, 0.2), (0.7, 10.0), (0.7, 0.2)),       # a bound active, the limit not
    ((3.0, -1.0), (10.0, 10.0), (2.5, -1.5)),    # the limit active off the diagonal
])
def test_constrained_gauss_newton_converges_to_the_constrained_minimiser(a, upper, expected):
    """min 0.5 |z - a|^2 subject to z0 + z1 <= 1 and the bounds: the minimiser is known (KKT), and
    every iterate is feasible."""
    seen = []
    res = gauss_newton(_residual(np.array(a)), np.zeros(2), np.full(2, -10.0), np.array(upper),
                       GaussNewtonOptions(max_iter=30, ftol=0.0, xtol=0.0), constraints=SUM_AT_MOST_ONE,
                       callback=lambda e: seen.append(e["z"]))
    assert res.z == pytest.approx(expected, abs=1e-7)
    assert all(SUM_AT_MOST_ONE.feasible(z) and (z <= np.array(upper)).all() for z in seen)


def test_a_limit_that_does_not_bind_leaves_gauss_newton_bit_for_bit():
    kw = dict(lower=np.full(2, -10.0), upper=np.full(2, 10.0), options=GaussNewtonOptions(max_iter=5))
    free = gauss_newton(_residual(np.array([0.3, 0.2])), np.zeros(2), **kw)
    held = gauss_newton(_residual(np.array([0.3, 0.2])), np.zeros(2), constraints=SUM_AT_MOST_ONE, **kw)
    assert np.array_equal(free.z, held.z) and free.objective == held.objective
    assert not any(e["qp_step"] for e in held.history)


def test_an_infeasible_start_is_refused_by_gauss_newton():
    with pytest.raises(ValueError, match="the start breaks the constraints"):
        gauss_newton(_residual(np.zeros(2)), np.array([0.8, 0.8]), np.full(2, -10.0), np.full(2, 10.0),
                     constraints=SUM_AT_MOST_ONE)


@pytest.mark.parametrize("robot, gait", [
    ("tripod", QUICK), ("puppy", QUICK), ("puppy", QUICK.replace(symmetry=False, n_keyframes=8)),
    ("puppy", QUICK.replace(n_prep=0)), ("tripod", QUICK.replace(n_cycles=1)),
])
def test_the_inequalities_are_the_played_steps(robot, gait):
    """G z - h, maximised over each step's two rows, is |change| - max_step of every step of the
    controls as played for many cycles (rest -> u[0], prep, cycles, wrap-around), for random z."""
    param = GaitParameterization.for_robot(load_robot(robot), gait)
    max_step = np.linspace(1.0, 2.0, param.n_motors) * 1e-3
    c = speed_limit_constraints(param, max_step)
    lo, hi = param.bounds()
    for seed in range(5):
        z = np.random.default_rng(seed).uniform(lo, hi)
        excess = worst_step(param.controls(z, 7), param.u_rest, gait.n_prep, gait.n_cycle, max_step)[0]
        assert c.violation(z) == pytest.approx(excess, abs=1e-15)


@pytest.mark.parametrize("robot", ["tripod", "puppy"])
def test_the_papers_gait_cannot_break_the_limit(robot):
    """72-step cycles of 4 keyframes and a 24-step prep: no keyframes in the motor ranges break
    the limit (the largest G z over the box is below h), so the paper's Table I gaits are the
    same with the limit on, bit for bit."""
    param = GaitParameterization.for_robot(load_robot(robot), GaitSpec())
    c = speed_limit_constraints(param, load_robot(robot).max_contraction_step(0.033))
    lo, hi = param.bounds()
    worst = np.maximum(c.G * lo, c.G * hi).sum(axis=1) - c.h
    assert worst.max() < -1e-5


def _obeys_over_ten_cycles(res: Result, u_rest: np.ndarray, max_step: float = STEP) -> float:
    gait = GaitSpec.from_settings(res.settings)
    param = GaitParameterization(np.array([[0.0, 1.0]] * len(u_rest)), np.arange(len(u_rest)), u_rest,
                                 gait.replace(symmetry=False))
    kf = np.asarray(res.settings["keyframes"])
    u = param.controls(param.z_from_keyframes(kf), 10)
    assert np.allclose(u[:len(res.u)], res.u, atol=1e-12, rtol=0)
    return float(np.abs(played_steps(u, u_rest, gait.n_prep, gait.n_cycle)).max() - max_step)


@pytest.mark.parametrize("task, contact", [("walk", "paper"), ("walk", "coulomb"), ("turn", None),
                                           ("incline", None)])
def test_every_optimised_result_obeys_the_limit_at_every_step(task, contact, tmp_path):
    """Quick optimisations (24-step cycles of 4 keyframes: the unconstrained optimum breaks the
    limit) of every task, both laws: ``u`` repeated for 10 cycles never moves a cable more than
    v_max h in a step, from rest and across the wrap-around (1e-9 m); the limit is recorded and
    the result saves and loads (its checks re-measure it)."""
    env = soft_envs.envs.make_gradient_env("tripod", contact=contact, incline_deg=10.0 if task == "incline" else 0.0)
    gait = QUICK.replace(n_keyframes=8) if task == "turn" else QUICK
    res = optimize_gait(env, task, gait=gait, speed_bl_per_min=20.0, options=GaussNewtonOptions(max_iter=2),
                        n_seeds=1, eval_cycles=1)
    assert res.settings["motor_limit"]["max_step_m"] == pytest.approx([STEP, STEP], rel=1e-12)
    assert res.settings["motor_limit"]["max_speed_rpm"] == pytest.approx([100.0, 100.0], rel=1e-12)
    assert _obeys_over_ten_cycles(res, env.robot.u_rest) <= 1e-9
    assert any(e["qp_step"] for e in res.history), "the limit never bound: the test would not test it"
    assert Result.load(res.save(tmp_path / "r")).settings["motor_limit"] == res.settings["motor_limit"]


def test_without_the_limit_the_quick_gait_breaks_it_and_records_none():
    res = optimize_gait("tripod", "walk", gait=QUICK, speed_bl_per_min=20.0, options=GaussNewtonOptions(max_iter=2),
                        n_seeds=1, eval_cycles=1, motor_limit=False)
    assert res.settings["motor_limit"] is None and "qp_step" not in res.history[0]
    assert _obeys_over_ten_cycles(res, np.zeros(2)) > 1e-4


def test_a_slower_robot_gets_a_slower_limit(tmp_path):
    toml = copy_robot("tripod", tmp_path, "max_speed_rpm = 50")
    res = optimize_gait(str(toml), "walk", gait=QUICK, speed_bl_per_min=20.0,
                        options=GaussNewtonOptions(max_iter=1), n_seeds=1, eval_cycles=1)
    assert res.settings["motor_limit"]["max_speed_rpm"] == pytest.approx([50.0, 50.0])
    assert _obeys_over_ten_cycles(res, np.zeros(2), STEP / 2) <= 1e-9


@pytest.fixture(scope="module")
def unlimited_result(tmp_path_factory) -> Path:
    """A quick gait made without the limit (it breaks it), saved."""
    out = tmp_path_factory.mktemp("unlimited")
    assert main(["optimize", "tripod", "--prep-steps", "6", "--cycle-steps", "24", "--iterations", "2", "--seeds", "1",
                 "--cycles", "1", "--speed", "20", "--quiet", "--no-motor-limit", "--out", str(out),
                 "--name", "fast"]) == 0
    return out / "fast.npz"


def test_an_infeasible_warm_start_is_projected_and_reported(unlimited_result, tmp_path, capsys):
    old = Result.load(unlimited_result)
    excess = worst_step(old.u, np.zeros(2), 6, 24, np.full(2, STEP))[0]
    assert old.settings["motor_limit"] is None and excess > 1e-4
    capsys.readouterr()
    assert main(["optimize", "tripod", "--prep-steps", "6", "--cycle-steps", "24", "--iterations", "1", "--seeds", "0",
                 "--cycles", "1", "--speed", "20", "--quiet", "--warm-start", str(unlimited_result),
                 "--out", str(tmp_path), "--name", "warm"]) == 0
    out = capsys.readouterr().out
    assert f"{unlimited_result}: breaks the motors' speed limit (1.728 mm per step) by up to " \
           f"{1e3 * excess:.3f} mm in a step; projected onto it: keyframes moved by up to" in out
    res = Result.load(tmp_path / "warm.npz")
    report = res.settings["start_projection"]
    assert report["violation_before_m"] == pytest.approx(excess, rel=1e-12) and report["moved_max_m"] > 0
    assert _obeys_over_ten_cycles(res, np.zeros(2)) <= 1e-9


def test_a_result_that_breaks_the_limit_it_records_is_refused(unlimited_result, tmp_path):
    res = Result.load(unlimited_result)
    res.settings["motor_limit"] = {"max_step_m": [STEP, STEP]}
    with pytest.raises(ValueError, match=r"field 'u' moves motor '(front|back)' by .* beyond the limit it was made "
                                         r"under \(1\.7279 mm, settings 'motor_limit'\)"):
        res.save(tmp_path / "edited")


@pytest.mark.parametrize("robot, args", [
    ("tripod", ["--prep-steps", "24", "--cycle-steps", "36", "--keyframes", "2"]),
    ("tripod", ["--prep-steps", "6", "--cycle-steps", "24"]), ("tripod", ["--prep-steps", "4", "--cycle-steps", "12"]),
    ("puppy", ["--prep-steps", "6", "--cycle-steps", "24"])])
def test_play_dry_run_accepts_what_optimize_writes(tmp_path, capsys, robot, args):
    """``trajopt play --dry-run`` of a result ``optimize`` wrote (under the limit) with the
    shipped robot's example hardware file: accepted (its max_speed is the robot's 100 rpm, its
    max_accel a full-speed reversal within a step), and each motor's largest step reported
    against the robot's limit."""
    from trajopt.hardware import EXAMPLE_PUPPY, EXAMPLE_TRIPOD
    assert main(["optimize", robot, *args, "--seeds", "1", "--cycles", "1", "--iterations", "2", "--speed", "20",
                 "--quiet", "--out", str(tmp_path), "--name", "gait"]) == 0
    capsys.readouterr()
    hw = EXAMPLE_TRIPOD if robot == "tripod" else EXAMPLE_PUPPY
    code = main(["play", str(tmp_path / "gait.npz"), "--hardware", str(hw), "--dry-run"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "largest step of each motor against its robot's limit (robot.toml max_speed_rpm 100 rpm: 1.728 mm" in err
    assert "warning" not in err


def test_an_environment_without_a_limit_gives_no_inequalities():
    """``motor_speed_rpm=None`` (no limit): the optimiser's limit is the environment's, so none."""
    from trajopt.optim.motor_limit import max_step_of_env
    env = gym.make("SoftTripod-v1", motor_speed_rpm=None).unwrapped
    max_step = max_step_of_env(env)
    assert np.isinf(max_step).all()
    c = speed_limit_constraints(GaitParameterization.for_robot(env.robot, QUICK), max_step)
    assert c.G.shape == (0, 8) and c.feasible(np.zeros(8))
    assert max_step_of_env(gym.make("SoftTripod-v1", motor_speed_rpm=50).unwrapped) == pytest.approx([STEP / 2] * 2)
