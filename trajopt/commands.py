"""What the ``trajopt`` sub-commands do (argument parsing lives in :mod:`trajopt.cli`; the
library functions they call live in :mod:`trajopt.optimize`, :mod:`trajopt.evaluation` and
:mod:`trajopt.replay`)."""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from soft_envs.envs import cable_points, make_gradient_env, strain_energy_density

from .evaluation import evaluate_result
from .gait import GaitSpec
from .gauss_newton import GaussNewtonOptions
from .optimize import TASK_CONTACT, optimize_gait
from .replay import env_for_result, replay
from .results import Result

__all__ = ["run_optimize", "run_evaluate", "run_render", "run_export", "run_plot"]


def _print_table(rows: list[tuple[str, str]]) -> None:
    w = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"  {k.ljust(w)}  {v}")


def _gait_rows(task: str, ev: dict, target_speed: float | None = None) -> list[tuple[str, str]]:
    """Speed and heading (yaw of the best-fit rotation of all nodes) over the evaluated cycles.
    A turn's speed is along its COM path sampled once per cycle (along a fixed direction it
    averages out; every step's path adds the sway within a stride); it also shows its heading
    per cycle and over the optimised horizon, with the COM's RMS distance from the circle."""
    aim = f" (target {target_speed:g})" if target_speed is not None else ""
    if task != "turn":
        return [("speed", f"{ev['speed_bl_per_min']:.2f} BL/min over {ev['cycles']} cycles{aim}"),
                ("per cycle", " ".join(f"{v:.2f}" for v in ev.get("speed_per_cycle_bl_per_min", []))),
                ("heading change", f"{ev.get('heading_change_deg', float('nan')):+.1f} deg over {ev['cycles']} cycles")]
    rows = [("speed", f"{ev.get('cycle_path_speed_bl_per_min', float('nan')):.2f} BL/min along the COM path "
                      f"(cycle to cycle) over {ev['cycles']} cycles{aim}"),
            ("heading change", f"{ev.get('heading_change_deg', float('nan')):+.1f} deg over {ev['cycles']} cycles"),
            ("heading per cycle", " ".join(f"{v:+.1f}" for v in ev.get("heading_per_cycle_deg", [])))]
    if "horizon_heading_change_deg" in ev:
        rows.append(("heading, horizon", f"{ev['horizon_heading_change_deg']:+.1f} deg over the optimised "
                                         f"{ev['horizon_steps']} steps; COM {ev['horizon_rms_to_target_bl']:.3f} "
                                         "BL RMS from the target"))
    return rows


def _load_resume(out: Path) -> Result | None:
    """The interrupted run saved at ``out`` (its settings are checked by ``optimize_gait``), or
    None when it is finished."""
    prev = Result.load(out)
    if prev.status not in ("running", "interrupted"):
        print(f"{out} is finished ({prev.status}); nothing to resume. {prev.summary()}")
        return None
    print(f"resuming {out} after iteration {len(prev.history)}")
    prev.settings["source"] = str(out)          # named by the settings check's error
    return prev


def run_optimize(args) -> int:
    task = args.task
    name = args.name or f"{Path(args.robot).stem if args.robot.endswith('.toml') else args.robot}_{task}"
    out = args.out / f"{name}.npz"
    incline = args.angle if task == "incline" else 0.0
    resume = None
    if args.resume and out.is_file():
        resume = _load_resume(out)
        if resume is None:
            return 0
    warm = Result.load(args.warm_start) if args.warm_start else None
    if warm is not None:
        warm.settings["source"] = str(args.warm_start)
    gait = GaitSpec.for_task(task, symmetry=args.symmetry, n_prep=args.prep_steps, n_cycle=args.cycle_steps,
                             n_keyframes=args.keyframes)
    contact = args.contact or TASK_CONTACT.get(task)          # the turn pivots on feet that stick
    env = make_gradient_env(args.robot, incline_deg=incline, heading_deg=args.heading, contact=contact)
    print(f"{env.robot.summary()}; task {task}; {env.contact_model} contact law"
          + (f" (the {task}'s default; --contact paper for the paper's)" if contact and not args.contact else "")
          + (f", slope {incline:g} deg" if incline else ""))
    bar = None
    if not args.quiet:
        from tqdm import tqdm
        bar = tqdm(total=args.iterations, desc="Gauss-Newton", unit="it", file=sys.stderr)
    latest: dict = {}

    def checkpoint(entry: dict, partial: Result) -> None:
        latest["result"] = partial
        partial.save(out)                      # atomic: a crash leaves the previous checkpoint
        if bar is not None:
            bar.update(1)
            bar.set_postfix(objective=f"{entry['objective_after']:.4g}", step=f"{entry['step']:.1e}")

    options = GaussNewtonOptions(max_iter=args.iterations - (len(resume.history) if resume else 0))
    t0 = time.perf_counter()
    try:
        res = optimize_gait(env, task, gait=gait, speed_bl_per_min=args.speed, heading_deg=args.heading,
                            turn=args.turn, options=options, warm_start=warm, n_seeds=args.seeds,
                            eval_cycles=args.cycles, robot_spec=args.robot, callback=checkpoint, resume=resume)
    except KeyboardInterrupt:
        if bar is not None:
            bar.close()
        if "result" in latest:
            latest["result"].status = "interrupted"
            latest["result"].save(out)
            print(f"\ninterrupted: last iterate saved to {out}; continue with --resume", file=sys.stderr)
        return 130
    if bar is not None:
        bar.close()
    path = res.save(out)
    ev = res.evaluation
    print(f"\nsaved {path} ({time.perf_counter() - t0:.1f} s)")
    _print_table([
        ("status", res.status),
        ("iterations", str(len(res.history))),
        ("objective", f"{ev['objective']:.5g}"),
        *_gait_rows(res.task, ev, res.settings["speed_bl_per_min"]),
        ("upright", str(ev["upright"])),
        ("simulation steps", str(ev["optimization_sim_steps"])),
    ])
    return 0


