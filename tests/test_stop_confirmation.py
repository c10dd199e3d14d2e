"""A stop is confirmed only by an encoder seen at rest (issue #30, class "hardware confirmation
tried one way"): after an acknowledged duty 0, a channel whose encoder read-back goes unanswered
(at the first or at a later reading), or whose motor keeps moving, ends unconfirmed; one whose
encoder stands still within STANDSTILL_COUNTS is confirmed. The encoder confirmation step of
trajopt.hardware.stop is driven by a scripted controller and a simulated clock (no sleeping)."""
from __future__ import annotations

from types import SimpleNamespace

import pytest

from trajopt.hardware import stop
from trajopt.hardware.errors import RoboClawTimeout


class ScriptedEncoders:
    """``read_encoder(ch)`` answers from ``script[ch]``: a count, or None for no answer."""

    def __init__(self, script: dict[int, list]):
        self.script = {ch: list(v) for ch, v in script.items()}
        self.reads = {ch: 0 for ch in script}

    def read_encoder(self, ch: int):
        seq = self.script[ch]
        value = seq[min(self.reads[ch], len(seq) - 1)]
        self.reads[ch] += 1
        if value is None:
            raise RoboClawTimeout("no reply to read encoder")
        return SimpleNamespace(count=value)


class SimClock:
    def __init__(self):
        self.t = 0.0

    def __call__(self) -> float:
        return self.t

    def sleep(self, dt: float) -> None:
        self.t += dt


def standstill(script: dict[int, list]) -> dict[int, tuple[bool, str]]:
    clock = SimClock()
    held: list[str] = []
    out = stop._standstill(ScriptedEncoders(script), sorted(script), held, clock, clock.sleep)
    assert held == []
    return out


def test_an_encoder_at_rest_confirms_the_stop():
    out = standstill({1: [500, 500 + stop.STANDSTILL_COUNTS], 2: [-20, -20]})
    assert out[1][0] and out[2][0]
    assert "at rest" in out[1][1]


@pytest.mark.parametrize("script", [[None], [500, None], [500, 900, None]],
                         ids=["first read unanswered", "second read unanswered", "later read unanswered"])
def test_an_unanswered_encoder_read_back_leaves_the_stop_unconfirmed(script):
    out = standstill({1: script, 2: [7, 7]})
    assert out[1][0] is False and "encoder could not be read" in out[1][1]
    assert out[2][0] is True                                   # the other channel is judged on its own


def test_a_motor_that_keeps_moving_leaves_the_stop_unconfirmed():
    moving = [100 * k for k in range(100)]                     # 100 counts per reading, for ever
    out = standstill({1: moving, 2: [3, 3]})
    assert out[1][0] is False and "still moves" in out[1][1]
    assert out[2][0] is True


def test_a_motor_that_comes_to_rest_in_time_is_confirmed():
    slowing = [0, 200, 300, 350, 351, 351]
    out = standstill({1: slowing})
    assert out[1][0] is True


def test_one_count_more_than_standstill_is_moving():
    drift = [10 * (stop.STANDSTILL_COUNTS + 1) * k for k in range(200)]
    assert standstill({2: drift})[2][0] is False
