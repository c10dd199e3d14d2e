"""Derivatives of the design parameters (issue #29 items 1-2) against central finite differences:
regional moduli, via-point rest positions (the embedding, the cable force, the clearance) and
leg lengths (the morph: force and masses), per energy system in several regimes, and each
kind's whole-rollout Jacobian column under both contact laws. Each check states its relative
error in the assertion message.

Per term: relative step 1e-6 of a modulus, 1e-7 m of a point or leg, relative error <= 1e-6.
Whole rollouts (24 steps of the Tripod from its rest state): Newton tolerance 1e-12 m, rest
state to 1e-13 m, relative error of the COM's Jacobian <= 1e-6: every column on its own under
the Coulomb law (23: two regional moduli, 18 via-point coordinates, three legs; measured at
most 2.4e-7), a random direction per kind under the paper's law (measured 8.9e-9 to 8.3e-8).
Leg steps are 3e-7 m (the error grows as the step squared: truncation). The same rollouts check
the cable deformations' Jacobian ``dgammadtheta`` (the tensions' sensitivities, co-design's
torque-speed rows; measured at most 2.7e-8 per column under Coulomb's law, 1.2e-7 in a random
direction under the paper's), and ``dGamma/dtheta`` at fixed positions is checked per column
(measured at most 6.6e-9).
"""
from __future__ import annotations

import numpy as np
import pytest

from soft_envs.sim import NewtonOptions, Simulator, load_robot
from soft_envs.sim.design import (DesignParameters, LegMorph, RegionalModuli, TendonRouting, embedding_jacobian,
                                  legs_below, region_from_boxes, region_from_cell_tags, signed_distance)
from soft_envs.sim.parameters import with_parameters
from soft_envs.sim.system import EnergySystem

from .conftest import small_robot
from .gradcheck import relative_error
from .test_energy_derivatives import perturbed_state
from .test_parameter_derivatives import gait

RTOL_TERM = 1e-6
RTOL_ROLLOUT = 1e-6


def system_gradient(robot, sim, x, x_prev, u, history) -> np.ndarray:
    """The whole energy's gradient of ``robot`` in ``sim``'s setting (gravity, control)."""
    system = EnergySystem(robot, gravity=sim.system.gravity, control=sim.system.control)
    return system.assemble(x, x_prev, u, want_hess=False, history=history)[1]


def fd_columns(design, sim, x, x_prev, u, history, steps) -> np.ndarray:
    theta = design.values
    cols = []
    for j, h in enumerate(steps):
        d = np.zeros(len(theta))
        d[j] = h
        g = [system_gradient(design.robot_at(theta + s * d), sim, x, x_prev, u, history) for s in (1, -1)]
        cols.append((g[0] - g[1]) / (2 * h))
    return np.array(cols).T


def check_columns(J, fd, what):
    for j in range(fd.shape[1]):
        err = relative_error(J[:, j], fd[:, j])
        assert np.linalg.norm(fd[:, j]) > 0, f"{what}[{j}]: finite differences vanish"
        assert err <= RTOL_TERM, f"{what}[{j}]: relative error {err:.2e} > {RTOL_TERM:.0e}"


def two_regions(robot):
    return [region_from_boxes(robot, "left", [[0, 0, 0, 0.02, 0.02, 0.02]]),
            region_from_boxes(robot, "middle", [[0.02, 0, 0, 0.04, 0.02, 0.02]])]


@pytest.mark.parametrize("case", ["taut_cable_contact_friction", "coulomb_stick_and_slip", "fixed_nodes"])
def test_regional_moduli_force_jacobian(case):
    sim, x, x_prev, u, _ = perturbed_state(case)
    robot = sim.robot
    design = DesignParameters(robot, [RegionalModuli(robot, two_regions(robot))])
    history = sim.system.initial_history(x_prev)
    J = design.force_jacobian(sim.system, x, x_prev, u, history)
    fd = fd_columns(design, sim, x, x_prev, u, history, 1e-6 * design.values)
    check_columns(J, fd, f"{case}: d grad / d E_region")
    # the regions add up to the uniform modulus' derivative
    whole = sim.system.parameter_jacobian(x, x_prev, u, ["youngs_modulus"], history)[:, 0]
    rest = RegionalModuli(robot, [region_from_cell_tags(robot, "right", robot.mesh.points[robot.mesh.tets]
                                                        .mean(axis=1)[:, 0] > 0.04, True)])
    total = J.sum(axis=1) + rest.force_jacobian(sim.system, x, x_prev, u, history)[:, 0]
    assert relative_error(total, whole) <= 1e-12


