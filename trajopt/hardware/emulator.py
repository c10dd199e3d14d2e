"""RoboClaw emulator on a pseudo-terminal, for tests and demos without hardware (POSIX only).

One emulator is one serial bus: it answers for one or more packet-serial
addresses (one per emulated controller), each with two motor channels
(see :mod:`._motion` for the motor model).  Open :attr:`RoboClawEmulator.port`
with pyserial (or :class:`~trajopt.hardware.RoboClaw`) like a real device::

    with RoboClawEmulator(addresses=(0x80,)) as emu:
        rc = RoboClaw(emu.port, 0x80, timeout=0.05)
        rc.duty(1, 0)

Like the real device it silently drops packets with a bad CRC, packets for
unknown commands, and partial packets after 10 ms without a byte.  Faults can
be injected: :meth:`inject_no_reply`, :meth:`inject_bad_crc`,
:meth:`inject_bad_ack`, :meth:`disconnect`, :meth:`disconnect_after`.
"""

from __future__ import annotations

import os
import select
import struct
import threading
import time
import tty
from dataclasses import dataclass
from typing import Callable, Iterable, NamedTuple

from . import protocol as P
from ._motion import ChannelModel, Move

DEFAULT_FIRMWARE = "USB Roboclaw 2x7a v4.1.34"


class ReceivedPacket(NamedTuple):
    """A CRC-valid packet addressed to the emulator; ``answered`` is False if a fault swallowed it."""

    time: float
    address: int
    command: int
    data: bytes
    answered: bool


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


class _Controller:
    def __init__(self, address: int, no_load_speed: float, battery_voltage: float) -> None:
        self.address = address
        self.channels = (ChannelModel(no_load_speed), ChannelModel(no_load_speed))
        self.battery_voltage = battery_voltage
        self.status = 0


