"""Runnable documentation: every script in ``examples/`` runs, on tiny settings.

The project-wide convention is the environment variable ``SOFT_ENVS_QUICK=1``: every example
reads it and shrinks its work (iterations, timesteps, cycles) to a smoke test. Each script runs
in a subprocess with it set, in a temporary working directory (examples may write files
there), with this checkout first on the import path. It must exit with 0 and print what it
promises; for the examples listed in ``EXPECTED`` that is checked line by line, for any other
(new) example at least some output.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))

#: per example: regular expressions its output must contain (in any order)
EXPECTED = {
    "simulate_tripod.py": [r"tripod: \d+ nodes", r"COM moved [+-]\d+\.\d+ mm along x in 0\.5 s",
                           r"Newton iterations per step: \d", r"d COM_x\(final\) / d amplitude"],
    "gym_random_agent.py": [r"observation: 38 numbers", r"summed reward terms: \{'reward_forward'",
                            r"COM displacement: x [+-]\d+\.\d+ mm", r"saved a 480x360 frame to "],
    "optimize_tripod_walk.py": [r"iteration 1: objective \S+ -> \S+", r"speed per cycle \[BL/min\]: \[\S+\]",
                                r"saved tripod_walk\.npz", r"front: \[", r"back: \["],
    "play_on_emulator.py": [r"robot 'tripod': motors \['front', 'back'\]", r"30/30 steps sent in \d+\.\d+ s"],
    "rl_baseline.py": [r"trained 64 steps in \d+ s", r"PPO     : +[+-]?\d+\.\d+ BL/min, upright: (True|False)",
                       r"exported: "],
}
#: modules an example needs beyond the core install (skipped with a reason when missing)
NEEDS = {"rl_baseline.py": "stable_baselines3", "play_on_emulator.py": "serial"}


def test_expected_outputs_name_existing_examples():
    """Every entry of EXPECTED is a script in examples/ (new examples without an entry run too,
    with the generic check: add their expected output here)."""
    names = {p.name for p in EXAMPLES}
    assert names, "no examples found"
    assert not (set(EXPECTED) - names), f"EXPECTED names examples that no longer exist: {set(EXPECTED) - names}"


@pytest.mark.parametrize("script", EXAMPLES, ids=lambda p: p.name)
def test_example_runs_quick(script, tmp_path):
    if script.name in NEEDS:
        pytest.importorskip(NEEDS[script.name])
    env = {**os.environ, "SOFT_ENVS_QUICK": "1", "MPLBACKEND": "Agg",
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, f"{script.name} exited with {proc.returncode}:\n{proc.stdout}\n{proc.stderr}"
    out = proc.stdout
    for pattern in EXPECTED.get(script.name, [r"\S"]):
        assert re.search(pattern, out), f"{script.name}: no match for {pattern!r} in its output:\n{out}"
    if script.name == "optimize_tripod_walk.py":
        assert (tmp_path / "tripod_walk.npz").is_file() and (tmp_path / "tripod_walk.json").is_file()
    if script.name == "rl_baseline.py":
        assert (tmp_path / "runs" / "tripod_ppo.npz").is_file()
