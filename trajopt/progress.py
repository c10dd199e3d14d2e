"""Progress of long commands on stderr: a tqdm bar on a terminal, plain lines otherwise (a log
file, a pipe, CI), so that a log never fills with carriage returns.

Off a terminal, :class:`Progress` also prints a heartbeat line whenever nothing was printed for
``interval`` seconds (30 by default), from a background thread: a command is never silent for
long even when one item (an iteration, a run, a training) takes minutes.
:class:`IterationProgress` is the Gauss-Newton iterations' (``trajopt optimize``)."""
from __future__ import annotations

import sys
import threading
import time
from typing import IO, Callable

__all__ = ["Progress", "IterationProgress", "HEARTBEAT_S"]

#: off a terminal, the longest silence [s] before a heartbeat line
HEARTBEAT_S = 30.0


class Progress:
    """A count of ``total`` items (``total`` may be None: unknown). ``update(n, line=...)`` after
    items, ``set_postfix(**figures)`` for the figures shown beside the count, ``line(text)`` to
    print a message, ``close()`` at the end (also a context manager). The attributes ``total``
    and ``n`` may be changed (``refresh()`` shows it on the bar).

    ``tty`` (default ``stream.isatty()``) chooses the bar; off it, ``per_item`` prints a line
    per ``update`` (the ``line`` given, else the count), and a heartbeat line follows any
    silence of ``interval`` seconds (``None``: never). ``clock`` measures the silences (a fake
    one in tests, with :meth:`beat` called by hand: ``interval=None`` then starts no thread
    while ``heartbeat_every`` still sets the period)."""

    def __init__(self, total: int | None, desc: str, unit: str = "it", *, initial: int = 0,
                 stream: IO[str] | None = None, tty: bool | None = None, per_item: bool = True,
                 interval: float | None | str = "default", heartbeat_every: float | None = None,
                 clock: Callable[[], float] = time.monotonic, first_line: str | None = None):
        if interval == "default":               # read now: tests shorten it
            interval = HEARTBEAT_S
        self.stream = sys.stderr if stream is None else stream
        self.total, self.n, self.desc, self.unit = total, int(initial), desc, unit
        self.per_item, self.clock = per_item, clock
        self.every = heartbeat_every if heartbeat_every is not None else interval
        self.postfix: dict[str, str] = {}
        self.t0 = self.last = clock()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = None
        self.bar = None
        isatty = getattr(self.stream, "isatty", lambda: False)
        if isatty() if tty is None else tty:
            from tqdm import tqdm
            self.bar = tqdm(total=total, initial=self.n, desc=desc, unit=unit, file=self.stream)
            return
        if first_line:
            self.line(first_line)
        if interval is not None and interval > 0:
            self._thread = threading.Thread(target=self._beat_loop, args=(float(interval),),
                                            name=f"progress:{desc}", daemon=True)
            self._thread.start()

    # -- output
    def line(self, text: str) -> None:
        """Print ``text`` (above the bar on a terminal)."""
        with self._lock:
            if self.bar is not None:
                self.bar.write(text, file=self.stream)
            else:
                print(text, file=self.stream, flush=True)
            self.last = self.clock()

    def count(self) -> str:
        """"desc: n/total units" (n alone when the total is unknown)."""
        of = f"/{self.total}" if self.total is not None else ""
        return f"{self.desc}: {self.n}{of} {self.unit}s"

    def _figures(self) -> str:
        return "".join(f", {k} {v}" for k, v in self.postfix.items())

    def update(self, n: int = 1, line: str | None = None) -> None:
        """Count ``n`` more items; ``line`` is printed (above the bar on a terminal)."""
        self.n += int(n)
        if line is not None:
            self.line(line)
        if self.bar is not None:
            self.bar.update(n)
        elif line is None and self.per_item:
            self.line(f"{self.count()}{self._figures()}, {self.clock() - self.t0:.0f} s")

    def set_postfix(self, **figures) -> None:
        self.postfix = {k: str(v) for k, v in figures.items()}
        if self.bar is not None:
            self.bar.set_postfix(**figures)

    def refresh(self) -> None:
        if self.bar is not None:
            self.bar.total = self.total
            self.bar.refresh()

    # -- heartbeat
    def beat(self) -> bool:
        """Print a heartbeat line if nothing was printed for the heartbeat period; True if it did."""
        if self.bar is not None or self.every is None:
            return False
        now = self.clock()
        if now - self.last < self.every:
            return False
        self.line(f"{self.count()}{self._figures()}, still working ({now - self.t0:.0f} s elapsed)")
        return True

    def _beat_loop(self, interval: float) -> None:
        while not self._stop.wait(max(min(interval - (self.clock() - self.last), interval), 0.01)):
            self.beat()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class IterationProgress:
    """``update(entry)`` after each Gauss-Newton iteration (a history entry), ``close()`` at the
    end. ``stream`` defaults to stderr; ``tty`` (default: ``stream.isatty()``) chooses the bar;
    off a terminal, a line per iteration and a heartbeat when an iteration takes over
    ``interval`` seconds."""

    def __init__(self, total: int, first: int = 1, stream: IO[str] | None = None, tty: bool | None = None,
                 interval: float | None | str = "default", **kwargs):
        self.progress = Progress(int(total), "Gauss-Newton", "iteration", initial=int(first) - 1, stream=stream,
                                 tty=tty, interval=interval, first_line=(
                                     f"Gauss-Newton: up to {int(total)} iterations (the first also compiles the "
                                     "simulator's kernels on a fresh install)"), **kwargs)
        self.stream, self.total = self.progress.stream, int(total)

    @property
    def bar(self):
        return self.progress.bar

    @property
    def done(self) -> int:
        return self.progress.n

    def update(self, entry: dict) -> None:
        objective, step = entry.get("objective_after", float("nan")), entry.get("step", 0.0)
        p = self.progress
        if p.bar is not None:
            p.update(1)
            p.set_postfix(objective=f"{objective:.4g}", step=f"{step:.1e}")
            return
        verdict = "accepted" if entry.get("accepted", True) else "rejected (no decrease)"
        p.update(1, line=f"Gauss-Newton iteration {p.n + 1}/{self.total}: objective {objective:.4g}, step "
                         f"{step:.1e} {verdict}, {p.clock() - p.t0:.1f} s")

    def close(self) -> None:
        self.progress.close()
