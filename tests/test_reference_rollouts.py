"""Regression test that pins the physics: short rollouts of both shipped robots (gait, random
and zero controls, tension control, a 10-degree slope) against committed reference data
(``tests/data/reference_rollouts.npz``, made by ``tests/data/make_reference.py``; read its
docstring before regenerating: only for an intended change of behaviour).

Tolerances, robust across machines and solver settings (steps solved to 1e-11 m, where valid
solver settings agree to 1.5e-11 m in positions and 1.5e-7 relative in dcomdz over the 30 steps):

* COM, node positions and cable deformations: 1e-7 m absolute;
* dcomdz: 1e-5 of the case's largest entry.

Any change of the physics worth the name (a friction weight, a stiffness, a mass, a contact
law, a time-stepping detail) moves these by micrometres to millimetres.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

POSITION_ATOL = 1e-7       # [m]
SENSITIVITY_RTOL = 1e-5    # of max |dcomdz| of the case

_spec = importlib.util.spec_from_file_location("make_reference", Path(__file__).with_name("data") / "make_reference.py")
make_reference = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(make_reference)

CASES = {key: (robot, kw, u) for key, robot, kw, u in make_reference.cases()}


@pytest.fixture(scope="module")
def reference():
    with np.load(make_reference.PATH) as f:
        return {k: f[k] for k in f.files}


def test_reference_file_covers_every_case(reference):
    names = ("com", "gamma", "nodes", "dcomdz")
    assert set(reference) == {f"{key}/{n}" for key in CASES for n in names}
    assert make_reference.PATH.stat().st_size < 300e3


@pytest.mark.parametrize("case", list(CASES))
def test_rollout_matches_reference(case, reference):
    robot, kw, u = CASES[case]
    got = make_reference.simulate(robot, kw, u)
    report = []
    for name in ("com", "nodes", "gamma"):
        ref = reference[f"{case}/{name}"]
        assert got[name].shape == ref.shape, f"{case}/{name}: shape {got[name].shape} != {ref.shape}"
        err = np.abs(got[name] - ref)
        if err.max() > POSITION_ATOL:
            k = int(np.unravel_index(err.argmax(), err.shape)[0])
            report.append(f"{name}: max |diff| {err.max():.3e} m at step {k} (tolerance {POSITION_ATOL:g} m)")
    ref = reference[f"{case}/dcomdz"]
    scale = np.abs(ref).max()
    err = np.abs(got["dcomdz"] - ref).max()
    if err > SENSITIVITY_RTOL * max(scale, 1e-300):
        report.append(f"dcomdz: max |diff| {err:.3e} = {err / max(scale, 1e-300):.2e} of its largest entry "
                      f"(tolerance {SENSITIVITY_RTOL:g})")
    assert not report, f"{case} moved:\n  " + "\n  ".join(report)
    assert np.abs(ref).max() > 0 or case.endswith("/zero")
