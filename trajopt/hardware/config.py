"""Hardware description of a cable-driven robot (TOML), and cable-length <-> encoder conversion.

File layout (see ``example_hardware.toml`` and ``example_tripod.toml`` beside this module)::

    robot = "puppy"                # optional: the robot this hardware is (a robot name, or a
                                   # robot.toml path relative to this file); `trajopt play`
                                   # refuses results made for another (--ignore-robot-mismatch)

    [settings]                     # optional table, all keys optional
    min_battery_voltage = 10.5     # V, pre-flight refuses to play below this
    baudrate = 115200              # ignored by USB RoboClaws
    timeout = 0.1                  # s, reply timeout
    retries = 2                    # extra attempts on timeout / CRC error
    max_tracking_error = 0.002     # m of cable, beyond the lag the speed/accel limits explain
    max_tracking_error_time = 0.3  # s; playback aborts (and stops) after this long above the bound
    allow_untested_firmware = false  # true: play on firmware other than 4.x with a warning

    [motors.left]                  # one table per motor, keyed by motor name
    port = "/dev/ttyACM0"          # device path or pyserial URL
    address = 0x80                 # 0x80..0x87
    channel = 1                    # 1 (M1) or 2 (M2)
    spool_radius = 0.005           # m
    counts_per_rev = 3575.04       # optional, encoder counts per OUTPUT revolution (12 * 297.92)
    direction = 1                  # optional, +1 or -1: sign of counts when cable is pulled in
    max_speed = 4000               # counts/s
    max_accel = 40000              # counts/s^2
    u_min = 0.0                    # optional, m (contracted cable length bounds)
    u_max = 0.03                   # optional, m

Cable model: ``u = r * theta`` (u = contracted length in metres, positive =
cable pulled in), hence ``counts = direction * round(u / r / (2 pi) * counts_per_rev)``.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

try:
    import tomllib
except ImportError:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

from ..results.files import decode_utf8
from .protocol import ADDRESS_MAX, ADDRESS_MIN, INT32_MAX

#: Pololu 298:1 micro metal gearmotor: 12 counts per motor revolution times 297.92:1.
DEFAULT_COUNTS_PER_REV = 12 * 297.92
EXAMPLE_PUPPY = Path(__file__).with_name("example_hardware.toml")
EXAMPLE_TRIPOD = Path(__file__).with_name("example_tripod.toml")

_TOP_KEYS = {"settings", "motors", "robot"}


@dataclass(frozen=True)
class MotorConfig:
    """One cable motor: where it is wired and how cable length maps to encoder counts."""

    name: str
    port: str
    address: int
    channel: int
    spool_radius: float
    max_speed: float
    max_accel: float
    counts_per_rev: float = DEFAULT_COUNTS_PER_REV
    direction: int = 1
    u_min: float | None = None
    u_max: float | None = None

    def to_counts(self, u: Any) -> Any:
        """Encoder counts (int or int64 array) for contracted cable length(s) ``u`` in metres."""
        counts = np.round(self.to_counts_float(u)).astype(np.int64)
        return int(counts) if counts.ndim == 0 else counts

    def to_counts_float(self, u: Any) -> Any:
        """Unrounded encoder counts for ``u`` (used for limit checks)."""
        return self.direction * np.asarray(u, dtype=float) / self.spool_radius / (2 * math.pi) * self.counts_per_rev

    def to_length(self, counts: Any) -> Any:
        """Contracted cable length in metres for encoder ``counts`` (inverse of :meth:`to_counts`)."""
        turns = np.asarray(counts, dtype=float) / self.counts_per_rev
        return self.direction * turns * (2 * math.pi) * self.spool_radius


@dataclass(frozen=True)
class HardwareConfig:
    """All motors of a robot plus global communication settings."""

    motors: dict[str, MotorConfig]
    min_battery_voltage: float = 0.0
    baudrate: int = 115200
    timeout: float = 0.1
    retries: int = 2
    robot: str = ""
    path: str = "<memory>"
    #: Tracking-error bound [m of cable] beyond the lag explained by the speed / acceleration limits.
    max_tracking_error: float = 0.002
    #: Playback aborts when a motor stays above ``max_tracking_error`` this long [s].
    max_tracking_error_time: float = 0.3
    #: Play on firmware other than :data:`~.protocol.SUPPORTED_FIRMWARE_MAJOR` (with a warning).
    allow_untested_firmware: bool = False

    def controllers(self, names: list[str] | None = None) -> list[tuple[str, int]]:
        """Sorted distinct ``(port, address)`` pairs of the given (default: all) motors."""
        chosen = self.motors.values() if names is None else [self.motors[n] for n in names]
        return sorted({(m.port, m.address) for m in chosen})

    def with_port_override(self, port: str | None) -> HardwareConfig:
        """Copy with every motor's port replaced by ``port`` (no-op for ``None``)."""
        if port is None:
            return self
        motors = {n: dataclasses.replace(m, port=port) for n, m in self.motors.items()}
        _check_unique_wiring(self.path, motors)
        return dataclasses.replace(self, motors=motors)


