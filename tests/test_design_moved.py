"""Mirror legs tied (issue #29: a co-designed Puppy stays bilaterally symmetric) and the design
block rebuilt at a moved design (``DesignParameters.moved_to``, what the co-design linearises at
every iterate), against central finite differences: the tied legs' force and mass Jacobians per
term (<= 1e-6), and whole-rollout COM Jacobian columns (Coulomb law, Newton tolerance 1e-12 m,
<= 1e-6) of the tied Puppy legs and, at a moved Tripod design (a leg 3 mm longer, a via point
1 mm inwards, a modulus x1.5), one column per kind. Also the written robot folder of a moved
design: ``load_design`` on it finds the same parameters."""
from __future__ import annotations

import numpy as np
import pytest

from soft_envs.sim import NewtonOptions, Simulator, load_robot
from soft_envs.sim.design import (DesignParameters, LegMorph, RegionalModuli, TendonRouting, legs_below, load_design,
                                  region_from_boxes, write_designed_robot)

from .gradcheck import relative_error
from .test_design_derivatives import RTOL_ROLLOUT, check_columns, fd_columns, tripod_off_faces
from .test_parameter_derivatives import gait

TIGHT = NewtonOptions(tol=1e-12)


def puppy_legs(robot=None):
    robot = robot or load_robot("puppy")
    return DesignParameters(robot, [LegMorph(robot, legs_below(robot, 0.04), 0.04)])


def mirror(points: np.ndarray, width: float) -> np.ndarray:
    out = np.array(points)
    out[..., 2] = width - out[..., 2]
    return out


def test_mirror_legs_are_tied_and_full_width_legs_are_not():
    design = puppy_legs()
    morph = design.kinds[0]
    assert design.names == ("legs:leg0+leg1", "legs:leg2+leg3") and morph.groups == ((0, 1), (2, 3))
    assert np.allclose(morph.bounds, [[-0.02, 0.02]] * 2)
    robot = design.robot
    longer = design.robot_at([0.004, -0.002])                    # hind legs 4 mm longer, fore legs 2 mm shorter
    moved = longer.mesh.points - robot.mesh.points
    assert np.isclose(-moved[:, 1].min(), 0.004) and np.isclose(moved[:, 1].max(), 0.002)
    assert not moved[:, [0, 2]].any()
    # the moved robot is its own mirror image: each node's move is its mirror node's
    width = robot.mesh.points[:, 2].max()
    pts = robot.mesh.points
    mirror_of = [int(np.argmin(np.linalg.norm(pts - p, axis=1))) for p in mirror(pts, width)]
    assert np.allclose(pts[mirror_of], mirror(pts, width)) and np.allclose(moved[mirror_of], moved)
    for t in longer.tendons:                                          # so are the tendons
        assert any(np.allclose(mirror(t.points, width), o.points, rtol=0, atol=1e-12) for o in longer.tendons), t.name
    tripod = load_robot("tripod")
    morph = LegMorph(tripod, legs_below(tripod, 0.036), 0.036)   # each leg spans the full width
    assert morph.names == ("legs:leg0", "legs:leg1", "legs:leg2") and morph.groups == ((0,), (1,), (2,))
    with pytest.raises(ValueError, match="each of the 3 legs once"):
        LegMorph(tripod, morph.legs, 0.036, groups=[(0, 1)])


def puppy_state(robot, K=6):
    """A Puppy state a few steps into a gait: ``(sim, x, x_prev, u, history)``."""
    sim = Simulator(robot)
    u = gait(robot, K)
    traj = sim.rollout(u, x0=sim.rest_state())
    x, x_prev = traj.x[-1], traj.x[-2]
    return sim, x, x_prev, u[-1], sim.system.initial_history(x_prev)


def test_tied_legs_force_and_mass_jacobians():
    design = puppy_legs()
    sim, x, x_prev, u, history = puppy_state(design.robot)
    J = design.force_jacobian(sim.system, x, x_prev, u, history)
    fd = fd_columns(design, sim, x, x_prev, u, history, [1e-7] * len(design))
    check_columns(J, fd, "Puppy: d grad / d (tied leg lengths)")
    single = DesignParameters(design.robot, [LegMorph(design.robot, design.kinds[0].legs, 0.04,
                                                      groups=[(0,), (1,), (2,), (3,)])])
    J1 = single.force_jacobian(sim.system, x, x_prev, u, history)
    assert relative_error(J[:, 0], J1[:, 0] + J1[:, 1]) <= 1e-12       # a group: the sum of its legs
    h = 1e-7
    for j in range(len(design)):
        d = h * np.eye(len(design))[j]
        fdm = (design.robot_at(d).node_masses - design.robot_at(-d).node_masses) / (2 * h)
        err = relative_error(design.node_mass_jacobian()[:, j], fdm)
        assert err <= 1e-6, f"d masses / d {design.names[j]}: relative error {err:.2e}"
    assert (design.total_mass_jacobian() > 0).all()


