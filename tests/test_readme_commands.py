"""The README's shell commands run, in order, from an empty directory.

Every fenced ```bash block of README.md is read in order; each line (a trailing backslash
continues it, ``&&`` chains commands) is one command. The commands run in a fresh temporary
directory holding only copies of the repository files the commands name (``examples/...``,
``trajopt/hardware/example_tripod.toml``), so each one works on files the project ships or an
earlier README command wrote, as on a fresh clone. A command that exits non-zero fails the test
with its output, and so does one that prints Gymnasium's deprecation warning of a ``-v0`` id
(issue #31: the project's own commands make the latest ids).

Not run:
- ``pip install ...`` (the test runs in the environment those commands built) and
  ``python -m pytest`` (the suite itself);
- a command whose comment says ``(not run by the README test: REASON)``, e.g. playback on a
  real serial port (docs/testing.md).

Three runs of the same list:
- ``test_readme_commands_run_quick`` (default suite; 130 s on two cores both busy, load 10): each long
  command gets the quick settings of ``QUICK_ARGS`` appended (one Gauss-Newton iteration on
  12-step cycles, 2 robustness replays of one cycle, ...), ``python examples/...`` runs with
  ``SOFT_ENVS_QUICK=1``; the ``HEAVY`` commands (``trajopt rl ...``, ``trajopt sweep``,
  ``trajopt calibrate``) are left out (``test_readme_commands_name_files_that_exist`` still
  checks their files). It checks that the commands, their arguments and the files they hand on to each other
  are right, not the figures.
- ``test_readme_commands_run_quick_with_rl_and_sweeps`` (``-m slow``): the same with the HEAVY
  commands (64 RL steps, ``trajopt sweep --quick``, the calibration).
- ``test_readme_commands_run_as_written`` (``-m slow``; the README's own times add up to about
  half an hour on a quiet machine): the commands exactly as the README prints them.
"""
from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
NOT_RUN = re.compile(r"\(not run by the README test: ([^)]+)\)")

#: quick settings appended to a command whose words start with the key (argparse: the last wins)
QUICK_ARGS = {
    # the walk `trajopt play --dry-run` checks against the motors' speed limits keeps the paper's
    # cycle (24 + 2 x 72 steps): a 12-step cycle asks the motors for 6x the speed of the real gait,
    # beyond them under the Coulomb law (one iteration of the paper's law happened to stay small)
    ("trajopt", "optimize", "tripod", "--task", "walk", "--overwrite"): ["--iterations", "1", "--seeds", "1",
                                                                         "--keyframes", "2", "--cycles", "1"],
    ("trajopt", "optimize"): ["--iterations", "1", "--seeds", "1", "--cycle-steps", "12", "--prep-steps", "4",
                              "--keyframes", "2", "--cycles", "1"],
    ("trajopt", "evaluate"): ["--cycles", "1"],
    ("trajopt", "render"): ["--cycles", "1", "--every", "4"],
    ("trajopt", "rl", "train"): ["--timesteps", "64", "--n-envs", "1", "--hp", "n_steps=32", "--hp", "batch_size=32"],
    ("trajopt", "sweep"): ["--quick"],
    ("trajopt", "robustness"): ["--samples", "2", "--cycles", "1"],
    ("trajopt", "mesh"): ["--edge-length", "0.035"],
    # SOFT_ENVS_QUICK=1 makes it the quick co-design; its gait is not searched again from scratch
    # (a quick --speed max search, which the README's optimize commands above run)
    ("trajopt", "codesign"): ["--no-reoptimise"],
}
#: commands the default run leaves to ``-m slow`` even with quick settings (Ray's start, PyTorch's
#: import and training, a calibration that must converge: 20-40 s each on two quiet cores, minutes
#: under load)
HEAVY = [("trajopt", "rl"), ("trajopt", "sweep"), ("trajopt", "calibrate")]


def readme_commands(text: str) -> list[tuple[list[str], str | None]]:
    """``[(argv, reason not run or None)]`` of every command in the ```bash blocks, in order."""
    commands = []
    for block in re.findall(r"^```bash\n(.*?)^```", text, flags=re.S | re.M):
        for line in block.replace("\\\n", " ").splitlines():
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            marker = NOT_RUN.search(line)
            words = shlex.split(line, comments=True)
            argv: list[str] = []
            for word in words + ["&&"]:
                if word != "&&":
                    argv.append(word)
                    continue
                if argv[:2] == ["pip", "install"]:
                    reason = "installs packages into the environment the test runs in"
                elif argv[:3] == ["python", "-m", "pytest"]:
                    reason = "the test suite itself"
                else:
                    reason = marker.group(1) if marker else None
                commands.append((argv, reason))
                argv = []
    return commands


def _executable(argv: list[str]) -> list[str]:
    if argv[0] == "python":
        return [sys.executable, *argv[1:]]
    if argv[0] == "trajopt":
        script = Path(sys.executable).with_name("trajopt")
        return [str(script), *argv[1:]] if script.exists() else [sys.executable, "-c",
                                                                  "import sys; from trajopt.cli import main; "
                                                                  "sys.exit(main(sys.argv[1:]))", *argv[1:]]
    return argv


def _quick(argv: list[str]) -> list[str]:
    for prefix, extra in QUICK_ARGS.items():
        if tuple(argv[:len(prefix)]) == prefix:
            return argv + extra
    return argv


