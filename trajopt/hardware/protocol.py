"""RoboClaw packet-serial protocol: command numbers, CRC, frame builders, reply parsers.

Pure functions only (no I/O, no pyserial), shared by the driver (:mod:`.driver`),
the dry-run command stream (:mod:`.playback`) and the emulator (:mod:`.emulator`),
so that all three agree byte for byte.

Frame layout (host -> controller)::

    [address 0x80..0x87][command][big-endian data ...][CRC16 hi][CRC16 lo]

The CRC is CRC-16/XMODEM (polynomial 0x1021, initial value 0, no reflection,
no final xor) over address, command and data.  Writes are acknowledged with
the single byte ``0xFF``; reads answer ``[reply data ...][CRC16 hi][CRC16 lo]``
where the CRC covers the *request's* address and command bytes followed by the
reply data.

Status (command 90): newer firmware (4.x) answers a 32-bit status word, older
firmware a 16-bit one.  This package implements the **uint32** variant only, and
playback accepts firmware 4.x only (:func:`parse_firmware_version`).
"""

from __future__ import annotations

import binascii
import re
import struct
from enum import IntEnum
from typing import NamedTuple

ADDRESS_MIN = 0x80
ADDRESS_MAX = 0x87
ACK = 0xFF
#: Scale of the fixed-point position PID gains (P, I, D are sent as ``round(gain * 1024)``).
PID_SCALE = 1024
DUTY_MAX = 32767
INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1
UINT32_MAX = 2**32 - 1
FIRMWARE_MAX_LEN = 48
FIRMWARE_TERMINATOR = b"\n\x00"
#: Firmware major version(s) this driver was written and tested for (status word, reply layouts).
SUPPORTED_FIRMWARE_MAJOR = (4,)
_FIRMWARE_VERSION = re.compile(r"roboclaw\b.*\bv(\d+)\.(\d+)\.(\d+)", re.IGNORECASE)


class Cmd(IntEnum):
    """Packet-serial command numbers used by this package."""

    READ_ENCODER_M1 = 16
    READ_ENCODER_M2 = 17
    RESET_ENCODERS = 20
    READ_FIRMWARE = 21
    SET_ENCODER_M1 = 22
    SET_ENCODER_M2 = 23
    READ_MAIN_BATTERY = 24
    DUTY_M1 = 32
    DUTY_M2 = 33
    SPEED_M1 = 35
    SPEED_M2 = 36
    SET_POSITION_PID_M1 = 61
    SET_POSITION_PID_M2 = 62
    READ_POSITION_PID_M1 = 63
    READ_POSITION_PID_M2 = 64
    SPEED_ACCEL_DECEL_POSITION_M1 = 65
    SPEED_ACCEL_DECEL_POSITION_M2 = 66
    READ_STATUS = 90


#: Number of data bytes the host sends after the command byte (before the CRC).
REQUEST_DATA_LEN: dict[int, int] = {
    Cmd.READ_ENCODER_M1: 0, Cmd.READ_ENCODER_M2: 0, Cmd.RESET_ENCODERS: 0,
    Cmd.READ_FIRMWARE: 0, Cmd.SET_ENCODER_M1: 4, Cmd.SET_ENCODER_M2: 4,
    Cmd.READ_MAIN_BATTERY: 0, Cmd.DUTY_M1: 2, Cmd.DUTY_M2: 2,
    Cmd.SPEED_M1: 4, Cmd.SPEED_M2: 4,
    Cmd.SET_POSITION_PID_M1: 28, Cmd.SET_POSITION_PID_M2: 28,
    Cmd.READ_POSITION_PID_M1: 0, Cmd.READ_POSITION_PID_M2: 0,
    Cmd.SPEED_ACCEL_DECEL_POSITION_M1: 17, Cmd.SPEED_ACCEL_DECEL_POSITION_M2: 17,
    Cmd.READ_STATUS: 0,
}

#: Commands answered with data + CRC (all others are writes answered with 0xFF).
READ_COMMANDS: frozenset[int] = frozenset({
    Cmd.READ_ENCODER_M1, Cmd.READ_ENCODER_M2, Cmd.READ_FIRMWARE, Cmd.READ_MAIN_BATTERY,
    Cmd.READ_POSITION_PID_M1, Cmd.READ_POSITION_PID_M2, Cmd.READ_STATUS,
})