def rollout_columns(design, columns, steps, K=24):
    """``(relative errors, names)`` of the whole-rollout COM Jacobian's ``columns`` of
    ``design`` (from its rest state) against central differences with ``steps``."""
    robot = design.robot
    u = gait(robot, K)
    sim = Simulator(robot, newton=TIGHT)
    x0, h0, dx0, dh0 = sim.rest_sensitivity(design, tol=1e-13)
    traj = sim.rollout(u, x0=x0, history0=h0, params=design, dx0dtheta=dx0, dhistory0dtheta=dh0)
    errors = []
    for j, h in zip(columns, steps):
        runs = []
        for s in (1.0, -1.0):
            moved = Simulator(design.robot_at(design.values + s * h * np.eye(len(design))[j]), newton=TIGHT)
            runs.append(moved.rollout(u, x0=moved.rest_state(tol=1e-13)))
        fd = (runs[0].com - runs[1].com) / (2 * h)
        assert np.linalg.norm(fd) > 0, f"{design.names[j]}: finite differences vanish"
        errors.append(relative_error(traj.dcomdtheta[:, :, j], fd))
    return errors


def test_tied_legs_rollout_column_matches_finite_differences():
    """At the shipped Puppy all four feet tie for the lowest node, where the rest placement has
    a kink (the derivative is one-sided); with the hind legs 1 mm longer (``moved_to``) the
    hind feet are lowest, left and right alike (tied), and both columns are smooth."""
    design = puppy_legs().moved_to([0.001, 0.0])
    for name, err in zip(design.names, rollout_columns(design, [0, 1], [3e-7, 3e-7])):
        assert err <= RTOL_ROLLOUT, f"Puppy {name}: COM Jacobian column, relative error {err:.2e}"


def tripod_design(robot):
    regions = [region_from_boxes(robot, "middle_leg", [[0.055, -1, -1, 0.085, 0.036, 1]]),
               region_from_boxes(robot, "body", [[-1, 0.036, -1, 1, 1, 1]])]
    return DesignParameters(robot, [RegionalModuli(robot, regions), TendonRouting(robot, ["front_a", "back_a"]),
                                    LegMorph(robot, legs_below(robot, 0.036), 0.036)])


def moves(design):
    """The moved design of the issue's checks: the middle leg 3 mm longer, front_a's via point 1
    moved 1 mm inwards (-x, into the middle leg), the middle leg's modulus x1.5."""
    theta = design.values.copy()
    theta[design.names.index("legs:leg1")] += 0.003
    theta[design.names.index("routing:front_a[1].x")] -= 0.001
    theta[design.names.index("stiffness:middle_leg")] *= 1.5
    return theta


def test_moved_to_keeps_the_declaration_at_the_moved_robot():
    block = tripod_design(tripod_off_faces())
    theta = moves(block)
    new = block.moved_to(theta)
    want = block.robot_at(theta)
    assert np.array_equal(new.robot.mesh.points, want.mesh.points)
    assert np.array_equal(new.robot.element_modulus_scale, want.element_modulus_scale)
    assert all(np.array_equal(a.points, b.points) for a, b in zip(new.robot.tendons, want.tendons))
    assert new.names == block.names and np.array_equal(new.bounds, block.bounds)
    routing = [i for i, n in enumerate(new.names) if n.startswith("routing:")]
    others = np.setdiff1d(np.arange(len(new)), routing)
    assert np.array_equal(new.values[others], theta[others])     # absolute E, cumulative leg lengths
    # routing: the points as they are in the moved robot (the morph carried those in the middle leg)
    leader_points = np.concatenate([new.robot.tendons[t].points[s] for t, s in new.kinds[1].free])
    assert np.array_equal(new.values[routing], leader_points)
    assert np.allclose(new.values[routing], theta[routing], atol=0.0031) and not np.allclose(new.values[routing],
                                                                                           theta[routing])
    again = new.robot_at(new.values)
    assert np.array_equal(again.mesh.points, new.robot.mesh.points)
    assert all(np.allclose(a.points, b.points, rtol=0, atol=1e-15) for a, b in zip(again.tendons, new.robot.tendons))
    morph, morph0 = new.kinds[2], block.kinds[2]
    assert morph.hip_height == morph0.hip_height
    assert all(np.array_equal(a.elements, b.elements) for a, b in zip(morph.legs, morph0.legs))
    # a further step from the moved block is the same robot as that step from the original
    step = np.zeros(len(block))
    step[block.names.index("stiffness:body")] = 2e4
    step[block.names.index("routing:back_a[0].y")] = 5e-4
    assert np.allclose(new.robot_at(new.values + step).element_modulus_scale,
                       block.robot_at(theta + step).element_modulus_scale)
    tendons = new.robot_at(new.values + step).tendons
    assert np.allclose(tendons[new.robot.tendon_names.index("back_b")].points[0],
                       block.robot_at(theta + step).tendons[block.robot.tendon_names.index("back_b")].points[0])


