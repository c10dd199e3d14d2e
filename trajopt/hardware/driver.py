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

Every reply is matched to its own request.  A controller answers its requests in
order, one at a time, but a reply can come late (after the driver gave up on it)
and a write's acknowledgement is the single byte 0xFF, whatever the command.  So:

* stale bytes are drained before every request (after a failure, until the line
  has been quiet for :attr:`RoboClaw.SETTLE` s);
* :class:`LineState` (shared by every driver on one serial object) remembers
  which replies may still arrive late; a write is only sent on a line that owes
  nothing -- otherwise a *probe* (a read whose reply cannot be confused with any
  owed one: its CRC covers address and command) first proves that every owed
  reply has arrived; if the probe fails the write is still sent, but its 0xFF
  raises :class:`RoboClawUnmatchedReply` instead of counting as a success;
* bytes beyond the expected reply make the exchange an error, not a success.

Retries: a timeout, a CRC mismatch, a wrong ACK byte or an unmatched reply is
retried ``retries`` times; every request used here is idempotent, so re-sending
a write whose ACK was lost is harmless.  Port failures
(:class:`RoboClawConnectionError`) are not retried.
"""

from __future__ import annotations

import logging
import time
from typing import Any, Callable, Protocol, TypeVar

from . import protocol as P
from ._line import ACK_REPLY, SYNC_PROBES, UNKNOWN_REPLY, LineState, line_state
from .errors import (
    RoboClawConnectionError,
    RoboClawCRCError,
    RoboClawError,
    RoboClawNoAck,
    RoboClawTimeout,
    RoboClawUnmatchedReply,
)

T = TypeVar("T")
log = logging.getLogger("trajopt.hardware")

_RETRYABLE = (RoboClawTimeout, RoboClawCRCError, RoboClawNoAck, RoboClawUnmatchedReply)

#: Shortest write timeout [s] of a port opened here: only a device that stops taking bytes (a stuck
#: USB link) hits it, so it is generous -- a busy host that stalls a moment must not abort a playback.
WRITE_TIMEOUT = 2.0

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
        return serial.serial_for_url(port, baudrate=baudrate, timeout=timeout, write_timeout=max(timeout, WRITE_TIMEOUT))
    except (serial.SerialException, OSError) as exc:
        raise RoboClawConnectionError(f"cannot open serial port {port!r}: {exc}") from exc


class RoboClaw:
    """Driver for one RoboClaw controller (one address) in packet-serial mode.

    Args:
        port_or_serial: port name / pyserial URL (opened with ``serial.serial_for_url``)
            or an already-open serial-like object (not closed by :meth:`close`).
        address: packet-serial address 0x80..0x87.
        timeout: seconds to wait for a complete reply.
        retries: extra attempts after a timeout / CRC error / bad ACK / unmatched reply.
        baudrate: only used when opening a port by name (ignored by USB RoboClaws).
    """

    #: Silence [s] that ends the drain after a failed exchange (the device's packet gap).
    SETTLE = 0.010

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
        self._line = line_state(self._ser)
        self._can_peek = hasattr(type(self._ser), "in_waiting")  # pyserial: bytes already received

    # ------------------------------------------------------------------ lifecycle
    def at_address(self, address: int) -> RoboClaw:
        """A driver for another controller on the same serial port (shares, does not own, it)."""
        return RoboClaw(self._ser, address, timeout=self.timeout, retries=self.retries)

    @property
    def serial(self) -> Any:
        """The underlying serial object."""
        return self._ser

    @property
    def line(self) -> LineState:
        """Replies still owed on this driver's serial line (shared with its siblings)."""
        return self._line

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
            buf += self._read_chunk(len(sofar) + n - len(buf), command, bytes(buf))
        return bytes(buf[len(sofar):])

    def _in_waiting(self, command: int) -> int:
        try:
            return int(self._ser.in_waiting)
        except Exception as exc:  # noqa: BLE001 - SerialException/OSError on a dead port
            raise self._error(RoboClawConnectionError, f"port check failed: {exc}", command, b"") from exc

    def _drain(self, command: int, quiet: float) -> None:
        """Discard stale input; with ``quiet > 0`` keep discarding until the line was silent that long."""
        stray = bytearray()
        start = last = time.monotonic()
        while self._can_peek:
            n = self._in_waiting(command)
            now = time.monotonic()
            if n:
                stray += self._read_chunk(n, command, bytes(stray))
                last = now
            elif now - last >= quiet or now - start > quiet + self.timeout:  # a babbling line cannot hold us
                break
            else:
                time.sleep(0.001)
        try:
            self._ser.reset_input_buffer()
        except Exception as exc:  # noqa: BLE001 - termios.error on a dead pty
            raise self._error(RoboClawConnectionError, f"flush failed: {exc}", command, b"") from exc
        if stray:
            self._line.stray_bytes += len(stray)
            log.warning("%s: discarded %d stale byte(s) before command %d (%s): %s", self, len(stray), command,
                        P.command_name(command), bytes(stray).hex(" "))
            if self._line.in_sync():  # nothing was owed: some earlier exchange may have been mismatched
                for address in self._line.addresses:
                    self._line.owe(address, UNKNOWN_REPLY)

    def _read_chunk(self, n: int, command: int, sofar: bytes) -> bytes:
        try:
            return bytes(self._ser.read(n))
        except Exception as exc:  # noqa: BLE001
            raise self._error(RoboClawConnectionError, f"read failed: {exc}", command, sofar) from exc

    def _resync(self, kind: int, command: int) -> RoboClawError | None:
        """Probe the controllers that may owe a reply confusable with ``kind``; ``None`` once in sync."""
        addresses = sorted(self._line.addresses | set(self._line.owed)) if kind == ACK_REPLY else [self.address]
        for address in addresses:
            owed = self._line.owed.get(address)
            if not owed:
                continue
            probe = next((c for c in SYNC_PROBES if c not in owed and c != kind), SYNC_PROBES[0])
            drv = self if address == self.address else self.at_address(address)
            try:
                drv._attempt(P.read_frame(address, probe), drv._fixed_reply(probe), probe, quiet=self.SETTLE,
                             probing=True)
            except RoboClawConnectionError:
                raise
            except RoboClawError as exc:
                return exc
        if self._line.owes(self.address, kind):
            return self._error(RoboClawUnmatchedReply, "owed replies could not be ruled out", command, b"")
        return None

    def _attempt(self, frame: bytes, receive: Callable[[float], T], kind: int, quiet: float,
                 probing: bool = False) -> T:
        """One request/reply; any failure (even KeyboardInterrupt) leaves its reply owed.

        A read is not sent while its reply could be confused with a late one (the probe failed);
        a write is sent anyway (a stop must go out), but its 0xFF then does not count as an ACK.
        A probe never probes: if its own kind is owed, success proves only that nothing else is.
        """
        command, line = frame[1], self._line
        line.addresses.add(self.address)
        matched = False
        try:
            self._drain(command, quiet)
            still_owed = probing and line.owes(self.address, kind)
            doubt = self._resync(kind, command) if not probing and line.owes(self.address, kind) else None
            if doubt is not None:
                probe = P.command_name(doubt.command if doubt.command is not None else command)
                why = f"sync probe {probe} of {doubt.address or self.address:#04x} failed ({doubt.detail}) " \
                      "after an earlier request went unanswered"
                if kind != ACK_REPLY:
                    cls = type(doubt) if isinstance(doubt, _RETRYABLE) else RoboClawUnmatchedReply
                    raise self._error(cls, f"not sent: {why}", command, doubt.received)
            self._send(frame)
            result = receive(time.monotonic() + self.timeout)
            extra = self._read_chunk(self._in_waiting(command), command, b"") if self._can_peek else b""
            if extra:
                raise self._error(RoboClawUnmatchedReply, f"{len(extra)} byte(s) beyond the reply arrived, so the "
                                  "reply may belong to another request", command, extra)
            if doubt is not None:
                raise self._error(RoboClawUnmatchedReply, f"0xff received but it may be a late reply: {why}",
                                  command, bytes((P.ACK,)))
            matched = not still_owed
            line.matched(self.address)
            return result
        finally:
            if not matched:
                line.owe(self.address, kind)

    def _exchange(self, frame: bytes, receive: Callable[[float], T], kind: int) -> T:
        """Send ``frame`` and parse the answer with ``receive(deadline)``, retrying transient errors.

        After the last attempt the *first* error is raised (the root cause; later ones are often
        failed sync probes), with ``attempts`` set.
        """
        first: RoboClawError | None = None
        for attempt in range(self.retries + 1):
            try:
                return self._attempt(frame, receive, kind, quiet=self.SETTLE if attempt else 0.0)
            except _RETRYABLE as exc:
                first = first or exc
        assert first is not None
        first.attempts = self.retries + 1
        raise first

    def _write(self, frame: bytes) -> None:
        command = frame[1]

        def receive(deadline: float) -> None:
            got = self._read_exact(1, deadline, command)
            if got[0] != P.ACK:
                raise self._error(RoboClawNoAck, "expected ACK 0xff", command, got)

        self._exchange(frame, receive, ACK_REPLY)

    def _check_crc(self, command: int, data: bytes, crc: bytes) -> bytes:
        if P.reply_crc(self.address, command, data) != crc:
            raise self._error(RoboClawCRCError, f"reply CRC mismatch (expected "
                              f"{P.reply_crc(self.address, command, data).hex()})", command, data + crc)
        return data

    def _fixed_reply(self, command: int) -> Callable[[float], bytes]:
        """Receiver of a fixed-length read reply: the CRC-checked data."""
        n = P.REPLY_DATA_LEN[command]
        assert n is not None

        def receive(deadline: float) -> bytes:
            raw = self._read_exact(n + 2, deadline, command)
            return self._check_crc(command, raw[:n], raw[n:])

        return receive

    def _read(self, command: int) -> bytes:
        """Send a read request and return the CRC-checked reply data."""
        return self._exchange(P.read_frame(self.address, command), self._fixed_reply(command), command)

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

        return self._exchange(P.read_frame(self.address, command), receive, command)

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
