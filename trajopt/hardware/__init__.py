"""Playing optimised trajectories on real cable-driven robots (RoboClaw controllers, packet serial).

* :class:`RoboClaw` -- packet-serial driver (pyserial, imported only when a port is opened);
* :func:`load_hardware_config` -- TOML hardware description (motors, spools, limits);
* :func:`play_trajectory` -- pre-flight checks, timed streaming, CSV log, tracking-error abort;
* :func:`stop_motors` -- stop every channel whatever happens meanwhile; :class:`StopReport` says
  which stops were confirmed (read back) and which were not;
* :class:`Terminated` -- what SIGTERM / SIGHUP raise during a playback (after its stop sequence);
* :class:`RoboClawEmulator` -- pty-based emulated controllers for tests and demos (POSIX).

The ``trajopt play`` command that drives them is :mod:`trajopt.cli.play`.

Importing this package does not need pyserial; opening a port without it raises
``ImportError("... pip install soft-envs[hardware]")``.
"""

from __future__ import annotations

from typing import Any

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
    RoboClawUnmatchedReply,
    TrackingError,
)
from .playback import PlaybackSummary, play_trajectory
from .protocol import Cmd, EncoderReading, PositionPID, crc16, parse_firmware_version
from .signals import Terminated
from .stop import ChannelStop, StopReport, stop_all_reachable, stop_motors
from .trajectory import (
    PlannedCommand,
    TrajectoryLimitError,
    TrajectoryPlan,
    describe_plan,
    iter_command_stream,
    plan_trajectory,
)

__all__ = [
    "ChannelStop", "Cmd", "DEFAULT_COUNTS_PER_REV", "EXAMPLE_PUPPY", "EXAMPLE_TRIPOD", "EncoderReading",
    "HardwareConfig", "MotorConfig", "PlannedCommand", "PlaybackError", "PlaybackSummary", "PositionPID", "RoboClaw",
    "RoboClawCRCError", "RoboClawConnectionError", "RoboClawEmulator", "RoboClawError", "RoboClawNoAck",
    "RoboClawTimeout", "RoboClawUnmatchedReply", "StopReport", "Terminated", "TrackingError", "TrajectoryLimitError",
    "TrajectoryPlan", "crc16", "describe_plan", "iter_command_stream", "load_hardware_config",
    "open_serial", "parse_firmware_version", "parse_hardware_config", "plan_trajectory", "play_trajectory",
    "stop_all_reachable", "stop_motors",
]


def __getattr__(name: str) -> Any:
    """Import the emulator lazily (it needs POSIX ptys)."""
    if name == "RoboClawEmulator":
        from .emulator import RoboClawEmulator

        return RoboClawEmulator
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
