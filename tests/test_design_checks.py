"""The independent check of a co-designed robot's written files (issue #29, trajopt/codesign/checks.py)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import tomlkit

from soft_envs.sim import load_robot
from soft_envs.sim.design import (DesignParameters, LegMorph, RegionalModuli, TendonRouting, legs_below,
                                  region_from_boxes, write_designed_robot)
from soft_envs.sim.robot_file import asset_path
from trajopt.codesign.checks import (DesignCheckError, check_designed_robot, format_checks, require_design_checks,
                                   signed_clearance)

TRIPOD = asset_path("tripod")


def _copy(tmp_path: Path, edit, name: str = "tripod") -> Path:
    """The shipped robot's robot.toml with ``edit(doc)`` applied, in tmp_path (mesh: the shipped file)."""
    src = asset_path(name)
    doc = tomlkit.parse(src.read_text(encoding="utf-8"))
    doc["robot"]["mesh"] = str(src.parent / str(doc["robot"]["mesh"]))
    edit(doc)
    out = tmp_path / "designed"
    out.mkdir(parents=True)
    (out / "robot.toml").write_text(tomlkit.dumps(doc), encoding="utf-8")
    return out


def _failed(checks) -> dict:
    return {c.name: c for c in checks if not c.passed}


@pytest.mark.parametrize("name", ["tripod", "puppy"])
def test_shipped_robots_pass_against_themselves(name):
    checks = check_designed_robot(asset_path(name), asset_path(name).parent)
    assert not _failed(checks), format_checks(checks)
    clearance = next(c for c in checks if c.name == "via points inside by the clearance")
    assert clearance.value == pytest.approx(0.002, abs=1e-9)       # the shipped points sit at exactly 2 mm
    table = format_checks(checks)
    assert table.startswith("| check |") and table.count("\n") == len(checks) + 2


def test_a_written_design_within_its_bounds_passes(tmp_path):
    robot = load_robot("tripod")
    design = DesignParameters(robot, [
        RegionalModuli(robot, [region_from_boxes(robot, "middle_leg", [[0.055, 0.0, 0.0, 0.085, 0.03, 0.04]])]),
        TendonRouting(robot, robot.tendon_names),
        LegMorph(robot, legs_below(robot, 0.03), 0.03)])
    theta = design.values.copy()
    theta[0] *= 2.5                                              # a stiffer middle leg
    theta[design.names.index("routing:front_a[1].z")] += 0.004    # a via point 4 mm sideways (mirror follows)
    theta[design.names.index("legs:leg1")] = 0.003                # the middle leg 3 mm longer
    written = write_designed_robot(design, theta, tmp_path / "designed")
    checks = require_design_checks(TRIPOD, written.parent)
    mass = next(c for c in checks if c.name == "total mass")
    assert mass.value > load_robot("tripod").total_mass            # the longer leg is heavier
    moduli = next(c for c in checks if c.name == "moduli within bounds")
    assert moduli.value == pytest.approx(2.5)


def test_signed_clearance_of_a_unit_tet():
    points = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    tets = np.array([[0, 1, 2, 3]])
    assert signed_clearance(points, tets, np.array([0.1, 0.1, 0.1])) == pytest.approx(0.1)
    assert signed_clearance(points, tets, np.array([0.2, 0.2, -0.3])) == pytest.approx(-0.3)     # below a face
    assert signed_clearance(points, tets, np.array([-1.0, -1.0, 0.0])) == pytest.approx(-np.sqrt(2))   # a vertex
    assert signed_clearance(points, tets, np.array([0.5, -1.0, -1.0])) == pytest.approx(-np.sqrt(2))   # an edge


@pytest.mark.parametrize("x, expected", [(0.079, 0.001), (0.0805, -0.0005)])
def test_a_via_point_too_close_or_outside_is_named(tmp_path, x, expected):
    def edit(doc):
        doc["tendons"][0]["points"][1][0] = x                    # front_a[1]: 2 mm from the leg's face at x = 0.08
    out = _copy(tmp_path, edit)
    failed = _failed(check_designed_robot(TRIPOD, out))
    assert set(failed) >= {"via points inside by the clearance"}
    assert failed["via points inside by the clearance"].value == pytest.approx(expected, abs=1e-9)
    with pytest.raises(DesignCheckError, match=r"(?s)designed/robot\.toml.*tendon point front_a\[1\]"):
        require_design_checks(TRIPOD, out)


def test_a_modulus_outside_the_bounds_is_named(tmp_path):
    def edit(doc):
        regions = tomlkit.aot()
        for name, factor, tets in (("soft", 0.5, [0, 1, 2]), ("stiff_leg", 3.5, [3, 4, 5])):
            t = tomlkit.table()
            t["name"], t["youngs_modulus"], t["tets"] = name, factor * 1e5, tets
            regions.append(t)
        doc["material"]["regions"] = regions
    out = _copy(tmp_path, edit)
    failed = _failed(check_designed_robot(TRIPOD, out))
    assert set(failed) == {"moduli within bounds"}
    assert failed["moduli within bounds"].value == pytest.approx(3.5)
    with pytest.raises(DesignCheckError, match=r"(?s)designed/robot\.toml.*region 'stiff_leg'.*3\.5 x") as err:
        require_design_checks(TRIPOD, out)
    assert "'soft'" not in str(err.value)
    assert not _failed(check_designed_robot(TRIPOD, out, modulus_bounds=(0.3, 4.0)))


