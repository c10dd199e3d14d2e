"""Smoke test of the MuJoCo side of ``benchmarks/bench_vs_mujoco.py`` (``benchmarks/mujoco_flex.py``):
the Tripod's tet mesh compiles as a MuJoCo 3-D flex with the same nodes, tets, node masses and
time step. Nothing is timed and no step is taken (the benchmark is not a test)."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from soft_envs.sim import load_robot

mujoco = pytest.importorskip("mujoco", reason="MuJoCo is in the optional 'bench' extra (pip install -e .[bench])")


@pytest.fixture(scope="module")
def mujoco_flex():
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "mujoco_flex.py"
    spec = importlib.util.spec_from_file_location("mujoco_flex", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_frames_are_a_rotation(mujoco_flex):
    x = np.random.default_rng(0).normal(size=(5, 3))
    np.testing.assert_array_equal(mujoco_flex.from_mujoco_frame(mujoco_flex.to_mujoco_frame(x)), x)
    np.testing.assert_array_equal(mujoco_flex.to_mujoco_frame(np.eye(3)), [[1, 0, 0], [0, 0, 1], [0, -1, 0]])
    assert np.linalg.det(mujoco_flex.to_mujoco_frame(np.eye(3))) == pytest.approx(1.0)


def test_tripod_flex_has_the_mesh_masses_and_time_step(mujoco_flex):
    robot = load_robot("tripod")
    mj = mujoco_flex.FlexModel(robot, dt=0.033)
    m = mj.model
    assert (m.nflex, m.nflexvert, m.nflexelem, m.nq) == (1, robot.mesh.n_nodes, robot.mesh.n_tets,
                                                         3 * robot.mesh.n_nodes)
    assert m.opt.timestep == 0.033 and m.opt.integrator == mujoco.mjtIntegrator.mjINT_DISCRETE
    np.testing.assert_allclose(mj.masses, robot.node_masses, rtol=1e-15)     # payload included
    # vertex i of the flex is node i of the mesh, lowered onto the ground
    placement = np.array(robot.mesh.points)
    placement[:, 1] -= placement[:, 1].min()
    np.testing.assert_allclose(mujoco_flex.from_mujoco_frame(mj.data.flexvert_xpos), placement, atol=1e-15)
    # every tet of the mesh is an element of the flex (MuJoCo may reorder a tet's vertices)
    assert {tuple(sorted(t)) for t in m.flex_elem.reshape(-1, 4)} == {tuple(sorted(t)) for t in robot.mesh.tets}
    x = placement + np.random.default_rng(1).uniform(-1e-3, 1e-3, placement.shape)
    mj.set_state(x)
    np.testing.assert_allclose(mj.positions(), x, atol=1e-15)
    np.testing.assert_allclose(mujoco_flex.from_mujoco_frame(mj.data.flexvert_xpos), x, atol=1e-15)
