"""A third contact law added from outside the package (issue #27 item 2): frictionless contact,
one class and one registry line, then used like the shipped laws.

The law is the normal penalty alone. With it a robot file names ``model = "frictionless"``; a
cube released on a 20-degree slope slides with the acceleration ``g sin a``; every energy
derivative and parameter derivative passes the finite-difference checks of
``test_energy_derivatives`` / ``test_parameter_derivatives``; parameters, calibration's name
check and domain randomisation ask the law for its friction parameter (it has none). The
fixture removes the law again afterwards.
"""
from __future__ import annotations

import math

import meshio
import numpy as np
import pytest
from numba import njit

from soft_envs.sim import ContactParams, Simulator, incline_gravity, load_robot
from soft_envs.sim.contact import (CONTACT_LAWS, ContactLaw, register_contact_law, unregister_contact_law)
from soft_envs.sim.contact.penalty import normal_penalty
from soft_envs.sim.meshgen import voxel_tet_mesh
from soft_envs.sim.parameters import check_parameters, parameter_values, scale_parameters

from .test_energy_derivatives import check_every_term, check_total_energy, perturbed_state
from .test_parameter_derivatives import check_term_parameter_jacobians

G = 9.81


# ---------------------------------------------------------------------- the third law: one class
@njit(cache=True)
def _frictionless_assemble(x, nodes, k_n, eps_n, grad, hdata, diag_slots, want_grad, want_hess):
    total = 0.0
    for c in range(nodes.shape[0]):
        n = nodes[c]
        total += normal_penalty(x, n, k_n, eps_n, grad, hdata, diag_slots[3 * n + 1], want_grad, want_hess)
    return total


class FrictionlessContact(ContactLaw):
    """Ground contact without friction: ``E = sum_i Q_n(-y_i)``. Reads ``stiffness`` and
    ``blend`` and owns ``contact_stiffness`` (the base's declarations and parameter derivative);
    no friction parameter."""

    model = "frictionless"

    def energy(self, x, x_prev, u, hist=None) -> float:
        return _frictionless_assemble(x, self.nodes, self.k_n, self.eps_n, self._scratch, self._scratch,
                                      self.diag_slots, False, False)

    def assemble(self, x, x_prev, u, hist, grad, hdata, want_hess) -> float:
        return _frictionless_assemble(x, self.nodes, self.k_n, self.eps_n, grad, hdata, self.diag_slots,
                                      True, want_hess)


@pytest.fixture
def frictionless():
    register_contact_law(FrictionlessContact)          # the one registry line
    yield FrictionlessContact
    unregister_contact_law(FrictionlessContact.model)
    assert "frictionless" not in CONTACT_LAWS


def cube_file(tmp_path, model: str = "frictionless", size: float = 0.02, n: int = 2):
    """A robot.toml of a soft cube (no cables) with ``[contact] model = model``."""
    xs = np.linspace(0.0, size, n + 1)
    p, t = voxel_tet_mesh(xs, xs, xs, np.ones((n, n, n), bool))
    meshio.write(tmp_path / "cube.vtu", meshio.Mesh(p, [("tetra", t)]))
    path = tmp_path / "robot.toml"
    path.write_text(f'''[robot]
name = "cube"
mesh = "cube.vtu"

[material]
youngs_modulus = 1e5
poisson_ratio = 0.3
density = 200.0

[payload]
mass = 0.0

[contact]
model = "{model}"
stiffness = 2000.0
blend = 5e-4
''')
    return path


# ---------------------------------------------------------------------- tests
def test_a_robot_file_with_the_third_law_slides_without_friction(frictionless, tmp_path):
    """A cube at rest (normal gravity), released on a 20-degree slope: no friction holds it, so
    its centre of mass accelerates down the slope at g sin(20 deg) (within 3 %)."""
    robot = load_robot(cube_file(tmp_path))
    assert robot.contact.model == "frictionless" and robot.contact.law is FrictionlessContact
    a_deg = 20.0
    sim = Simulator(robot, gravity=incline_gravity(a_deg, uphill=(-1.0, 0.0)))
    assert isinstance(sim.system.contact, FrictionlessContact) and not sim.system.has_history
    K = int(round(1.5 / sim.dt))
    traj = sim.rollout(np.zeros((K, 0)))                 # from its rest state, under the full gravity
    t = np.arange(K + 1) * sim.dt
    s = traj.com[:, 0] - traj.com[0, 0]
    late = t >= 0.3
    acc = 2.0 * np.polyfit(t[late], s[late], 2)[0]
    expected = G * math.sin(math.radians(a_deg))
    assert abs(acc - expected) <= 0.03 * expected, (acc, expected)
    assert np.abs(traj.com[:, 1] - traj.com[0, 1]).max() < 1e-3      # it slides, it does not bounce or sink


