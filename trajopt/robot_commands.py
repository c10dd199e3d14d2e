"""Moved: ``trajopt mesh`` and ``check`` are :mod:`trajopt.cli.robot_commands` (issue #27;
docs/api-changes.md). This name stays importable."""
from __future__ import annotations

from .cli.robot_commands import run_check, run_mesh

__all__ = ["run_mesh", "run_check"]
