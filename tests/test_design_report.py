"""The co-design picture and report (issue #29 item 3, trajopt/codesign/report.py)."""
from __future__ import annotations

import numpy as np
import pytest

from soft_envs.sim import load_robot
from soft_envs.sim.design import (DesignParameters, LegMorph, RegionalModuli, TendonRouting, legs_below,
                                  region_from_boxes, write_designed_robot)
from soft_envs.sim.robot_file import asset_path
from trajopt.codesign.checks import check_designed_robot
from trajopt.codesign.report import plot_robots_side_by_side, write_codesign_report

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    """The Tripod with a stiffer middle leg, a via point moved and the middle leg 3 mm longer,
    written to a folder; (design, theta, robot.toml)."""
    robot = load_robot("tripod")
    design = DesignParameters(robot, [
        RegionalModuli(robot, [region_from_boxes(robot, "middle_leg", [[0.055, 0.0, 0.0, 0.085, 0.03, 0.04]])]),
        TendonRouting(robot, ["front_a", "back_a"]),
        LegMorph(robot, legs_below(robot, 0.03), 0.03)])
    theta = design.values.copy()
    theta[0] *= 2.0
    theta[design.names.index("routing:front_a[0].z")] += 0.003
    theta[design.names.index("legs:leg1")] = 0.003
    return design, theta, write_designed_robot(design, theta, tmp_path_factory.mktemp("designed") / "robot")


def test_the_picture_is_a_png_of_both_robots(tmp_path, designed):
    design, theta, written = designed
    png = plot_robots_side_by_side(load_robot("tripod"), written, tmp_path / "robots.png")
    data = png.read_bytes()
    assert data.startswith(PNG) and len(data) > 30_000
    uniform = plot_robots_side_by_side("tripod", asset_path("tripod"), tmp_path / "same.png", titles=("a", "b"))
    assert uniform.read_bytes().startswith(PNG) and uniform.stat().st_size > 20_000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["robots.png", "same.png"]     # no temporaries left


def test_the_report_lists_every_change_the_ratio_and_the_checks(tmp_path, designed):
    design, theta, written = designed
    changes = [{"name": n, "before": float(b), "after": float(a), "unit": "Pa" if n.startswith("stiffness") else "m"}
               for n, b, a in zip(design.names, design.values, theta) if a != b]
    assert len(changes) == 3             # the modulus, one via point's z, the middle leg
    checks = check_designed_robot(asset_path("tripod"), written)
    picture = plot_robots_side_by_side(load_robot("tripod"), written, tmp_path / "figures" / "robots.png")
    before = {"speed_bl_per_min": 20.0, "n_cycle": 16, "n_keyframes": 4, "upright": True,
              "total_sim_steps": 12345, "wall_time_s": 61.5}
    after = {**before, "speed_bl_per_min": 26.0, "max_tilt_deg": 12.5}
    text = write_codesign_report(tmp_path / "report.md", robot_name="tripod", before=before, after=after,
                                 reoptimised={"speed_bl_per_min": 25.0, "upright": True}, changes=changes,
                                 checks=checks, picture=str(picture), settings={"vary": "routing,stiffness,legs",
                                                                                "contact": "coulomb"})
    assert (tmp_path / "report.md").read_text() == text
    assert "1.300x" in text and "1.250x" in text                  # co-designed and re-optimised over shipped
    for c in changes:
        assert f"| {c['name']} | {c['before']:.6g} | {c['after']:.6g} |" in text
    for c in checks:
        assert f"| {c.name} | yes |" in text
    assert "every constraint holds in the written files" in text
    assert "![shipped and co-designed robot](figures/robots.png)" in text
    assert "| max_tilt_deg | - | 12.5 | - |" in text and "| simulation steps | 12,345 |" in text
    assert "| contact | coulomb |" in text


def test_the_report_without_a_reoptimised_gait_and_with_a_failed_check(tmp_path):
    from trajopt.codesign.checks import DesignCheck
    checks = [DesignCheck("total mass", False, 0.06, 0.0666, "robot.toml: 88 % of the source's", "kg")]
    text = write_codesign_report(tmp_path / "r.md", robot_name="puppy", before={"speed_bl_per_min": 10.0},
                                 after={"speed": 12.0}, reoptimised=None, changes=[], checks=checks,
                                 picture="robots.png", settings={})
    assert "1.200x" in text and "re-optimised" not in text.lower().split("## settings")[0].split("## speed")[1]
    assert "FAILED: total mass" in text and "No design parameter changed." in text
    with pytest.raises(ValueError, match="before has no speed_bl_per_min"):
        write_codesign_report(tmp_path / "r2.md", robot_name="puppy", before={}, after={"speed": 1.0},
                              reoptimised=None, changes=[], checks=[], picture="p.png", settings={})
    assert not (tmp_path / "r2.md").exists()
    assert np.isfinite(12.0)


def test_the_picture_states_the_speed_gain_in_its_title(tmp_path, png_titles):
    """codesign.png's title says what the co-design gained (#41): baseline and new speed in BL/min
    and their ratio."""
    import trajopt.codesign.report as report_module
    titles = png_titles(report_module)
    plot_robots_side_by_side("tripod", asset_path("tripod"), tmp_path / "gain.png", speeds=(20.0, 26.0))
    assert titles[0].startswith("speed 20.00 -> 26.00 BL/min (x 1.30): shipped vs co-designed")
