"""The layers' boundaries hold at import time: ``soft_envs.sim`` <- ``soft_envs.envs`` <- ``trajopt``.

Each import runs in a fresh interpreter with the forbidden packages blocked
(``sys.modules[name] = None`` makes ``import name`` raise ImportError), so a stray import
anywhere on the import path fails the test. The source is also scanned (AST) for imports that
cross a boundary the wrong way.
"""
from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _python(code: str) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=ROOT,
                          timeout=300)


def _with_blocked(blocked: list[str], code: str) -> str:
    return "import sys\n" + "".join(f"sys.modules[{name!r}] = None\n" for name in blocked) + code


def _loaded(prefix: str) -> str:
    return f"sorted(m for m in sys.modules if (m == {prefix!r} or m.startswith({prefix + '.'!r})) " \
           f"and sys.modules[m] is not None)"


def test_sim_imports_without_gymnasium():
    code = _with_blocked(["gymnasium"], f"""
import soft_envs.sim
from soft_envs.sim import Simulator, load_robot
robot = load_robot("tripod")
assert {_loaded("soft_envs.envs")} == [], {_loaded("soft_envs.envs")}
print("ok")
""")
    r = _python(code)
    assert r.returncode == 0 and r.stdout.strip().endswith("ok"), r.stderr


def test_hardware_imports_without_soft_envs_numba_scipy():
    """Playback reads a result file (numpy data) and talks to motor controllers: nothing on its
    import path may pull in the simulator."""
    code = _with_blocked(["soft_envs", "numba", "scipy"], """
import trajopt.hardware
import trajopt.hardware.cli
from trajopt.hardware import load_hardware_config, play_trajectory
from trajopt.results import Result
print("ok")
""")
    r = _python(code)
    assert r.returncode == 0 and r.stdout.strip().endswith("ok"), r.stderr


def test_import_trajopt_is_light():
    """``import trajopt`` (and building the command-line parser, i.e. ``trajopt --help``) loads
    no part of soft_envs; the library names still resolve on first use."""
    code = f"""
import sys
import trajopt
from trajopt.cli import build_parser
build_parser()
assert {_loaded("soft_envs")} == [], {_loaded("soft_envs")}
from trajopt import GaitSpec, Result
assert {_loaded("soft_envs")} == [], {_loaded("soft_envs")}
from trajopt import optimize_gait, measure_gait
assert "soft_envs.envs" in sys.modules
print("ok")
"""
    r = _python(code)
    assert r.returncode == 0 and r.stdout.strip().endswith("ok"), r.stderr


def test_registration_with_and_without_importing_the_package():
    code = """
import gymnasium as gym
env = gym.make("soft_envs:SoftPuppy-v0")
assert type(env.unwrapped).__name__ == "SoftPuppyEnv"
import soft_envs
env = gym.make("SoftPuppy-v0")
assert type(env.unwrapped).__name__ == "SoftPuppyEnv"
assert gym.spec("SoftPuppy-v0").max_episode_steps == soft_envs.MAX_EPISODE_STEPS
print("ok")
"""
    r = _python(code)
    assert r.returncode == 0 and r.stdout.strip().endswith("ok"), r.stderr


def _imported_modules(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module name) of every import statement in ``path``; relative imports are
    resolved against the file's package."""
    package = ".".join(path.relative_to(ROOT).with_suffix("").parts[:-1])
    out = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            out.append((node.lineno, module))
            out += [(node.lineno, f"{module}.{alias.name}") for alias in node.names]
    return out


def _violations(folder: str, forbidden: tuple[str, ...]) -> list[str]:
    bad = []
    for path in sorted((ROOT / folder).rglob("*.py")):
        for line, module in _imported_modules(path):
            if any(module == f or module.startswith(f + ".") for f in forbidden):
                bad.append(f"{path.relative_to(ROOT)}:{line} imports {module}")
    return bad


@pytest.mark.parametrize("folder, forbidden", [
    ("trajopt", ("soft_envs.sim",)),                             # trajopt goes through soft_envs.envs
    ("soft_envs", ("trajopt",)),                                 # arrows point one way
    ("soft_envs/sim", ("gymnasium", "soft_envs.envs", "soft_envs.render", "soft_envs.animation")),
    ("trajopt/hardware", ("soft_envs", "numba", "scipy")),
], ids=["trajopt-not-sim", "soft_envs-not-trajopt", "sim-not-envs", "hardware-not-simulator"])
def test_source_imports_respect_the_layers(folder, forbidden):
    assert _violations(folder, forbidden) == []


def test_the_source_scan_sees_imports():
    """The scan itself finds what it should (so an empty list above means something)."""
    found = {m for _, m in _imported_modules(ROOT / "soft_envs" / "envs" / "base.py")}
    assert "soft_envs.sim" in found and "soft_envs.sim.Simulator" in found
