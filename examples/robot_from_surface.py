"""Bring your own robot: from a designer's surface mesh of a foam body to a walking gait.

Run:  python examples/robot_from_surface.py                (a few minutes; 8.9 BL/min)
      SOFT_ENVS_QUICK=1 python examples/robot_from_surface.py   (tiny settings, as CI runs it)

1. mesh ``examples/data/quadruped.obj`` (millimetres, +Z up, +X forward, as CAD exports it; made
   by ``examples/data/make_quadruped.py``) with gmsh into the robot frame, and write a robot.toml
   with a tendon pair on the front and the back face of every leg (the shipped Puppy's layout);
2. check the robot and draw it (mesh, tendons by motor, payload nodes);
3. optimise a walking gait with shooting Gauss-Newton (paper III) and print its speed.

The same from the shell:
    trajopt mesh examples/data/quadruped.obj --scale 0.001 --up +z --tendons legs --out results/quadruped
    trajopt check results/quadruped/robot.toml
    trajopt optimize results/quadruped/robot.toml --task walk --out results/
Needs the optional extra ``soft-envs[mesh]`` (gmsh).
"""
import os
from pathlib import Path

from soft_envs.robot_check import check_robot, draw_robot
from soft_envs.skeleton import make_robot
from trajopt import GaitSpec, GaussNewtonOptions, optimize_gait

QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"
SURFACE = Path(__file__).resolve().parent / "data" / "quadruped.obj"
OUT = Path("results") / ("quadruped_quick" if QUICK else "quadruped")   # quick: a coarser mesh, its own folder

# 1. surface -> tet mesh + robot.toml (overwritten: this folder is the example's own output)
mesh, vtu, toml = make_robot(SURFACE, OUT, scale=1e-3, up="+z", forward="+x", tendons="legs",
                             edge_length=0.035 if QUICK else None, overwrite=True)
for w in mesh.warnings:
    print("warning:", w)
q = mesh.quality
print(f"meshed {SURFACE.name}: {len(mesh.points)} nodes, {len(mesh.tets)} tets, min dihedral "
      f"{q.min_dihedral_deg:.1f} deg, radius ratio min {q.min_radius_ratio:.2f} / median "
      f"{q.median_radius_ratio:.2f}; wrote {vtu} and {toml}")

# 2. validate, summarise and draw
check = check_robot(toml)
for label, value in check.rows[:6]:
    print(f"  {label:<16} {value}")
for w in check.warnings:
    print("warning:", w)
picture = OUT / "quadruped.png"
draw_robot(check.robot, picture)
print(f"picture: {picture}")


# 3. a walking gait (symmetric: left motors mirror right ones)
def progress(entry, partial):
    print(f"iteration {entry['iteration']}: objective {entry['objective']:.4g} -> "
          f"{entry['objective_after']:.4g} ({entry['time']:.1f} s)")


settings = (dict(gait=GaitSpec(n_prep=8, n_cycle=24), n_seeds=1, eval_cycles=1,
                 options=GaussNewtonOptions(max_iter=1))
            if QUICK else dict(n_seeds=8, eval_cycles=6, options=GaussNewtonOptions(max_iter=10)))
result = optimize_gait(toml, task="walk", speed_bl_per_min=10.0, robot_spec=str(toml), callback=progress,
                       **settings)   # robot_spec: the saved result names robot.toml, so render/plot find it
ev = result.evaluation
print(result.summary())
print(f"speed: {ev['speed_bl_per_min']:.2f} body lengths/min over {ev['cycles']} cycles "
      "(compare the shipped Puppy: trajopt optimize puppy --task walk)")
path = result.save(OUT / "quadruped_walk.npz")
print(f"saved {path}; look at it with: trajopt render {path} --gif {OUT / 'quadruped_walk.gif'}")