def _err(path: str, where: str, msg: str) -> ValueError:
    return ValueError(f"{path}: {where}: {msg}")


def _number(path: str, where: str, value: Any, *, positive: bool = False, nonneg: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _err(path, where, f"expected a number, got {type(value).__name__} {value!r}")
    if not math.isfinite(value):
        raise _err(path, where, f"expected a finite number, got {value!r}")
    if positive and value <= 0:
        raise _err(path, where, f"must be > 0, got {value!r}")
    if nonneg and value < 0:
        raise _err(path, where, f"must be >= 0, got {value!r}")
    return float(value)


def _integer(path: str, where: str, value: Any, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise _err(path, where, f"expected an integer, got {type(value).__name__} {value!r}")
    if not lo <= value <= hi:
        raise _err(path, where, f"{value!r} out of range [{lo:#x}, {hi:#x}]" if lo >= 0x80 else
                   f"{value!r} out of range [{lo}, {hi}]")
    return value


_MOTOR_REQUIRED = ("port", "address", "channel", "spool_radius", "max_speed", "max_accel")
_MOTOR_OPTIONAL = ("counts_per_rev", "direction", "u_min", "u_max")
_SETTINGS = ("min_battery_voltage", "baudrate", "timeout", "retries", "max_tracking_error",
             "max_tracking_error_time", "allow_untested_firmware")


def _parse_motor(path: str, name: str, table: Any) -> MotorConfig:
    where = f"motors.{name}"
    if not isinstance(table, dict):
        raise _err(path, where, f"expected a table, got {type(table).__name__}")
    unknown = sorted(set(table) - set(_MOTOR_REQUIRED) - set(_MOTOR_OPTIONAL))
    if unknown:
        allowed = ", ".join(_MOTOR_REQUIRED + _MOTOR_OPTIONAL)
        raise _err(path, f"{where}.{unknown[0]}", f"unknown key (allowed: {allowed})")
    for key in _MOTOR_REQUIRED:
        if key not in table:
            raise _err(path, f"{where}.{key}", "missing required key")
    port = table["port"]
    if not isinstance(port, str) or not port:
        raise _err(path, f"{where}.port", f"expected a non-empty string, got {port!r}")
    direction = _integer(path, f"{where}.direction", table.get("direction", 1), -1, 1)
    if direction == 0:
        raise _err(path, f"{where}.direction", "must be +1 or -1, got 0")
    u_min = table.get("u_min")
    u_max = table.get("u_max")
    u_min = None if u_min is None else _number(path, f"{where}.u_min", u_min)
    u_max = None if u_max is None else _number(path, f"{where}.u_max", u_max)
    if u_min is not None and u_max is not None and u_min >= u_max:
        raise _err(path, f"{where}.u_max", f"must be > u_min ({u_min!r}), got {u_max!r}")
    motor = MotorConfig(
        name=name,
        port=port,
        address=_integer(path, f"{where}.address", table["address"], ADDRESS_MIN, ADDRESS_MAX),
        channel=_integer(path, f"{where}.channel", table["channel"], 1, 2),
        spool_radius=_number(path, f"{where}.spool_radius", table["spool_radius"], positive=True),
        max_speed=_number(path, f"{where}.max_speed", table["max_speed"], positive=True),
        max_accel=_number(path, f"{where}.max_accel", table["max_accel"], positive=True),
        counts_per_rev=_number(path, f"{where}.counts_per_rev", table.get("counts_per_rev", DEFAULT_COUNTS_PER_REV),
                               positive=True),
        direction=direction, u_min=u_min, u_max=u_max,
    )
    for key in ("max_speed", "max_accel"):
        if getattr(motor, key) > INT32_MAX:
            raise _err(path, f"{where}.{key}", f"{getattr(motor, key)!r} exceeds {INT32_MAX}")
    return motor


def _check_unique_wiring(path: str, motors: dict[str, MotorConfig]) -> None:
    seen: dict[tuple[str, int, int], str] = {}
    for name, m in motors.items():
        key = (m.port, m.address, m.channel)
        if key in seen:
            raise _err(path, f"motors.{name}", f"same port/address/channel as motors.{seen[key]} "
                       f"({m.port}, {m.address:#x}, M{m.channel})")
        seen[key] = name


def parse_hardware_config(data: dict[str, Any], path: str = "<memory>") -> HardwareConfig:
    """Validate an already-parsed TOML document; errors are ValueError naming ``path`` and the field."""
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise _err(path, unknown[0], f"unknown top-level key (allowed: {', '.join(sorted(_TOP_KEYS))})")
    robot = data.get("robot", "")
    if not isinstance(robot, str):
        raise _err(path, "robot", f"expected a string, got {robot!r}")
    settings = data.get("settings", {})
    if not isinstance(settings, dict):
        raise _err(path, "settings", "expected a table")
    bad = sorted(set(settings) - set(_SETTINGS))
    if bad:
        raise _err(path, f"settings.{bad[0]}", f"unknown key (allowed: {', '.join(_SETTINGS)})")
    motors_table = data.get("motors")
    if motors_table is None:
        raise _err(path, "motors", "missing required table")
    if not isinstance(motors_table, dict) or not motors_table:
        raise _err(path, "motors", "expected a non-empty table of motor tables")
    motors = {name: _parse_motor(path, name, table) for name, table in motors_table.items()}
    _check_unique_wiring(path, motors)
    defaults = HardwareConfig  # class attributes hold the field defaults
    allow = settings.get("allow_untested_firmware", False)
    if not isinstance(allow, bool):
        raise _err(path, "settings.allow_untested_firmware", f"expected true or false, got {allow!r}")
    return HardwareConfig(
        motors=motors,
        min_battery_voltage=_number(path, "settings.min_battery_voltage", settings.get("min_battery_voltage", 0.0),
                                    nonneg=True),
        baudrate=_integer(path, "settings.baudrate", settings.get("baudrate", 115200), 1, 10_000_000),
        timeout=_number(path, "settings.timeout", settings.get("timeout", 0.1), positive=True),
        retries=_integer(path, "settings.retries", settings.get("retries", 2), 0, 100),
        robot=robot,
        path=path,
        max_tracking_error=_number(path, "settings.max_tracking_error",
                                   settings.get("max_tracking_error", defaults.max_tracking_error), positive=True),
        max_tracking_error_time=_number(path, "settings.max_tracking_error_time",
                                        settings.get("max_tracking_error_time", defaults.max_tracking_error_time),
                                        nonneg=True),
        allow_untested_firmware=allow,
    )


def load_hardware_config(path: str | os.PathLike[str]) -> HardwareConfig:
    """Read and validate a hardware TOML file (every content error is a ValueError naming file and field)."""
    path_str = str(path)
    with open(path, "rb") as fh:
        text = decode_utf8(fh.read(), path_str, hint="save the file as UTF-8")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path_str}: invalid TOML: {exc}") from exc
    return parse_hardware_config(data, path_str)
