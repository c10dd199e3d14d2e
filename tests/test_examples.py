"""Runnable documentation: every script in ``examples/`` runs, on tiny settings.

The project-wide convention is the environment variable ``SOFT_ENVS_QUICK=1``: every example
reads it and shrinks its work (iterations, timesteps, cycles) to a smoke test. Each script runs
in a subprocess with it set, in a temporary working directory (its TMPDIR a folder ``tmp`` in it),
with this checkout first on the import path. It must exit with 0, print what it promises
(``EXPECTED``, checked line by line), write the files it says it writes (``WRITES``) and write
nothing in the working directory outside ``results/``; a quick run writes names of its own. Every script in ``examples/`` needs an ``EXPECTED`` entry and must read
``SOFT_ENVS_QUICK``: a new example without them fails here until it is covered. No example
prints Gymnasium's deprecation warning of a ``-v0`` id (the project makes the latest ids).
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
                                r"saved results/tripod_walk_example_quick\.npz", r"front: \[", r"back: \["],
    "calibrate_from_markers.py": [r"\d+ samples of 8 markers over",
                                  r"youngs_modulus +\d+ -> \d+ \+- \S+ Pa",
                                  r"RMS marker error \d+\.\d+ mm -> \d+\.\d+ mm",
                                  r"wrote results/calibration_quick/fit/robot\.toml"],
    "gait_robustness.py": [r"\d+ replays of \d+ cycles .*running in-process", r"nominal speed +[+-]?\d+\.\d+ BL/min",
                           r"perturbed speed +median [+-]?\d+\.\d+, 5th-95th percentile",
                           r"wrote results/robustness_example_quick/report\.json"],
    "play_on_emulator.py": [r"robot 'tripod': motors \['front', 'back'\]",
                            r"30/30 steps sent in \d+\.\d+ s; .*motors confirmed stopped: front, back",
                            r"aborted: motor 'front' .*: tracking error \d+ counts",
                            r"(?m)^motors confirmed stopped: front, back$"],
    "task_suite.py": [r"trajopt, open loop +: advance [+-]\d+\.\d+ BL on SoftTripodClimbStep-v0 \(1 episodes, success \d+%",
                      r"PPO, 128 steps +: advance [+-]\d+\.\d+ BL on SoftTripodClimbStep-v0 \(1 episodes",
                      r"trajopt +: (\S+ / ){2}\S+ BL at 16\.5 / 8\.25 / 4\.125 ms: credible",
                      r"PPO +: (\S+ / ){2}\S+ BL at 16\.5 .* ms: credible .*, spread .*, (holds|does not hold)"],
    "rl_baseline.py": [r"trained 64 steps in \d+ s", r"PPO     : +[+-]?\d+\.\d+ BL/min, upright: (True|False)",
                       r"compared against: nothing here \(pass a trajopt result .*\); the headline "
                       r"\(benchmarks/results/rl_vs_trajopt_coulomb\.md\) compares PPO and SAC with the fastest gait "
                       r".*`trajopt optimize tripod --speed max`", r"exported: "],
    "puppy_turn.py": [r"puppy walk, \d+ steps x 8 motors", r"puppy turn, \d+ steps x 8 motors, .* along its path",
                      r"heading over the optimised horizon: [+-]\d+\.\d deg \(target \+90\)",
                      r"heading per cycle \[deg\], 6 cycles:( [+-]\d+\.\d){6}",
                      r"saved results/puppy_turn_example_quick\.npz"],
    "fastest_gait.py": [r"coarse cycle +\d+ steps, \d keyframes: +\d+\.\d+ BL/min",
                        r"chosen: \d+\.\d+ BL/min on a \d+-step cycle of \d keyframes, upright over \d+ cycles: True",
                        r"simulation steps of the whole search: [\d,]+",
                        r"saved results/tripod_fastest_example_quick\.npz and results/tripod_fastest_example_quick"
                        r"\.search\.csv"],
    "credible_gait.py": [r"default physics alone: [+-]?\d+\.\d+ BL/min at the default physics",
                         r"ensemble of 2, 4, 8 steps: [+-]?\d+\.\d+ BL/min at the default physics; members "
                         r"[+-]?\d+\.\d+ at 4 steps, [+-]?\d+\.\d+ at 2 steps, [+-]?\d+\.\d+ at 8 steps; "
                         r"credible [+-]?\d+\.\d+ BL/min",
                         r"replayed: [+-]?\d+\.\d+ at 8\.25 ms, [+-]?\d+\.\d+ at 4\.12 ms; spread \d+\.\d %",
                         r"saved results/tripod_credible_example_quick\.npz"],
    "codesign_tripod.py": [r"shipped design, fastest gait: \d+\.\d+ BL/min \(\d+-step cycle\), slowest \S+, spread "
                           r"\S+ % \((holds|does not hold)\)",
                           r"co-designed robot and gait: +\d+\.\d+ BL/min, slowest \S+, spread \S+ % \((holds|does not "
                           r"hold)\): \S+x at the slowest step; \d+ Gauss-Newton iterations",
                           r"its gait re-optimised from scratch: \d+\.\d+ BL/min, slowest \S+, spread \S+ % "
                           r"\((holds|does not hold)\): \S+x at the slowest step",
                           r"constraints checked in the written files: all hold",
                           r"robot results/tripod_codesign_example_quick/robot\.toml"],
    "motor_line.py": [r"speed +: +[+-]?\d+\.\d+ BL/min as optimised, +[+-]?\d+\.\d+ BL/min played by motors on "
                      r"their line \(off by \d+\.\d\d %, \d+ motor-steps held back\); peak torque 0\.\d+ N m",
                      r"torque-speed: +[+-]?\d+\.\d+ BL/min as optimised, .* \(off by 0\.\d\d %, "   # within 1 %
                      r"\d+ motor-steps held back\); .*worst line excess [+-]0\.\d %",
                      r"wrote results/motor_line_example_quick\.png"],
    "rough_ground.py": [r"plane y = 0 +: COM +[+-]\d+\.\d mm along x in 0\.7 s \([+-]\d+\.\d+ BL/min\), "
                        r"largest tilt +\d+\.\d deg, deepest foot \d\.\d\d mm into the ground",
                        r"rough, RMS 1 mm +: COM", r"rough, RMS 3 mm +: COM", r"step up 5 mm at x = 0\.2 m +: COM",
                        r"trench 5 mm deep, 3 cm long +: COM"],
    "benchmark_tasks.py": [r"SoftTripodWalk-v0 +obs 20, act 2, task parts -; 5 steps: reward +[+-]\d+\.\d+ = forward "
                           r"+[+-]\d+\.\d+ +ctrl +-\d+\.\d+ +survive +\+\d\.\d+ +success",
                           r"SoftPuppyRoughTerrain-v0 +obs 41, act 8, task parts \['terrain'\]",
                           r"SoftTripodReachGoal-v0 +obs 22, act 2, task parts \['goal_offset'\]",
                           r"SoftPuppyCarry-v0 +obs 50, act 8, task parts \['box_offset', 'box_velocity', 'box_axes'\]",
                           r"20 task ids made at difficulty 'medium'"],
    "carry_and_push.py": [r"SoftTripodCarry-v0 +easy +: robot +[+-]\d+\.\d mm, payload \d+\.\d g \(mu 0\.8\) moved "
                          r"+[+-]\d+\.\d mm, tilt +\d+\.\d deg; return +[+-]\d+\.\d+; ran 10 steps",
                          r"SoftTripodPushBox-v0 +easy +: robot +[+-]\d+\.\d mm, box \d+\.\d g pushed +[+-]\d+\.\d mm",
                          r"d\(box x after 0\.20 s\) / d amplitude: [+-]\d+\.\d+ mm exact; central differences "
                          r"[+-]\d+\.\d+ mm \(h = 1e-4\)",
                          r"trajopt push_box \(1 Gauss-Newton iterations\): the robot walks [+-]?\d+\.\d+ BL/min with the "
                          r"box ahead; on SoftTripodPushBox-v0 the box is pushed [+-]\d+\.\d+ BL \(\w+ at step \d+\)"],
    "robot_from_surface.py": [r"meshed quadruped\.obj: \d+ nodes, \d+ tets",
                              r"mass +body \d+\.\d g \+ payload \d+\.\d g on \d+ top nodes",
                              r"picture: results/quadruped_quick/quadruped\.png", r"iteration 1: objective \S+ -> \S+",
                              r"speed: [+-]?\d+\.\d+ body lengths/min over 1 cycles",
                              r"saved results/quadruped_quick/quadruped_walk\.npz"],
    "tune_rl.py": [r"SoftTripodWalk-v0 PPO: 2 trials scored \(256 steps each, training seed 100, episodes from seed 100\)",
                   r"trial +0: +[+-]\d+\.\d+ BL/min +\d+ s \(the defaults\)",
                   r"best: trial \d \([+-]\d+\.\d+ BL/min\); train with it:",
                   r"trajopt rl train SoftTripodWalk-v0 --algo ppo --n-envs 2 --timesteps 256 --vec-env dummy",
                   r"best minus the defaults: [+-]\d+\.\d+ BL/min", r"wrote results/tuning/example_quick/tuning\.json"],
}
#: files (relative to the working directory) an example must leave behind
WRITES = {
    "optimize_tripod_walk.py": ["results/tripod_walk_example_quick.npz", "results/tripod_walk_example_quick.json"],
    "calibrate_from_markers.py": ["results/calibration_quick/fit/robot.toml", "results/calibration_quick/fit/tracks.png",
                                  "results/calibration_quick/fit/calibration.json"],
    "gait_robustness.py": ["results/robustness_example_quick/report.json", "results/robustness_example_quick/samples.csv",
                           "results/robustness_example_quick/robustness.png"],
    "rl_baseline.py": ["results/tripod_ppo_example_quick.npz"],
    "task_suite.py": ["results/tripod_climb_step_example_quick.npz", "results/runs/climb_step_ppo_example_quick/model.zip"],
    "motor_line.py": ["results/motor_line_example_quick.png"],
    "tune_rl.py": ["results/tuning/example_quick/tuning.json", "results/tuning/example_quick/study.db"],
    "credible_gait.py": ["results/tripod_credible_example_quick.npz", "results/tripod_credible_example_quick.json"],
    "fastest_gait.py": ["results/tripod_fastest_example_quick.npz", "results/tripod_fastest_example_quick.search.csv",
                        "results/tripod_fastest_example_quick.search.md"],
    "puppy_turn.py": ["results/puppy_turn_example_quick.npz", "results/puppy_turn_example_quick.json"],
    "codesign_tripod.py": ["results/tripod_codesign_example_quick/robot.toml",
                           "results/tripod_codesign_example_quick/tripod_walk.npz",
                           "results/tripod_codesign_example_quick/codesign.md",
                           "results/tripod_codesign_example_quick/codesign.png"],
    "robot_from_surface.py": ["results/quadruped_quick/robot.toml", "results/quadruped_quick/quadruped.vtu",
                              "results/quadruped_quick/quadruped.png", "results/quadruped_quick/quadruped_walk.npz",
                              "results/quadruped_quick/quadruped_walk.json"],
}
#: modules an example needs beyond the core install (skipped with a reason when missing)
NEEDS = {"rl_baseline.py": "stable_baselines3", "tune_rl.py": "optuna", "task_suite.py": "stable_baselines3", "play_on_emulator.py": "serial", "robot_from_surface.py": "gmsh"}


def test_every_example_is_covered():
    """EXPECTED has an entry for exactly the scripts in examples/ (and WRITES, NEEDS name only
    those), and every script reads SOFT_ENVS_QUICK (so CI can run it on tiny settings)."""
    names = {p.name for p in EXAMPLES}
    assert len(names) >= 6, f"examples missing: {sorted(names)}"
    assert set(EXPECTED) == names, (f"examples without an EXPECTED entry: {sorted(names - set(EXPECTED))}; "
                                    f"entries without an example: {sorted(set(EXPECTED) - names)}")
    assert set(WRITES) <= names and set(NEEDS) <= names
    not_quick = [p.name for p in EXAMPLES if "SOFT_ENVS_QUICK" not in p.read_text()]
    assert not not_quick, f"examples that ignore SOFT_ENVS_QUICK: {not_quick}"


@pytest.mark.parametrize("script", EXAMPLES, ids=lambda p: p.name)
def test_example_runs_quick(script, tmp_path):
    if script.name in NEEDS:
        pytest.importorskip(NEEDS[script.name])
    (tmp_path / "tmp").mkdir()
    env = {**os.environ, "SOFT_ENVS_QUICK": "1", "MPLBACKEND": "Agg", "TMPDIR": str(tmp_path / "tmp"),
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
           "PYTHONWARNINGS": "always::DeprecationWarning"}          # shown, so that the check below sees them
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, f"{script.name} exited with {proc.returncode}:\n{proc.stdout}\n{proc.stderr}"
    out = proc.stdout
    for pattern in EXPECTED[script.name]:
        assert re.search(pattern, out), f"{script.name}: no match for {pattern!r} in its output:\n{out}"
    for name in WRITES.get(script.name, []):
        assert (tmp_path / name).is_file() and (tmp_path / name).stat().st_size > 0, f"{script.name}: no {name}"
    outside = sorted(p.name for p in tmp_path.iterdir() if p.name not in ("results", "tmp"))
    assert not outside, f"{script.name} wrote outside results/: {outside}"
    # the examples make the latest ids (issue #31): never Gymnasium's "SoftTripod-v0 is out of date"
    assert "is out of date" not in proc.stderr, f"{script.name} made a -v0 id:\n{proc.stderr[-2000:]}"


def test_quick_runs_have_their_own_file_names():
    """A quick run (SOFT_ENVS_QUICK=1) never replaces what the full run of the same example wrote:
    every file an example writes when quick is under a name or folder that says ``quick``."""
    not_quick = [(s, n) for s, names in WRITES.items() for n in names if "quick" not in n]
    assert not not_quick, f"quick runs writing the full run's names: {not_quick}"
    for script in EXAMPLES:
        if script.name in WRITES:
            assert re.search(r"quick", script.read_text().split('"""', 2)[-1]), script.name


