"""Import boundary: ``trajopt.hardware`` needs only the standard library, numpy, pyserial (lazily) and
``trajopt.results`` -- never the simulator stack (DESIGN.md: playback reads a result file, numpy data)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("soft_envs", "numba", "scipy")
NOT_LOADED = HEAVY + ("serial", "gymnasium", "matplotlib", "meshio", "cvxopt", "torch", "stable_baselines3", "tqdm")
BLOCK = f"import sys\nfor name in {HEAVY!r}: sys.modules[name] = None  # importing them raises ImportError\n"
# Load the trajopt package without running trajopt/__init__.py (which imports the optimiser today).
STUB = ("import types\npkg = types.ModuleType('trajopt')\n"
        f"pkg.__path__ = [{str(ROOT / 'trajopt')!r}]\nsys.modules['trajopt'] = pkg\n")


def run_python(code: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=120)


def test_hardware_modules_import_no_heavy_module(tmp_path: Path) -> None:
    code = BLOCK + "sys.modules['serial'] = None\n" + STUB + f"""
import importlib, pkgutil
import trajopt.hardware as hw
modules = [m.name for m in pkgutil.iter_modules(hw.__path__)]
for name in modules:
    importlib.import_module('trajopt.hardware.' + name)
import trajopt.results
loaded = sorted(m for m in sys.modules if m.split('.')[0] in {NOT_LOADED!r} and sys.modules[m] is not None)
assert not loaded, loaded
print(len(modules))
"""
    result = run_python(code, tmp_path)
    assert result.returncode == 0, result.stderr
    assert int(result.stdout) >= 12  # every module of the package was imported


def test_play_dry_run_without_the_simulator_stack(tmp_path: Path) -> None:
    """Load a real result file and dry-run it through the ``trajopt play`` handler."""
    code = BLOCK + STUB + """
import numpy as np
from trajopt.results import Result
from trajopt.hardware import EXAMPLE_TRIPOD
from trajopt.cli.play import add_play_parser
import argparse
s = np.linspace(0, 1, 40)[:, None]
u = 0.004 * np.sin(np.pi * s) ** 2 * np.ones((1, 2))
Result(robot='tripod', task='walk', motor_names=['front', 'back'], dt=0.033, z=np.zeros(1), u=u, u_post=u,
       target=np.zeros((0, 2)), com=np.zeros((0, 3))).save('gait.npz')
parser = argparse.ArgumentParser(prog='trajopt')
add_play_parser(parser.add_subparsers(dest='command'))
args = parser.parse_args(['play', 'gait.npz', '--hardware', str(EXAMPLE_TRIPOD), '--dry-run'])
sys.exit(args.func(args))
"""
    result = run_python(code, tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().splitlines()[-1] == "dry run: 40 steps planned, nothing sent"


def test_plain_import_without_the_simulator_stack(tmp_path: Path) -> None:
    result = run_python(BLOCK + "import trajopt.hardware, trajopt.results\n", tmp_path)
    assert result.returncode == 0, result.stderr


def test_package_imports_without_pyserial(tmp_path: Path) -> None:
    code = ("import sys; sys.modules['serial'] = None\n" + STUB
            + "import trajopt.hardware as hw\nassert hw.load_hardware_config and hw.play_trajectory\n"
            + "try:\n    hw.RoboClaw('loop://')\nexcept ImportError as exc:\n    print(exc)\n")
    result = run_python(code, tmp_path)
    assert result.returncode == 0, result.stderr
    assert "pip install soft-envs[hardware]" in result.stdout
