"""Every perturbation reaches the physics (issue #30, class "a perturbation never shown to reach
the physics").

For each quantity that ``trajopt robustness`` perturbs, a replay with that quantity alone
perturbed is compared with the replay of the unperturbed values: the robot the replay simulates
has the parameter nominal x factor (both contact laws for friction), the motors' applied
controls or the slope are the perturbed ones, and the replayed trajectory differs. The same for
domain randomisation: the robot an environment resets to has every drawn factor applied.
"""
from __future__ import annotations

import numpy as np
import pytest

import trajopt.robustness.study as rb
from soft_envs.envs import load_robot, parameter_values, with_contact_law
from soft_envs.envs.domain import randomized_robot

#: the perturbation that changes nothing: factors 1, no lag, no speed limit, no jitter, no slope
IDENTITY = {"friction": 1.0, "youngs_modulus": 1.0, "density": 1.0, "payload_mass": 1.0, "contact_stiffness": 1.0,
            "cable_stiffness": 1.0, "motor_lag_s": 0.0, "motor_speed": 1e10, "timing_jitter_s": 0.0,
            "slope_deg": 0.0, "slope_direction_deg": 0.0}
#: one perturbed value per quantity (inside the documented ranges)
ONE = {"friction": 1.4, "youngs_modulus": 0.75, "density": 1.08, "payload_mass": 1.12, "contact_stiffness": 1.8,
       "cable_stiffness": 0.6, "motor_lag_s": 0.08, "motor_speed": 0.6, "timing_jitter_s": 0.01, "slope_deg": 8.0}
_REAL_MAKE_ENV = rb.make_gradient_env
FACTORS = ("friction", "youngs_modulus", "density", "payload_mass", "contact_stiffness", "cable_stiffness")


def _step_controls(robot) -> np.ndarray:
    """6 steps (prep 2, one cycle of 4): rest, then a step to mid-range on every motor."""
    u = np.tile(robot.u_rest, (6, 1))
    u[1:] = 0.5 * (robot.u_bounds[:, 0] + robot.u_bounds[:, 1])
    return u


def replay(monkeypatch, perturbation: dict, contact: str | None = None) -> dict:
    """run_sample of the step controls, recording the robot, slope and controls it simulated."""
    seen: dict = {}
    real = _REAL_MAKE_ENV

    def spy(robot, **kw):
        env = real(robot, **kw)
        rollout = env.rollout

        def record(u, *a, **k):
            traj = rollout(u, *a, **k)
            seen.update(u=np.array(u), x=np.array(traj.x))
            return traj
        env.rollout = record
        seen.update(robot=robot, incline=kw["incline_deg"], uphill=kw["heading_deg"])
        return env
    monkeypatch.setattr(rb, "make_gradient_env", spy)
    robot = with_contact_law(load_robot("tripod"), contact)
    job = rb.SampleJob("tripod", _step_controls(robot), 0.033, 2, 4, 0.0, 0.0, 0, 0, dict(perturbation), contact)
    seen["out"] = rb.run_sample(job)
    return seen


@pytest.fixture(scope="module")
def nominal_replays():
    with pytest.MonkeyPatch.context() as mp:
        return {law: replay(mp, IDENTITY, law) for law in ("paper", "coulomb")}


def test_the_identity_perturbation_is_the_nominal_replay(nominal_replays, monkeypatch):
    plain = replay(monkeypatch, IDENTITY)
    robot = load_robot("tripod")
    names = ["youngs_modulus", "density", "contact_stiffness", "friction", "payload_mass", "cable_stiffness"]
    assert np.allclose(parameter_values(plain["robot"], names), parameter_values(robot, names), rtol=1e-12)
    np.testing.assert_allclose(plain["u"], _step_controls(robot), rtol=0, atol=1e-15)
    assert (plain["incline"], plain["uphill"]) == pytest.approx((0.0, 0.0), abs=1e-9)


@pytest.mark.parametrize("name, law", [(n, "paper") for n in FACTORS] + [("friction", "coulomb")])
def test_each_factor_reaches_the_replayed_robot(nominal_replays, monkeypatch, name, law):
    nominal = nominal_replays[law]
    seen = replay(monkeypatch, {**IDENTITY, name: ONE[name]}, law)
    param = name if name != "friction" else ("friction" if law == "paper" else "friction_coefficient")
    base = parameter_values(with_contact_law(load_robot("tripod"), law), [param])[0]
    assert parameter_values(seen["robot"], [param])[0] == pytest.approx(base * ONE[name], rel=1e-12)
    others = [n for n in ("youngs_modulus", "density", "contact_stiffness", "payload_mass", "cable_stiffness")
              if n != name]
    assert np.allclose(parameter_values(seen["robot"], others), parameter_values(nominal["robot"], others), rtol=1e-12)
    assert np.abs(seen["x"] - nominal["x"]).max() > 1e-7, f"perturbing {name} alone did not change the replay"


