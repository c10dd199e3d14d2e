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
import trajopt.cli.play
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
env = gym.make("soft_envs:SoftPuppy-v1")
assert type(env.unwrapped).__name__ == "SoftPuppyEnv"
import soft_envs
env = gym.make("SoftPuppy-v1")
assert type(env.unwrapped).__name__ == "SoftPuppyEnv"
assert gym.spec("SoftPuppy-v1").max_episode_steps == soft_envs.MAX_EPISODE_STEPS
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


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(packages: tuple[str, ...] = ("trajopt", "soft_envs")) -> dict[str, dict[str, str]]:
    """module -> {module it imports: "file:line"}, for every module of ``packages``: module-level
    and function-level imports alike (a lazy import still closes a cycle), relative imports
    resolved; ``from package import name`` points at the submodule when ``name`` is one, else
    at the package, and ``from module import name`` at the module."""
    files = {_module_name(p): p for pkg in packages for p in sorted((ROOT / pkg).rglob("*.py"))}
    graph: dict[str, dict[str, str]] = {}
    for module, path in files.items():
        package = module if path.name == "__init__.py" else module.rpartition(".")[0]
        edges: dict[str, str] = {}
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = package.split(".")
                    base = ".".join(parts[: len(parts) - node.level + 1] + ([node.module] if node.module else []))
                names = [f"{base}.{a.name}" if f"{base}.{a.name}" in files else base for a in node.names]
            else:
                continue
            for name in names:
                while name and name not in files:          # an imported name: its module
                    name = name.rpartition(".")[0]
                if name and name != module:
                    edges.setdefault(name, f"{path.relative_to(ROOT)}:{node.lineno}")
        graph[module] = edges
    return graph


def find_cycle(graph: dict[str, dict[str, str]]) -> list[str] | None:
    """One import cycle ``[a, b, ..., a]`` of ``graph``, or None (depth-first search)."""
    state: dict[str, int] = {}          # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in graph.get(node, {}):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        state[node] = 2
        path.pop()
        return None

    for start in sorted(graph):
        if start not in state:
            found = visit(start)
            if found:
                return found
    return None


def test_no_import_cycles():
    """No module of trajopt or soft_envs imports, directly or through others, itself (issue
    #27: the 8-file cycle cli -> sweep -> cli is gone; a lazy import inside a function counts)."""
    graph = import_graph()
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(
        [f"{a} ({graph[a][b]})" for a, b in zip(cycle, cycle[1:])] + [cycle[-1]])


def test_the_cycle_finder_finds_cycles():
    """The check itself sees a cycle, also one closed by a function-level import."""
    assert find_cycle({"a": {"b": 1}, "b": {"c": 2}, "c": {"a": 3}, "d": {"a": 1}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b": 1}, "b": {}}) is None
    graph = import_graph()
    assert "trajopt.sweep.runner" in graph["trajopt.robustness.study"]    # a function-level import
    assert "trajopt.results" in graph["trajopt.cli.play"]                 # ... resolved to a module
    assert "trajopt.cli.commands" in graph["trajopt.cli"]                 # relative, in a package


def test_the_wheel_lists_every_package():
    """``pyproject.toml`` names every package of the source tree (a missing one, as
    ``trajopt.codesign`` once was, is absent from a non-editable install)."""
    import tomllib
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for pkg in ("soft_envs", "trajopt")
             for p in (ROOT / pkg).rglob("__init__.py")}
    assert found - listed == set()
    assert listed - found == {"soft_envs.assets"}          # the shipped robots, from assets/ (package-dir)
