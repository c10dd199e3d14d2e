"""RoboClaw emulator on a pseudo-terminal, for tests and demos without hardware (POSIX only).

One emulator is one serial bus: it answers for one or more packet-serial
addresses (one per emulated controller), each with two motor channels
(see :mod:`._motion` for the motor model).  Open :attr:`RoboClawEmulator.port`
with pyserial (or :class:`~trajopt.hardware.RoboClaw`) like a real device::

    with RoboClawEmulator(addresses=(0x80,)) as emu:
        rc = RoboClaw(emu.port, 0x80, timeout=0.05)
        rc.duty(1, 0)

Like the real device it silently drops packets with a bad CRC, packets for
unknown commands, and partial packets after 10 ms without a byte, and it
answers requests in order.  Faults can be injected, each for the next ``times``
valid packets (``None`` = forever), optionally only for one ``command``:

* :meth:`inject_no_reply` -- the request is lost: not executed, no reply
  (forever: a hung controller, :meth:`hang`);
* :meth:`inject_lost_reply` -- executed, but the reply is lost;
* :meth:`inject_late_reply` -- executed, the reply leaves ``delay`` s later
  (later replies queue behind it, as on a busy controller); ``delay=None``: it
  leaves when the next request arrives -- later than any client timeout, whatever the load;
* :meth:`inject_partial_reply` -- executed, only the first bytes of the reply leave;
* :meth:`inject_bad_crc` / :meth:`inject_bad_ack` -- corrupted read CRC / ACK byte 0x00;
* :meth:`jam` -- a channel cannot move (snagged cable): its encoder stays put;
* :meth:`run_away` -- a channel turns whatever it is commanded (duty 0 acknowledged, motor still moving);
* :meth:`disconnect` / :meth:`disconnect_after` -- the port disappears (unplugged);
* :meth:`after_packets` -- run any of these at a chosen packet.
"""

from __future__ import annotations

import math
import os
import select
import struct
import threading
import time
import tty
from collections import deque
from dataclasses import dataclass
from typing import Callable, Iterable, NamedTuple

from . import protocol as P
from ._emulated import ControllerSnapshot, EmulatedController

__all__ = ["ControllerSnapshot", "DEFAULT_FIRMWARE", "ReceivedPacket", "RoboClawEmulator"]

DEFAULT_FIRMWARE = "USB Roboclaw 2x7a v4.1.34"


class ReceivedPacket(NamedTuple):
    """A CRC-valid packet addressed to the emulator.

    ``executed`` is False if a fault lost the request, ``answered`` False if no reply (or only part
    of it) left.
    """

    time: float
    address: int
    command: int
    data: bytes
    answered: bool
    executed: bool = True


