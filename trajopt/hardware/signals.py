"""The signals that end a playback (SIGINT, SIGTERM, SIGHUP, SIGQUIT, ...): raised as exceptions, or held during the stop.

A playback must end with its stop sequence however it is asked to end: Ctrl-C
(SIGINT), a service manager stopping it (SIGTERM), a closed terminal or SSH
session (SIGHUP), Ctrl-\\ (SIGQUIT), ``kill -USR1``: every catchable signal whose
default action ends the process (:data:`STOP_SIGNALS`; not the faults SIGSEGV,
SIGBUS, SIGFPE, SIGILL and SIGABRT, after which no code can be trusted to run, nor
the signals whose default stops, continues or ignores the process).
:class:`StopSignals` installs a handler for each of them
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

#: The catchable signals whose default action ends the process (those this platform has).
ENDING_SIGNAL_NAMES = ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT", "SIGUSR1", "SIGUSR2", "SIGALRM", "SIGVTALRM",
                       "SIGPROF", "SIGXCPU", "SIGXFSZ", "SIGIO", "SIGPWR", "SIGSTKFLT", "SIGPIPE", "SIGBREAK")


def _ending_signals() -> tuple[int, ...]:
    found = [int(getattr(signal, name)) for name in ENDING_SIGNAL_NAMES if hasattr(signal, name)]
    if hasattr(signal, "SIGRTMIN") and hasattr(signal, "SIGRTMAX"):       # real-time signals end it too
        found += range(int(signal.SIGRTMIN), int(signal.SIGRTMAX) + 1)
    return tuple(dict.fromkeys(found))


#: Signals a playback turns into its stop sequence: every catchable signal whose default action
#: ends the process (SIGPIPE and SIGXFSZ are ignored by Python from the start, and stay so).
STOP_SIGNALS: tuple[int, ...] = _ending_signals()
#: The signals every other command turns into an orderly end (a checkpoint, workers ended):
#: SIGINT (KeyboardInterrupt, Python's own), SIGTERM and SIGHUP.
COMMAND_SIGNALS: tuple[int, ...] = tuple(int(getattr(signal, name)) for name in ("SIGTERM", "SIGHUP")
                                         if hasattr(signal, name))


class Terminated(BaseException):
    """SIGTERM, SIGHUP, SIGQUIT ... received: like KeyboardInterrupt, not caught by ``except Exception``."""

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
        if hasattr(signal, "SIGRTMIN") and signal.SIGRTMIN <= signum <= signal.SIGRTMAX:
            return f"SIGRTMIN+{signum - signal.SIGRTMIN}"
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
    """Context manager: the :data:`STOP_SIGNALS` raised as exceptions until ``holding``, then recorded.

    Args:
        holding: record from the start (the stop sequence itself).
        notify: called with a line when a signal is held (its exceptions are swallowed).
        labels: a list that also gets the label of each held signal (in order with other entries).
        signals: the signals handled (default :data:`STOP_SIGNALS`).
    """

    def __init__(self, holding: bool = False, notify: Callable[[str], None] | None = None,
                 labels: list[str] | None = None, signals: tuple[int, ...] | None = None) -> None:
        self.holding = holding  # an attribute, set in one bytecode: no signal can slip in between
        self.held: list[int] = []
        self._notify, self._labels = notify, labels
        self._signals = STOP_SIGNALS if signals is None else tuple(signals)
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
        for signum in self._signals:
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