@pytest.mark.parametrize("name", ["motor_lag_s", "motor_speed", "timing_jitter_s"])
def test_each_motor_perturbation_reaches_the_applied_controls(nominal_replays, monkeypatch, name):
    nominal = nominal_replays["paper"]
    seen = replay(monkeypatch, {**IDENTITY, name: ONE[name]})
    assert np.abs(seen["u"] - nominal["u"]).max() > 1e-5, f"{name} did not change the applied controls"
    assert np.abs(seen["x"] - nominal["x"]).max() > 1e-7, f"perturbing {name} alone did not change the replay"
    assert parameter_values(seen["robot"], ["youngs_modulus"]) == parameter_values(nominal["robot"], ["youngs_modulus"])


@pytest.mark.parametrize("direction", [0.0, 90.0])
def test_the_extra_slope_reaches_the_replay(nominal_replays, monkeypatch, direction):
    nominal = nominal_replays["paper"]
    seen = replay(monkeypatch, {**IDENTITY, "slope_deg": ONE["slope_deg"], "slope_direction_deg": direction})
    assert (seen["incline"], seen["uphill"]) == pytest.approx((ONE["slope_deg"], direction), abs=1e-9)
    assert np.abs(seen["x"] - nominal["x"]).max() > 1e-7
    assert seen["out"]["slope_along_heading_deg"] == pytest.approx(ONE["slope_deg"] * (direction == 0.0), abs=1e-12)


@pytest.mark.parametrize("law", ["paper", "coulomb"])
def test_every_domain_randomisation_factor_reaches_the_robot(law):
    base = with_contact_law(load_robot("tripod"), law)
    f = {"friction": 1.2, "contact_stiffness": 0.7, "youngs_modulus": 1.1, "density": 0.95, "payload_mass": 1.05}
    drawn = randomized_robot(base, f)
    fr = "friction" if law == "paper" else "friction_coefficient"
    names = [fr, "contact_stiffness", "youngs_modulus", "density", "payload_mass"]
    expected = parameter_values(base, names) * np.array([f["friction"], *(f[n] for n in names[1:])])
    np.testing.assert_allclose(parameter_values(drawn, names), expected, rtol=1e-12)
    assert drawn.node_masses.sum() != pytest.approx(base.node_masses.sum(), rel=1e-6)


def test_the_stall_torque_reaches_the_motors_of_a_gait_made_under_the_line(monkeypatch):
    """A gait made under the torque-speed line is replayed by motors that follow it: the
    environment stepped has each motor's stall torque x the factor (and its no-load speed x
    ``motor_speed``), and a weaker motor winds the step more slowly (issue #38)."""
    seen = []
    real = rb.SoftRobotEnv

    def spy(robot, **kw):
        seen.append((robot, kw))
        return real(robot, **kw)
    monkeypatch.setattr(rb, "SoftRobotEnv", spy)
    robot = load_robot("tripod")
    u = _step_controls(robot)
    out = {}
    for factor in (0.8, 1.2):
        p = {**IDENTITY, "motor_speed": 1.0, "stall_torque": factor}
        job = rb.SampleJob("tripod", u, 0.033, 2, 4, 0.0, 0.0, 0, 0, p, "coulomb", motor_model="torque-speed")
        out[factor] = rb.run_sample(job)
        env_robot, kw = seen[-1]
        assert kw["motor_model"] == "torque-speed"
        assert [m.stall_torque for m in env_robot.motors] == pytest.approx([0.39 * factor] * 2, rel=1e-12)
        assert [m.max_speed_rpm for m in env_robot.motors] == pytest.approx([100.0, 100.0], rel=1e-12)
    assert out[0.8]["speed_bl_per_min"] != out[1.2]["speed_bl_per_min"]
    assert "stall_torque" in rb.PERTURBATIONS and rb.PERTURBATIONS["stall_torque"] == ("factor", 0.8, 1.2)
    # a gait made under the speed limit alone: the stall torque plays no part
    speed = rb.run_sample(rb.SampleJob("tripod", u, 0.033, 2, 4, 0.0, 0.0, 0, 0,
                                       {**IDENTITY, "stall_torque": 0.8}, "coulomb"))
    same = rb.run_sample(rb.SampleJob("tripod", u, 0.033, 2, 4, 0.0, 0.0, 0, 0,
                                      {**IDENTITY, "stall_torque": 1.2}, "coulomb"))
    assert speed["speed_bl_per_min"] == same["speed_bl_per_min"]
