"""Moved: ``trajopt render``, ``export`` and ``plot`` are :mod:`trajopt.cli.output_commands`
(issue #27; docs/api-changes.md). This name stays importable."""
from __future__ import annotations

from .cli.output_commands import check_video_writer, run_export, run_plot, run_render

__all__ = ["run_render", "run_export", "run_plot", "check_video_writer"]