def _copy_shipped_files(commands, workdir: Path) -> list[str]:
    """Copy every repository path a command names into ``workdir``; the paths copied."""
    copied = []
    for argv, _ in commands:
        for word in argv:
            src = ROOT / word
            if "/" in word and not word.startswith("results") and src.exists() and not (workdir / word).exists():
                (workdir / word).parent.mkdir(parents=True, exist_ok=True)
                (shutil.copytree if src.is_dir() else shutil.copy2)(src, workdir / word)
                copied.append(word)
                if src.suffix == ".npz" and src.with_suffix(".json").exists():     # a result is .npz + .json
                    shutil.copy2(src.with_suffix(".json"), (workdir / word).with_suffix(".json"))
    return copied


def _run_all(workdir: Path, quick: bool, heavy: bool = True) -> None:
    commands = readme_commands(README.read_text())
    _copy_shipped_files(commands, workdir)
    env = {**os.environ, "MPLBACKEND": "Agg",      # TMPDIR kept: Ray's socket paths must stay short
           "PYTHONWARNINGS": "always::DeprecationWarning"}      # shown, so that the check below sees them
    env.pop("SOFT_ENVS_QUICK", None)
    if quick:
        env["SOFT_ENVS_QUICK"] = "1"
    for argv, reason in commands:
        if reason is not None or (not heavy and any(tuple(argv[:len(h)]) == h for h in HEAVY)):
            continue
        run = _quick(argv) if quick else argv
        start = time.monotonic()
        proc = subprocess.run(_executable(run), cwd=workdir, env=env, capture_output=True, text=True,
                              timeout=None if not quick else 900)
        assert proc.returncode == 0, (f"README command `{shlex.join(argv)}` (run as `{shlex.join(run)}`) exited "
                                      f"with {proc.returncode}:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
        # the commands make the latest ids (issue #31): never Gymnasium's "SoftTripod-v0 is out of date"
        assert "is out of date" not in proc.stderr, f"README command `{shlex.join(argv)}` made a -v0 id"
        print(f"{time.monotonic() - start:6.1f} s  {shlex.join(run)}")   # shown with -s: where the time goes


def test_readme_command_list_is_read_in_order():
    """The parser finds the README's commands: the set-up optimisation first (after its pip
    install), the calibration and mesh commands on shipped or generated files, nothing lost."""
    commands = readme_commands(README.read_text())
    run = [shlex.join(a) for a, reason in commands if reason is None]
    assert commands[0] == (["pip", "install", "-e", "."], "installs packages into the environment the test runs in")
    assert run[0] == "trajopt optimize tripod --task walk --out results/"
    assert any(c.startswith("trajopt calibrate tripod --markers examples/data/tripod_tracks.csv") for c in run)
    assert any(c.startswith("trajopt mesh examples/data/quadruped.obj") for c in run)
    assert len(run) >= 20
    marked = readme_commands("```bash\ntrajopt play r.npz --hardware hw.toml   # (not run by the README test: a real "
                             "serial port)\nls && pip install x\n```\n")
    assert marked == [(["trajopt", "play", "r.npz", "--hardware", "hw.toml"], "a real serial port"), (["ls"], None),
                      (["pip", "install", "x"], "installs packages into the environment the test runs in")]


def test_readme_commands_name_files_that_exist():
    """Every path a README command reads is shipped (exists in the repository) or under results/,
    where an earlier command writes; the sweep's output is the path its sweep file and
    docs/scale.md print (issue #31 item 7)."""
    commands = readme_commands(README.read_text())
    for argv, reason in commands:
        if reason is not None:
            continue
        for word in argv[1:]:
            looks_like_a_file = "/" in word or re.search(r"[A-Za-z_]\.[A-Za-z]{2,4}$", word)
            if looks_like_a_file and not word.startswith("-") and not word.startswith("results/"):
                assert (ROOT / word).exists(), f"README command `{shlex.join(argv)}` names {word}, which does not ship"
    sweeps = [a for a, _ in commands if a[:3] == ["trajopt", "sweep", "examples/sweep_speeds.toml"]]
    assert sweeps and all(a[a.index("--out") + 1] == "results/sweeps/speeds" for a in sweeps)
    for doc in (ROOT / "docs" / "scale.md", ROOT / "examples" / "sweep_speeds.toml"):
        outs = re.findall(r"sweep_speeds\.toml --out (\S+)", doc.read_text())
        assert outs and set(outs) == {"results/sweeps/speeds"}, f"{doc.name}: {outs}"


def test_readme_commands_run_quick(tmp_path):
    """Every README command but the HEAVY ones runs, in order, with the quick settings of QUICK_ARGS."""
    pytest.importorskip("gmsh")
    _run_all(tmp_path, quick=True, heavy=False)


@pytest.mark.slow
def test_readme_commands_run_quick_with_rl_and_sweeps(tmp_path):
    """Every README command runs, in order, with the quick settings of QUICK_ARGS (HEAVY included)."""
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("ray")
    pytest.importorskip("gmsh")
    _run_all(tmp_path, quick=True)


@pytest.mark.slow
def test_readme_commands_run_as_written(tmp_path):
    """Every README command runs, in order, exactly as written (about half an hour)."""
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("ray")
    pytest.importorskip("gmsh")
    _run_all(tmp_path, quick=False)
