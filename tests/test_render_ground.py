"""The ground under a rendered robot (soft_envs/render_ground.py): the plane's tiles unchanged, a
relief's heights computed once per lattice point and interpolated exactly on it, its quads shaded
by their slope, the shadow, trail and goal on the relief; and the task environments draw their
ground and goal."""
from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import soft_envs  # noqa: F401  (registers the ids)
from soft_envs.render import Renderer, surface_triangles
from soft_envs.render_ground import TILE_A, TILE_B, Relief, goal_ring, ground_tiles
from soft_envs.sim.ground import HeightField
from soft_envs.sim.meshgen import graded, voxel_tet_mesh

W, H = 240, 180


class CountingGround:
    """y = 0.1 x + 0.2 z^2, counting the points it is asked for."""

    def __init__(self):
        self.asked = 0

    def height(self, x, z):
        x, z = np.broadcast_arrays(np.asarray(x, float), np.asarray(z, float))
        self.asked += x.size
        return 0.1 * x + 0.2 * z ** 2


@pytest.fixture(scope="module")
def block():
    pts, tets = voxel_tet_mesh(graded(0, 0.1, 4), graded(0, 0.03, 2), graded(-0.025, 0.025, 2),
                               np.ones((4, 2, 2), dtype=bool))
    return pts, surface_triangles(tets, pts)


def test_relief_evaluates_each_lattice_point_once_and_is_exact_on_the_lattice():
    ground, exact = CountingGround(), CountingGround()
    relief = Relief(ground, 0.01)
    lat = relief.lattice(np.arange(-2, 3), np.arange(0, 4))
    assert ground.asked == 20
    x, z = np.meshgrid(np.arange(-2, 3) * 0.01, np.arange(0, 4) * 0.01, indexing="ij")
    assert np.allclose(lat, exact.height(x, z), rtol=0, atol=1e-15)
    relief.lattice(np.arange(-1, 3), np.arange(1, 4))          # known points: not asked again
    assert ground.asked == 20
    assert np.allclose(relief.at(x, z), exact.height(x, z), rtol=0, atol=1e-15)
    # between lattice points, bilinear: exact for the linear part, the quadratic's chord for z^2
    assert relief.at(np.array([0.005]), np.array([0.0]))[0] == pytest.approx(0.0005, abs=1e-15)
    assert relief.at(np.array([0.0]), np.array([0.015]))[0] == pytest.approx(0.2 * (0.01 ** 2 + 0.02 ** 2) / 2, abs=1e-15)


def test_relief_refuses_what_is_not_a_ground():
    with pytest.raises(ValueError, match="height"):
        Relief(object(), 0.01)
    with pytest.raises(ValueError, match="spacing"):
        Relief(CountingGround(), 0.0)


def test_plane_tiles_checker_and_fade_and_a_flat_relief_has_the_same_colours():
    target = np.array([0.03, 0.0, -0.01])
    quads, cols = ground_tiles(target, 0.05, 0.4)
    assert np.all(quads[..., 1] == 0.0)
    assert np.allclose(np.abs(quads[:, 2, [0, 2]] - quads[:, 0, [0, 2]]), 0.05)
    near = np.argmin(np.hypot(*(quads.mean(axis=1)[:, [0, 2]] - target[[0, 2]]).T))
    assert any(np.allclose(cols[near], c, atol=0.02) for c in (TILE_A, TILE_B))
    light = np.array([0.3, 1.0, 0.6]) / np.linalg.norm([0.3, 1.0, 0.6])
    flat = HeightField.flat(0.0)
    rq, rc = ground_tiles(target, 0.05, 0.4, relief=Relief(flat, 0.0125), subdivisions=4, light=light)
    assert len(rq) == 16 * len(quads)
    assert np.allclose(rq[..., 1], 0.0, atol=1e-15)
    # a flat relief is coloured as the plane: each sub-quad as the tile it lies in (fade aside)
    inner = np.hypot(*(rq.mean(axis=1)[:, [0, 2]] - target[[0, 2]]).T) < 0.02
    assert inner.any()
    assert all(any(np.allclose(c, t, atol=0.01) for t in (TILE_A, TILE_B)) for c in rc[inner])


