"""``trajopt codesign`` off a terminal: its screening stage (rounds of ``--speed max`` searches
that take minutes, with nothing printed between two designs) prints a heartbeat line after any
silence of the heartbeat period (30 s, shortened here) (#41). The screening itself is replaced
by a slow stand-in: what is tested is the line, not the screening."""
from __future__ import annotations

import sys
import time
from types import SimpleNamespace

import numpy as np

import trajopt.codesign.run as run_module
import trajopt.progress
from trajopt.codesign.joint import JointState
from trajopt.codesign.screen import ScreenProgress


def test_the_screening_beats_off_a_terminal(monkeypatch, capsys):
    monkeypatch.setattr(trajopt.progress, "HEARTBEAT_S", 0.05)

    def slow_screening(problem, theta0, z0, base_speed, target, settings, *, round_done, **kw):
        for rnd in (1, 2):
            time.sleep(0.3)
            round_done(ScreenProgress(rounds_done=rnd, theta=list(theta0), z=list(z0), speed=base_speed))
        return ScreenProgress(rounds_done=2, theta=list(theta0), z=list(z0), speed=base_speed, finished=True)

    monkeypatch.setattr(run_module, "screen_designs", slow_screening)
    run = SimpleNamespace(screen=SimpleNamespace(rounds=2), quiet=False, n_workers=lambda: 1,
                          search=SimpleNamespace(target=lambda speed: 2 * speed))
    problem = SimpleNamespace(anchor=np.zeros(2), sim_steps=0)
    state = JointState(w=[0.0] * 4, best_speed=3.0)
    run_module._screen(run, problem, state, SimpleNamespace(z=np.zeros(2), evaluation={"speed_bl_per_min": 3.0}),
                       lambda s: None, lambda text: print(text, file=sys.stderr))
    err = capsys.readouterr().err
    assert "co-design screening: 0/2 rounds, still working" in err
    assert "co-design screening: 1/2 rounds, still working" in err and "\r" not in err
    assert state.screened
