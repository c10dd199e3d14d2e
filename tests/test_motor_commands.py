"""The motor model on the command line (issue #38): ``trajopt optimize --motor-model`` (and the
``--no-motor-limit`` alias), resuming results of before the model, and ``trajopt play
--dry-run`` against the gearbox's ``max_torque``."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from trajopt.cli import main
from trajopt.optim.motor_limit import motor_model_of
from trajopt.optim.start import check_resume
from trajopt.results.motor_load import load_report, recorded_torque
from trajopt.results.result import Result

from .test_motor_limit import copy_robot

QUICK_ARGS = ["--prep-steps", "6", "--cycle-steps", "24", "--iterations", "2", "--seeds", "1", "--cycles", "1",
              "--speed", "20", "--quiet"]


def _optimize(robot: str, out: Path, name: str, *extra: str) -> Result:
    assert main(["optimize", robot, *QUICK_ARGS, "--out", str(out), "--name", name, *extra]) == 0
    return Result.load(out / f"{name}.npz")


@pytest.fixture(scope="module")
def made(tmp_path_factory) -> dict[str, Result]:
    out = tmp_path_factory.mktemp("motor_models")
    return {"torque-speed": _optimize("tripod", out, "line"), "speed": _optimize("tripod", out, "speed",
                                                                                    "--motor-model", "speed"),
            "ideal": _optimize("tripod", out, "ideal", "--motor-model", "ideal"),
            "alias": _optimize("tripod", out, "alias", "--no-motor-limit")}


def test_each_model_is_recorded_and_no_motor_limit_is_ideal(made):
    assert {k: r.settings["motor_model"] for k, r in made.items()} == {
        "torque-speed": "torque-speed", "speed": "speed", "ideal": "ideal", "alias": "ideal"}
    assert made["torque-speed"].settings["motor_line"]["max_torque_nm"] == [0.196, 0.196]
    assert made["speed"].settings["motor_line"] is None and made["speed"].settings["motor_limit"] is not None
    assert made["ideal"].settings["motor_limit"] is None
    assert np.array_equal(made["ideal"].z, made["alias"].z) and np.array_equal(made["ideal"].u_post,
                                                                               made["alias"].u_post)
    assert not np.array_equal(made["torque-speed"].z, made["speed"].z)       # the line binds on this gait


def test_both_flags_at_once_are_refused(capsys, tmp_path):
    with pytest.raises(SystemExit) as exc:
        main(["optimize", "tripod", "--motor-model", "speed", "--no-motor-limit", "--out", str(tmp_path)])
    assert exc.value.code == 2 and "not allowed with argument" in capsys.readouterr().err


def test_results_of_before_the_model_read_as_speed_or_ideal_and_resume_under_it(made):
    old = Result(**{**made["speed"].__dict__, "settings": {k: v for k, v in made["speed"].settings.items()
                                                           if k not in ("motor_model", "motor_line")}})
    assert motor_model_of(old.settings) == "speed"
    assert motor_model_of({"motor_limit": None}) == "ideal"
    asked = {**made["speed"].settings}
    check_resume(old, "walk", asked, None)                                   # --motor-model speed: resumes
    with pytest.raises(ValueError, match=r"cannot resume: the settings differ .*'motor_model': \('speed', "
                                         r"'torque-speed'\)"):
        check_resume(old, "walk", {**asked, "motor_model": "torque-speed",
                                   "motor_line": made["torque-speed"].settings["motor_line"]}, None)


def test_the_load_is_recorded_and_reported(made):
    res = made["torque-speed"]
    tau = recorded_torque(res)
    assert tau.shape == (len(res.u) + 1, 2) and (tau >= 0).all() and tau[0].max() < 1e-3     # at rest: no load
    report = load_report(res, tau)
    assert report.peak_torque == pytest.approx(tau.max(axis=0))
    assert (report.margin >= -0.01).all() and not report.over_max_torque.any()


def test_play_refuses_a_gait_beyond_max_torque_unless_forced(tmp_path, capsys):
    """A Tripod whose gearboxes allow 0.05 N m, a gait made under the speed limit alone (which
    knows nothing of the torque): ``play --dry-run`` prints each motor's peak torque and margin,
    refuses (exit 2, nothing planned), and plays it with ``--force``."""
    from trajopt.hardware import EXAMPLE_TRIPOD
    toml = copy_robot("tripod", tmp_path / "weak")
    toml.write_text(toml.read_text().replace("max_torque = 0.196", "max_torque = 0.05"))
    res = _optimize(str(toml), tmp_path, "weak", "--motor-model", "speed")
    peak = np.array(res.evaluation["motor_load"]["peak_torque_nm"])
    assert peak.max() > 0.05 * 1.01
    capsys.readouterr()
    play = ["play", str(tmp_path / "weak.npz"), "--hardware", str(EXAMPLE_TRIPOD), "--dry-run",
            "--ignore-robot-mismatch"]
    assert main(play) == 2
    err = capsys.readouterr().err
    assert "predicted load of each motor" in err and f"peak {peak[0]:.3f} N m" in err and "line margin" in err
    assert "refused: the gait loads motor(s) beyond their gearbox's max_torque" in err and "--force" in err
    assert "dry run" not in err
    assert main([*play, "--force"]) == 0
    assert "refused" not in capsys.readouterr().err


def test_play_accepts_a_gait_made_under_the_line(made, tmp_path, capsys):
    from trajopt.hardware import EXAMPLE_TRIPOD
    path = made["torque-speed"].save(tmp_path / "line")
    capsys.readouterr()
    assert main(["play", str(path), "--hardware", str(EXAMPLE_TRIPOD), "--dry-run"]) == 0
    err = capsys.readouterr().err
    assert "predicted load of each motor" in err and "refused" not in err and "beyond the torque-speed line" not in err


def test_a_result_beyond_the_line_it_records_is_refused(made, tmp_path):
    """A result's checks (on every load and save) hold ``u`` to the line it was made under, with
    the load torques it records: torques tripled put its steps beyond the line."""
    res = made["torque-speed"]
    res.save(tmp_path / "fine")
    edited = Result(**{**res.__dict__, "evaluation": {**res.evaluation, "motor_load": {
        **res.evaluation["motor_load"], "torque_nm": (3 * np.array(res.evaluation["motor_load"]["torque_nm"])).tolist()}}})
    with pytest.raises(ValueError, match=r"field 'u' breaks the motors' torque-speed line it was made under by "
                                         r"\d+\.\d\d % \(motor '(front|back)', step \d+; tolerance 1 %"):
        edited.save(tmp_path / "edited")