def run_evaluate(args) -> int:
    res = Result.load(args.result)
    ev = evaluate_result(res, args.cycles)
    print(res.summary())
    _print_table([*_gait_rows(res.task, ev),
                  ("max tilt", f"{ev.get('max_tilt_deg', float('nan')):.1f} deg"),
                  ("upright", str(ev["upright"]))])
    return 0 if ev["upright"] else 1


def run_render(args) -> int:
    from soft_envs.render import Renderer, write_animation
    if args.gif is None and args.mp4 is None:
        raise ValueError("give --gif PATH and/or --mp4 PATH")
    res = Result.load(args.result)
    env, u, traj = replay(res, args.cycles)
    robot = env.robot
    w, h = (int(v) for v in args.size.lower().split("x"))
    renderer = Renderer(robot.mesh.surface, width=w, height=h, body_length=robot.body_length)
    frames = []
    for k in range(0, len(traj.x), max(args.every, 1)):
        uk = u[min(max(k - 1, 0), len(u) - 1)]
        tension = env.cable_tension(traj.x[k], uk)
        cables = [(pts, float(t)) for pts, t in zip(cable_points(robot, traj.x[k]), tension)]
        frames.append(renderer.render(traj.x[k], cables=cables, com_trail=traj.com[:k + 1],
                                      gravity=env.gravity, title=f"t = {k * env.timestep:.2f} s"))
    fps = 1.0 / (env.timestep * max(args.every, 1))
    for path in (args.gif, args.mp4):
        if path is not None:
            write_animation(frames, path, fps)
            print(f"wrote {path} ({len(frames)} frames)")
    return 0


def run_export(args) -> int:
    from .export import export_vtu_series
    res = Result.load(args.result)
    env, u, traj = replay(res, args.cycles)
    robot = env.robot
    pvd = export_vtu_series(args.vtu, robot.mesh.tets, robot.mesh.points, traj.x, env.timestep,
                            cell_data={"strain_energy_density": strain_energy_density(robot, traj.x)},
                            cables=cable_points(robot, traj.x), basename=Path(args.result).stem)
    print(f"wrote {pvd} ({len(traj.x)} steps)")
    return 0


def run_plot(args) -> int:
    from . import plots
    res = Result.load(args.result)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    stem = Path(args.result).stem
    x0, _ = env_for_result(res).reset_state()
    s = res.settings
    ext = args.format
    written = [plots.plot_com_topdown(res.com, res.target, out / f"{stem}_com.{ext}", body_outline=x0,
                                      prep_steps=s.get("n_prep"))]
    written.append(plots.plot_controls(res.u, res.dt, res.motor_names, out / f"{stem}_controls.{ext}",
                                       n_prep=s.get("n_prep"), n_cycle=s.get("n_cycle"), u_post=res.u_post))
    if res.history:
        written.append(plots.plot_convergence(res.history, out / f"{stem}_convergence.{ext}"))
    speeds = res.evaluation.get("speed_per_cycle_bl_per_min")
    if speeds:
        ref = {"tripod": 6.1, "puppy": 8.6}.get(res.robot)
        written.append(plots.plot_speed_per_cycle(np.asarray(speeds), out / f"{stem}_speed.{ext}", reference=ref))
    for w in written:
        print(f"wrote {w}")
    return 0