def test_physical_parameters_of_a_robot_with_regional_moduli():
    """``youngs_modulus`` scales every region alike and ``poisson_ratio`` acts in each with its
    modulus: their Jacobians (``Elastic.add_parameter_jacobian`` with ``modulus_scale``) against
    central differences."""
    sim0, x, x_prev, u, _ = perturbed_state("taut_cable_contact_friction")
    base = sim0.robot
    design = DesignParameters(base, [RegionalModuli(base, two_regions(base))])
    robot = design.robot_at([2.5e5, 0.4e5])
    system = EnergySystem(robot)
    J = system.parameter_jacobian(x, x_prev, u, ["youngs_modulus", "poisson_ratio"])
    for j, (name, value) in enumerate((("youngs_modulus", robot.youngs_modulus), ("poisson_ratio", robot.poisson_ratio))):
        h = 1e-6 * value
        g = [EnergySystem(with_parameters(robot, {name: value + s * h})).assemble(x, x_prev, u, want_hess=False)[1]
             for s in (1, -1)]
        err = relative_error(J[:, j], (g[0] - g[1]) / (2 * h))
        assert err <= RTOL_TERM, f"d grad / d {name} with regional moduli: relative error {err:.2e}"


def test_regional_moduli_set_the_elements_and_check_their_input():
    robot = small_robot()
    regions = two_regions(robot)
    design = DesignParameters(robot, [RegionalModuli(robot, regions)])
    assert np.allclose(design.values, robot.youngs_modulus) and np.allclose(design.bounds, [[3e4, 3e5]] * 2)
    moved = design.robot_at([2e5, 5e4])
    mu, _ = moved.element_lame()
    mu0, _ = robot.element_lame()
    assert np.allclose(mu[regions[0].elements], 2 * mu0[0]) and np.allclose(mu[regions[1].elements], 0.5 * mu0[0])
    others = np.setdiff1d(np.arange(robot.mesh.n_tets), np.concatenate([r.elements for r in regions]))
    assert np.allclose(mu[others], mu0[0]) and robot.modulus_scale is None
    with pytest.raises(ValueError, match="overlap"):
        RegionalModuli(robot, [regions[0], regions[0]])
    with pytest.raises(ValueError, match="no tet centroid"):
        region_from_boxes(robot, "nowhere", [[1, 1, 1, 2, 2, 2]])
    with pytest.raises(ValueError, match="'stiffness:left'"):
        design.robot_at([np.nan, 1e5])


def mirrored_robot(relation="mirror", **kw):
    """The bar with two tendons on one motor (a tendon pair), the second the mirror image of the
    first in the bar's mid-plane z = 0.01 (``relation="mirror"``) or its translate by 9 mm in z
    (``"pair"``)."""
    a = [[0.055, 0.016, 0.0042], [0.031, 0.0123, 0.0061], [0.0052, 0.0155, 0.0043]]
    b = [[p[0], p[1], 0.02 - p[2] if relation == "mirror" else p[2] + 0.009] for p in a]
    return small_robot(tendons=[dict(name="a", points=a), dict(name="b", points=b)],
                       motors=[dict(name="m0", tendons=["a", "b"], u_max=0.01)], **kw)


def test_embedding_jacobian_is_the_deformation_gradient():
    robot = mirrored_robot()
    rng = np.random.default_rng(1)
    x = robot.mesh.points + rng.normal(scale=1e-3, size=robot.mesh.points.shape)
    routing = TendonRouting(robot, fixed=())
    design = DesignParameters(robot, [routing])
    theta, h = design.values, 1e-7

    def point(r, t=0, s=1):
        cd = r.cable_data
        k = cd.ptr[t] + s
        return cd.pt_w[k] @ x[cd.pt_nodes[k]]
    F = embedding_jacobian(robot.mesh, robot._binding[0][0][1], x)
    for i in range(3):
        d = np.zeros(len(theta))
        d[3 + i] = h                   # tendon a, point 1
        fd = (point(design.robot_at(theta + d)) - point(design.robot_at(theta - d))) / (2 * h)
        err = relative_error(F[:, i], fd)
        assert err <= RTOL_TERM, f"dp/dq[:, {i}]: relative error {err:.2e}"
        # the mirrored point moves with the mirrored direction
        fdb = (point(design.robot_at(theta + d), 1) - point(design.robot_at(theta - d), 1)) / (2 * h)
        Fb = embedding_jacobian(robot.mesh, robot._binding[1][0][1], x)
        err = relative_error(Fb @ routing.reflect[:, i], fdb)
        assert err <= RTOL_TERM, f"mirror dp/dq[:, {i}]: relative error {err:.2e}"


