"""The motors' torque-speed line (issue #38): the law (:mod:`soft_envs.sim.motors`), the robot
file's ``stall_torque`` / ``max_torque``, the fingerprint, and the environments' ``motor_model``."""
from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import soft_envs  # noqa: F401  (registers the environments)
from soft_envs.envs import SoftRobotEnv
from soft_envs.sim import load_robot
from soft_envs.sim.fingerprint import robot_fingerprint
from soft_envs.sim.motors import (MOTOR_MODELS, MotorLaw, line_excess, load_torque, motor_step, tendon_tensions,
                                  winding_speed)
from soft_envs.sim.robot import DEFAULT_MAX_TORQUE, DEFAULT_STALL_TORQUE
from trajopt.results.robot_match import describe_difference

from .conftest import small_robot
from .test_motor_limit import copy_robot

V0 = 100 * 2 * math.pi / 60 * 0.005          # [m/s] the shipped motors' no-load contraction speed
H = 0.033


def _with_motor_line(name: str, directory, line: str):
    """The shipped robot's files in ``directory`` with ``line`` added after every motor's
    ``max_speed_rpm``."""
    path = copy_robot(name, directory)
    text = path.read_text().splitlines()
    out = []
    for row in text:
        if row.startswith(line.split("=")[0].strip() + " ") or row.startswith(line.split("=")[0].strip() + "="):
            continue               # replace the key where the file already writes it
        out.append(row)
        if row.startswith("max_speed_rpm"):
            out.append(line)
    path.write_text("\n".join(out) + "\n")
    return path


# ---------------------------------------------------------------------- the robot file
def test_the_defaults_are_the_298_to_1_hp_motor_at_6_volts():
    assert (DEFAULT_STALL_TORQUE, DEFAULT_MAX_TORQUE) == (0.39, 0.196)
    for name in ("tripod", "puppy"):
        robot = load_robot(name)
        assert list(robot.stall_torques) == [0.39] * robot.n_motors
        assert list(robot.max_torques) == [0.196] * robot.n_motors


def test_the_design_checker_knows_the_defaults():
    from soft_envs.envs import MOTOR_DEFAULTS
    from trajopt.codesign.checks import _MOTOR_DEFAULTS
    assert {k: _MOTOR_DEFAULTS[k] for k in MOTOR_DEFAULTS} == MOTOR_DEFAULTS


def test_a_file_without_the_keys_gets_the_defaults_and_values_are_read(tmp_path):
    bare = copy_robot("tripod", tmp_path / "bare")
    bare.write_text("\n".join(r for r in bare.read_text().splitlines()
                              if not r.startswith(("stall_torque", "max_torque"))) + "\n")
    robot = load_robot(bare)
    assert list(robot.stall_torques) == [0.39, 0.39] and list(robot.max_torques) == [0.196, 0.196]
    weak = load_robot(_with_motor_line("tripod", tmp_path / "weak", "stall_torque = 0.235"))
    assert list(weak.stall_torques) == [0.235, 0.235]
    assert list(load_robot(_with_motor_line("tripod", tmp_path / "m", "max_torque = 1")).max_torques) == [1.0, 1.0]


@pytest.mark.parametrize("key", ["stall_torque", "max_torque"])
@pytest.mark.parametrize("value, message", [
    ("0", r"motors\[0\] \('front'\)\.{key} must be a finite positive number \[N m\], got 0\.0"),
    ("-0.2", r"motors\[0\] \('front'\)\.{key} must be a finite positive number \[N m\], got -0\.2"),
    ("nan", r"motors\[0\]\.{key} must be a finite number, got nan"),
    ("inf", r"motors\[0\]\.{key} must be a finite number, got inf"),
    ('"strong"', r"motors\[0\]\.{key} has the wrong type \(str\)"),
    ("true", r"motors\[0\]\.{key} has the wrong type \(bool\)"),
])
def test_a_bad_torque_names_the_file_the_motor_and_the_key(tmp_path, key, value, message):
    path = _with_motor_line("tripod", tmp_path, f"{key} = {value}")
    with pytest.raises(ValueError, match=message.format(key=key)) as err:
        load_robot(path)
    assert str(err.value).startswith(str(path))


@pytest.mark.parametrize("key", ["stall_torque", "max_torque"])
@pytest.mark.parametrize("value", [0.0, -1.0, float("nan"), float("inf"), "0.3", True])
def test_a_bad_torque_is_refused_in_python_too(key, value):
    with pytest.raises(ValueError, match=rf"motors\[0\] \('m0'\)\.{key} must be a finite positive number \[N m\]"):
        small_robot(motors=[dict(name="m0", tendons=["t0"], u_max=0.01, **{key: value})])


