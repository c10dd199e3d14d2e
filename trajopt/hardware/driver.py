"""RoboClaw packet-serial driver over pyserial (or any serial-like object).

Example::

    from trajopt.hardware import RoboClaw
    with RoboClaw("/dev/ttyACM0", address=0x80, timeout=0.1) as rc:
        print(rc.read_firmware(), rc.read_main_battery_voltage())
        rc.speed_accel_decel_position(1, accel=20000, speed=4000, decel=20000,
                                      position=1000, buffer=False)

Several controllers on one port (one RS-232/USB bus, addresses 0x80..0x87)
share one serial object: open it once and derive siblings with
:meth:`RoboClaw.at_address`.

Retries: a timeout, a CRC mismatch or a wrong ACK byte is retried
``retries`` times (the input buffer is flushed before each retry); every
request used here is idempotent, so re-sending a write whose ACK was lost is
harmless.  Port failures (:class:`RoboClawConnectionError`) are not retried.
"""

from __future__ import annotations

import time
from typing import Any, Callable, Protocol, TypeVar

from . import protocol as P
from .errors import RoboClawConnectionError, RoboClawCRCError, RoboClawError, RoboClawNoAck, RoboClawTimeout

T = TypeVar("T")

PYSERIAL_HINT = "pyserial is required to talk to RoboClaw controllers: pip install soft-envs[hardware]"


class SerialLike(Protocol):
    """The subset of ``serial.Serial`` the driver uses (``read`` must honour a finite timeout)."""

    def write(self, data: bytes) -> int | None: ...
    def read(self, size: int = 1) -> bytes: ...
    def reset_input_buffer(self) -> None: ...
    def close(self) -> None: ...


def import_serial() -> Any:
    """Import pyserial lazily, with an actionable message if it is missing."""
    try:
        import serial  # type: ignore[import-untyped,unused-ignore]
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(PYSERIAL_HINT) from exc
    return serial


def open_serial(port: str, baudrate: int = 115200, timeout: float = 0.1) -> Any:
    """Open ``port`` (device path or pyserial URL such as ``loop://``) with ``serial.serial_for_url``."""
    serial = import_serial()
    try:
        return serial.serial_for_url(port, baudrate=baudrate, timeout=timeout, write_timeout=max(timeout, 0.5))
    except (serial.SerialException, OSError) as exc:
        raise RoboClawConnectionError(f"cannot open serial port {port!r}: {exc}") from exc