@pytest.mark.parametrize("case, relation", [("taut_cable_contact_friction", "mirror"), ("cable_in_blend", "mirror"),
                                            ("tension_control", "mirror"), ("coulomb_stick_and_slip", "mirror"),
                                            ("taut_cable_contact_friction", "pair")])
def test_routing_force_jacobian(case, relation):
    sim0, x, x_prev, u, _ = perturbed_state(case)
    robot = mirrored_robot(relation, contact=sim0.robot.contact)
    sim = Simulator(robot, control=sim0.control, gravity=sim0.gravity)
    if sim.control == "length":      # Gamma as in the case: the pair's first tendon as taut as the bar's
        u = u + (robot.cable_data.rest_length[0] - sim0.system.cables.alpha0[0]) \
            - (sim.system.cables.lengths(x)[0] - sim0.system.cables.lengths(x)[0])
    routing = TendonRouting(robot, fixed=())
    design = DesignParameters(robot, [routing])
    assert routing.leaders == [0] and list(routing.followers) == [1] and routing.followers[1][0] == 0
    assert len(design) == 9
    history = sim.system.initial_history(x_prev)
    J = design.force_jacobian(sim.system, x, x_prev, u, history)
    fd = fd_columns(design, sim, x, x_prev, u, history, [1e-7] * len(design))
    check_columns(J, fd, f"{case}: d grad / d q")


@pytest.mark.parametrize("case", ["taut_cable_contact_friction", "coulomb_stick_and_slip", "fixed_nodes",
                                  "tension_control"])
def test_leg_morph_force_and_mass_jacobians(case):
    """The bar's lower half as a "leg" (hip at 12 mm) with a routed tendon through it: the
    morph's force Jacobian (elastic, cables, gravity) and mass Jacobian, next to routing
    columns (the morph carries the routed points)."""
    sim0, x, x_prev, u, _ = perturbed_state(case)
    robot = mirrored_robot(contact=sim0.robot.contact, fixed_nodes=sim0.robot.fixed_nodes)
    sim = Simulator(robot, control=sim0.control, gravity=sim0.gravity)
    legs = legs_below(robot, 0.012)
    assert [leg.name for leg in legs] == ["leg0"]
    design = DesignParameters(robot, [LegMorph(robot, legs, 0.012), TendonRouting(robot)])
    history = sim.system.initial_history(x_prev)
    J = design.force_jacobian(sim.system, x, x_prev, u, history)
    fd = fd_columns(design, sim, x, x_prev, u, history, [1e-7] * len(design))
    check_columns(J, fd, f"{case}: d grad / d (leg length, routing)")
    h = 1e-7
    dm = [design.robot_at(design.values + s * h * np.eye(len(design))[0]).node_masses for s in (1, -1)]
    fdm = (dm[0] - dm[1]) / (2 * h)
    err = relative_error(design.node_mass_jacobian()[:, 0], fdm)
    assert err <= RTOL_TERM, f"d masses / d leg length: relative error {err:.2e}"
    assert abs(design.total_mass_jacobian()[0] - fdm.sum()) <= RTOL_TERM * abs(fdm.sum())
    assert design.total_mass_jacobian()[0] > 0          # a longer leg is heavier