@dataclass
class _Fault:
    kind: str
    remaining: int  # -1 = forever
    command: int | None
    arg: float = 0.0  # delay [s] (late_reply) or bytes kept (partial_reply)


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
        self._ctrl = {a: EmulatedController(a, no_load_speed, battery_voltage) for a in addrs}
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
        self._faults: list[_Fault] = []
        self._outbox: deque[tuple[float, bytes]] = deque()  # (release time, bytes), in order
        self._disconnect_after: int | None = None
        self._hooks: list[list] = []  # [packets left, callback]
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
    def _inject(self, kind: str, times: int | None, command: int | None, arg: float = 0.0) -> None:
        remaining = -1 if times is None else P.check_int("times", times, 1, 2**31)
        if command is not None:
            P.check_int("command", command, 0, 255)
        with self._lock:
            self._faults.append(_Fault(kind, remaining, command, float(arg)))

    def inject_no_reply(self, times: int | None = 1, command: int | None = None) -> None:
        """Lose the next ``times`` valid requests (not executed, no reply); ``None`` = forever."""
        self._inject("no_reply", times, command)

    def hang(self) -> None:
        """The controller stops answering (and executing) anything from now on."""
        self.inject_no_reply(None)

    def inject_lost_reply(self, times: int | None = 1, command: int | None = None) -> None:
        """Execute the next ``times`` valid requests but lose their replies."""
        self._inject("lost_reply", times, command)

    def inject_late_reply(self, delay: float | None, times: int | None = 1, command: int | None = None) -> None:
        """Execute the next ``times`` valid requests now but send their replies ``delay`` s later; ``None``: when
        the next request arrives (after the client gave up, whatever the load: it sends nothing new before)."""
        if delay is not None and not delay > 0:
            raise ValueError(f"delay {delay!r} must be a positive number of seconds or None")
        self._inject("late_reply", times, command, math.inf if delay is None else delay)

    def inject_partial_reply(self, n_bytes: int, times: int | None = 1, command: int | None = None) -> None:
        """Execute the next ``times`` valid requests but send only the first ``n_bytes`` of each reply."""
        self._inject("partial_reply", times, command, P.check_int("n_bytes", n_bytes, 0, 1000))

    def inject_bad_crc(self, times: int | None = 1, command: int | None = None) -> None:
        """Corrupt the CRC of the next ``times`` read replies; ``None`` = forever."""
        self._inject("bad_crc", times, command)

    def inject_bad_ack(self, times: int | None = 1, command: int | None = None) -> None:
        """Answer the next ``times`` writes with 0x00 instead of 0xFF (executed anyway); ``None`` = forever."""
        self._inject("bad_ack", times, command)

    def jam(self, channel: int, address: int | None = None, jammed: bool = True) -> None:
        """Jam (or free) motor ``channel``: whatever it is commanded, its encoder stays put."""
        with self._lock:
            self._advance(self._clock())
            self._controller(address).channels[P.check_channel(channel) - 1].jammed = bool(jammed)

    def run_away(self, channel: int, speed: float | None, address: int | None = None) -> None:
        """Motor ``channel`` turns at ``speed`` counts/s whatever it is commanded (``None``: obeys again)."""
        with self._lock:
            self._advance(self._clock())
            motor = self._controller(address).channels[P.check_channel(channel) - 1]
            motor.runaway = None if speed is None else float(speed)

    def clear_faults(self) -> None:
        """Cancel all pending injected faults (not a disconnect that already happened, nor a jam)."""
        with self._lock:
            self._faults.clear()
            self._disconnect_after = None
            self._hooks.clear()

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

    def after_packets(self, packets: int, callback: Callable[[], object]) -> None:
        """Call ``callback()`` (in the serving thread) on receipt of the ``packets``-th next valid packet,
        before that packet is handled -- e.g. to inject faults at a chosen point of a playback."""
        with self._lock:
            self._hooks.append([P.check_int("packets", packets, 1, 2**31), callback])

    def _take_fault(self, kind: str, command: int, is_read: bool | None = None) -> _Fault | None:
        if is_read is not None and (command in P.READ_COMMANDS) != is_read:
            return None
        for fault in self._faults:
            if fault.kind == kind and fault.remaining != 0 and fault.command in (None, command):
                if fault.remaining > 0:
                    fault.remaining -= 1
                return fault
        return None

    # ------------------------------------------------------------------ inspection
    def _controller(self, address: int | None) -> EmulatedController:
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
            return self._controller(address).snapshot()

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
                c.advance(h)
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
                self._flush_outbox(now)

    def _flush_outbox(self, now: float) -> None:
        while self._outbox and self._outbox[0][0] <= now and self._connected:
            _, reply = self._outbox.popleft()
            try:
                os.write(self._master, reply)
            except (BlockingIOError, OSError):
                pass  # client not reading: the reply is lost, like on a real line

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
            if self._outbox and self._outbox[-1][0] == math.inf:  # replies held until a request arrives
                self._outbox = deque((min(t, now), reply) for t, reply in self._outbox)
                self._flush_outbox(now)
            for hook in list(self._hooks):
                hook[0] -= 1
                if hook[0] <= 0:
                    self._hooks.remove(hook)
                    hook[1]()
            if self._disconnect_after is not None:
                self._disconnect_after -= 1
                if self._disconnect_after <= 0:
                    self._log.append(ReceivedPacket(now, address, command, payload, False, False))
                    self._close_fds()
                    return
            if self._take_fault("no_reply", command):
                self._log.append(ReceivedPacket(now, address, command, payload, False, False))
                continue
            self._reply(address, command, payload, now)

    def _reply(self, address: int, command: int, payload: bytes, now: float) -> None:
        """Execute a valid request and queue its reply, applying the injected faults."""
        reply = self._ctrl[address].execute(command, payload, self.firmware)
        if self._take_fault("bad_crc", command, is_read=True):
            reply = reply[:-2] + bytes(b ^ 0xFF for b in reply[-2:])
        if self._take_fault("bad_ack", command, is_read=False):
            reply = bytes((0x00,))
        answered = True
        if self._take_fault("lost_reply", command):
            reply, answered = b"", False
        partial = self._take_fault("partial_reply", command)
        if partial is not None:
            reply, answered = reply[:int(partial.arg)], False
        late = self._take_fault("late_reply", command)
        release = now + (late.arg if late is not None else 0.0)
        if self._outbox:
            release = max(release, self._outbox[-1][0])  # replies leave in order
        self._log.append(ReceivedPacket(now, address, command, payload, answered))
        if reply:
            self._outbox.append((release, reply))
        self._flush_outbox(now)
