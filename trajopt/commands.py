"""Moved: ``trajopt optimize`` and ``evaluate`` are :mod:`trajopt.cli.commands`; the run's files,
checkpoints and resume are the library's :mod:`trajopt.optimize_run` (issue #27;
docs/api-changes.md). This name stays importable."""
from __future__ import annotations

from .cli.commands import STATUS_MEANING, evaluation_rows, run_evaluate, run_optimize

__all__ = ["run_optimize", "run_evaluate", "STATUS_MEANING", "evaluation_rows"]