def test_overlapping_regions_and_a_changed_density_are_found(tmp_path):
    def edit(doc):
        regions = tomlkit.aot()
        for name, tets in (("a", [0, 1]), ("b", [1, 2])):
            t = tomlkit.table()
            t["name"], t["youngs_modulus"], t["tets"] = name, 2e5, tets
            regions.append(t)
        doc["material"]["regions"] = regions
        doc["material"]["density"] = 130.0
    failed = _failed(check_designed_robot(TRIPOD, _copy(tmp_path, edit)))
    assert "tet 1 also in 'a'" in failed["regions disjoint"].detail
    assert "density" in failed["base material and payload unchanged"].detail
    assert "total mass" not in failed                             # denser is heavier: the floor holds


def test_a_shortened_leg_below_the_mass_floor(tmp_path):
    robot = load_robot("tripod")
    design = DesignParameters(robot, [LegMorph(robot, legs_below(robot, 0.03), 0.03)])
    theta = np.array([0.0, -0.0149, 0.0])                          # the middle leg 14.9 mm shorter: 97.8 %
    written = write_designed_robot(design, theta, tmp_path / "designed")
    failed = _failed(check_designed_robot(TRIPOD, written))
    assert "total mass" in failed
    m = failed["total mass"]
    assert m.value / (m.limit / 0.98) == pytest.approx(design.robot_at(theta).total_mass / robot.total_mass, rel=1e-9)
    with pytest.raises(DesignCheckError, match=r"(?s)designed/robot\.toml: .*97\.7\d* % of the source"):
        require_design_checks(TRIPOD, written)


def test_a_motor_speed_limit_changed(tmp_path):
    def edit(doc):
        doc["motors"][1]["max_speed_rpm"] = 150.0
    failed = _failed(check_designed_robot(TRIPOD, _copy(tmp_path, edit)))
    assert set(failed) == {"same motors"}
    assert "motor 'back': max_speed_rpm = 150.0 instead of 100.0" in failed["same motors"].detail


def test_a_tendon_moved_to_another_motor(tmp_path):
    def edit(doc):
        doc["motors"][0]["tendons"] = ["front_a"]
        doc["motors"][1]["tendons"] = ["back_a", "back_b", "front_b"]
    out = _copy(tmp_path, edit)
    failed = _failed(check_designed_robot(TRIPOD, out))
    assert "same motors" in failed
    with pytest.raises(DesignCheckError, match=r"(?s)designed/robot\.toml.*motor 'front': tendons = \['front_a'\]"):
        require_design_checks(TRIPOD, out)


def test_a_folder_that_does_not_load_fails_the_last_check(tmp_path):
    def edit(doc):
        doc["robot"]["colour"] = "red"                             # an unknown key: load_robot refuses it
    failed = _failed(check_designed_robot(TRIPOD, _copy(tmp_path, edit)))
    assert set(failed) == {"loads and simulates"}
    assert "colour" in failed["loads and simulates"].detail


def test_malformed_files_are_clear_errors_or_failed_checks(tmp_path):
    def no_density(doc):
        del doc["material"]["density"]
    with pytest.raises(ValueError, match=r"designed/robot\.toml: \[material\]\.density is missing"):
        check_designed_robot(TRIPOD, _copy(tmp_path / "a", no_density))

    def bad_region(doc):
        regions = tomlkit.aot()
        t = tomlkit.table()
        t["name"], t["tets"] = "no_modulus", [0]
        regions.append(t)
        doc["material"]["regions"] = regions
        doc["tendons"][1]["stiffness"] = 2e5
    failed = _failed(check_designed_robot(TRIPOD, _copy(tmp_path / "b", bad_region)))
    assert "region 'no_modulus': needs a youngs_modulus" in failed["moduli within bounds"].detail
    assert "tendon 'front_b': stiffness 200000.0 instead of 100000.0" in failed["same tendons"].detail
    assert "loads and simulates" in failed


def test_the_fixed_points_the_design_table_names_may_sit_on_the_surface(tmp_path):
    def edit(doc):
        doc["tendons"][0]["points"][0][1] = 0.0                  # front_a[0] on the foot's sole
    out = _copy(tmp_path / "a", edit)
    failed = _failed(check_designed_robot(TRIPOD, out))
    assert failed["via points inside by the clearance"].value == pytest.approx(0.0, abs=1e-12)

    def fixed_first(doc):
        edit(doc)
        doc["design"] = {"fixed_points": [0, -1]}
    checks = check_designed_robot(TRIPOD, _copy(tmp_path / "b", fixed_first))
    assert not _failed(checks)
    assert next(c for c in checks if c.name == "fixed points in the body").value == pytest.approx(0.0, abs=1e-12)