class RoboClaw:
    """Driver for one RoboClaw controller (one address) in packet-serial mode.

    Args:
        port_or_serial: port name / pyserial URL (opened with ``serial.serial_for_url``)
            or an already-open serial-like object (not closed by :meth:`close`).
        address: packet-serial address 0x80..0x87.
        timeout: seconds to wait for a complete reply.
        retries: extra attempts after a timeout / CRC error / bad ACK.
        baudrate: only used when opening a port by name (ignored by USB RoboClaws).
    """

    def __init__(self, port_or_serial: str | SerialLike, address: int = 0x80, timeout: float = 0.1,
                 retries: int = 2, baudrate: int = 115200) -> None:
        self.address = P.check_address(address)
        if not (isinstance(timeout, (int, float)) and timeout > 0):
            raise ValueError(f"timeout {timeout!r} must be a positive number of seconds")
        self.timeout = float(timeout)
        self.retries = P.check_int("retries", retries, 0, 100)
        if isinstance(port_or_serial, str):
            self.port: str = port_or_serial
            self._ser: Any = open_serial(port_or_serial, baudrate=baudrate, timeout=self.timeout)
            self._owns_port = True
        else:
            if getattr(port_or_serial, "timeout", 0.0) is None:
                raise ValueError("serial object has timeout=None (blocking reads); give it a finite timeout")
            self.port = str(getattr(port_or_serial, "port", None) or getattr(port_or_serial, "name", "<serial>"))
            self._ser = port_or_serial
            self._owns_port = False

    # ------------------------------------------------------------------ lifecycle
    def at_address(self, address: int) -> RoboClaw:
        """A driver for another controller on the same serial port (shares, does not own, it)."""
        return RoboClaw(self._ser, address, timeout=self.timeout, retries=self.retries)

    @property
    def serial(self) -> Any:
        """The underlying serial object."""
        return self._ser

    def close(self) -> None:
        """Close the port if this driver opened it."""
        if self._owns_port:
            try:
                self._ser.close()
            except Exception:  # noqa: BLE001 - closing a dead port must not raise
                pass

    def __enter__(self) -> RoboClaw:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"RoboClaw(port={self.port!r}, address={self.address:#04x})"

    # ------------------------------------------------------------------ low level
    def _error(self, cls: type[RoboClawError], detail: str, command: int, received: bytes) -> RoboClawError:
        return cls(f"{detail} (port {self.port})", address=self.address, command=command, received=received)

    def _send(self, frame: bytes) -> None:
        try:
            self._ser.write(frame)  # one write: the device drops packets with >10 ms gaps
        except Exception as exc:  # noqa: BLE001 - pyserial raises SerialException/OSError
            raise self._error(RoboClawConnectionError, f"write failed: {exc}", frame[1], b"") from exc

    def _read_exact(self, n: int, deadline: float, command: int, sofar: bytes = b"") -> bytes:
        buf = bytearray(sofar)
        while len(buf) < len(sofar) + n:
            if time.monotonic() > deadline:
                raise self._error(RoboClawTimeout, f"no complete reply within {self.timeout:g} s", command,
                                  bytes(buf))
            try:
                chunk = self._ser.read(len(sofar) + n - len(buf))
            except Exception as exc:  # noqa: BLE001
                raise self._error(RoboClawConnectionError, f"read failed: {exc}", command, bytes(buf)) from exc
            buf += chunk
        return bytes(buf[len(sofar):])

    def _flush_input(self, command: int) -> None:
        try:
            self._ser.reset_input_buffer()
        except Exception as exc:  # noqa: BLE001 - termios.error on a dead pty
            raise self._error(RoboClawConnectionError, f"flush failed: {exc}", command, b"") from exc

    def _exchange(self, frame: bytes, receive: Callable[[float], T]) -> T:
        """Send ``frame`` and parse the answer with ``receive(deadline)``, retrying transient errors."""
        last: RoboClawError | None = None
        for attempt in range(self.retries + 1):
            if attempt:
                self._flush_input(frame[1])
            self._send(frame)
            try:
                return receive(time.monotonic() + self.timeout)
            except (RoboClawTimeout, RoboClawCRCError, RoboClawNoAck) as exc:
                last = exc
        assert last is not None
        last.attempts = self.retries + 1
        raise last

    def _write(self, frame: bytes) -> None:
        command = frame[1]

        def receive(deadline: float) -> None:
            got = self._read_exact(1, deadline, command)
            if got[0] != P.ACK:
                raise self._error(RoboClawNoAck, "expected ACK 0xff", command, got)

        self._exchange(frame, receive)

    def _check_crc(self, command: int, data: bytes, crc: bytes) -> bytes:
        if P.reply_crc(self.address, command, data) != crc:
            raise self._error(RoboClawCRCError, f"reply CRC mismatch (expected "
                              f"{P.reply_crc(self.address, command, data).hex()})", command, data + crc)
        return data

    def _read(self, command: int) -> bytes:
        """Send a read request and return the CRC-checked reply data."""
        n = P.REPLY_DATA_LEN[command]
        assert n is not None

        def receive(deadline: float) -> bytes:
            raw = self._read_exact(n + 2, deadline, command)
            return self._check_crc(command, raw[:n], raw[n:])

        return self._exchange(P.read_frame(self.address, command), receive)

    # ------------------------------------------------------------------ commands
    def read_encoder(self, channel: int) -> P.EncoderReading:
        """Commands 16/17: ``(count, status)`` of encoder ``channel`` (1 or 2)."""
        return P.parse_encoder(self._read(P.channel_command(P.Cmd.READ_ENCODER_M1, channel)))

    def reset_encoders(self) -> None:
        """Command 20: set both encoder counts to 0."""
        self._write(P.reset_encoders_frame(self.address))

    def read_firmware(self) -> str:
        """Command 21: firmware version string (without the ``\\n\\0`` terminator)."""
        command = int(P.Cmd.READ_FIRMWARE)

        def receive(deadline: float) -> str:
            text = b""
            while not text.endswith(P.FIRMWARE_TERMINATOR):
                if len(text) > P.FIRMWARE_MAX_LEN + 2:
                    raise self._error(RoboClawCRCError, "firmware string not terminated", command, text)
                text += self._read_exact(1, deadline, command, text)
            crc = self._read_exact(2, deadline, command, text)
            return self._check_crc(command, text, crc)[:-2].decode("ascii", "replace")

        return self._exchange(P.read_frame(self.address, command), receive)

    def set_encoder(self, channel: int, count: int) -> None:
        """Commands 22/23: set encoder ``channel`` to ``count`` (int32)."""
        self._write(P.set_encoder_frame(self.address, channel, count))

    def read_main_battery_voltage(self) -> float:
        """Command 24: main battery voltage in volts."""
        return P.parse_battery(self._read(P.Cmd.READ_MAIN_BATTERY))

    def duty(self, channel: int, value: int) -> None:
        """Commands 32/33: signed duty cycle -32767..32767 (0 stops the motor)."""
        self._write(P.duty_frame(self.address, channel, value))

    def speed(self, channel: int, counts_per_s: int) -> None:
        """Commands 35/36: signed speed in counts/s (closed loop)."""
        self._write(P.speed_frame(self.address, channel, counts_per_s))

    def set_position_pid(self, channel: int, p: float, i: float, d: float, max_i: int, deadzone: int,
                         min_pos: int, max_pos: int) -> None:
        """Commands 61/62: position PID; gains are floats sent as ``round(gain * 1024)``."""
        self._write(P.set_position_pid_frame(self.address, channel, p, i, d, max_i, deadzone, min_pos, max_pos))

    def read_position_pid(self, channel: int) -> P.PositionPID:
        """Commands 63/64: position PID settings of ``channel``."""
        return P.parse_position_pid(self._read(P.channel_command(P.Cmd.READ_POSITION_PID_M1, channel)))

    def speed_accel_decel_position(self, channel: int, accel: int, speed: int, decel: int, position: int,
                                   buffer: bool = True) -> None:
        """Commands 65/66: move to ``position`` [counts] with trapezoid limits.

        ``buffer=True`` queues the move after the current one (flag 0);
        ``buffer=False`` replaces the current move immediately (flag 1).
        """
        self._write(P.speed_accel_decel_position_frame(self.address, channel, accel, speed, decel, position, buffer))

    def read_status(self) -> int:
        """Command 90: controller status word (uint32 variant, newer firmware)."""
        return P.parse_status(self._read(P.Cmd.READ_STATUS))

    def stop_all(self) -> None:
        """Duty 0 on both channels; tries channel 2 even if channel 1 fails, then re-raises."""
        first: RoboClawError | None = None
        for channel in (1, 2):
            try:
                self.duty(channel, 0)
            except RoboClawError as exc:
                first = first or exc
                if isinstance(exc, RoboClawConnectionError):
                    break
        if first is not None:
            raise first