def test_moved_design_rollout_columns_match_finite_differences():
    """At the moved design, one whole-rollout column per kind: the moved modulus, the moved
    via point's coordinate, the moved leg (Coulomb law). The leg's step is 5e-8 m: with the via
    point 1 mm deeper in the middle leg its column curves more (truncation 9.7e-7 at 1e-7 m,
    2.4e-7 at 5e-8 m, 7.8e-8 at 3e-8 m: the error falls as the step squared)."""
    new = tripod_design(tripod_off_faces()).moved_to(moves(tripod_design(tripod_off_faces())))
    names = ["stiffness:middle_leg", "routing:front_a[1].x", "legs:leg1"]
    columns = [new.names.index(n) for n in names]
    steps = [1e-5 * new.values[columns[0]], 1e-7, 5e-8]
    for name, err in zip(names, rollout_columns(new, columns, steps)):
        assert err <= RTOL_ROLLOUT, f"moved design, {name}: COM Jacobian column, relative error {err:.2e}"


@pytest.mark.parametrize("name", ["tripod", "puppy"])
def test_a_written_moved_design_declares_the_same_parameters(name, tmp_path):
    """``write_designed_robot`` of a design with longer legs writes a ``[design]`` table whose
    hip height (above the new lowest node) and regions (cell tags of the new mesh) select the
    same legs and regions: ``load_design`` on the written folder gives the parameters of
    ``moved_to`` (names, leaders, tets and values; the legs start again from 0 there)."""
    block = load_design(load_robot(name))
    theta = block.values.copy()
    theta[block.names.index("legs:leg1" if name == "tripod" else "legs:leg0+leg1")] += 0.003
    theta[block.names.index("stiffness:body")] *= 1.5
    theta[[i for i, n in enumerate(block.names) if n.endswith("[1].y")][0]] += 0.001
    new = block.moved_to(theta)
    back = load_design(load_robot(write_designed_robot(block, theta, tmp_path / "designed")))
    assert back.names == new.names
    assert [k.kind for k in back.kinds] == [k.kind for k in new.kinds]
    for a, b in zip(back.kinds[0].regions, new.kinds[0].regions):
        assert a.name == b.name and np.array_equal(a.elements, b.elements)
    assert back.kinds[1].leaders == new.kinds[1].leaders and list(back.kinds[1].followers) == list(new.kinds[1].followers)
    assert np.isclose(back.kinds[2].hip_height, new.kinds[2].hip_height, rtol=0, atol=1e-15)
    assert back.kinds[2].groups == new.kinds[2].groups
    for a, b in zip(back.kinds[2].legs, new.kinds[2].legs):
        assert np.array_equal(a.elements, b.elements)
    legs = [i for i, n in enumerate(new.names) if n.startswith("legs:")]
    others = np.setdiff1d(np.arange(len(new)), legs)
    assert np.allclose(back.values[others], new.values[others], rtol=1e-12, atol=1e-15)
    assert not back.values[legs].any()
    assert np.allclose(back.robot.mesh.points, new.robot.mesh.points, rtol=0, atol=1e-15)
    again = write_designed_robot(new, new.values, tmp_path / "again")     # the moved block writes its robot
    assert (again.parent / "mesh.vtu").is_file()
    assert np.allclose(load_robot(again).mesh.points, new.robot.mesh.points, rtol=0, atol=1e-15)
    assert load_design(load_robot(again)).names == new.names


def test_describe_changes_names_every_change_plainly():
    block = tripod_design(load_robot("tripod"))
    theta = moves(block)
    theta[block.names.index("routing:back_a[0].y")] += 0.0005
    rows = block.describe_changes(block.values, theta)
    assert [r["name"] for r in rows] == ["stiffness:middle_leg", "routing:front_a[1].x", "routing:back_a[0].y",
                                         "legs:leg1"]
    assert [r["unit"] for r in rows] == ["Pa", "m", "m", "m"]
    assert rows[0]["before"] == 1e5 and rows[0]["after"] == 1.5e5
    assert [r["description"] for r in rows] == [
        "Young's modulus of middle_leg x1.50 (1e+05 -> 1.5e+05 Pa)",
        "via point 1 of front_a moved 1.0 mm inwards (x)",          # 2 mm inside the middle leg's front face
        "via point 0 of back_a moved 0.5 mm up (y)",
        "leg1 3.0 mm longer"]
    assert block.describe_changes(theta, theta) == []
    puppy = puppy_legs()
    assert puppy.describe_changes([0, 0], [0, -0.002])[0]["description"] == "leg2 and leg3 2.0 mm shorter"
    with pytest.raises(ValueError, match="has 2 entries"):
        puppy.describe_changes([0], [0, 0])
