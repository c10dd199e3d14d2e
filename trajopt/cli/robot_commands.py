"""``trajopt mesh`` (a closed surface -> tet mesh + robot.toml skeleton) and ``trajopt check``
(validate a robot, print its summary, draw it). Argument parsing lives in :mod:`trajopt.cli`."""
from __future__ import annotations

import sys
from pathlib import Path

from .table import print_table

__all__ = ["run_mesh", "run_check"]


def _warn(messages: list[str]) -> None:
    for m in messages:
        print(f"warning: {m}", file=sys.stderr)


def run_mesh(args) -> int:
    try:
        from soft_envs.skeleton import make_robot
        material = {k: getattr(args, k) for k in ("density", "youngs_modulus", "payload_mass")
                    if getattr(args, k) is not None}
        result, vtu, toml = make_robot(args.surface, args.out, name=args.name, scale=args.scale,
                                       forward=args.forward, up=args.up, edge_length=args.edge_length,
                                       remesh=not args.keep_surface, tendons=args.tendons,
                                       overwrite=args.force, max_elements=args.max_elements,
                                       on_estimate=_print_estimate, **material)
    except ImportError as exc:
        print(f"trajopt: error: {exc}", file=sys.stderr)
        return 1
    _warn(result.warnings)
    s, ext = result.surface, result.points.max(axis=0) - result.points.min(axis=0)
    print(f"meshed {args.surface} with gmsh")
    print_table([
        ("surface", f"{len(s.points)} points, {len(s.triangles)} triangles, closed, one body, "
                    f"volume {s.volume:.4e} m^3"),
        ("frame", f"forward {args.forward} -> +x, up {args.up} -> +y, scale {args.scale:g}; lowest point at y = 0"),
        ("size", f"{1e3 * ext[0]:.1f} mm long, {1e3 * ext[1]:.1f} mm high, {1e3 * ext[2]:.1f} mm wide"),
        ("tet mesh", f"{len(result.points)} nodes, {len(result.tets)} tets, volume {result.volume:.4e} m^3, "
                     "all positively oriented"),
        *result.quality.rows(),
        ("wrote", f"{vtu}, {toml}"),
    ])
    print(f"\nnext: edit {toml} (material, payload, tendons and motors: its comments say how), then\n"
          f"  trajopt check {toml}\n  trajopt optimize {toml} --task walk --out results/")
    return 0


def _print_estimate(n: int, edge_length: float) -> None:
    print(f"meshing at edge length {edge_length:.4g} m: about {n} tets expected", flush=True)


def run_check(args) -> int:
    from soft_envs.robot_check import check_robot, draw_robot

    check = check_robot(args.robot)           # ValueError naming file and field -> exit code 2
    robot = check.robot
    print(f"{robot.name}: valid")
    print_table(check.rows)
    _warn(check.warnings)
    if not args.no_picture:
        if args.picture is not None:
            picture = args.picture
        elif Path(args.robot).suffix == ".toml" or Path(args.robot).is_file():
            picture = Path(args.robot).parent / f"{robot.name}.png"
        else:
            picture = Path(f"{robot.name}.png")
        draw_robot(robot, picture)
        print(f"picture: {picture} (views of the mesh, tendons coloured by motor, payload nodes black)")
    return 0
