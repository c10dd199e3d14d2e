"""trajopt.progress: off a terminal, plain lines (no carriage return) and a heartbeat after any
silence of the heartbeat period, so that a long command is never silent in a log (#41); on a
terminal, a bar. With a fake clock, or a period of a few milliseconds: no sleep of 30 s."""
from __future__ import annotations

import io
import time

from trajopt.progress import HEARTBEAT_S, IterationProgress, Progress


class FakeClock:
    def __init__(self):
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_a_heartbeat_follows_a_silence_of_the_period_and_not_before():
    out, clock = io.StringIO(), FakeClock()
    p = Progress(4, "--speed max", "run", stream=out, tty=False, per_item=False, interval=None,
                 heartbeat_every=HEARTBEAT_S, clock=clock)
    p.update(1)
    clock.t = HEARTBEAT_S - 1
    assert not p.beat() and out.getvalue() == ""
    p.set_postfix(best="3.20 BL/min")
    clock.t = HEARTBEAT_S + 0.5
    assert p.beat()
    assert out.getvalue() == "--speed max: 1/4 runs, best 3.20 BL/min, still working (30 s elapsed)\n"
    clock.t += HEARTBEAT_S - 1                        # counted from the last line printed
    assert not p.beat()
    p.line("a message")
    clock.t += 2
    assert not p.beat()
    p.close()
    assert "\r" not in out.getvalue()


def test_a_thread_prints_the_heartbeat_while_the_caller_is_busy():
    """The heartbeat does not wait for the next item: one item may take minutes."""
    out = io.StringIO()
    with Progress(None, "rl train", "step", stream=out, tty=False, interval=0.02) as p:
        p.n = 128
        time.sleep(0.3)
    lines = out.getvalue().splitlines()
    assert len(lines) >= 2 and all(line.startswith("rl train: 128 steps, still working") for line in lines)
    n = len(lines)
    time.sleep(0.1)
    assert len(out.getvalue().splitlines()) == n          # closed: no more lines


def test_per_item_lines_off_a_terminal_and_a_bar_on_one():
    out = io.StringIO()
    p = Progress(2, "sweep", "run", stream=out, tty=False, interval=None)
    p.update(1)
    p.update(1, line="run b done")
    p.close()
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("sweep: 1/2 runs") and lines[1] == "run b done"
    tty = io.StringIO()
    p = Progress(2, "sweep", "run", stream=tty, tty=True)
    p.update(2)
    p.close()
    assert "\r" in tty.getvalue() and "2/2" in tty.getvalue()


def test_gauss_newton_iterations_slower_than_the_period_get_a_heartbeat():
    """``trajopt optimize``: a line per iteration, and one between two iterations far apart."""
    out, clock = io.StringIO(), FakeClock()
    it = IterationProgress(3, stream=out, tty=False, interval=None, heartbeat_every=HEARTBEAT_S, clock=clock)
    clock.t = 5.0
    it.update({"objective_after": 1.5, "step": 1.0})
    clock.t = 5.0 + HEARTBEAT_S
    assert it.progress.beat()
    it.close()
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("Gauss-Newton: up to 3 iterations")
    assert lines[1].startswith("Gauss-Newton iteration 1/3: objective 1.5")
    assert lines[2] == "Gauss-Newton: 1/3 iterations, still working (35 s elapsed)"
