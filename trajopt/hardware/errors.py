"""Exceptions raised by the RoboClaw driver and the trajectory playback."""

from __future__ import annotations

from .protocol import command_name


class RoboClawError(Exception):
    """Base class of all RoboClaw communication errors.

    Attributes:
        detail: what went wrong, in words.
        address: controller address (0x80..0x87) or ``None``.
        command: command number or ``None``.
        received: the bytes received for the failed exchange (possibly empty).
        attempts: how many times the request was sent.
    """

    def __init__(self, detail: str, *, address: int | None = None, command: int | None = None,
                 received: bytes = b"", attempts: int = 1) -> None:
        self.detail = detail
        self.address = address
        self.command = command
        self.received = bytes(received)
        self.attempts = attempts
        super().__init__(detail)

    def __str__(self) -> str:
        where = "RoboClaw"
        if self.address is not None:
            where += f" {self.address:#04x}"
        if self.command is not None:
            where += f" command {self.command} ({command_name(self.command)})"
        got = self.received.hex(" ") if self.received else "nothing"
        tries = f" after {self.attempts} attempts" if self.attempts > 1 else ""
        return f"{where}: {self.detail}{tries}; received {len(self.received)} byte(s): {got}"


class RoboClawTimeout(RoboClawError):
    """The controller did not answer (completely) within the timeout."""


class RoboClawCRCError(RoboClawError):
    """A read reply arrived but its CRC does not match."""


class RoboClawNoAck(RoboClawError):
    """A write was answered with something other than the ACK byte 0xFF."""


class RoboClawUnmatchedReply(RoboClawError):
    """The bytes received cannot be told to be the reply to this request.

    A write's acknowledgement is one byte, 0xFF, whatever the command: after an
    earlier request went unanswered (its reply may still arrive late) or when
    more bytes arrive than the request asks for, an 0xFF proves nothing.  The
    request was sent; whether the controller executed it is unknown.
    """


class RoboClawConnectionError(RoboClawError):
    """The serial port itself failed (unplugged, closed, I/O error); not retried."""


class PlaybackError(RuntimeError):
    """Pre-flight check or playback failure that is not a communication error (e.g. low battery)."""


class TrackingError(PlaybackError):
    """A motor stayed too far from its commanded position for too long (jammed cable, stalled motor,
    disconnected encoder): playback was aborted and the motors stopped."""
