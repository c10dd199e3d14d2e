"""Which replies may still arrive on a serial line: the bookkeeping that matches every reply to its request.

A RoboClaw answers its requests in order, one at a time, but a reply can come
late (after the driver gave up on it), and every write is acknowledged by the
same single byte 0xFF.  :class:`LineState` records, per controller address,
the *kinds* of reply still owed (:data:`ACK_REPLY` for writes, the command
number for reads, :data:`UNKNOWN_REPLY` after stray bytes); the driver
(:mod:`.driver`) sends a write only on a line that owes nothing, and a read
only when no reply of its own kind is owed by its controller -- otherwise it
first *probes* with a read of another kind, whose CRC (over address and
command) no owed reply can pass.
"""

from __future__ import annotations

import weakref
from typing import Any

from . import protocol as P

#: Reply kind of every write (the byte 0xFF); a read's reply kind is its command number.
ACK_REPLY = -1
#: Stray bytes of unknown origin were drained from a line that owed nothing.
UNKNOWN_REPLY = -2
#: Reads used as probes to bring a line back in sync (short, fixed-length replies), by preference.
SYNC_PROBES = (P.Cmd.READ_MAIN_BATTERY, P.Cmd.READ_ENCODER_M1, P.Cmd.READ_ENCODER_M2,
               P.Cmd.READ_POSITION_PID_M1, P.Cmd.READ_POSITION_PID_M2)


class LineState:
    """Which replies may still arrive (late) on one serial line, per controller address.

    A controller answers in order, so once one of its replies is matched for
    certain (a read whose kind was not owed), it owes nothing earlier.
    """

    def __init__(self) -> None:
        self.owed: dict[int, set[int]] = {}
        self.addresses: set[int] = set()
        self.stray_bytes = 0

    def in_sync(self) -> bool:
        """True if no reply may still arrive from any controller on the line."""
        return not any(self.owed.values())

    def owes(self, address: int, kind: int) -> bool:
        """True if a request of ``kind`` to ``address`` cannot be told apart from an owed reply."""
        if kind == ACK_REPLY:  # every write gets the same 0xFF; any owed byte could pass for it
            return not self.in_sync()
        return kind in self.owed.get(address, ())

    def owe(self, address: int, kind: int) -> None:
        """A request of ``kind`` was sent but its reply was not (certainly) received."""
        self.owed.setdefault(address, set()).add(kind)

    def matched(self, address: int) -> None:
        """A reply of ``address`` was matched for certain: nothing earlier is owed by it."""
        self.owed.pop(address, None)


_LINES: weakref.WeakKeyDictionary[Any, LineState] = weakref.WeakKeyDictionary()


def line_state(ser: Any) -> LineState:
    """The :class:`LineState` shared by all drivers on serial object ``ser``."""
    try:
        return _LINES.setdefault(ser, LineState())
    except TypeError:  # not weak-referenceable: private to this driver
        return LineState()
