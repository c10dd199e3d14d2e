"""The ``trajopt`` command line on bad input and faults (issue #16 items 4 and 7, issue #20's
output items): one line naming the argument or file and exit code 2, outputs never replaced
without --overwrite, checkpoints beside the finished result, a failure's reason printed, plain
progress lines in log files, and one results folder."""
from __future__ import annotations

import argparse
import contextlib
import io
import shutil
import sys
from pathlib import Path

import pytest

from trajopt.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]
# without the motors' limit: an 8-step cycle under it barely moves, so Gauss-Newton stops at once
# (ftol) where these tests need it to run every iteration asked for (the limit: test_motor_limit.py)
TINY = ["--iterations", "1", "--prep-steps", "2", "--cycle-steps", "8", "--keyframes", "2", "--seeds", "0",
        "--cycles", "1", "--no-motor-limit"]


def run(argv, capsys) -> tuple[int, str, str]:
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:              # argparse
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """A one-iteration Tripod walk through ``trajopt optimize`` (its output is tested below)."""
    out = tmp_path_factory.mktemp("results")
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = main(["optimize", "tripod", *TINY, "--out", str(out)])
    assert code == 0, stderr.getvalue()
    return out / "tripod_walk.npz", stdout.getvalue(), stderr.getvalue()


def bad_argument_cases(result: str, tmp: str) -> list[tuple[list[str], str]]:
    opt = ["optimize", "tripod", *TINY, "--out", tmp]
    train = ["rl", "train", "tripod", "--timesteps", "8", "--n-envs", "1", "--vec-env", "dummy", "--out", tmp]
    return [
        ([*opt, "--keyframes", "0"], "--keyframes"), ([*opt, "--speed", "nan"], "--speed"),
        ([*opt, "--speed", "-1"], "--speed"), ([*opt, "--heading", "nan"], "--heading"),
        ([*opt, "--heading", "inf"], "--heading"), ([*opt, "--iterations", "-3"], "--iterations"),
        ([*opt, "--iterations", "1.5"], "--iterations"), ([*opt, "--angle", "95"], "--angle"),
        ([*opt, "--seeds", "-1"], "--seeds"), ([*opt, "--cycles", "0"], "--cycles"),
        ([*opt, "--cycle-steps", "0"], "--cycle-steps"), ([*opt, "--prep-steps", "-1"], "--prep-steps"),
        ([*opt, "--keyframes", "9"], "--keyframes 9 must be at most --cycle-steps 8"),
        (["evaluate", result, "--cycles", "0"], "--cycles"),
        (["evaluate", result, "--cycles", "100000"], "--cycles"), ([*opt, "--name", "../x"], "--name"),
        (["render", result, "--every", "0", "--gif", f"{tmp}/a.gif"], "--every"),
        (["render", result, "--size", "0x0", "--gif", f"{tmp}/b.gif"], "--size"),
        (["render", result, "--size", "big", "--gif", f"{tmp}/c.gif"], "--size"),
        (["render", result, "--cycles", "0", "--gif", f"{tmp}/d.gif"], "--cycles"),
        (["export", result, "--cycles", "-1", "--vtu", f"{tmp}/vtu"], "--cycles"),
        (["mesh", "body.stl", "--out", tmp, "--scale", "0"], "--scale"),
        (["mesh", "body.stl", "--out", tmp, "--scale", "nan"], "--scale"),
        (["mesh", "body.stl", "--out", tmp, "--edge-length", "-1"], "--edge-length"),
        (["mesh", "body.stl", "--out", tmp, "--density", "inf"], "--density"),
        ([*train[:3], "--timesteps", "0"], "--timesteps"), ([*train, "--n-envs", "0"], "--n-envs"),
        ([*train, "--incline", "nan"], "--incline"), ([*train, "--frame-skip", "0"], "--frame-skip"),
        ([*train, "--seed", "-1"], "--seed"), ([*train, "--episode-steps", "0"], "--episode-steps"),
        ([*train, "--checkpoint-every", "0"], "--checkpoint-every"),
        (["rl", "evaluate", tmp, "--cycles", "0"], "--cycles"),
        (["rl", "evaluate", tmp, "--reset-noise", "-1"], "--reset-noise"),
        (["rl", "export", tmp, "--cycles", "0"], "--cycles"),
        (["play", result, "--hardware", "hw.toml", "--loops", "0"], "--loops"),
    ]


def test_every_numeric_argument_is_checked(tiny, tmp_path, capsys):
    """Each bad value ends in one line naming the argument, exit code 2, nothing written."""
    failures = []
    for argv, name in bad_argument_cases(str(tiny[0]), str(tmp_path)):
        code, out, err = run(argv, capsys)
        lines = err.strip().splitlines()
        if not (code == 2 and len(lines) == 1 and name in lines[0]):
            failures.append(f"{' '.join(argv[:2])} ... {argv[-2:]}: exit {code}, stderr {err[-300:]!r}")
    assert not failures, "\n".join(failures)
    assert list(tmp_path.iterdir()) == []


