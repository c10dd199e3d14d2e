"""Progress of the Gauss-Newton iterations on stderr: a tqdm bar on a terminal, plain lines
otherwise (a log file, a pipe, CI), one per iteration."""
from __future__ import annotations

import sys
import time
from typing import IO

__all__ = ["IterationProgress"]


class IterationProgress:
    """``update(entry)`` after each iteration (a Gauss-Newton history entry), ``close()`` at the
    end. ``stream`` defaults to stderr; ``tty`` (default: ``stream.isatty()``) chooses the bar."""

    def __init__(self, total: int, first: int = 1, stream: IO[str] | None = None, tty: bool | None = None):
        self.stream = sys.stderr if stream is None else stream
        self.total, self.done = int(total), int(first) - 1
        self.t0 = time.perf_counter()
        isatty = getattr(self.stream, "isatty", lambda: False)
        self.bar = None
        if isatty() if tty is None else tty:
            from tqdm import tqdm
            self.bar = tqdm(total=self.total, initial=self.done, desc="Gauss-Newton", unit="it", file=self.stream)
        else:
            print(f"Gauss-Newton: up to {self.total} iterations (the first also compiles the simulator's "
                  "kernels on a fresh install)", file=self.stream, flush=True)

    def update(self, entry: dict) -> None:
        self.done += 1
        objective, step = entry.get("objective_after", float("nan")), entry.get("step", 0.0)
        if self.bar is not None:
            self.bar.update(1)
            self.bar.set_postfix(objective=f"{objective:.4g}", step=f"{step:.1e}")
            return
        verdict = "accepted" if entry.get("accepted", True) else "rejected (no decrease)"
        print(f"Gauss-Newton iteration {self.done}/{self.total}: objective {objective:.4g}, step {step:.1e} "
              f"{verdict}, {time.perf_counter() - self.t0:.1f} s", file=self.stream, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None
