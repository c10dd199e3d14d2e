"""Smoke test of ``benchmarks/study_newton_iterations.py``: its solver subclasses still fit the
Newton solver they hook into, and the claims its report rests on hold on a short Tripod run
(nothing is timed)."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.fixture(scope="module")
def study():
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(BENCH))              # the study imports benchmarks/common.py
        spec = importlib.util.spec_from_file_location("study_newton_iterations", BENCH / "study_newton_iterations.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        yield module


def test_newton_from_the_solution_is_quadratic_and_slower_farther_out(study):
    rows = {r["guess"]: r for r in study.near_solution("tripod", 12)}
    near, far = rows["solution + noise 1 um"], rows["solution + noise 100 um"]
    assert near["factorizations"] == 1.0 and near["newton_its"] <= 3.5     # Newton's quadratic regime
    assert far["newton_its"] > near["newton_its"] and far["factorizations"] > near["factorizations"]


def test_linearly_implicit_steps_run_and_approach_the_converged_motion(study):
    rows = [r for r in study.linearly_implicit("tripod", 12) if r["controls"] == "gait"]
    dev = {r["iterations_per_step"]: r["max_com_deviation_mm"] for r in rows}
    assert all(np.isfinite(v) for v in dev.values())
    assert dev[10] < dev[1]