def test_the_rl_example_says_what_it_compares_against(tmp_path):
    """examples/rl_baseline.py names the gait it compares the policy with and how it relates to
    the headline (#41): the default walk tracks 8 BL/min on a 72-step cycle, not the fastest gait
    (the headline's `--speed max`)."""
    import importlib.util

    import numpy as np

    from trajopt import Result
    spec = importlib.util.spec_from_file_location("rl_baseline_example", ROOT / "examples" / "rl_baseline.py")
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except ImportError as exc:                   # the example imports trajopt.rl
        pytest.skip(f"needs the RL extra: {exc}")
    K = 24 + 72
    walk = Result(robot="tripod", task="walk", motor_names=["front", "back"], dt=0.033, z=np.zeros(2),
                  u=np.zeros((K, 2)), u_post=np.zeros((K, 2)), target=np.zeros((K + 1, 2)), com=np.zeros((K + 1, 3)),
                  settings={"speed_bl_per_min": 8.0, "n_cycle": 72, "n_prep": 24})
    path = walk.save(tmp_path / "tripod_walk.npz")
    text = module.comparison(str(path))
    assert "tracks a 8 BL/min COM path on a 72-step cycle: it is not the fastest gait" in text
    assert "`trajopt optimize tripod --speed max`" in text
    walk.settings["search"] = {"runs": 12}
    fastest = walk.save(tmp_path / "tripod_fastest.npz")
    assert "a --speed max gait (the fastest within the motors' limits), as in the headline" in \
        module.comparison(str(fastest))
