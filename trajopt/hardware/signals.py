"""The signals that end a playback (SIGINT, SIGTERM, SIGHUP): raised as exceptions, or held during the stop.

A playback must end with its stop sequence however it is asked to end: Ctrl-C
(SIGINT), a service manager stopping it (SIGTERM), a closed terminal or SSH
session (SIGHUP).  :class:`StopSignals` installs a handler for each of them
(main thread only; a signal whose handler is ``SIG_IGN``, e.g. SIGHUP under
``nohup``, stays ignored) and restores the previous handlers on exit:

* while ``holding`` is False a signal is raised in the main thread as an
  exception -- :class:`KeyboardInterrupt` for SIGINT, :class:`Terminated` for
  the others -- so the playback unwinds into its stop sequence;
* once ``holding`` is True (the stop sequence has begun) a signal is only
  recorded in ``held`` (and announced), so nothing can end the stop part-way.

SIGKILL cannot be caught: against it only the controllers' own serial-timeout
failsafe helps (docs/failure-modes.md).
"""

from __future__ import annotations

import signal
import threading
from types import TracebackType
from typing import Any, Callable

#: Signals a playback turns into its stop sequence (those this platform has).
STOP_SIGNALS: tuple[int, ...] = tuple(int(getattr(signal, name)) for name in ("SIGINT", "SIGTERM", "SIGHUP")
                                      if hasattr(signal, name))


class Terminated(BaseException):
    """SIGTERM / SIGHUP received: like KeyboardInterrupt, not caught by ``except Exception``."""

    def __init__(self, signum: int) -> None:
        self.signum = int(signum)
        super().__init__(f"terminated by {signal_label(signum)}")


def signal_label(signum: int) -> str:
    """``"Ctrl-C"`` for SIGINT, else the signal's name (``"SIGTERM"``)."""
    if signum == signal.SIGINT:
        return "Ctrl-C"
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


def interruption(signum: int) -> BaseException:
    """The exception that stands for ``signum``: KeyboardInterrupt for SIGINT, else :class:`Terminated`."""
    return KeyboardInterrupt() if signum == signal.SIGINT else Terminated(signum)


def signal_of(exc: BaseException) -> int | None:
    """The signal ``exc`` stands for (SIGINT for a KeyboardInterrupt), or ``None`` if it is no interruption."""
    if isinstance(exc, Terminated):
        return exc.signum
    if isinstance(exc, KeyboardInterrupt):
        return int(signal.SIGINT)
    return None


class StopSignals:
    """Context manager: SIGINT / SIGTERM / SIGHUP raised as exceptions until ``holding``, then recorded.

    Args:
        holding: record from the start (the stop sequence itself).
        notify: called with a line when a signal is held (its exceptions are swallowed).
        labels: a list that also gets the label of each held signal (in order with other entries).
    """

    def __init__(self, holding: bool = False, notify: Callable[[str], None] | None = None,
                 labels: list[str] | None = None) -> None:
        self.holding = holding  # an attribute, set in one bytecode: no signal can slip in between
        self.held: list[int] = []
        self._notify, self._labels = notify, labels
        self._previous: dict[int, Any] = {}

    def _handle(self, signum: int, frame: object) -> None:
        if not self.holding:
            raise interruption(signum)
        self.held.append(int(signum))
        if self._labels is not None:
            self._labels.append(signal_label(signum))
        if self._notify is not None:
            try:
                self._notify(f"stopping the motors first: {signal_label(signum)} is held until the stop "
                             "sequence ends")
            except Exception:  # noqa: BLE001 - a closed terminal must not break the stop
                pass

    def __enter__(self) -> StopSignals:
        if threading.current_thread() is not threading.main_thread():
            return self
        for signum in STOP_SIGNALS:
            try:
                previous = signal.getsignal(signum)
                if previous == signal.SIG_IGN:
                    continue
                signal.signal(signum, self._handle)
            except (ValueError, OSError):  # pragma: no cover - not the main interpreter
                continue
            self._previous[signum] = previous
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        for signum, previous in self._previous.items():
            if previous is None:  # installed from outside Python: fall back to the default
                previous = signal.default_int_handler if signum == signal.SIGINT else signal.SIG_DFL
            signal.signal(signum, previous)
        self._previous.clear()
