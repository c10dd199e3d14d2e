"""The co-design screening (trajopt.codesign.screen, issue #29): its candidates scored in worker
processes give exactly what they give one after another here, a screening interrupted between
rounds continues to exactly the uninterrupted result, and an interruption mid-round leaves no
worker process behind.

A short Tripod walk (4 prep steps, two 8-step cycles, Coulomb law), its moduli and leg lengths
as the design, two rounds of one Gauss-Newton iteration per candidate.
"""
from __future__ import annotations

import json
import multiprocessing
from dataclasses import asdict

import numpy as np
import pytest

from soft_envs.envs import make_gradient_env
from soft_envs.envs.design import load_design
from trajopt.codesign import CodesignProblem
from trajopt.codesign.joint import replay_path
from trajopt.codesign.screen import ScreenProgress, ScreenSettings, screen_designs
from trajopt.optim.gait import GaitSpec
from trajopt.optim.motor_limit import gait_constraints, max_step_of_env, project_start

GAIT = GaitSpec(n_prep=4, n_cycle=8, n_cycles=2, n_keyframes=4, interpolation="linear")
SETTINGS = ScreenSettings(rounds=2, iterations=1, modulus_factors=(2.0,), routing_steps=(), eval_cycles=2, warm=1)
TARGET = 20.0


def _problem() -> CodesignProblem:
    env = make_gradient_env("tripod", contact="coulomb")
    return CodesignProblem(env, load_design(env.robot, ("stiffness", "legs")), GAIT, TARGET,
                           max_step=max_step_of_env(env))


def _start(p: CodesignProblem) -> np.ndarray:
    z0 = np.clip(p.param.initial_z(0.5), *p.param.bounds())
    return project_start(z0, p.param, gait_constraints(p.param, p.max_step))[0]


def _screen(p: CodesignProblem, **kw) -> ScreenProgress:
    return screen_designs(p, p.anchor.copy(), _start(p), 0.0, TARGET, SETTINGS, **kw)


@pytest.fixture(scope="module")
def serial():
    """The uninterrupted screening in this process, and its progress after round 1 (as JSON)."""
    p = _problem()
    after_first: list[str] = []
    end = _screen(p, workers=1, round_done=lambda s: after_first.append(json.dumps(asdict(s))))
    return end, json.loads(after_first[0]), p.sim_steps


def test_screening_moves_the_design(serial):
    end, first, _ = serial
    assert end.rounds_done == 2 and first["rounds_done"] == 1
    assert len(end.rows) == 2 * 11            # the current design, 4 moduli x2, 3 legs +-3 mm; per round
    assert end.path and end.path[0] == first["theta"]        # round 2 started from round 1's winner
    assert np.isfinite(end.speed) and all(r["status"] for r in end.rows)


def test_workers_and_resume_give_the_serial_result(serial):
    """Round 2 resumed from round 1's checkpoint (a fresh problem moved along its path), scored
    in two worker processes: the same rows, design, gait and simulation steps, bit for bit."""
    end, first, steps = serial
    p = _problem()
    progress = ScreenProgress(**first)
    p.block, p.anchor = replay_path(p, progress.path)
    p.sim_steps = sum(r["sim_steps"] for r in progress.rows)
    again = _screen(p, workers=2, resume=progress)
    assert json.dumps(again.rows) == json.dumps(end.rows)          # NaN == NaN as text
    assert again.theta == end.theta and again.z == end.z and again.speed == end.speed
    assert again.path == end.path and p.sim_steps == steps


@pytest.mark.parametrize("error", [KeyboardInterrupt, RuntimeError])
def test_an_interruption_or_an_error_mid_round_stops_every_worker(error):
    """Ctrl-C (or SIGTERM, SIGHUP: raised as exceptions by the command line) or an exception
    in the main process while the workers score (issue #40 defect 4: every way out)."""
    p = _problem()
    rows = []

    def interrupt(row):
        rows.append(row)
        if len(rows) == 2:
            raise error("stop")

    with pytest.raises(error):
        _screen(p, workers=2, done=interrupt)
    assert multiprocessing.active_children() == []


def test_workers_must_be_positive():
    with pytest.raises(ValueError, match="workers"):
        _screen(_problem(), workers=0)
