"""One emulated RoboClaw controller: its state and the execution of valid packets (used by :mod:`.emulator`).

Two motor channels (:class:`~._motion.ChannelModel`), a battery voltage and a
status word.  :meth:`EmulatedController.execute` runs one CRC-valid request and
returns the bytes a faithful controller would answer; faults (lost, late,
partial or corrupted replies) are applied by the emulator around it.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from . import protocol as P
from ._motion import ChannelModel, Move


@dataclass(frozen=True)
class ControllerSnapshot:
    """Inspection snapshot of one emulated controller."""

    address: int
    counts: tuple[int, int]
    velocities: tuple[float, float]
    modes: tuple[str, str]
    targets: tuple[int | None, int | None]
    duties: tuple[int, int]
    speeds: tuple[int, int]
    queued: tuple[int, int]
    battery_voltage: float
    jammed: tuple[bool, bool] = (False, False)


class EmulatedController:
    """State of one controller (one packet-serial address) and its command handling."""

    def __init__(self, address: int, no_load_speed: float, battery_voltage: float) -> None:
        self.address = address
        self.channels = (ChannelModel(no_load_speed), ChannelModel(no_load_speed))
        self.battery_voltage = battery_voltage
        self.status = 0

    def snapshot(self) -> ControllerSnapshot:
        """Current state (call after integrating the motion up to now)."""
        a, b = self.channels
        return ControllerSnapshot(
            self.address, (a.count, b.count), (a.vel, b.vel), (a.mode, b.mode), (a.target, b.target),
            (a.duty, b.duty), (a.speed_cmd, b.speed_cmd), (len(a.queue), len(b.queue)), self.battery_voltage,
            (a.jammed, b.jammed))

    def advance(self, h: float) -> None:
        """Integrate both channels over ``h`` seconds."""
        for ch in self.channels:
            ch.advance(h)

    def execute(self, command: int, data: bytes, firmware: str) -> bytes:
        """Execute one valid packet and return the reply bytes (read: data + CRC; write: ACK)."""
        C = P.Cmd
        if command in P.READ_COMMANDS:
            if command in (C.READ_ENCODER_M1, C.READ_ENCODER_M2):
                ch = self.channels[command - C.READ_ENCODER_M1]
                body = struct.pack(">iB", ch.count, 0x02 if ch.vel < 0 else 0x00)
            elif command == C.READ_FIRMWARE:
                body = firmware.encode("ascii")[:P.FIRMWARE_MAX_LEN] + P.FIRMWARE_TERMINATOR
            elif command == C.READ_MAIN_BATTERY:
                body = struct.pack(">H", max(0, min(65535, round(self.battery_voltage * 10))))
            elif command in (C.READ_POSITION_PID_M1, C.READ_POSITION_PID_M2):
                body = struct.pack(">IIIIIii", *self.channels[command - C.READ_POSITION_PID_M1].pid)
            else:  # READ_STATUS
                body = struct.pack(">I", self.status)
            return body + P.reply_crc(self.address, command, body)
        if command == C.RESET_ENCODERS:
            for ch in self.channels:
                ch.set_count(0)
        elif command in (C.SET_ENCODER_M1, C.SET_ENCODER_M2):
            self.channels[command - C.SET_ENCODER_M1].set_count(struct.unpack(">i", data)[0])
        elif command in (C.DUTY_M1, C.DUTY_M2):
            self.channels[command - C.DUTY_M1].set_duty(struct.unpack(">h", data)[0])
        elif command in (C.SPEED_M1, C.SPEED_M2):
            self.channels[command - C.SPEED_M1].set_speed(struct.unpack(">i", data)[0])
        elif command in (C.SET_POSITION_PID_M1, C.SET_POSITION_PID_M2):
            d, p, i, max_i, deadzone, min_pos, max_pos = struct.unpack(">IIIIIii", data)
            self.channels[command - C.SET_POSITION_PID_M1].pid = (p, i, d, max_i, deadzone, min_pos, max_pos)
        elif command in (C.SPEED_ACCEL_DECEL_POSITION_M1, C.SPEED_ACCEL_DECEL_POSITION_M2):
            accel, speed, decel, position, flag = struct.unpack(">IIIiB", data)
            self.channels[command - C.SPEED_ACCEL_DECEL_POSITION_M1].command_move(
                Move(accel, speed, decel, position), immediate=flag != 0)
        return bytes((P.ACK,))
