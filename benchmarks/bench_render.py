"""Renderer benchmark: frames/s of ``soft_envs.render.Renderer.render``.

Prints frames/s at 480x360 for a synthetic ~400-triangle block (12 x 3 x 4 cubes, 384 boundary
triangles), bare and with two cables, a 200-point COM trail, gravity arrow and title, plus the
shipped robots' coarse meshes when the simulator can load them. Target: >= 15 frames/s.
Run: python benchmarks/bench_render.py
"""
from __future__ import annotations

import numpy as np

from common import best_of, report
from soft_envs.render import Renderer, surface_triangles
from soft_envs.sim.meshgen import graded, voxel_tet_mesh


def block(nx: int = 12, ny: int = 3, nz: int = 4, size=(0.12, 0.03, 0.04)) -> tuple[np.ndarray, np.ndarray]:
    """Points and (6 per cube) tets of a block resting on y = 0."""
    return voxel_tet_mesh(graded(0, size[0], nx), graded(0, size[1], ny), graded(-size[2] / 2, size[2] / 2, nz),
                          np.ones((nx, ny, nz), dtype=bool))


def frames_per_second(tris: np.ndarray, states: list[np.ndarray], body_length: float, extras: bool) -> float:
    r = Renderer(tris, width=480, height=360, body_length=body_length)
    kw = {}
    if extras:
        p0 = states[0]
        lo, hi = p0.min(axis=0), p0.max(axis=0)
        mid = 0.5 * (lo + hi)
        kw = dict(cables=[(np.linspace([lo[0], mid[1], mid[2]], [hi[0], mid[1], mid[2]], 5), 3.0),
                          (np.linspace([lo[0], hi[1], lo[2]], [hi[0], hi[1], lo[2]], 5), 0.0)],
                  com_trail=np.stack([np.linspace(-body_length, 0, 200), np.zeros(200),
                                      0.01 * np.sin(np.linspace(0, 8, 200))], axis=1) + [mid[0], 0, mid[2]],
                  gravity=(0.0, -9.81, 0.0), title="t = 1.23 s")
    n = len(states)
    return n / best_of(lambda: [r.render(x, **kw) for x in states], repeat=3)


def main() -> None:
    pts, tets = block()
    tris = surface_triangles(tets, pts)
    states = []
    for k in range(20):   # a bending wave travelling along the body
        x = pts.copy()
        x[:, 1] += 0.01 * np.sin(2 * np.pi * (x[:, 0] / 0.12 - k / 20)) * x[:, 1] / 0.03
        states.append(x + [0.002 * k, 0.0, 0.0])
    rows = [{"mesh": "block 12x3x4", "triangles": len(tris), "extras": e,
             "frames/s": frames_per_second(tris, states, 0.12, e)} for e in (False, True)]
    try:
        from soft_envs.sim import Simulator, load_robot
        for name in ("tripod", "puppy"):
            robot = load_robot(name)
            x0 = Simulator(robot).rest_positions()
            surf = np.asarray(robot.mesh.surface)
            rows.append({"mesh": name, "triangles": len(surf), "extras": True,
                         "frames/s": frames_per_second(surf, [x0] * 20, robot.body_length, True)})
    except Exception as err:  # the simulator is optional for this benchmark
        print(f"(shipped robots skipped: {type(err).__name__}: {err})")
    report("Renderer.render at 480x360 (target >= 15 frames/s)", rows)


if __name__ == "__main__":
    main()