@pytest.mark.parametrize("case", ["taut_cable_contact_friction", "tension_control"])
@pytest.mark.parametrize("kinds", ["routing", "legs+routing", "moduli"])
def test_deformation_jacobian_at_fixed_positions(case, kinds):
    """``dGamma/dtheta`` at fixed x (the block's part of the rollout's ``dgammadtheta``): via points
    move their cable points and the assembly lengths (a mirror pair: the follower's row through
    its map), a leg morph only the assembly lengths (its points ride with their tets), moduli
    nothing. Relative error <= 1e-6 per column, step 1e-7 m."""
    sim0, x, _, u, _ = perturbed_state(case)
    robot = mirrored_robot(contact=sim0.robot.contact)
    sim = Simulator(robot, control=sim0.control, gravity=sim0.gravity)
    parts = {"routing": [TendonRouting(robot, fixed=())],
             "legs+routing": [LegMorph(robot, legs_below(robot, 0.012), 0.012), TendonRouting(robot)],
             "moduli": [RegionalModuli(robot, two_regions(robot))]}[kinds]
    design = DesignParameters(robot, parts)
    J = design.deformation_jacobian(sim.system, x)
    assert J.shape == (2, len(design))
    if kinds == "moduli":
        assert not J.any()
        return
    theta = design.values
    for j in range(len(design)):
        d = 1e-7 * np.eye(len(design))[j]
        gam = [EnergySystem(design.robot_at(theta + s * d), control=sim.control).cables.deformation(x, u)
               for s in (1, -1)]
        fd = (gam[0] - gam[1]) / 2e-7
        assert np.linalg.norm(fd) > 0, f"{design.names[j]}: finite differences vanish"
        err = relative_error(J[:, j], fd)
        assert err <= RTOL_TERM, f"{case}: dGamma / d {design.names[j]}: relative error {err:.2e}"


def test_routing_ties_mirrors_and_pairs_of_the_puppy():
    """The Puppy's 16 tendons: the "_a" tendon of each left motor leads; its pair "_b" (same
    motor, 1 cm apart) and the right side's mirror images follow."""
    robot = load_robot("puppy")
    routing = TendonRouting(robot)
    names = robot.tendon_names
    assert [names[t] for t in routing.leaders] == ["hind_left_front_a", "hind_left_back_a", "fore_left_front_a",
                                                   "fore_left_back_a"]
    assert len(routing.followers) == 12 and len(routing.names) == 4 * 3 * 3
    theta = routing.values + np.random.default_rng(4).uniform(-1e-3, 1e-3, len(routing.names))
    pts = routing.points(robot, theta)
    for t, (lead, R, c) in routing.followers.items():
        assert np.allclose(pts[t], pts[lead] @ R.T + c)
    la, lb, rb = (names.index(f"fore_{n}") for n in ("left_front_a", "left_front_b", "right_front_b"))
    assert np.allclose(pts[lb][:, 2] - pts[la][:, 2], 0.01)           # the pair keeps its spacing
    assert np.allclose(pts[rb][:, 2], 0.08 - pts[la][:, 2])           # the outer ones mirror in z = 0.04


def test_routing_keeps_rest_length_offsets_and_fixes_the_motor_end():
    robot = mirrored_robot()
    routing = TendonRouting(robot)
    assert [routing.names[3 * j][8:12] for j in range(len(routing.free))] == ["a[0]", "a[1]"]
    off = 0.003
    tendons = tuple(t.__class__(t.name, t.points, t.stiffness,
                                float(np.linalg.norm(np.diff(t.points, axis=0), axis=1).sum()) - off)
                    for t in robot.tendons)
    tight = robot.replace(tendons=tendons)
    design = DesignParameters(tight, [TendonRouting(tight)])
    theta = design.values + 1e-3 * np.random.default_rng(0).uniform(-1, 1, len(design))
    moved = design.robot_at(theta)
    for t in moved.tendons:
        assert np.isclose(np.linalg.norm(np.diff(t.points, axis=0), axis=1).sum() - t.rest_length, off)
        assert np.array_equal(t.points[-1], tight.tendons[0].points[-1] * [1, 1, 0] + [0, 0, 0.02 * (t.name == "b")]
                              + [0, 0, tight.tendons[0].points[-1][2] * (1 if t.name == "a" else -1)])


def test_clearance_and_its_gradient():
    robot = mirrored_robot()
    routing = TendonRouting(robot, fixed=())
    d, J = routing.clearance(robot)
    assert d.shape == (6,) and np.allclose(d[0::2], d[1::2]) and (d > 0).all()   # a point, its mirror
    assert np.isclose(d[0], 0.004, atol=1e-12)           # (0.055, 0.016, 0.0042): 4 mm below the top
    assert np.allclose(J[0], np.r_[0, -1, 0, np.zeros(6)]) and np.allclose(J[1], J[0])
    rng = np.random.default_rng(2)
    for q in robot.tendons[0].points:
        for _ in range(3):
            v = rng.normal(size=3)
            h = 1e-7
            _, g = signed_distance(robot.mesh, q)
            fd = (signed_distance(robot.mesh, q + h * v)[0] - signed_distance(robot.mesh, q - h * v)[0]) / (2 * h)
            assert abs(g @ v - fd) <= 1e-6 * abs(fd) + 1e-9, f"clearance at {q}: {g @ v} vs {fd}"
    assert signed_distance(robot.mesh, [0.03, 0.025, 0.01])[0] == pytest.approx(-0.005)