def test_unwritable_outputs_are_refused_before_any_work(tiny, tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a directory")
    for argv, name in [(["optimize", "tripod", "--out", blocker / "sub"], "--out"),
                       (["plot", tiny[0], "--out", blocker], "--out"),
                       (["render", tiny[0], "--gif", blocker / "x.gif"], "--gif"),
                       (["export", tiny[0], "--vtu", blocker], "--vtu")]:
        code, _, err = run(argv, capsys)
        assert code == 2 and name in err and "a_file" in err and len(err.strip().splitlines()) == 1, err


def test_outputs_are_never_replaced_without_overwrite(tiny, tmp_path, capsys):
    result = tiny[0]
    commands = {"plot": ["plot", result, "--out", tmp_path / "plots"],
                "render": ["render", result, "--gif", tmp_path / "r.gif", "--every", "5", "--size", "64x48",
                           "--cycles", "1"],
                "export": ["export", result, "--vtu", tmp_path / "vtu", "--cycles", "1"]}
    for name, argv in commands.items():
        assert run(argv, capsys)[0] == 0, name
        before = {p: p.stat().st_mtime_ns for p in tmp_path.rglob("*") if p.is_file()}
        code, _, err = run(argv, capsys)
        assert code == 2 and "exists already" in err and "--overwrite" in err, (name, err)
        assert {p: p.stat().st_mtime_ns for p in tmp_path.rglob("*") if p.is_file()} == before
        assert run([*argv, "--overwrite"], capsys)[0] == 0, name
    assert not [p for p in tmp_path.rglob("*") if p.name.startswith(".")]       # no temporaries


def test_optimize_says_what_the_status_means_where_the_files_are_and_what_next(tiny):
    path, out, err = tiny
    assert f"saved {path} and {path.with_suffix('.json')}" in out
    assert "status            max_iter: ran all the Gauss-Newton iterations asked for" in out
    assert "not a failure" in out
    assert f"trajopt render {path}" in out and f"trajopt plot {path}" in out
    assert "Gauss-Newton iteration 1/1: objective" in err and "\r" not in err       # plain lines in a log
    # the target is the tracked COM path's speed, not enforced (#41)
    assert "tracking target   8 BL/min: the speed of the target COM path the optimiser tracks, not enforced" in out
    assert not path.with_name("tripod_walk.partial.npz").exists()


def test_a_finished_result_is_never_replaced_and_checkpoints_go_beside_it(tiny, tmp_path, monkeypatch, capsys):
    out = tmp_path / "results"
    out.mkdir()
    finished = out / "tripod_walk.npz"
    shutil.copy(tiny[0], finished)
    shutil.copy(tiny[0].with_suffix(".json"), finished.with_suffix(".json"))
    original = finished.read_bytes()
    argv = ["optimize", "tripod", *TINY, "--iterations", "3", "--out", out]
    code, _, err = run(argv, capsys)
    assert code == 2 and "tripod_walk.npz: a result of this name exists" in err and "--overwrite" in err

    import trajopt.optimize_run as commands
    real = commands.optimize_gait

    def interrupted_after_one_iteration(*args, callback, **kwargs):       # Ctrl-C during iteration 2
        def once(entry, partial):
            callback(entry, partial)
            raise KeyboardInterrupt
        return real(*args, callback=once, **kwargs)
    monkeypatch.setattr(commands, "optimize_gait", interrupted_after_one_iteration)
    code, _, err = run([*argv, "--overwrite"], capsys)
    assert code == 130 and "tripod_walk.partial.npz" in err
    assert finished.read_bytes() == original                              # the finished result is intact
    partial = out / "tripod_walk.partial.npz"
    from trajopt.results.result import Result
    assert Result.load(partial).status == "interrupted" and len(Result.load(partial).history) == 1
    code, _, err = run(argv, capsys)                                      # neither is replaced silently
    assert code == 2 and "interrupted run" in err and "--resume" in err
    code, _, err = run([*argv, "--resume"], capsys)
    assert code == 2 and "--overwrite" in err

    monkeypatch.setattr(commands, "optimize_gait", real)
    code, out_text, err = run([*argv, "--resume", "--overwrite"], capsys)
    assert code == 0 and "resuming" in out_text, err
    assert not partial.exists() and not partial.with_suffix(".json").exists()
    assert len(Result.load(finished).history) == 3 and finished.read_bytes() != original


def test_evaluate_prints_the_reason_of_a_failed_simulation(tiny, monkeypatch, capsys):
    from soft_envs.envs import SimulationError, SoftRobotEnv

    def fail(self, u, dudz=None, **kw):
        raise SimulationError("step 3: Newton did not converge (injected)")
    monkeypatch.setattr(SoftRobotEnv, "rollout", fail)
    code, out, err = run(["evaluate", tiny[0]], capsys)
    assert code == 1 and "FAILED: step 3: Newton did not converge (injected)" in out
    assert "nan" not in out.lower()


def test_render_mp4_without_the_video_extra_fails_before_rendering(tiny, tmp_path, monkeypatch, capsys):
    import soft_envs.render
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)

    def no_rendering(*args, **kwargs):
        raise AssertionError("rendered although the MP4 cannot be written")
    monkeypatch.setattr(soft_envs.render.Renderer, "render", no_rendering)
    code, _, err = run(["render", tiny[0], "--mp4", tmp_path / "r.mp4"], capsys)
    assert code == 2 and "video extra" in err and "pip install" in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_render_help_documents_every_option():
    parser = build_parser()
    render = parser._subparsers._group_actions[0].choices["render"]
    documented = {a.option_strings[0]: a.help for a in render._actions if a.option_strings}
    for option in ("--gif", "--mp4", "--cycles", "--every", "--size", "--overwrite"):
        assert documented.get(option), option


