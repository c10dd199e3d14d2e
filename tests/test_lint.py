"""The code passes ruff (``pyproject.toml``'s ``[tool.ruff]``: pyflakes' errors, such as an
unused import or a name ``__all__`` exports that does not exist, and pycodestyle's E4/E7/E9)."""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_ruff_finds_nothing():
    ruff = pytest.importorskip("ruff")
    binary = ruff.find_ruff_bin()
    proc = subprocess.run([binary, "check", "--no-cache", "--output-format", "concise", str(ROOT)],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_the_check_catches_an_unused_import(tmp_path):
    ruff = pytest.importorskip("ruff")
    bad = tmp_path / "bad.py"
    bad.write_text("import os\n")
    proc = subprocess.run([ruff.find_ruff_bin(), "check", "--no-cache", "--config", str(ROOT / "pyproject.toml"),
                           str(bad)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1 and "F401" in proc.stdout, proc.stdout + proc.stderr