#: Fixed reply data length of read commands (firmware is variable: ``None``).
REPLY_DATA_LEN: dict[int, int | None] = {
    Cmd.READ_ENCODER_M1: 5, Cmd.READ_ENCODER_M2: 5, Cmd.READ_FIRMWARE: None,
    Cmd.READ_MAIN_BATTERY: 2, Cmd.READ_POSITION_PID_M1: 28, Cmd.READ_POSITION_PID_M2: 28,
    Cmd.READ_STATUS: 4,
}


def command_name(command: int) -> str:
    """Readable name of a command number, e.g. ``16 -> 'READ_ENCODER_M1'``."""
    try:
        return Cmd(command).name
    except ValueError:
        return f"UNKNOWN_{command}"


class EncoderReading(NamedTuple):
    """Reply of commands 16/17: signed count and status byte.

    Status bits: 0 = counter underflow, 1 = direction (1 = backwards), 2 = overflow.
    """

    count: int  # type: ignore[assignment]  # shadows tuple.count on purpose
    status: int


class PositionPID(NamedTuple):
    """Position PID settings (gains as floats, already divided by :data:`PID_SCALE`)."""

    p: float
    i: float
    d: float
    max_i: int
    deadzone: int
    min_pos: int
    max_pos: int


def crc16(data: bytes) -> int:
    """CRC-16/XMODEM (poly 0x1021, init 0) of ``data``; ``crc16(b"123456789") == 0x31C3``."""
    return binascii.crc_hqx(bytes(data), 0)


# ----------------------------------------------------------------------------- validation
def check_address(address: int) -> int:
    """Return ``address`` if it is an int in 0x80..0x87, else raise ValueError naming it."""
    if isinstance(address, bool) or not isinstance(address, int):
        raise ValueError(f"RoboClaw address {address!r} must be an integer in [0x80, 0x87]")
    if not ADDRESS_MIN <= address <= ADDRESS_MAX:
        raise ValueError(f"RoboClaw address {address} ({address:#04x}) out of range [0x80, 0x87]")
    return address


def check_channel(channel: int) -> int:
    """Return ``channel`` if it is 1 or 2, else raise ValueError naming it."""
    if isinstance(channel, bool) or channel not in (1, 2):
        raise ValueError(f"motor channel {channel!r} must be 1 or 2")
    return int(channel)


def check_int(name: str, value: object, lo: int, hi: int) -> int:
    """Return ``value`` as int if it is integral and in ``[lo, hi]``, else raise ValueError naming it."""
    if isinstance(value, bool):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    try:
        as_int: int = int(value)  # type: ignore[call-overload]
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be an integer, got {value!r}") from None
    if as_int != value:
        raise ValueError(f"{name} must be an integer, got {value!r}")
    if not lo <= as_int <= hi:
        raise ValueError(f"{name} = {as_int} out of range [{lo}, {hi}]")
    return as_int


def channel_command(base_m1: int, channel: int) -> int:
    """Command number for ``channel`` given the M1 variant (M2 is always ``base_m1 + 1``)."""
    return base_m1 + check_channel(channel) - 1


# ----------------------------------------------------------------------------- frames
def build_frame(address: int, command: int, data: bytes = b"") -> bytes:
    """Full request frame ``address, command, data, CRC16 (big-endian)``."""
    head = bytes((check_address(address), check_int("command", command, 0, 255))) + bytes(data)
    return head + struct.pack(">H", crc16(head))


def read_frame(address: int, command: int) -> bytes:
    """Request frame of a read command (no data)."""
    return build_frame(address, command)


def reset_encoders_frame(address: int) -> bytes:
    """Command 20: reset both encoder counters to 0."""
    return build_frame(address, Cmd.RESET_ENCODERS)


def set_encoder_frame(address: int, channel: int, count: int) -> bytes:
    """Commands 22/23: set encoder count (int32)."""
    count = check_int("encoder count", count, INT32_MIN, INT32_MAX)
    return build_frame(address, channel_command(Cmd.SET_ENCODER_M1, channel), struct.pack(">i", count))


def duty_frame(address: int, channel: int, duty: int) -> bytes:
    """Commands 32/33: signed duty cycle (int16, -32767..32767)."""
    duty = check_int("duty", duty, -DUTY_MAX, DUTY_MAX)
    return build_frame(address, channel_command(Cmd.DUTY_M1, channel), struct.pack(">h", duty))


