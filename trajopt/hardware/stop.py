"""Stop every motor whatever happens meanwhile, and say exactly which stops were confirmed.

:func:`stop_motors` sends duty 0 to both channels of every controller, then
confirms each stop by reading state back: a channel is *confirmed stopped* only
if its duty 0 was acknowledged by a reply matched to it (see :mod:`.driver`)
**and** its encoder then stayed within :data:`STANDSTILL_COUNTS` over
:data:`STANDSTILL_WINDOW` s (within :data:`CONFIRM_TIME` s).  A channel whose
duty 0 was acknowledged but that still moves, or whose encoder cannot be read,
gets its duty 0 once more.

Nothing ends the sequence part-way: every step catches everything (timeouts,
port errors, a KeyboardInterrupt raised by a hook, any other exception),
records it and retries an interrupted step; in the main thread Ctrl-C (SIGINT),
SIGTERM, SIGHUP, SIGQUIT and every other signal that would end the process are recorded instead of raised until the sequence ends
(:class:`~.signals.StopSignals`).  Its duration is bounded
by the drivers' timeouts and retries (a controller that does not answer at all
costs about ``2 * (max(retries, 2) + 1) * 2 * timeout`` s: two channels, each
attempt a probe of the line and the write).

Limitation: the stop is confirmed through the encoder; a motor whose encoder is
disconnected could spin while its count stands still (the duty 0 must still
have been acknowledged).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence, TypeVar

from .driver import RoboClaw
from .errors import RoboClawError
from .signals import StopSignals

T = TypeVar("T")

#: Largest encoder change [counts] over :data:`STANDSTILL_WINDOW` that still counts as standing still.
STANDSTILL_COUNTS = 2
#: Time [s] between the two encoder readings of the standstill check.
STANDSTILL_WINDOW = 0.05
#: Longest wait [s] for a channel to come to rest after its duty 0, per round.
CONFIRM_TIME = 0.5
#: Duty-0 rounds: the second re-sends duty 0 to channels acknowledged but not seen at rest.
ROUNDS = 2
#: Times an operation interrupted by something other than a RoboClaw error is tried again.
INTERRUPTED_TRIES = 3
#: The stop retries each request at least this often, whatever the configured ``retries``.
MIN_STOP_RETRIES = 2


@dataclass(frozen=True)
class ChannelStop:
    """Outcome of the stop of one motor channel."""

    label: str  # motor name, or "PORT 0x80 M2 (unused)" for a channel no motor of the config uses
    port: str
    address: int
    channel: int
    confirmed: bool
    detail: str


@dataclass(frozen=True)
class StopReport:
    """Which channels were confirmed stopped, which were not (and why), what was held back meanwhile."""

    channels: tuple[ChannelStop, ...] = ()
    unreached: tuple[str, ...] = ()  # motors on ports that never opened: nothing was sent to them
    interruptions: tuple[str, ...] = ()  # signals (Ctrl-C, SIGTERM ...) and exceptions that arrived during the stop
    signals: tuple[int, ...] = ()  # the signals among them, in order

    @property
    def all_confirmed(self) -> bool:
        """True if every channel of every reached controller was confirmed stopped."""
        return all(c.confirmed for c in self.channels)

    @property
    def confirmed(self) -> tuple[str, ...]:
        """Labels of the channels confirmed stopped."""
        return tuple(c.label for c in self.channels if c.confirmed)

    @property
    def unconfirmed(self) -> tuple[ChannelStop, ...]:
        """Channels whose stop could not be confirmed."""
        return tuple(c for c in self.channels if not c.confirmed)

    def __str__(self) -> str:
        parts = []
        if self.confirmed:
            parts.append("motors confirmed stopped: " + ", ".join(self.confirmed))
        if self.unconfirmed:
            parts.append("motors NOT confirmed stopped (cut their power): "
                         + "; ".join(f"{c.label} ({c.detail})" for c in self.unconfirmed))
        if self.unreached:
            parts.append("not reached, nothing was sent to them: " + ", ".join(self.unreached))
        if self.interruptions:
            parts.append("held back until the stop ended: " + ", ".join(self.interruptions))
        return "; ".join(parts) if parts else "no controller to stop"


def _guarded(call: Callable[[], T], held: list[str]) -> tuple[T | None, str | None]:
    """``(result, None)``, or ``(None, why)``; anything raised is caught, an interruption retried."""
    why = "not attempted"
    for _ in range(INTERRUPTED_TRIES):
        try:
            return call(), None
        except RoboClawError as exc:
            return None, str(exc)
        except KeyboardInterrupt:
            held.append("Ctrl-C")
            why = "interrupted by Ctrl-C"
        except BaseException as exc:  # noqa: BLE001 - the stop must go on whatever arrives
            why = f"{type(exc).__name__}: {exc}"
            held.append(why)
    return None, why


def _standstill(drv: RoboClaw, channels: Sequence[int], held: list[str], clock: Callable[[], float],
                sleep: Callable[[float], None]) -> dict[int, tuple[bool, str]]:
    """Read each channel's encoder until two readings STANDSTILL_WINDOW apart agree (or CONFIRM_TIME ends)."""
    outcome: dict[int, tuple[bool, str]] = {}
    last: dict[int, int] = {}
    unreadable = "duty 0 acknowledged but the encoder could not be read: "
    for ch in channels:
        count, why = _guarded(lambda: drv.read_encoder(ch).count, held)  # noqa: B023 - called at once
        if why is not None:
            outcome[ch] = (False, unreadable + why)
        else:
            last[ch] = int(count)  # type: ignore[arg-type]
    deadline = clock() + CONFIRM_TIME
    while last:
        _guarded(lambda: sleep(STANDSTILL_WINDOW), held)
        for ch in list(last):
            count, why = _guarded(lambda: drv.read_encoder(ch).count, held)  # noqa: B023 - called at once
            if why is not None:
                outcome[ch] = (False, unreadable + why)
            elif abs(int(count) - last[ch]) <= STANDSTILL_COUNTS:  # type: ignore[arg-type]
                outcome[ch] = (True, f"duty 0 acknowledged, encoder at rest at {count} over {STANDSTILL_WINDOW:g} s")
            elif clock() > deadline:
                outcome[ch] = (False, f"duty 0 acknowledged but the motor still moves ({last[ch]} -> {count} "
                                      f"counts in {STANDSTILL_WINDOW:g} s)")
            else:
                last[ch] = int(count)  # type: ignore[arg-type]
                continue
            del last[ch]
    return outcome


