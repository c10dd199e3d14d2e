"""Every rule of a behaviour with several, each on its own (issue #30, class "one of several
rules exercised"): health by tilt and by COM height, the turn reward to either side and with its
own radius, domain randomisation of friction under both contact laws, and the encoder read-back
of a motor wound either way."""
from __future__ import annotations

import math

import numpy as np
import pytest

from soft_envs.envs import load_robot, with_contact_law
from soft_envs.envs.domain import randomized_robot
from soft_envs.envs.task import LocomotionTask
from trajopt.hardware.config import MotorConfig

REST_HEIGHT = 0.04


@pytest.mark.parametrize("tilt_deg, height_fraction, healthy", [
    (0.0, 1.0, True), (59.0, 0.51, True),
    (61.0, 1.0, False),               # the tilt rule alone
    (0.0, 0.49, False),               # the COM-height rule alone
])
def test_health_needs_both_rules(tilt_deg, height_fraction, healthy):
    task = LocomotionTask()          # healthy_tilt_deg 60, healthy_height_fraction 0.5
    com = np.array([0.3, height_fraction * REST_HEIGHT, -0.2])
    assert task.is_healthy(tilt_deg, com, REST_HEIGHT) is healthy


def test_health_height_rule_follows_its_fraction():
    com = np.array([0.0, 0.7 * REST_HEIGHT, 0.0])
    assert LocomotionTask(healthy_height_fraction=0.6).is_healthy(0.0, com, REST_HEIGHT)
    assert not LocomotionTask(healthy_height_fraction=0.8).is_healthy(0.0, com, REST_HEIGHT)


@pytest.mark.parametrize("direction, yaw_rate, expected_progress", [
    ("right", 0.5, 0.5), ("right", -0.5, -0.5), ("left", -0.5, 0.5), ("left", 0.5, -0.5)])
def test_turn_reward_to_either_side(direction, yaw_rate, expected_progress):
    """progress = +-yaw_rate x radius / BL (radius one body length by default); +yaw turns right."""
    task = LocomotionTask(task="turn", turn_direction=direction, ctrl_cost_weight=0.0, healthy_reward=0.0)
    reward, info = task.reward(0.0, yaw_rate, np.full(3, -1.0), True, body_length=0.1)
    assert info["reward_forward"] == pytest.approx(10.0 * expected_progress, rel=1e-12)
    assert reward == pytest.approx(10.0 * expected_progress, rel=1e-12)


def test_turn_reward_uses_its_radius():
    task = LocomotionTask(task="turn", turn_radius=0.25, ctrl_cost_weight=0.0, healthy_reward=0.0)
    _, info = task.reward(0.0, 0.4, np.zeros(3), True, body_length=0.1)
    assert info["reward_forward"] == pytest.approx(10.0 * 0.4 * 0.25 / 0.1, rel=1e-12)


@pytest.mark.parametrize("law, field", [("paper", "friction"), ("coulomb", "friction_coefficient")])
def test_domain_randomisation_scales_the_friction_of_either_law(law, field):
    base = with_contact_law(load_robot("tripod"), law)
    drawn = randomized_robot(base, {"friction": 1.25, "contact_stiffness": 0.6})
    assert getattr(drawn.contact, field) == pytest.approx(1.25 * getattr(base.contact, field), rel=1e-12)
    assert drawn.contact.stiffness == pytest.approx(0.6 * base.contact.stiffness, rel=1e-12)
    assert drawn.contact.model == law


@pytest.mark.parametrize("direction", [1, -1])
def test_encoder_read_back_of_a_motor_wound_either_way(direction):
    """counts = direction x u / r / 2 pi x counts_per_rev, and back (cable metres)."""
    m = MotorConfig(name="m", port="/dev/null", address=0x80, channel=1, spool_radius=0.004, max_speed=4000,
                    max_accel=40000, counts_per_rev=1000.0, direction=direction)
    u = 2 * math.pi * 0.004 * 0.5                          # half a turn
    assert m.to_counts(u) == direction * 500
    assert m.to_length(direction * 500) == pytest.approx(u, rel=1e-12)
    assert m.to_length(m.to_counts(np.array([0.0, u]))) == pytest.approx([0.0, u], rel=1e-12)
