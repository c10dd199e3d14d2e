"""Tables pinned to their documented numbers (issue #30, class "tables tested against themselves").

Each range below is written out as literal numbers from the documentation (the module
docstrings of trajopt.robustness and soft_envs.envs.domain, docs/calibration.md, README), not
read from the table under test: a range in the wrong unit, or narrowed, fails here.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from soft_envs.envs.domain import DEFAULT_DOMAIN_RANDOMIZATION
from trajopt.hardware.config import DEFAULT_COUNTS_PER_REV, MotorConfig
from trajopt.robustness.study import PERTURBATIONS, draw_perturbation

#: docs/calibration.md and trajopt/robustness/study.py's docstring: name -> (low, high, log-uniform)
DOCUMENTED_PERTURBATIONS = {
    "friction": (0.5, 1.5, False), "youngs_modulus": (0.7, 1.3, False), "density": (0.9, 1.1, False),
    "payload_mass": (0.85, 1.15, False), "contact_stiffness": (0.5, 2.0, True), "cable_stiffness": (0.5, 2.0, True),
    "motor_lag_s": (0.0, 0.1, False), "motor_speed": (0.6, 1.4, False), "timing_jitter_s": (0.0, 0.010, False),
    "slope_deg": (0.0, 10.0, False), "slope_direction_deg": (0.0, 360.0, False), "stall_torque": (0.8, 1.2, False)}


@pytest.fixture(scope="module")
def draws() -> dict[str, np.ndarray]:
    samples = [draw_perturbation(7, i) for i in range(600)]
    return {k: np.array([s[k] for s in samples]) for k in samples[0]}


def test_robustness_table_is_the_documented_one():
    assert set(PERTURBATIONS) == set(DOCUMENTED_PERTURBATIONS)
    for name, (lo, hi, log) in DOCUMENTED_PERTURBATIONS.items():
        kind, t_lo, t_hi = PERTURBATIONS[name]
        assert (t_lo, t_hi) == (lo, hi), name
        assert (kind == "log") == log, name


@pytest.mark.parametrize("name", sorted(DOCUMENTED_PERTURBATIONS))
def test_robustness_draws_fill_the_documented_range(draws, name):
    """600 draws lie in the documented range and reach within 3 % of both of its ends; a
    log-uniform draw has its median at the geometric mean (1 for x 0.5 - 2), a uniform one at
    the middle."""
    lo, hi, log = DOCUMENTED_PERTURBATIONS[name]
    x = draws[name]
    assert x.min() >= lo and x.max() <= hi
    span = hi - lo
    assert x.min() < lo + 0.03 * span and x.max() > hi - 0.03 * span
    centre = math.sqrt(lo * hi) if log else 0.5 * (lo + hi)
    assert abs(np.median(x) - centre) < 0.08 * span


def test_default_domain_randomisation_is_the_documented_one():
    """README and soft_envs/envs/domain.py: friction (0.7, 1.3), Young's modulus (0.8, 1.2),
    density and payload mass (0.9, 1.1)."""
    assert dict(DEFAULT_DOMAIN_RANDOMIZATION) == {"friction": (0.7, 1.3), "youngs_modulus": (0.8, 1.2),
                                                  "density": (0.9, 1.1), "payload_mass": (0.9, 1.1)}


def test_default_encoder_counts_are_the_gearmotors():
    """Pololu 298:1 micro metal gearmotor: 12 counts per motor turn x 297.92 = 3575.04 per output
    turn; one output turn of a 5 mm spool pulls in 2 pi 5 mm of cable."""
    assert DEFAULT_COUNTS_PER_REV == pytest.approx(3575.04, abs=1e-9)
    m = MotorConfig(name="m", port="/dev/null", address=0x80, channel=1, spool_radius=0.005, max_speed=4000,
                    max_accel=40000)
    assert m.to_counts(2 * math.pi * 0.005) == 3575
