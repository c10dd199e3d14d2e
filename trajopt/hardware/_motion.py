"""Idealised motor model of one emulated RoboClaw channel (used by :mod:`.emulator`).

The encoder position is a float integrated with small fixed sub-steps:

* ``duty`` mode: velocity = duty / 32767 * ``no_load_speed`` (no dynamics);
* ``speed`` mode: velocity = commanded speed (no dynamics);
* ``position`` mode (commands 65/66): trapezoidal profile toward the target
  with the commanded speed, acceleration and deceleration; the velocity is
  steered toward ``sign(d) * min(speed, v_stop(|d|))`` (``d`` = distance to
  go, ``v_stop`` the largest speed from which a stop within ``|d|`` is still
  possible, ~``sqrt(2 * decel * |d|)``), changing by at most ``accel``
  (speeding up) or ``decel`` (slowing down) per second.  An acceleration / deceleration of 0 means
  "unlimited"; a speed of 0 holds the motor still.  Queued moves (buffer flag
  0) start when the current move has arrived; flag 1 clears the queue.

A *jammed* channel (a snagged cable, a stalled motor) does not move whatever
it is commanded: its encoder count stays put.  A *runaway* channel (a shorted
H-bridge, a controller past its own fault handling) turns at a fixed speed
whatever it is commanded, duty 0 included, and still acknowledges every command.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import NamedTuple


class Move(NamedTuple):
    """A position move as received in commands 65/66."""

    accel: int
    speed: int
    decel: int
    position: int


@dataclass
class ChannelModel:
    """State and dynamics of one motor channel."""

    no_load_speed: float = 6000.0
    pos: float = 0.0
    vel: float = 0.0
    mode: str = "idle"  # idle | duty | speed | position
    duty: int = 0
    speed_cmd: int = 0
    move: Move | None = None
    queue: deque[Move] = field(default_factory=deque)
    pid: tuple[int, int, int, int, int, int, int] = (0, 0, 0, 0, 0, 0, 0)  # raw P, I, D, MaxI, DZ, Min, Max
    jammed: bool = False
    runaway: float | None = None  # counts/s it turns at whatever it is commanded; None = obeys

    @property
    def count(self) -> int:
        """Integer encoder count as reported by commands 16/17."""
        return int(math.floor(self.pos + 0.5))

    @property
    def target(self) -> int | None:
        """Current position target (``None`` outside position mode)."""
        return self.move.position if self.mode == "position" and self.move else None

    def set_count(self, count: int) -> None:
        """Commands 20/22/23: overwrite the counter; an active position move keeps its target."""
        self.pos = float(count)

    def set_duty(self, duty: int) -> None:
        """Commands 32/33 (duty 0 = stop and clear queued moves)."""
        self.mode, self.duty, self.move = ("duty" if duty else "idle"), duty, None
        self.queue.clear()
        if not duty:
            self.vel = 0.0

    def set_speed(self, speed: int) -> None:
        """Commands 35/36."""
        self.mode, self.speed_cmd, self.move = "speed", speed, None
        self.queue.clear()

    def command_move(self, move: Move, immediate: bool) -> None:
        """Commands 65/66: execute now (``immediate``) or after the current move."""
        if immediate or self.mode != "position" or self.move is None:
            self.queue.clear()
            self.mode, self.move = "position", move
        else:
            self.queue.append(move)

    def advance(self, h: float) -> None:
        """Integrate the model over ``h`` seconds (call with small ``h``)."""
        if self.jammed:
            self.vel = 0.0
            return
        if self.runaway is not None:
            self.vel = self.runaway
            self.pos += self.vel * h
            return
        if self.mode == "duty":
            self.vel = self.duty / 32767.0 * self.no_load_speed
        elif self.mode == "speed":
            self.vel = float(self.speed_cmd)
        elif self.mode == "position" and self.move is not None:
            self._advance_position(h)
            return
        else:
            self.vel = 0.0
        self.pos += self.vel * h

    def _advance_position(self, h: float) -> None:
        move = self.move
        assert move is not None
        if self.pos == move.position and self.vel == 0.0 and self.queue:
            self.move = move = self.queue.popleft()
        accel = float(move.accel) if move.accel > 0 else math.inf
        decel = float(move.decel) if move.decel > 0 else math.inf
        d = move.position - self.pos
        if move.speed <= 0:
            self.vel = 0.0
            return
        if d == 0.0:
            v_des = 0.0
        else:
            # largest speed from which a stop within |d| is still possible in discrete steps of h:
            # v*h + v^2 / (2 decel) <= |d|
            if decel == math.inf:
                v_stop = math.inf
            else:
                v_stop = -decel * h + math.sqrt((decel * h) ** 2 + 2.0 * decel * abs(d))
            v_des = math.copysign(min(float(move.speed), v_stop), d)
        dv = v_des - self.vel
        limit = (decel if self.vel * dv < 0 else accel) * h
        self.vel += max(-limit, min(limit, dv))
        step = self.vel * h
        if d != 0.0 and step / d >= 1.0:  # would reach or pass the target: arrive
            self.pos, self.vel = float(move.position), 0.0
        else:
            self.pos += step
