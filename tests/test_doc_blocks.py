"""Every ```python block of README.md and docs/*.md runs as printed.

The blocks of one file run in order in one namespace (a later block may use what an earlier one
defined, as a reader pasting them into one session would), from an empty temporary working
directory, with matplotlib's non-interactive backend. A block that is not meant to run (a
fragment, an excerpt of a file) is preceded by the line ``<!-- doc-test: skip (REASON) -->``
(docs/testing.md); the reason is required. A block that raises fails the test with the file,
the block's first line number and the traceback.
"""
from __future__ import annotations

import re
import traceback
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOC_FILES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
BLOCK = re.compile(r"^```python[ \t]*\n(.*?)^```", re.S | re.M)
SKIP = re.compile(r"<!-- doc-test: skip \(([^)]+)\) -->\s*$")


def python_blocks(text: str) -> list[tuple[int, str, str | None]]:
    """``[(first line number, code, reason skipped or None)]`` of every ```python block."""
    blocks = []
    for m in BLOCK.finditer(text):
        before = text[:m.start()].rstrip("\n").rsplit("\n", 1)[-1]
        skip = SKIP.search(before)
        blocks.append((text.count("\n", 0, m.start()) + 2, m.group(1), skip.group(1) if skip else None))
    return blocks


FILES_WITH_BLOCKS = [p for p in DOC_FILES if python_blocks(p.read_text())]


def test_the_library_page_has_python_blocks_and_they_are_found():
    """The extraction sees docs/library.md's simulator and environment blocks (the README's
    before it became a short page; so a changed fence style cannot make the test below pass on
    nothing)."""
    blocks = python_blocks((ROOT / "docs" / "library.md").read_text())
    assert len(blocks) >= 2
    assert any("sim.rollout(" in code for _, code, _ in blocks)
    assert any("gym.make(" in code for _, code, _ in blocks)


@pytest.mark.parametrize("doc", FILES_WITH_BLOCKS, ids=lambda p: str(p.relative_to(ROOT)))
def test_python_blocks_run(doc, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    namespace: dict = {"__name__": "__doc_block__"}
    ran = 0
    for line, code, skip in python_blocks(doc.read_text()):
        if skip is not None:
            continue
        try:
            exec(compile(code, f"{doc.name}:{line}", "exec"), namespace)
        except Exception:
            pytest.fail(f"{doc.relative_to(ROOT)}, the python block at line {line} fails:\n{code}\n"
                        f"{traceback.format_exc()}")
        ran += 1
    assert ran, f"{doc.name}: every python block is skipped"


def test_sensitivities_asked_for_without_dudz_raise_saying_so():
    """The README block's promise: a rollout without ``dudz`` has no ``dcomdz`` / ``dgammadz``, and
    asking for them raises an AttributeError naming ``dudz`` (not a silent None)."""
    import numpy as np
    from soft_envs.sim import Simulator, load_robot
    robot = load_robot("tripod")
    sim = Simulator(robot)
    u = np.full((2, robot.n_motors), 0.002)
    traj = sim.rollout(u)
    for name in ("dcomdz", "dgammadz"):
        with pytest.raises(AttributeError, match=rf"Trajectory\.{name}: .* without dudz"):
            getattr(traj, name)
    with_z = sim.rollout(u, dudz=np.eye(robot.n_motors)[None].repeat(2, axis=0))
    assert with_z.dcomdz.shape == (3, 3, robot.n_motors) and with_z.dgammadz.shape[::2] == (3, robot.n_motors)
