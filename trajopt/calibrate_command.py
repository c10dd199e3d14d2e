"""Moved: ``trajopt calibrate`` is :mod:`trajopt.cli.calibrate_command`, its files (marker points,
the calibrated robot.toml, the tracks plot) :mod:`trajopt.calibration_files` (issue #27;
docs/api-changes.md). This name stays importable."""
from __future__ import annotations

from .calibration_files import HEADER, plot_tracks, read_marker_points, tracks_figure, write_calibrated_robot
from .cli.calibrate_command import run_calibrate

__all__ = ["run_calibrate", "read_marker_points", "write_calibrated_robot", "plot_tracks", "tracks_figure", "HEADER"]
