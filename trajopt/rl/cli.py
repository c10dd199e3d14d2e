"""Moved: the ``trajopt rl`` commands are :mod:`trajopt.cli.rl` (issue #27; docs/api-changes.md).
This name stays importable."""
from __future__ import annotations

from ..cli.rl import RUNS_DIR, add_rl_parser

__all__ = ["add_rl_parser", "RUNS_DIR"]