class RoboClawEmulator:
    """Emulated RoboClaw bus on a pty, served by a background thread.

    Args:
        addresses: packet-serial addresses answered on this bus.
        firmware: version string returned by command 21 (``"\\n\\0"`` is appended).
        battery_voltage: main battery voltage reported by command 24 [V].
        no_load_speed: velocity [counts/s] at full duty in duty mode.
        packet_gap: silence [s] after which a partial packet is dropped (10 ms on the device).
        clock: monotonic clock driving the motion model.
    """

    SUBSTEP = 0.0005

    def __init__(self, addresses: Iterable[int] = (0x80,), *, firmware: str = DEFAULT_FIRMWARE,
                 battery_voltage: float = 12.0, no_load_speed: float = 6000.0, packet_gap: float = 0.010,
                 clock: Callable[[], float] = time.monotonic) -> None:
        addrs = [P.check_address(a) for a in addresses]
        if not addrs:
            raise ValueError("addresses must not be empty")
        self._ctrl = {a: _Controller(a, no_load_speed, battery_voltage) for a in addrs}
        self.firmware = firmware
        self.packet_gap = packet_gap
        self._clock = clock
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._disconnect_now = threading.Event()
        self._closed = threading.Event()
        self._thread: threading.Thread | None = None
        self._master, self._slave = os.openpty()
        tty.setraw(self._master)
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.port: str = os.ttyname(self._slave)
        self._log: list[ReceivedPacket] = []
        self._faults = {"no_reply": 0, "bad_crc": 0, "bad_ack": 0}
        self._disconnect_after: int | None = None
        self._connected = True
        self.dropped_packets = 0
        self._last_t = clock()

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> RoboClawEmulator:
        """Start serving in a daemon thread (idempotent)."""
        if self._thread is None:
            self._last_t = self._clock()
            self._thread = threading.Thread(target=self._serve, name=f"RoboClawEmulator({self.port})", daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the thread and close the pty (idempotent)."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        self._close_fds()

    def __enter__(self) -> RoboClawEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _close_fds(self) -> None:
        with self._lock:
            if self._connected:
                self._connected = False
                for fd in (self._master, self._slave):
                    try:
                        os.close(fd)
                    except OSError:
                        pass
                self._closed.set()

    @property
    def connected(self) -> bool:
        """False once :meth:`disconnect` (or :meth:`stop`) closed the pty."""
        return self._connected

    # ------------------------------------------------------------------ faults
    def inject_no_reply(self, times: int | None = 1) -> None:
        """Ignore the next ``times`` valid packets entirely (not executed, no reply); ``None`` = forever."""
        with self._lock:
            self._faults["no_reply"] = -1 if times is None else times

    def inject_bad_crc(self, times: int | None = 1) -> None:
        """Corrupt the CRC of the next ``times`` read replies; ``None`` = forever."""
        with self._lock:
            self._faults["bad_crc"] = -1 if times is None else times

    def inject_bad_ack(self, times: int | None = 1) -> None:
        """Answer the next ``times`` writes with 0x00 instead of 0xFF (executed anyway); ``None`` = forever."""
        with self._lock:
            self._faults["bad_ack"] = -1 if times is None else times

    def clear_faults(self) -> None:
        """Cancel all pending injected faults (not a disconnect that already happened)."""
        with self._lock:
            self._faults = dict.fromkeys(self._faults, 0)
            self._disconnect_after = None

    def disconnect(self) -> None:
        """Close the emulator's end of the pty now: the client sees an I/O error / EOF.

        The serving thread closes the descriptors itself (never while it is
        blocked on them), so this waits up to a second for it.
        """
        thread = self._thread
        if thread is not None and thread.is_alive() and thread is not threading.current_thread():
            self._disconnect_now.set()
            self._closed.wait(timeout=1.0)
        else:
            self._close_fds()

    def disconnect_after(self, packets: int) -> None:
        """Disconnect on receipt of the ``packets``-th next valid packet (which is not answered)."""
        with self._lock:
            self._disconnect_after = P.check_int("packets", packets, 1, 2**31)

    def _take_fault(self, name: str) -> bool:
        n = self._faults[name]
        if n == 0:
            return False
        if n > 0:
            self._faults[name] = n - 1
        return True

    # ------------------------------------------------------------------ inspection
    def _controller(self, address: int | None) -> _Controller:
        if address is None:
            if len(self._ctrl) != 1:
                raise ValueError("several addresses emulated: pass address=")
            return next(iter(self._ctrl.values()))
        if address not in self._ctrl:
            raise ValueError(f"address {address:#x} is not emulated (have {[hex(a) for a in self._ctrl]})")
        return self._ctrl[address]

    def snapshot(self, address: int | None = None) -> ControllerSnapshot:
        """Current state of one controller (motion integrated up to now)."""
        with self._lock:
            self._advance(self._clock())
            c = self._controller(address)
            ch = c.channels
            return ControllerSnapshot(
                c.address, (ch[0].count, ch[1].count), (ch[0].vel, ch[1].vel), (ch[0].mode, ch[1].mode),
                (ch[0].target, ch[1].target), (ch[0].duty, ch[1].duty), (ch[0].speed_cmd, ch[1].speed_cmd),
                (len(ch[0].queue), len(ch[1].queue)), c.battery_voltage)

    def counts(self, address: int | None = None) -> tuple[int, int]:
        """Encoder counts (M1, M2) of one controller."""
        return self.snapshot(address).counts

    def set_counts(self, m1: int, m2: int, address: int | None = None) -> None:
        """Overwrite both encoder counters."""
        with self._lock:
            c = self._controller(address)
            c.channels[0].set_count(m1)
            c.channels[1].set_count(m2)

    def set_battery_voltage(self, volts: float, address: int | None = None) -> None:
        """Change the battery voltage reported by command 24."""
        with self._lock:
            self._controller(address).battery_voltage = float(volts)

    def set_status(self, status: int, address: int | None = None) -> None:
        """Change the uint32 status word reported by command 90."""
        with self._lock:
            self._controller(address).status = P.check_int("status", status, 0, P.UINT32_MAX)

    @property
    def received(self) -> list[ReceivedPacket]:
        """Copy of the log of valid packets received so far."""
        with self._lock:
            return list(self._log)

    def commands(self, address: int | None = None) -> list[int]:
        """Command numbers received (all addresses by default), in order."""
        return [p.command for p in self.received if address is None or p.address == address]

    # ------------------------------------------------------------------ serving
    def _advance(self, now: float) -> None:
        elapsed = min(now - self._last_t, 1.0)
        self._last_t = now
        while elapsed > 1e-12:
            h = min(self.SUBSTEP, elapsed)
            for c in self._ctrl.values():
                for ch in c.channels:
                    ch.advance(h)
            elapsed -= h

    def _serve(self) -> None:
        buf = bytearray()
        last_rx = 0.0
        while not self._stop.is_set() and self._connected:
            if self._disconnect_now.is_set():
                self._close_fds()
                break
            try:
                ready, _, _ = select.select([self._master], [], [], 0.002)
                data = os.read(self._master, 4096) if ready else b""
            except (OSError, ValueError):  # closed by disconnect()
                break
            now = self._clock()
            with self._lock:
                self._advance(now)
                if buf and now - last_rx > self.packet_gap:
                    buf.clear()  # partial packet: silence too long
                    self.dropped_packets += 1
                if data:
                    last_rx = now
                    buf += data
                    self._consume(buf, now)

    def _consume(self, buf: bytearray, now: float) -> None:
        while buf and self._connected:
            if not P.ADDRESS_MIN <= buf[0] <= P.ADDRESS_MAX:
                del buf[0]
                continue
            if len(buf) < 2:
                return
            n = P.REQUEST_DATA_LEN.get(buf[1])
            if n is None:  # unknown command: resynchronise on the next byte
                del buf[0]
                self.dropped_packets += 1
                continue
            if len(buf) < 4 + n:
                return
            frame = bytes(buf[:4 + n])
            del buf[:4 + n]
            if P.crc16(frame[:-2]) != struct.unpack(">H", frame[-2:])[0]:
                self.dropped_packets += 1
                continue
            address, command, payload = frame[0], frame[1], frame[2:-2]
            if address not in self._ctrl:
                continue
            if self._disconnect_after is not None:
                self._disconnect_after -= 1
                if self._disconnect_after <= 0:
                    self._log.append(ReceivedPacket(now, address, command, payload, False))
                    self._close_fds()
                    return
            if self._take_fault("no_reply"):
                self._log.append(ReceivedPacket(now, address, command, payload, False))
                continue
            self._log.append(ReceivedPacket(now, address, command, payload, True))
            reply = self._handle(self._ctrl[address], command, payload)
            try:
                os.write(self._master, reply)
            except (BlockingIOError, OSError):
                pass  # client not reading: the reply is lost, like on a real line

    def _handle(self, c: _Controller, command: int, data: bytes) -> bytes:
        """Execute one valid packet and return the reply bytes."""
        C = P.Cmd
        if command in P.READ_COMMANDS:
            if command in (C.READ_ENCODER_M1, C.READ_ENCODER_M2):
                ch = c.channels[command - C.READ_ENCODER_M1]
                body = struct.pack(">iB", ch.count, 0x02 if ch.vel < 0 else 0x00)
            elif command == C.READ_FIRMWARE:
                body = self.firmware.encode("ascii")[:P.FIRMWARE_MAX_LEN] + P.FIRMWARE_TERMINATOR
            elif command == C.READ_MAIN_BATTERY:
                body = struct.pack(">H", max(0, min(65535, round(c.battery_voltage * 10))))
            elif command in (C.READ_POSITION_PID_M1, C.READ_POSITION_PID_M2):
                body = struct.pack(">IIIIIii", *c.channels[command - C.READ_POSITION_PID_M1].pid)
            else:  # READ_STATUS
                body = struct.pack(">I", c.status)
            crc = P.reply_crc(c.address, command, body)
            if self._take_fault("bad_crc"):
                crc = bytes(b ^ 0xFF for b in crc)
            return body + crc
        if command == C.RESET_ENCODERS:
            for ch in c.channels:
                ch.set_count(0)
        elif command in (C.SET_ENCODER_M1, C.SET_ENCODER_M2):
            c.channels[command - C.SET_ENCODER_M1].set_count(struct.unpack(">i", data)[0])
        elif command in (C.DUTY_M1, C.DUTY_M2):
            c.channels[command - C.DUTY_M1].set_duty(struct.unpack(">h", data)[0])
        elif command in (C.SPEED_M1, C.SPEED_M2):
            c.channels[command - C.SPEED_M1].set_speed(struct.unpack(">i", data)[0])
        elif command in (C.SET_POSITION_PID_M1, C.SET_POSITION_PID_M2):
            d, p, i, max_i, deadzone, min_pos, max_pos = struct.unpack(">IIIIIii", data)
            c.channels[command - C.SET_POSITION_PID_M1].pid = (p, i, d, max_i, deadzone, min_pos, max_pos)
        elif command in (C.SPEED_ACCEL_DECEL_POSITION_M1, C.SPEED_ACCEL_DECEL_POSITION_M2):
            accel, speed, decel, position, flag = struct.unpack(">IIIiB", data)
            c.channels[command - C.SPEED_ACCEL_DECEL_POSITION_M1].command_move(
                Move(accel, speed, decel, position), immediate=flag != 0)
        return bytes((0x00,)) if self._take_fault("bad_ack") else bytes((P.ACK,))