def test_the_fingerprint_holds_the_torques_unless_written_at_their_defaults(tmp_path):
    """Results made before the keys existed still match the shipped robots (absent = the default
    written out), and another motor is another robot, named by the mismatch."""
    shipped = robot_fingerprint("tripod")
    bare = copy_robot("tripod", tmp_path / "bare")
    bare.write_text("\n".join(r for r in bare.read_text().splitlines()
                              if not r.startswith(("stall_torque", "max_torque"))) + "\n")
    assert robot_fingerprint(bare)["sha256"] == shipped["sha256"]
    weak = robot_fingerprint(_with_motor_line("tripod", tmp_path / "weak", "stall_torque = 0.235"))
    assert weak["sha256"] != shipped["sha256"]
    assert "stall_torque" in describe_difference(shipped, weak)
    assert weak["toml"]["motors"][0]["stall_torque"] == 0.235
    strong = robot_fingerprint(_with_motor_line("tripod", tmp_path / "strong", "max_torque = 0.3"))
    assert strong["sha256"] not in (shipped["sha256"], weak["sha256"])


# ---------------------------------------------------------------------- the law
def test_the_load_torque_is_the_spool_radius_times_the_tensions():
    tension = np.array([[1.0, 2.0, 4.0, 8.0]])          # tendons of motors 1, 1, 0 and a passive one
    tau = load_torque(tension, np.array([1, 1, 0, -1]), np.array([0.005, 0.01]))
    assert tau[0] == pytest.approx([0.02, 0.03], rel=1e-15)


def test_the_line_and_its_excess():
    tau = np.array([0.0, 0.195, 0.39, 0.5])
    assert winding_speed(tau, V0, 0.39) == pytest.approx([V0, V0 / 2, 0.0, 0.0], rel=1e-15)
    assert winding_speed(tau, np.inf, 0.39)[2:] == pytest.approx([0.0, 0.0])    # stalled also unlimited
    assert line_excess(V0 / 2, 0.195, V0, 0.39) == pytest.approx(0.0, abs=1e-15)
    assert line_excess(V0, 0.039, V0, 0.39) == pytest.approx(0.1, rel=1e-12)


def test_a_step_winds_on_the_line_unwinds_at_the_speed_limit_and_stops_at_max_torque():
    u, cmd = np.zeros(4), np.array([1.0, -1.0, 1.0, 1e-4])
    tau = np.array([0.195, 0.195, 0.2, 0.195])
    step = V0 * H
    nxt, limited = motor_step(u, cmd, tau, step, 0.39, 0.196)
    assert nxt == pytest.approx([step / 2, -step, 0.0, 1e-4], rel=1e-12)
    assert list(limited) == [True, True, True, False]
    speed, held = motor_step(u, cmd, tau, step, 0.39, 0.196, "speed")
    assert speed == pytest.approx([step, -step, step, 1e-4], rel=1e-15) and list(held) == [True, True, True, False]
    ideal, held = motor_step(u, cmd, tau, step, 0.39, 0.196, "ideal")
    assert np.array_equal(ideal, cmd) and not held.any()


def test_tensions_are_the_cables_law():
    s, d = tendon_tensions(np.array([-1e-3, 1e-4, 1e-3]), np.array([1e5, 1e5, 1e5]), 2e-4)
    assert s == pytest.approx([0.0, 0.5 * 1e5 * 1e-8 / 2e-4, 1e5 * (1e-3 - 1e-4)], rel=1e-14)
    assert d == pytest.approx([0.0, 1e5 * 1e-4 / 2e-4, 1e5], rel=1e-14)


# ---------------------------------------------------------------------- one motor pulling a known spring
def _spring_robot(stiffness: float, max_torque: float = 10.0):
    """A bar held still but for one node away from its cable: the cable's length is constant, so
    its tension is the linear spring ``k (u + L - alpha0 - blend / 2)`` beyond the C2 blend, and
    the motor's load torque is ``r k (u - blend / 2)`` (the cable just taut at rest)."""
    p = small_robot().mesh.points
    free = np.flatnonzero((p[:, 1] < 1e-9) & (np.abs(p[:, 0] - 0.02) < 1e-9))[:1]
    return small_robot(fixed_nodes=np.setdiff1d(np.arange(len(p)), free),
                       tendons=[dict(name="t0", points=[[0.055, 0.015, 0.01], [0.005, 0.015, 0.01]],
                                     stiffness=stiffness)],
                       motors=[dict(name="m0", tendons=["t0"], u_max=0.05, max_torque=max_torque)])