def test_the_third_law_passes_the_energy_derivative_checks(frictionless):
    """The finite-difference checks of every term (``test_energy_derivatives``) and of every
    term's parameter Jacobian (``test_parameter_derivatives``) with the frictionless law."""
    for case in ("taut_cable_contact_friction", "contact_in_blend"):
        sim, x, x_prev, u, rng = perturbed_state(case, contact=ContactParams(model="frictionless"))
        assert isinstance(sim.system.contact, FrictionlessContact)
        history = sim.system.initial_history(x_prev)
        check_every_term(sim, x, x_prev, u, rng, history)
        check_total_energy(sim, x, x_prev, u, rng)
        check_term_parameter_jacobians(sim, x, x_prev, u, history)


def test_parameters_and_domain_randomisation_ask_the_law_for_its_friction(frictionless, tmp_path):
    """The law has no friction parameter: naming one is refused with the reason, the domain
    randomisation's and robustness's "friction" factor changes nothing, the others apply."""
    robot = load_robot(cube_file(tmp_path))
    assert FrictionlessContact.friction_parameter is None
    assert check_parameters(robot, ["contact_stiffness", "youngs_modulus"]) == ("contact_stiffness", "youngs_modulus")
    for name in ("friction", "friction_coefficient"):
        with pytest.raises(ValueError, match=rf"cannot use parameter '{name}': the robot uses contact.model = "
                                             r"'frictionless'; that contact law has no friction parameter"):
            check_parameters(robot, [name])
    scaled = scale_parameters(robot, {"friction": 1.3, "contact_stiffness": 1.2, "youngs_modulus": 0.9})
    assert scaled.contact.stiffness == robot.contact.stiffness * 1.2
    assert scaled.youngs_modulus == robot.youngs_modulus * 0.9
    assert (scaled.contact.friction, scaled.contact.friction_coefficient) == \
        (robot.contact.friction, robot.contact.friction_coefficient)
    assert scale_parameters(robot, {"friction": 1.3}) is robot
    np.testing.assert_array_equal(parameter_values(scaled, ["contact_stiffness"]), [2400.0])


def test_an_environment_with_the_third_law_randomises_its_domain(frictionless):
    """The Tripod under the frictionless law (the ``contact`` keyword) resets with the default
    domain randomisation (friction factor drawn, nothing to scale) and steps."""
    from soft_envs.envs import SoftTripodEnv
    env = SoftTripodEnv(contact="frictionless", domain_randomization=True)
    try:
        assert env.contact_model == "frictionless"
        obs, info = env.reset(seed=3)
        f = info["domain_parameters"]
        assert set(f) == {"friction", "youngs_modulus", "density", "payload_mass"} and f["friction"] != 1.0
        robot = env.unwrapped.simulator.robot
        nominal = load_robot("tripod")
        if not info["domain_fallback"]:
            assert robot.youngs_modulus == nominal.youngs_modulus * f["youngs_modulus"]
        assert robot.contact.friction == nominal.contact.friction
        obs, *_ = env.step(env.action_space.sample())
        assert np.isfinite(obs).all()
    finally:
        env.close()


def test_an_unknown_law_in_a_robot_file_names_file_field_and_known_laws(tmp_path):
    path = cube_file(tmp_path, model="frictionles")
    with pytest.raises(ValueError) as err:
        load_robot(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}: [contact] contact.model must be one of the contact laws 'paper', 'coulomb'"), msg
    assert msg.endswith("got 'frictionles'"), msg


def test_registering_checks_the_declarations(frictionless):
    with pytest.raises(ValueError, match="must be a new name"):
        register_contact_law(FrictionlessContact)
    with pytest.raises(ValueError, match="built in"):
        unregister_contact_law("paper")

    class Bad(ContactLaw):
        model = "bad"
        friction_parameter = "rolling_resistance"
    with pytest.raises(ValueError, match="friction_parameter 'rolling_resistance'"):
        register_contact_law(Bad)
    assert "bad" not in CONTACT_LAWS


def test_the_command_line_knows_a_registered_law_without_being_edited(frictionless, capsys):
    """`--contact` is checked against the registry when it is parsed (optimize, rl train,
    calibrate and the sweep's run options): a law registered with one line is accepted, an
    unknown one refused naming the laws."""
    from trajopt.cli import build_parser
    from trajopt.sweep.kinds import KINDS
    parser = build_parser()
    for argv in (["optimize", "tripod"], ["rl", "train", "tripod"]):
        assert parser.parse_args([*argv, "--contact", "frictionless"]).contact == "frictionless"
        with pytest.raises(SystemExit):
            parser.parse_args([*argv, "--contact", "frictionles"])
        assert "'paper', 'coulomb', 'frictionless'" in capsys.readouterr().err
    assert KINDS["optimize"].check("contact", "frictionless") == "frictionless"
    with pytest.raises(ValueError, match="argument contact: invalid choice: .frictionles."):
        KINDS["optimize"].check("contact", "frictionles")