def speed_frame(address: int, channel: int, counts_per_s: int) -> bytes:
    """Commands 35/36: signed speed in encoder counts per second (int32)."""
    speed = check_int("speed [counts/s]", counts_per_s, INT32_MIN, INT32_MAX)
    return build_frame(address, channel_command(Cmd.SPEED_M1, channel), struct.pack(">i", speed))


def pid_gain_to_int(name: str, gain: float) -> int:
    """Fixed-point encoding ``round(gain * 1024)`` of a non-negative PID gain, range-checked."""
    try:
        scaled = round(float(gain) * PID_SCALE)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"PID gain {name} must be a finite number, got {gain!r}") from None
    return check_int(f"PID gain {name} * {PID_SCALE}", scaled, 0, UINT32_MAX)


def set_position_pid_frame(address: int, channel: int, p: float, i: float, d: float,
                           max_i: int, deadzone: int, min_pos: int, max_pos: int) -> bytes:
    """Commands 61/62. Wire order is **D, P, I**, MaxI, Deadzone, MinPos, MaxPos."""
    data = struct.pack(
        ">IIIIIii",
        pid_gain_to_int("d", d), pid_gain_to_int("p", p), pid_gain_to_int("i", i),
        check_int("max_i", max_i, 0, UINT32_MAX), check_int("deadzone", deadzone, 0, UINT32_MAX),
        check_int("min_pos", min_pos, INT32_MIN, INT32_MAX), check_int("max_pos", max_pos, INT32_MIN, INT32_MAX),
    )
    return build_frame(address, channel_command(Cmd.SET_POSITION_PID_M1, channel), data)


def speed_accel_decel_position_frame(address: int, channel: int, accel: int, speed: int,
                                     decel: int, position: int, buffer: bool) -> bytes:
    """Commands 65/66: buffered move. ``buffer=True`` queues (flag 0), ``False`` executes now (flag 1)."""
    data = struct.pack(
        ">IIIiB",
        check_int("accel [counts/s^2]", accel, 0, UINT32_MAX),
        check_int("speed [counts/s]", speed, 0, UINT32_MAX),
        check_int("decel [counts/s^2]", decel, 0, UINT32_MAX),
        check_int("position [counts]", position, INT32_MIN, INT32_MAX),
        0 if buffer else 1,
    )
    return build_frame(address, channel_command(Cmd.SPEED_ACCEL_DECEL_POSITION_M1, channel), data)


# ----------------------------------------------------------------------------- replies
def reply_crc(address: int, command: int, data: bytes) -> bytes:
    """The two CRC bytes a controller appends to a read reply."""
    return struct.pack(">H", crc16(bytes((address, command)) + bytes(data)))


def parse_encoder(data: bytes) -> EncoderReading:
    """Parse the 5 data bytes of an encoder reply (int32 count, uint8 status)."""
    count, status = struct.unpack(">iB", data)
    return EncoderReading(count, status)


def parse_position_pid(data: bytes) -> PositionPID:
    """Parse the 28 data bytes of a position-PID reply (P, I, D, MaxI, Deadzone, MinPos, MaxPos)."""
    p, i, d, max_i, deadzone, min_pos, max_pos = struct.unpack(">IIIIIii", data)
    return PositionPID(p / PID_SCALE, i / PID_SCALE, d / PID_SCALE, max_i, deadzone, min_pos, max_pos)


def parse_battery(data: bytes) -> float:
    """Parse a uint16 voltage in tenths of a volt, returning volts."""
    (tenths,) = struct.unpack(">H", data)
    return int(tenths) / 10.0


def parse_firmware_version(text: str) -> tuple[int, int, int] | None:
    """``(major, minor, patch)`` of a RoboClaw firmware string such as ``"USB Roboclaw 2x7a v4.1.34"``.

    Returns ``None`` if ``text`` is not a RoboClaw version string (another device on the port).
    """
    match = _FIRMWARE_VERSION.search(text)
    if match is None:
        return None
    major, minor, patch = (int(g) for g in match.groups())
    return major, minor, patch


def parse_status(data: bytes) -> int:
    """Parse the uint32 status word of command 90."""
    (status,) = struct.unpack(">I", data)
    return int(status)
