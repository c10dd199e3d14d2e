"""Moved: the ``trajopt sweep`` command is :mod:`trajopt.cli.sweep` (issue #27; docs/api-changes.md).
This name stays importable."""
from __future__ import annotations

from ..cli.sweep import add_sweep_parser, run_sweep_command

__all__ = ["add_sweep_parser", "run_sweep_command"]
