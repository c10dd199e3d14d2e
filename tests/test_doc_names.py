"""Every dotted name of the project (``soft_envs.x.y``, ``trajopt.x``) and every project file
path (``benchmarks/x.py``, ``docs/x.md``, ...) that the docs, the README or a docstring names
exists: a moved or removed module leaves no stale pointer behind.

Scanned: README.md, docs/*.md (not CHANGELOG.md, whose rows name old places on
purpose), and the docstrings and comments of soft_envs/, trajopt/, benchmarks/ and examples/.
A dotted name resolves when its longest importable module prefix holds the rest as attributes
(``soft_envs.sim.Simulator.rollout``); a path when the file or folder is in the repository.
"""
from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("soft_envs", "trajopt")
#: ``soft_envs.sim.Simulator``, ``trajopt.rl``; not the second half of a file name (``x.soft_envs``)
DOTTED = re.compile(r"(?<![\w./-])((?:soft_envs|trajopt)(?:\.[A-Za-z_]\w*)+)")
#: ``benchmarks/x.py``, ``docs/x.md``, ``soft_envs/sim/x.py``, ``assets/tripod/robot.toml``
PATH = re.compile(r"(?<![\w./-])((?:soft_envs|trajopt|benchmarks|tests|examples|docs|assets)"
                  r"/[\w/.-]*\w\.(?:py|md|toml|vtu|npz|json))\b")
#: Sphinx cross-references relative to the module's package (``:mod:`.system```, ``~.cables.Q``)
RELATIVE = re.compile(r":(?:mod|class|func|meth|data|attr|exc):`~?(\.+)([A-Za-z_][\w.]*)`")


def scanned_files() -> list[Path]:
    files = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    for folder in (*PACKAGES, "benchmarks", "examples"):
        files += sorted((ROOT / folder).rglob("*.py"))
    return files


def resolves(name: str) -> bool:
    """Whether ``name`` is a module, or a module's attribute (chain)."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ModuleNotFoundError as e:
            if e.name and not e.name.startswith(PACKAGES):
                return True                       # an optional dependency is missing: cannot tell
            continue
        except ImportError:
            continue
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def stale_names(files: list[Path]) -> list[str]:
    """``["file:line: name"]`` of every dotted name or path that does not resolve."""
    out = []
    for f in files:
        rel = f.relative_to(ROOT)
        for n, line in enumerate(f.read_text(encoding="utf-8").splitlines(), 1):
            if f.suffix == ".py" and re.match(r"\s*(from|import)\s", line):
                continue                          # code: the import itself fails if stale
            for name in DOTTED.findall(line):
                name = name.rstrip(".")
                if name.endswith((".py", ".toml", ".md", ".npz", ".json")):
                    continue                      # a file name, checked as a path
                if not resolves(name):
                    out.append(f"{rel}:{n}: {name}")
            if f.suffix == ".py" and rel.parts[0] in PACKAGES:
                package = ".".join(rel.with_suffix("").parts[:-1])
                for dots, tail in RELATIVE.findall(line):
                    base = package.rsplit(".", len(dots) - 1)[0] if len(dots) > 1 else package
                    if not resolves(f"{base}.{tail}"):
                        out.append(f"{rel}:{n}: {dots}{tail}")
            for path in PATH.findall(line):
                if not (ROOT / path).exists():
                    out.append(f"{rel}:{n}: {path}")
    return out


def test_the_scan_finds_names_and_paths():
    """The patterns see the names of a sample text, so the test below cannot pass on nothing."""
    text = "see :mod:`soft_envs.sim.integrator` and ``trajopt.rl``, benchmarks/bench_sim.py."
    assert DOTTED.findall(text) == ["soft_envs.sim.integrator", "trajopt.rl"]
    assert PATH.findall(text) == ["benchmarks/bench_sim.py"]
    assert RELATIVE.findall("in :mod:`.system` and :func:`~..sim.cables.Q`") == [(".", "system"), ("..", "sim.cables.Q")]
    assert resolves("soft_envs.sim.Simulator.rollout") and not resolves("soft_envs.sim.no_such_module")


@pytest.mark.parametrize("group", ["docs", "code"])
def test_named_modules_and_files_exist(group):
    files = [f for f in scanned_files() if (f.suffix == ".md") == (group == "docs")]
    stale = stale_names(files)
    assert not stale, "names of things that do not exist (moved or removed?):\n" + "\n".join(stale)


def test_the_rl_zoo_pillow_downgrade_is_documented_with_its_workaround():
    """Installing rl_zoo3 downgrades Pillow (moviepy's pin, through sb3-team-hf-integration): the
    docs say so where the RL sweeps are documented, with the command that keeps Pillow (#41)."""
    text = (ROOT / "docs" / "scale.md").read_text()
    assert "rl_zoo3" in text and "pillow<12" in text and 'pip install rl_zoo3 "pillow>=12"' in text
