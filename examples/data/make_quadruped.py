"""Write ``quadruped.obj``: the closed surface of a small four-legged foam body, as a designer's
CAD tool would export it (millimetres, +Z up, +X forward, Y to the left).

Run:  python examples/data/make_quadruped.py

The body is a 130 x 80 x 30 mm slab on four legs 40 mm tall whose feet taper to 80 % of the
leg's cross-section (so the surface has slanted faces, not only axis-aligned ones). It is built
as the union of boxes on a grid, triangulated as the boundary of a voxel tet mesh (closed and
consistently oriented by construction), then the legs are tapered by moving vertices.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from soft_envs.sim.mesh import boundary_faces
from soft_envs.sim.meshgen import box_occupancy, voxel_tet_mesh

HERE = Path(__file__).resolve().parent
LENGTH, WIDTH, BODY, LEG = 130.0, 80.0, 30.0, 40.0      # mm
LEG_X = {"hind": (0.0, 30.0), "fore": (100.0, 130.0)}   # along +X (forward)
LEG_W = 20.0                                             # leg width across the body
FOOT = 0.8                                               # foot cross-section / leg cross-section


def surface() -> tuple[np.ndarray, np.ndarray]:
    """(points [mm] in the CAD frame, outward triangles) of the body."""
    # grid in the robot frame (x forward, y up, z to the right), mm
    xs = [0, 15, 30, 65, 100, 115, 130]
    ys = [0, 10, 20, 30, LEG, LEG + 15, LEG + BODY]
    zs = [0, 10, 20, 40, 60, 70, 80]
    legs = [(x, (0, LEG), z) for x in LEG_X.values() for z in ((0, LEG_W), (WIDTH - LEG_W, WIDTH))]
    boxes = [((0, LENGTH), (LEG, LEG + BODY), (0, WIDTH)), *legs]
    points, tets = voxel_tet_mesh(xs, ys, zs, box_occupancy(xs, ys, zs, boxes), mirror_z=WIDTH / 2)
    tris = boundary_faces(tets)
    used, inverse = np.unique(tris, return_inverse=True)
    points, tris = points[used].copy(), inverse.reshape(-1, 3)
    # taper each leg towards its foot: cross-section scaled by FOOT at y = 0, by 1 at the body
    for (x0, x1), (y0, y1), (z0, z1) in legs:
        inside = ((points[:, 0] >= x0) & (points[:, 0] <= x1) & (points[:, 2] >= z0) & (points[:, 2] <= z1)
                  & (points[:, 1] < y1))
        s = FOOT + (1 - FOOT) * points[inside, 1] / LEG
        centre = np.array([0.5 * (x0 + x1), 0.5 * (z0 + z1)])
        points[np.ix_(inside, [0, 2])] = centre + s[:, None] * (points[np.ix_(inside, [0, 2])] - centre)
    cad = np.stack([points[:, 0], -(points[:, 2] - WIDTH / 2), points[:, 1]], axis=1)  # X fwd, Y left, Z up
    return cad, tris          # (x, -z, y) keeps the orientation: the map has determinant +1


def write_obj(path: Path, points: np.ndarray, tris: np.ndarray) -> None:
    lines = ["# quadruped foam body, millimetres, +Z up, +X forward (examples/data/make_quadruped.py)"]
    lines += [f"v {x:g} {y:g} {z:g}" for x, y, z in points]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in tris]
    path.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    pts, tris = surface()
    out = HERE / "quadruped.obj"
    write_obj(out, pts, tris)
    print(f"wrote {out}: {len(pts)} vertices, {len(tris)} triangles, {out.stat().st_size / 1024:.1f} kB")
