"""Co-design ranks designs by credible speeds (issue #43): the screening by the slowest speed over
the hold stage's replays (trajopt.search.hold.slowest_rank; ``rank="holds-first"`` as the joint
stage), the joint stage by ``(holds, slowest)`` (trajopt.search.hold.credible_rank).

The scores are fakes (a made-up Score per candidate, a made-up evaluation per joint stage): what
is tested is the ranking, which a real run would take minutes to reach. The real scoring (the
replays of a gait found for a candidate) runs in tests/test_codesign_screen.py.
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

import trajopt.codesign.joint as joint
import trajopt.codesign.score as score
import trajopt.codesign.screen as screen
from trajopt.codesign.joint import JointSettings, JointState, optimise_jointly
from trajopt.codesign.score import Score
from trajopt.codesign.screen import ScreenSettings, screen_designs
from trajopt.search.hold import credible_rank, hold_verdict

NAN = float("nan")


def _hold(*speeds: float) -> dict:
    """A hold check of speeds at 2, 4, 8 and 16 physics steps per control step (NaN: it fell)."""
    return {"substeps": [2, 4, 8, 16][:len(speeds)], "speeds": list(speeds), **hold_verdict(speeds), "steps": 0}


def test_credible_rank_orders_holding_first_then_the_slowest():
    holds_slow = credible_rank(_hold(20.0, 20.5, 20.2, 20.4))
    spreads_fast = credible_rank(_hold(30.0, 36.0, 34.0, 33.0))          # 20 % spread
    fell = credible_rank(_hold(NAN, 40.0, 40.0, 40.0))                   # fast at 8.25 ms, falls at 16.5
    backwards = credible_rank(_hold(-5.0, -5.0, -5.1, -5.0))
    assert holds_slow == (1, 20.0) and spreads_fast == (0, 30.0)
    assert holds_slow > spreads_fast > fell
    assert fell == backwards == credible_rank(None) == (0, -math.inf)
    assert credible_rank(_hold(31.0, 36.0)) > spreads_fast               # among non-holding, the slowest


# ---------------------------------------------------------------- the screening, its scores faked
CANDIDATES = {
    # label: (own speed at 8.25 ms, hold check or None: not upright)
    "current design": (22.0, _hold(21.0, 22.0, 21.5, 21.2)),
    "fast, falls at 16.5 ms": (40.0, _hold(NAN, 40.0, 39.0, 38.0)),
    "faster, spreads 25 %": (38.0, _hold(30.0, 38.0, 37.0, 36.0)),
    "slower, holds": (25.0, _hold(24.5, 25.0, 24.8, 24.6)),
    "backwards": (-3.0, _hold(-3.0, -3.0, -3.1, -3.0)),
}


class _FakeProblem:
    """What a screening round asks of a CodesignProblem, designs standing for their labels."""

    contact, newton, substeps, gait, motor_model = "coulomb", None, 4, None, "torque-speed"

    def __init__(self, labels):
        self.labels = list(labels)
        self.anchor = np.zeros(1)
        self.sim_steps = 0

    def move_to(self, theta):
        self.anchor = np.asarray(theta, dtype=np.float64)

    def robot_at(self, theta):
        return self.labels[int(theta[0])]          # the "robot" is the label

    def design_violation(self, robot):
        return None


def _screen(monkeypatch, labels, table=CANDIDATES, **settings):
    problem = _FakeProblem(labels)
    monkeypatch.setattr(screen, "candidates", lambda p, th, z, s: [(lab, np.array([float(i)]))
                                                                   for i, lab in enumerate(labels) if i])

    def fake(job):
        own, hold = table[job.robot]
        return Score(own, hold, np.array([own]), 100, "fake")

    monkeypatch.setattr(score, "score_job", fake)
    return screen_designs(problem, np.zeros(1), np.zeros(1), 21.0, 25.0,
                          ScreenSettings(rounds=1, **settings), workers=1)


def test_the_screening_ranks_by_the_slowest_speed_and_never_keeps_a_gait_that_fell(monkeypatch):
    """The default order (rank="slowest"): the fastest at 8.25 ms falls at 16.5 ms and walking
    backwards ranks last; of the rest the slowest speed decides, so a gait faster at every step
    wins though it spreads 25 % (30 at its slowest against 24.5 for one that holds)."""
    end = _screen(monkeypatch, ["current design", "fast, falls at 16.5 ms", "backwards", "slower, holds",
                                "faster, spreads 25 %"])
    assert end.theta == [4.0] and end.speed == 30.0 and not end.holds and end.own == 38.0
    only_fallen = _screen(monkeypatch, ["current design", "fast, falls at 16.5 ms", "backwards"])
    assert only_fallen.finished and only_fallen.theta == [0.0] and only_fallen.speed == 21.0
    with pytest.raises(ValueError, match="screening rank must be one of slowest, holds-first, got 'fastest'"):
        ScreenSettings(rank="fastest")


def test_a_candidate_faster_at_the_default_step_that_falls_at_16ms_loses_to_one_that_holds(monkeypatch):
    """rank="holds-first" (the rule until 2026-12-07): the fastest at 8.25 ms falls at 16.5 ms;
    the one that holds wins, ahead of one that is faster at every step but spreads 25 %."""
    end = _screen(monkeypatch, ["current design", "fast, falls at 16.5 ms", "faster, spreads 25 %", "slower, holds"],
                  rank="holds-first")
    assert end.theta == [3.0] and end.z == [25.0]
    assert end.speed == 24.5 and end.holds and end.own == 25.0
    rows = {r["candidate"]: r for r in end.rows}
    assert math.isnan(rows["fast, falls at 16.5 ms"]["slowest_bl_per_min"])
    assert rows["faster, spreads 25 %"]["spread"] == pytest.approx(8 / 30) and not rows["faster, spreads 25 %"]["holds"]


def test_among_gaits_that_do_not_hold_the_slowest_speed_decides(monkeypatch):
    table = {**CANDIDATES, "current design": (22.0, _hold(15.0, 22.0, 21.0, 20.0)),
             "spreads, slowest 28": (45.0, _hold(28.0, 45.0, 40.0, 35.0))}
    end = _screen(monkeypatch, ["current design", "spreads, slowest 28", "faster, spreads 25 %"], table,
                  rank="holds-first")
    assert end.theta == [2.0] and end.speed == 30.0 and not end.holds


def test_nothing_beats_a_current_design_that_holds_but_a_design_that_holds_faster(monkeypatch):
    """A falling, a backwards and a spreading candidate, all faster at 8.25 ms than the current
    design, which holds: no better design, the screening ends."""
    end = _screen(monkeypatch, ["current design", "fast, falls at 16.5 ms", "backwards", "faster, spreads 25 %"],
                  rank="holds-first")
    assert end.finished and end.theta == [0.0] and end.speed == 21.0


def test_the_own_physics_alone_when_asked(monkeypatch):
    """``hold_factors=()``: the old ranking by the speed at the default step (the fake's checks
    stand for that: one speed each), the fastest wins."""
    table = {k: (own, None if hold is None else _hold(own)) for k, (own, hold) in CANDIDATES.items()}
    end = _screen(monkeypatch, ["current design", "fast, falls at 16.5 ms", "slower, holds"], table, hold_factors=())
    assert end.theta == [1.0] and end.speed == 40.0


# ---------------------------------------------------------------- the joint stage, accepted by credible speed
class _FakeJointProblem:
    def __init__(self):
        self.shipped = SimpleNamespace(values=np.zeros(1))
        self.block, self.anchor, self.sim_steps = self.shipped, np.zeros(1), 0

    def bounds(self):
        return np.full(3, -1.0), np.full(3, 1.0)

    def set_target(self, v):
        self.target = v

    @staticmethod
    def moved(block, anchor, theta):
        return block, np.asarray(theta, dtype=np.float64)

    def linearised_constraints(self, w):
        return None


@pytest.mark.parametrize("stage_hold, accepted", [
    (_hold(NAN, 30.0, 30.0, 30.0), False),          # faster at 8.25 ms, falls at 16.5 ms
    (_hold(24.0, 30.0, 29.0, 28.0), False),          # faster everywhere, spreads 25 %: the start holds
    (_hold(20.5, 21.0, 20.8, 20.6), True),           # holds, faster at the slowest step
    (_hold(19.0, 19.5, 19.2, 19.1), False),          # holds, slower
])
def test_a_joint_stage_is_accepted_only_when_its_credible_rank_improves(monkeypatch, stage_hold, accepted):
    start = [0.1, 0.2, 0.0]
    moved_to = [0.3, 0.4, 0.0]
    monkeypatch.setattr(joint, "gauss_newton", lambda *a, **k: SimpleNamespace(z=np.array(moved_to), status="fake"))
    monkeypatch.setattr(joint, "evaluate_design", lambda p, w, *a: {"speed_bl_per_min": 30.0, "upright": True,
                                                                   "hold": stage_hold})
    state = JointState(w=list(start), best_speed=20.0, best_holds=True)
    end = optimise_jointly(_FakeJointProblem(), state, JointSettings(stages=1, iterations=1, ensemble=()))
    assert end.best_w == (moved_to if accepted else start)
    assert (end.best_speed, end.best_holds) == ((20.5, True) if accepted else (20.0, True))
    assert end.stage_rows[0]["holds"] == stage_hold["holds"]


def test_a_checkpoint_made_before_credible_scores_is_refused(tmp_path):
    """A run interrupted before co-design ranked by credible speeds ranked its screening's designs
    otherwise: ``--resume`` refuses it in one line, before any work."""
    import json

    from trajopt.codesign.run import PARTIAL, CodesignRun, run_codesign
    (tmp_path / PARTIAL).write_text(json.dumps({"settings": {"robot": "tripod"}, "state": {"w": [0.0]}}))
    with pytest.raises(ValueError, match="made before co-design scored designs by credible speeds.*--overwrite"):
        run_codesign(CodesignRun("tripod", tmp_path, resume=True, quiet=True))


def test_a_checkpoint_keeps_a_start_without_credible_speed_and_refuses_a_bad_verdict(tmp_path):
    """A start that falls at a physics step has no credible speed (best_speed -inf, written as
    -Infinity): the checkpoint reads back; a verdict that is not true or false is refused."""
    import json

    from trajopt.codesign.partial import read_partial
    path = tmp_path / "codesign.partial.json"
    state = {"w": [0.0, 1.0], "best_speed": -math.inf, "best_holds": False,
             "screen_progress": {"rounds_done": 1, "theta": [1.0], "z": [0.0], "speed": -math.inf, "holds": False,
                                 "own": NAN}}
    path.write_text(json.dumps({"settings": {}, "state": state}))
    _, read = read_partial(path)
    assert read.best_speed == -math.inf and read.best_holds is False
    path.write_text(json.dumps({"settings": {}, "state": {**state, "best_holds": 1}}))
    with pytest.raises(ValueError, match="state.best_holds' must be true or false"):
        read_partial(path)
    path.write_text(json.dumps({"settings": {}, "state": {**state, "screen_progress": {
        **state["screen_progress"], "holds": "yes"}}}))
    with pytest.raises(ValueError, match="screen_progress.holds' must be true or false"):
        read_partial(path)
