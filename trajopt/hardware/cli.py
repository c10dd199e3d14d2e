"""Moved: the ``trajopt play`` command is :mod:`trajopt.cli.play` (issue #27; docs/api-changes.md).
This name stays importable."""
from __future__ import annotations

from ..cli.play import (EXIT_HARDWARE, EXIT_INPUT, EXIT_INTERRUPTED, EXIT_NOT_STOPPED, EXIT_OK, EXIT_SIGNAL_BASE,
                        add_play_parser, run_play)

__all__ = ["add_play_parser", "run_play", "EXIT_OK", "EXIT_HARDWARE", "EXIT_INPUT", "EXIT_NOT_STOPPED",
           "EXIT_INTERRUPTED", "EXIT_SIGNAL_BASE"]
