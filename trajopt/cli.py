"""trajopt: optimise, evaluate, render, export and play gaits of cable-driven soft robots.

    trajopt optimize tripod --task walk --out results/
    trajopt optimize puppy --task turn --warm-start results/puppy_walk.npz --out results/
    trajopt optimize puppy --task incline --angle 10 --out results/
    trajopt evaluate results/tripod_walk.npz [--cycles 10]
    trajopt render results/tripod_walk.npz --gif tripod.gif [--mp4 tripod.mp4]
    trajopt export results/tripod_walk.npz --vtu paraview/
    trajopt plot results/tripod_walk.npz --out plots/
    trajopt play results/tripod_walk.npz --hardware hw.toml [--dry-run]
    trajopt rl train tripod --algo ppo --timesteps 20000 --out runs/
    trajopt mesh body.stl --scale 0.001 --up +z --out my_robot/
    trajopt check my_robot/robot.toml
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from .gait import DEFAULT_EVAL_CYCLES, TURN_KEYFRAMES, GaitSpec

__all__ = ["main", "build_parser"]


def _add_optimize(sub) -> None:
    p = sub.add_parser("optimize", help="optimise a gait (paper III) and save a result")
    p.add_argument("robot", help="shipped robot (tripod, puppy) or path to a robot.toml")
    p.add_argument("--task", choices=["walk", "turn", "incline"], default="walk")
    p.add_argument("--speed", type=float, default=None, help="target speed [body lengths/min]")
    p.add_argument("--heading", type=float, default=0.0, help="walking direction [deg from +x to +z]")
    p.add_argument("--turn", choices=["right", "left"], default="right", help="turn direction (task turn)")
    p.add_argument("--angle", type=float, default=20.0, help="slope [deg] (task incline)")
    p.add_argument("--contact", choices=["paper", "coulomb"], default=None,
                   help="ground contact law: paper (II-C, viscous-like friction, Table I) or coulomb "
                        "(friction bounded by mu N, feet that stick); default: the robot file's, coulomb "
                        "for the turn (it pivots on a foot that sticks)")
    sym = p.add_mutually_exclusive_group()
    sym.add_argument("--symmetry", dest="symmetry", action="store_true", default=None,
                     help="bilateral symmetry on (default for walk and incline)")
    sym.add_argument("--no-symmetry", dest="symmetry", action="store_false", help="symmetry off (default for turn)")
    p.add_argument("--warm-start", type=Path, default=None, help="start from this result's keyframes")
    p.add_argument("--iterations", type=int, default=10, help="Gauss-Newton iterations at most")
    paper = GaitSpec()
    p.add_argument("--keyframes", type=int, default=None,
                   help=f"spline keyframes per cycle (default {paper.n_keyframes}, the paper's; turn {TURN_KEYFRAMES})")
    p.add_argument("--cycle-steps", type=int, default=paper.n_cycle,
                   help=f"simulation steps per gait cycle (default {paper.n_cycle}, the paper's)")
    p.add_argument("--prep-steps", type=int, default=paper.n_prep,
                   help=f"simulation steps of the preparatory phase (default {paper.n_prep}, the paper's)")
    p.add_argument("--seeds", type=int, default=8, help="random starting patterns tried (no warm start)")
    p.add_argument("--cycles", type=int, default=DEFAULT_EVAL_CYCLES, help="cycles played for the evaluation")
    p.add_argument("--out", type=Path, default=Path("results"), help="output directory")
    p.add_argument("--name", default=None, help="result file name (default ROBOT_TASK)")
    p.add_argument("--resume", action="store_true", help="continue an interrupted run of the same name")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_optimize)


def _add_result_commands(sub) -> None:
    p = sub.add_parser("evaluate", help="re-simulate a result and report its speed")
    p.add_argument("result", type=Path)
    p.add_argument("--cycles", type=int, default=None, help="cycles to play (default: as optimised)")
    p.set_defaults(func=_cmd_evaluate)
    p = sub.add_parser("render", help="animate a result (GIF through Pillow, MP4 with imageio-ffmpeg)")
    p.add_argument("result", type=Path)
    p.add_argument("--gif", type=Path, default=None)
    p.add_argument("--mp4", type=Path, default=None)
    p.add_argument("--cycles", type=int, default=GaitSpec().n_cycles,
                   help="gait cycles played after the prep phase (RL results play their own controls)")
    p.add_argument("--every", type=int, default=2, help="render every n-th simulation step")
    p.add_argument("--size", default="480x360", help="frame size WIDTHxHEIGHT")
    p.set_defaults(func=_cmd_render)
    p = sub.add_parser("export", help="ParaView time series (.vtu per step + .pvd)")
    p.add_argument("result", type=Path)
    p.add_argument("--vtu", type=Path, required=True, help="output directory")
    p.add_argument("--cycles", type=int, default=GaitSpec().n_cycles,
                   help="gait cycles played after the prep phase (RL results play their own controls)")
    p.set_defaults(func=_cmd_export)
    p = sub.add_parser("plot", help="COM path, controls, convergence and speed plots")
    p.add_argument("result", type=Path)
    p.add_argument("--out", type=Path, default=Path("plots"))
    p.add_argument("--format", choices=["png", "svg"], default="png")
    p.set_defaults(func=_cmd_plot)


def _add_robot_commands(sub) -> None:
    p = sub.add_parser("mesh", help="tet-mesh a closed surface (STL/OBJ/PLY...) and write a robot.toml skeleton")
    p.add_argument("surface", type=Path, help="closed surface, any format meshio reads")
    p.add_argument("--out", type=Path, required=True, help="output directory (<name>.vtu, robot.toml)")
    p.add_argument("--name", default=None, help="robot name (default: the surface file's stem)")
    p.add_argument("--scale", type=float, default=1.0, help="surface units -> metres (0.001 for mm)")
    axes = ["+x", "-x", "+y", "-y", "+z", "-z"]
    p.add_argument("--forward", default="+x", choices=axes, metavar="AXIS",
                   help="surface axis pointing forward: +x -x +y -y +z -z (negative: --forward=-y)")
    p.add_argument("--up", default="+y", choices=axes, metavar="AXIS",
                   help="surface axis pointing up (default +y; Z-up CAD: --up +z)")
    p.add_argument("--edge-length", type=float, default=None,
                   help="target tet edge length [m, after --scale] (default: body length / 6)")
    p.add_argument("--keep-surface", action="store_true", help="keep the surface triangles (no re-meshing)")
    p.add_argument("--tendons", choices=["example", "legs"], default="example",
                   help="one example tendon pair, or a pair on the front and back of every leg")
    p.add_argument("--density", type=float, default=None, help="[kg/m^3] (default 220)")
    p.add_argument("--youngs-modulus", type=float, default=None, help="[Pa] (default 1e5)")
    p.add_argument("--payload-mass", type=float, default=None, help="[kg] (default 1.5 x body mass)")
    p.add_argument("--force", action="store_true", help="replace an existing robot.toml")
    p.set_defaults(func=_cmd_mesh)
    p = sub.add_parser("check", help="validate a robot, print its summary and draw it")
    p.add_argument("robot", help="shipped robot (tripod, puppy) or path to a robot.toml")
    p.add_argument("--picture", type=Path, default=None,
                   help="PNG to write (default: <robot name>.png beside the robot.toml, or here)")
    p.add_argument("--no-picture", action="store_true", help="do not draw")
    p.set_defaults(func=_cmd_check)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="trajopt", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    _add_optimize(sub)
    _add_result_commands(sub)
    _add_robot_commands(sub)
    try:
        from .hardware.cli import add_play_parser
        add_play_parser(sub)
    except ImportError:   # pragma: no cover
        pass
    try:
        from .rl.cli import add_rl_parser
        add_rl_parser(sub)
    except ImportError:
        pass
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ValueError as exc:          # bad input: files, fields, values
        print(f"trajopt: error: {exc}", file=sys.stderr)
        return 2


# ---------------------------------------------------------------------- commands
def _cmd_optimize(args) -> int:
    from .commands import run_optimize
    return run_optimize(args)


def _cmd_evaluate(args) -> int:
    from .commands import run_evaluate
    return run_evaluate(args)


def _cmd_render(args) -> int:
    from .commands import run_render
    return run_render(args)


def _cmd_export(args) -> int:
    from .commands import run_export
    return run_export(args)


def _cmd_plot(args) -> int:
    from .commands import run_plot
    return run_plot(args)


def _cmd_mesh(args) -> int:
    from .robot_commands import run_mesh
    return run_mesh(args)


def _cmd_check(args) -> int:
    from .robot_commands import run_check
    return run_check(args)


if __name__ == "__main__":  # pragma: no cover
    np.seterr(all="ignore")
    sys.exit(main())