def tripod_off_faces(model="coulomb"):
    """The Tripod (contact law ``model``) with its via points moved off the mesh's faces (the embedding
    is piecewise affine: on a face the derivative is one-sided)."""
    robot = load_robot("tripod")
    robot = robot.replace(contact=robot.contact.__class__(**{**robot.contact.__dict__, "model": model}))
    shift = np.array([0.0007, 0.0011, 0.0013])
    tendons = []
    for t in robot.tendons:
        pts = np.array(t.points)
        side = 1.0 if pts[0, 2] < 0.02 else -1.0            # keep the pair mirrored about z = 0.02
        pts[:-1] += shift * [1, 1, side]
        tendons.append(t.__class__(t.name, pts, t.stiffness, t.rest_length))
    return robot.replace(tendons=tuple(tendons))


@pytest.mark.parametrize("model", ["coulomb", "paper"])
@pytest.mark.parametrize("kind", ["stiffness", "routing", "legs"])
def test_rollout_design_column_matches_finite_differences(kind, model):
    robot = tripod_off_faces(model)
    if kind == "stiffness":
        legs = [region_from_boxes(robot, "middle_leg", [[0.055, -1, -1, 0.085, 0.012, 1]]),
                region_from_boxes(robot, "body", [[-1, 0.03, -1, 1, 1, 1]])]
        design = DesignParameters(robot, [RegionalModuli(robot, legs)])
        scale = design.values
    elif kind == "routing":
        design = DesignParameters(robot, [TendonRouting(robot, tendons=["front_a", "back_a"])])
        scale = np.ones(len(design))
    else:
        design = DesignParameters(robot, [LegMorph(robot, legs_below(robot, 0.03), 0.03)])
        scale = np.ones(len(design))
    tight = NewtonOptions(tol=1e-12)
    K = 24
    u = gait(robot, K)
    sim = Simulator(robot, newton=tight)
    x0, h0, dx0, dh0 = sim.rest_sensitivity(design, tol=1e-13)
    traj = sim.rollout(u, x0=x0, history0=h0, params=design, dx0dtheta=dx0, dhistory0dtheta=dh0)
    assert traj.info["parameters"] == design.names
    h = {"stiffness": 1e-5, "routing": 1e-7, "legs": 3e-7}[kind]
    if model == "coulomb":            # every column on its own (the target law)
        directions = list(np.eye(len(design)) * scale)
    else:                             # a random direction
        d = np.random.default_rng(3).normal(size=len(design)) * scale
        directions = [d / np.linalg.norm(d / scale)]
    for j, d in enumerate(directions):
        runs = []
        for s in (1.0, -1.0):
            moved = Simulator(design.robot_at(design.values + s * h * d), newton=tight)
            runs.append(moved.rollout(u, x0=moved.rest_state(tol=1e-13)))       # a State: its anchors
        fd = (runs[0].com - runs[1].com) / (2 * h)
        what = design.names[j] if model == "coulomb" else f"{kind} (random direction)"
        err = relative_error(traj.dcomdtheta @ d, fd)
        assert err <= RTOL_ROLLOUT, f"{what}: COM Jacobian column, relative error {err:.2e} > {RTOL_ROLLOUT:.0e}"
        errx = relative_error(traj.dxdtheta @ d, (runs[0].x - runs[1].x).reshape(K + 1, -1) / (2 * h))
        assert errx <= 10 * RTOL_ROLLOUT, f"{what}: state Jacobian column, relative error {errx:.2e}"
        fdg = (runs[0].cable_deformation - runs[1].cable_deformation) / (2 * h)
        errg = relative_error(traj.dgammadtheta @ d, fdg)
        assert errg <= RTOL_ROLLOUT, f"{what}: cable deformations' Jacobian column, relative error {errg:.2e}"


def test_design_parameters_refuse_another_robot():
    robot = small_robot()
    design = DesignParameters(robot, [RegionalModuli(robot, two_regions(robot))])
    with pytest.raises(ValueError, match="belong to robot"):
        Simulator(small_robot()).rollout(np.zeros((2, 1)), params=design)
    assert design.total_mass() == robot.total_mass and not design.total_mass_jacobian().any()
