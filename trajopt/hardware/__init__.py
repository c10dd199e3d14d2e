"""Playing optimised trajectories on real cable-driven robots (RoboClaw controllers, packet serial).

* :class:`RoboClaw` -- packet-serial driver (pyserial, imported only when a port is opened);
* :func:`load_hardware_config` -- TOML hardware description (motors, spools, limits);
* :func:`play_trajectory` -- pre-flight checks, timed streaming, CSV log, safe stop;
* :class:`RoboClawEmulator` -- pty-based emulated controllers for tests and demos (POSIX);
* :func:`add_play_parser` / :func:`run_play` -- the ``trajopt play`` sub-command.

Importing this package does not need pyserial; opening a port without it raises
``ImportError("... pip install soft-envs[hardware]")``.
"""

from __future__ import annotations

from typing import Any

from .cli import add_play_parser, run_play
from .config import (
    DEFAULT_COUNTS_PER_REV,
    EXAMPLE_PUPPY,
    EXAMPLE_TRIPOD,
    HardwareConfig,
    MotorConfig,
    load_hardware_config,
    parse_hardware_config,
)
from .driver import RoboClaw, open_serial
from .errors import (
    PlaybackError,
    RoboClawConnectionError,
    RoboClawCRCError,
    RoboClawError,
    RoboClawNoAck,
    RoboClawTimeout,
)
from .playback import PlaybackSummary, play_trajectory, stop_all_reachable
from .protocol import Cmd, EncoderReading, PositionPID, crc16
from .trajectory import PlannedCommand, TrajectoryLimitError, TrajectoryPlan, iter_command_stream, plan_trajectory

__all__ = [
    "Cmd", "DEFAULT_COUNTS_PER_REV", "EXAMPLE_PUPPY", "EXAMPLE_TRIPOD", "EncoderReading", "HardwareConfig",
    "MotorConfig", "PlannedCommand", "PlaybackError", "PlaybackSummary", "PositionPID", "RoboClaw",
    "RoboClawCRCError", "RoboClawConnectionError", "RoboClawEmulator", "RoboClawError", "RoboClawNoAck",
    "RoboClawTimeout", "TrajectoryLimitError", "TrajectoryPlan", "add_play_parser", "crc16",
    "iter_command_stream", "load_hardware_config", "open_serial", "parse_hardware_config", "plan_trajectory",
    "play_trajectory", "run_play", "stop_all_reachable",
]


def __getattr__(name: str) -> Any:
    """Import the emulator lazily (it needs POSIX ptys)."""
    if name == "RoboClawEmulator":
        from .emulator import RoboClawEmulator

        return RoboClawEmulator
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