def test_a_motor_winding_against_a_spring_follows_the_closed_form():
    """k = 2000 N/m on a 5 mm spool: the torque rises 10 N m per metre of cable; winding at the
    line, ``u_{k+1} = u_k + h v0 (1 - tau(u_k) / stall)`` with ``tau = r k (u - eps/2)``: the
    distance to the stall point ``u_s = stall / (r k) + eps / 2`` shrinks by ``1 - h / T`` a step,
    ``T = stall / (r k v0)``, the exponential ``exp(-t / T)`` of continuous time to O(h / T)."""
    k, r, stall, eps = 2000.0, 0.005, 0.39, 2e-4
    env = SoftRobotEnv(_spring_robot(k), reset_noise_scale=0.0)
    env.reset(seed=0)
    us, T = stall / (r * k) + eps / 2, stall / (r * k * V0)
    u, taus = [0.0], []
    for _ in range(30):
        _, _, _, _, info = env.step(np.ones(1))
        u.append(float(info["u"][0]))
        taus.append(float(info["motor_torque"][0]))
        assert info["motor_limited"][0]
    u = np.array(u)
    assert taus == pytest.approx(r * k * (u[1:] - eps / 2), rel=1e-9)           # the known spring
    v = np.diff(u) / H
    tau_before = np.r_[0.0, taus[:-1]]
    assert v == pytest.approx(V0 * (1 - tau_before / stall), rel=1e-12)       # on the line, every step
    j = np.arange(1, 31)                       # from step 1 on, the cable is past its blend
    assert us - u[1:] == pytest.approx((us - u[1]) * (1 - H / T) ** (j - 1), rel=1e-9)
    t = H * (j - 1)
    assert np.abs((us - u[1:]) / (us - u[1]) - np.exp(-t / T)).max() < 2 * H / T


def test_winding_stops_at_max_torque_and_unwinding_is_free_of_the_load():
    k, r = 2000.0, 0.005
    env = SoftRobotEnv(_spring_robot(k, max_torque=0.05), reset_noise_scale=0.0)
    env.reset(seed=0)
    for _ in range(20):
        _, _, _, _, info = env.step(np.ones(1))
    tau = float(info["motor_torque"][0])
    assert 0.05 <= tau < 0.05 + r * k * V0 * H           # one step beyond the limit at most, then held
    held = float(info["u"][0])
    _, _, _, _, info = env.step(np.ones(1))
    assert info["u"][0] == held and info["motor_limited"][0]
    _, _, _, _, info = env.step(-np.ones(1))
    assert info["u"][0] == pytest.approx(held - V0 * H, rel=1e-12)          # unwinding: the speed limit


# ---------------------------------------------------------------------- the environments
def test_v0_and_v1_keep_the_speed_law_and_the_class_defaults_to_the_line():
    for env_id in ("SoftTripod-v0", "SoftTripod-v1", "SoftPuppy-v0", "SoftPuppy-v1"):
        assert gym.make(env_id).unwrapped.motor_model == "speed"
    assert SoftRobotEnv("tripod").motor_model == "torque-speed"
    assert gym.make("SoftTripod-v1", motor_model="torque-speed").unwrapped.motor_model == "torque-speed"
    assert MOTOR_MODELS == ("torque-speed", "speed", "ideal")


@pytest.mark.parametrize("bad", ["torque", "Speed", None, 1])
def test_a_bad_motor_model_is_refused(bad):
    with pytest.raises(ValueError, match="motor_model must be one of 'torque-speed', 'speed', 'ideal'"):
        gym.make("SoftTripod-v1", motor_model=bad)


def test_the_environment_steps_with_the_torque_of_the_state_before():
    """Tripod, random actions: every step's applied contraction is the law's step from the
    previous one at the load torque the previous info reported."""
    env = gym.make("SoftTripod-v1", motor_model="torque-speed", reset_noise_scale=0.0).unwrapped
    _, info = env.reset(seed=0)
    law = MotorLaw.of_robot(env.robot)
    rng = np.random.default_rng(1)
    seen_limited = 0
    for _ in range(40):
        u0, tau0 = info["u"], info["motor_torque"]
        a = rng.uniform(-1, 1, 2)
        _, _, _, _, info = env.step(a)
        expected, limited = motor_step(u0, env.action_to_control(a), tau0, law.no_load_speed * H,
                                       law.stall_torque, law.max_torque)
        assert np.array_equal(info["u"], expected) and np.array_equal(info["motor_limited"], limited)
        seen_limited += int((limited & (env.action_to_control(a) > u0)).sum())
    assert seen_limited > 0
    assert info["motor_torque"] == pytest.approx(law.torque(env.cable_deformation()), rel=1e-12)
