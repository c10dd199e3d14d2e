"""Write the closed surfaces the Hexapod and the Inchworm are meshed from (``trajopt mesh``).

Run:  python assets/make_surfaces.py          (writes assets/hexapod/hexapod.obj, assets/inchworm/inchworm.obj)

Each body is a union of boxes on a grid, triangulated as the boundary of a voxel tet mesh (closed
and consistently oriented by construction), with every leg tapered to 80 % of its cross-section at
the foot, written as a CAD tool exports it: millimetres, +Z up, +X forward, Y to the left (as
``examples/data/make_quadruped.py`` makes the quadruped). Foam bodies sized like the shipped
robots (Tripod 14 cm, Puppy 13 cm):

* **hexapod**: a 140 x 80 x 25 mm slab on six 35 mm legs (20 x 20 mm), three a side, at the
  back, the middle and the front: twice the Puppy's legs, so a gait can always keep a tripod of
  feet on the ground;
* **inchworm**: a 140 x 40 x 15 mm strip on two full-width feet 20 mm tall (25 mm long, at the
  back and the front): no left/right legs at all; its feet are bent by leg tendons and the strip
  between them is humped by a belly tendon (added by hand to robot.toml).

Then ``trajopt mesh`` (the commands are in docs/robots.md) tetrahedralises them with gmsh.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from soft_envs.sim.mesh import boundary_faces
from soft_envs.sim.meshgen import box_occupancy, voxel_tet_mesh

HERE = Path(__file__).resolve().parent
FOOT = 0.8            # foot cross-section / leg cross-section

#: per body: grid (robot frame, mm: x forward, y up, z to the right), body box, leg boxes
BODIES = {
    "hexapod": dict(
        xs=[0, 20, 40, 60, 80, 100, 120, 140], ys=[0, 17.5, 35, 47.5, 60],
        zs=[0, 20, 40, 60, 80], body=((0, 140), (35, 60), (0, 80)),
        legs=[(x, (0, 35), z) for x in ((0, 20), (60, 80), (120, 140)) for z in ((0, 20), (60, 80))]),
    "inchworm": dict(
        xs=[0, 12.5, 25, 40, 55, 70, 85, 100, 115, 127.5, 140], ys=[0, 10, 20, 27.5, 35],
        zs=[0, 20, 40], body=((0, 140), (20, 35), (0, 40)),
        legs=[(x, (0, 20), (0, 40)) for x in ((0, 25), (115, 140))]),
}


def surface(name: str) -> tuple[np.ndarray, np.ndarray]:
    """(points [mm] in the CAD frame, outward triangles) of body ``name``."""
    b = BODIES[name]
    xs, ys, zs, legs = b["xs"], b["ys"], b["zs"], b["legs"]
    width = zs[-1]
    points, tets = voxel_tet_mesh(xs, ys, zs, box_occupancy(xs, ys, zs, [b["body"], *legs]), mirror_z=width / 2)
    tris = boundary_faces(tets)
    used, inverse = np.unique(tris, return_inverse=True)
    points, tris = points[used].copy(), inverse.reshape(-1, 3)
    for (x0, x1), (y0, y1), (z0, z1) in legs:     # taper: x FOOT at y = 0, x 1 where the leg meets the body
        inside = ((points[:, 0] >= x0) & (points[:, 0] <= x1) & (points[:, 2] >= z0) & (points[:, 2] <= z1)
                  & (points[:, 1] < y1))
        s = FOOT + (1 - FOOT) * points[inside, 1] / y1
        centre = np.array([0.5 * (x0 + x1), 0.5 * (z0 + z1)])
        points[np.ix_(inside, [0, 2])] = centre + s[:, None] * (points[np.ix_(inside, [0, 2])] - centre)
    cad = np.stack([points[:, 0], -(points[:, 2] - width / 2), points[:, 1]], axis=1)  # X fwd, Y left, Z up
    return cad, tris          # (x, -z, y) keeps the orientation: the map has determinant +1


def write_obj(path: Path, name: str, points: np.ndarray, tris: np.ndarray) -> None:
    lines = [f"# {name} foam body, millimetres, +Z up, +X forward (assets/make_surfaces.py)"]
    lines += [f"v {x:g} {y:g} {z:g}" for x, y, z in points]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in tris]
    tmp = path.with_name(f".{path.name}.tmp")            # atomic: an interrupted run leaves the old file whole
    tmp.write_text("\n".join(lines) + "\n")
    os.replace(tmp, path)


if __name__ == "__main__":
    for name in BODIES:
        pts, tris = surface(name)
        out = HERE / name / f"{name}.obj"
        out.parent.mkdir(exist_ok=True)
        write_obj(out, name, pts, tris)
        print(f"wrote {out}: {len(pts)} vertices, {len(tris)} triangles, {out.stat().st_size / 1024:.1f} kB")