def _stop_controller(driver: RoboClaw, held: list[str], clock: Callable[[], float],
                     sleep: Callable[[float], None]) -> dict[int, tuple[bool, str]]:
    drv = RoboClaw(driver.serial, driver.address, timeout=driver.timeout,
                   retries=max(driver.retries, MIN_STOP_RETRIES))  # same port and line state
    outcome: dict[int, tuple[bool, str]] = {}
    todo = [1, 2]
    for _ in range(ROUNDS):
        acknowledged = []
        for ch in todo:
            _, why = _guarded(lambda: drv.duty(ch, 0), held)  # noqa: B023 - called at once
            if why is None:
                acknowledged.append(ch)
            else:
                outcome[ch] = (False, f"duty 0 not acknowledged: {why}")
        outcome.update(_standstill(drv, acknowledged, held, clock, sleep))
        todo = [ch for ch in acknowledged if not outcome[ch][0]]
        if not todo:
            break
    return outcome


def stop_motors(drivers: Mapping[tuple[str, int], RoboClaw], names: Mapping[tuple[str, int, int], str] | None = None,
                *, unreached: Sequence[str] = (), clock: Callable[[], float] = time.monotonic,
                sleep: Callable[[float], None] = time.sleep,
                notify: Callable[[str], None] | None = None) -> StopReport:
    """Stop both channels of every controller in ``drivers`` (keyed ``(port, address)``); never raises.

    Args:
        names: motor name of each ``(port, address, channel)`` (labels of the report).
        unreached: descriptions of motors on ports that never opened (copied to the report).
        clock, sleep: real time for the standstill check.
        notify: called with a message when a signal is held back (default: print to stderr).
    """
    names = names or {}
    held: list[str] = []
    results: list[ChannelStop] = []
    say = notify or _print_to_stderr
    signals = StopSignals(holding=True, notify=say, labels=held)
    with signals:
        for (port, address), drv in drivers.items():
            outcome, why = _guarded(lambda: _stop_controller(drv, held, clock, sleep), held)  # noqa: B023
            for ch in (1, 2):
                label = names.get((port, address, ch), f"{port} {address:#04x} M{ch} (unused)")
                ok, detail = (outcome or {}).get(ch, (False, why or "stop not attempted"))
                results.append(ChannelStop(label, port, address, ch, ok, detail))
    return StopReport(tuple(results), tuple(unreached), tuple(held), tuple(signals.held))


def _print_to_stderr(text: str) -> None:
    try:
        print(f"trajopt play: {text}", file=sys.stderr, flush=True)
    except (OSError, ValueError):  # a closed terminal (SIGHUP) must not break the stop
        pass


def stop_all_reachable(drivers: Mapping[tuple[str, int], RoboClaw]) -> list[str]:
    """:func:`stop_motors`, returning ``"label: why"`` for every channel *not* confirmed stopped."""
    return [f"{c.label}: {c.detail}" for c in stop_motors(drivers).unconfirmed]