def test_a_slope_facing_the_light_is_brighter_than_one_facing_away():
    light = np.array([0.0, 1.0, 1.0]) / np.sqrt(2.0)
    target = np.zeros(3)
    up_to_light = Relief(HeightField.incline(20.0, uphill=(0.0, -1.0)), 0.0125)     # rises towards -z: faces +z
    away = Relief(HeightField.incline(20.0, uphill=(0.0, 1.0)), 0.0125)
    _, bright = ground_tiles(target, 0.05, 0.4, relief=up_to_light, light=light)
    _, dark = ground_tiles(target, 0.05, 0.4, relief=away, light=light)
    assert np.all(bright.sum(axis=1) >= dark.sum(axis=1) - 1e-12)
    assert bright.sum() > 1.05 * dark.sum()


def test_goal_ring_lies_on_the_ground_around_the_goal():
    relief = Relief(CountingGround(), 0.01)
    ring, pole = goal_ring([0.2, 5.0, -0.1], 0.03, 0.05, relief=relief, lift=1e-4)
    assert np.allclose(np.hypot(ring[:, 0] - 0.2, ring[:, 2] + 0.1), 0.03)
    assert np.allclose(ring[:, 1], relief.at(ring[:, 0], ring[:, 2]) + 1e-4)
    assert np.allclose(pole[:, [0, 2]], [[0.2, -0.1]] * 2)
    assert pole[1, 1] - pole[0, 1] == pytest.approx(0.05)
    with pytest.raises(ValueError, match="goal"):
        goal_ring([0.2, np.nan, 0.0], 0.03, 0.05)
    with pytest.raises(ValueError, match="radius"):
        goal_ring([0.2, 0.0, 0.0], -0.03, 0.05)


def test_renderer_draws_a_relief_and_puts_the_shadow_and_trail_on_it(block):
    pts, tris = block
    step = HeightField.step(0.02, 0.12)              # a 2 cm step 12 cm ahead
    r = Renderer(tris, width=W, height=H, body_length=0.1)
    plane = r.render(pts)
    relief = r.render(pts, ground=step)
    assert not np.array_equal(plane, relief)
    assert r._relief is not None and r._relief.ground is step
    on = r._on_ground(np.array([[0.2, 1.0, 0.0], [0.0, 1.0, 0.0]]), 0.0, 0.0)
    assert on[0, 1] == pytest.approx(0.02, abs=1e-6) and on[1, 1] == pytest.approx(0.0, abs=1e-6)
    again = r.render(pts)                             # back to the plane: the first frame again
    assert np.array_equal(again, plane)


def test_renderer_draws_the_goal_where_it_projects(block):
    pts, tris = block
    r = Renderer(tris, width=W, height=H, body_length=0.1)
    goal = np.array([0.05, 0.0, 0.12])
    without, with_goal = r.render(pts), r.render(pts, goal=goal, goal_radius=0.02)
    diff = np.any(without != with_goal, axis=2)
    assert diff.any()
    greenish = with_goal[diff].astype(int)
    assert np.mean(greenish[:, 1] > greenish[:, 0] + 30) > 0.5
    target = r.camera_target(pts)
    col, row = r.project(goal[None], target)[0][0]
    rows, cols = np.nonzero(diff)
    assert np.min(np.hypot(rows - row, cols - col)) < 0.05 * W


@pytest.mark.parametrize("env_id, key", [("SoftTripodClimbStep-v0", "ground"), ("SoftTripodReachGoal-v0", "goal"),
                                         ("SoftTripod-v2", None)])
def test_task_environments_draw_their_ground_and_goal(env_id, key):
    env = gym.make(env_id, render_mode="rgb_array", width=W, height=H)
    try:
        env.reset(seed=0)
        scene = env.unwrapped._render_scene()
        assert (key in scene) if key else scene == {}
        if key == "goal":
            assert np.array_equal(scene["goal"], env.unwrapped.goal)
        frame = env.render()
        assert frame.shape == (H, W, 3)
    finally:
        env.close()


def test_one_colour_per_triangle_or_a_clear_error(block):
    pts, tris = block
    colours = np.tile([0.45, 0.70, 0.92], (len(tris), 1))
    colours[: len(tris) // 2] = [0.85, 0.62, 0.35]
    frame = Renderer(tris, width=W, height=H, body_length=0.1, color=colours).render(pts)
    assert frame.shape == (H, W, 3)
    with pytest.raises(ValueError, match="one per triangle"):
        Renderer(tris, width=W, height=H, body_length=0.1, color=colours[:-1])