def test_commands_write_under_one_results_folder(tiny, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    parser = build_parser()
    assert parser.parse_args(["optimize", "tripod"]).out == Path("results")
    assert parser.parse_args(["plot", "r.npz"]).out == Path("results/plots")
    assert parser.parse_args(["rl", "train", "tripod"]).out == Path("results/runs")
    code, out, _ = run(["render", tiny[0], "--every", "9", "--size", "64x48", "--cycles", "1"], capsys)
    assert code == 0 and (tmp_path / "results" / "tripod_walk.gif").is_file()
    assert run(["export", tiny[0], "--cycles", "1"], capsys)[0] == 0
    assert (tmp_path / "results" / "paraview" / "tripod_walk" / "tripod_walk.pvd").is_file()
    assert "/results/" in (ROOT / ".gitignore").read_text().split()


def test_the_rl_example_does_not_collide_with_the_readme_command():
    text = (ROOT / "examples" / "rl_baseline.py").read_text()
    assert 'NAME = "tripod_ppo_example_quick" if QUICK else "tripod_ppo_example"' in text
    assert 'out="results/runs", name=NAME' in text
    assert "tripod_ppo_example" not in (ROOT / "README.md").read_text()   # the README's runs are tripod_ppo_seedN


def _output_dir_options(parser, prefix=()):
    """``(command words, option)`` of every option of every (sub)command that names an output folder."""
    from trajopt.argtypes import output_dir
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for word, sub in action.choices.items():
                yield from _output_dir_options(sub, (*prefix, word))
        elif action.type is output_dir:
            yield prefix, action.option_strings[-1]


def test_an_output_folder_that_is_an_existing_file_is_refused_by_every_command(tmp_path, capsys):
    """``--out FILE`` (issue #26 item 7): exit 2 and one line naming the argument and the path,
    for every command that writes into a folder (optimize, plot, export, mesh, calibrate,
    robustness, sweep, rl train ...); nothing is written."""
    blocker = tmp_path / "a_file"
    blocker.write_text("not a directory")
    options = list(_output_dir_options(build_parser()))
    commands = {words[0] if words[0] != "rl" else " ".join(words) for words, _ in options}
    assert {"optimize", "plot", "export", "mesh", "calibrate", "robustness", "sweep", "rl train"} <= commands
    for words, option in options:
        code, out, err = run([*words, option, blocker], capsys)
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1 and f"argument {option}" in lines[0], (words, option, err)
        assert str(blocker) in lines[0] and "not a directory" in lines[0], (words, option, err)
    assert blocker.read_text() == "not a directory" and sorted(tmp_path.iterdir()) == [blocker]


def test_interpolation_is_an_option_of_every_optimisation(tmp_path, capsys):
    """``--interpolation {hermite,linear}`` (default: the task's) reaches the gait and is recorded;
    a bad value is refused naming the option; ``--resume`` refuses a checkpoint of the other
    interpolation (RESUME_KEYS) and continues one of the same."""
    from trajopt.optimize_run import OptimizeRun
    from trajopt.results.result import Result
    parser = build_parser()
    assert parser.parse_args(["optimize", "puppy"]).interpolation is None       # the task's
    assert parser.parse_args(["optimize", "puppy", "--interpolation", "linear"]).interpolation == "linear"
    assert OptimizeRun.from_mapping(vars(parser.parse_args(
        ["optimize", "puppy", "--task", "turn", "--interpolation", "hermite"]))).interpolation == "hermite"
    code, _, err = run(["optimize", "tripod", *TINY, "--out", tmp_path, "--interpolation", "cubic"], capsys)
    assert code == 2 and "--interpolation" in err and not list(tmp_path.iterdir())

    code, _, err = run(["optimize", "tripod", *TINY, "--out", tmp_path, "--interpolation", "linear"], capsys)
    assert code == 0, err
    res = Result.load(tmp_path / "tripod_walk.npz")
    assert res.settings["interpolation"] == "linear"
    res.status = "interrupted"
    res.save(tmp_path / "other.partial.npz")
    argv = ["optimize", "tripod", *TINY, "--out", tmp_path, "--name", "other", "--resume"]
    code, _, err = run(argv, capsys)                                  # the default, hermite: refused
    assert code == 2 and "interpolation" in err and not (tmp_path / "other.npz").exists()
    code, _, err = run([*argv, "--interpolation", "linear"], capsys)
    assert code == 0, err
    assert Result.load(tmp_path / "other.npz").settings["interpolation"] == "linear"
