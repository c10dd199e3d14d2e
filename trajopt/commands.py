"""What the ``trajopt`` sub-commands do (argument parsing lives in :mod:`trajopt.cli`)."""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from .gauss_newton import GaussNewtonOptions
from .hooks import make_hooks
from .optimize import optimize_gait
from .parameterization import GaitParameterization
from .results import Result

__all__ = ["run_optimize", "run_evaluate", "run_render", "run_export", "run_plot", "hooks_for_result",
           "replay"]


def hooks_for_result(res: Result):
    """The physics a result was made on (robot, slope, heading); refuses a different time step."""
    s = res.settings
    hooks = make_hooks(res.robot, incline_deg=float(s.get("incline_deg", 0.0)),
                       heading_deg=float(s.get("heading_deg", 0.0)))
    if abs(hooks.dt - res.dt) > 1e-12:
        raise ValueError(f"the result was made with dt = {res.dt} s, the simulator here uses {hooks.dt} s")
    return hooks


def parameterization_for(res: Result, robot) -> GaitParameterization:
    s = res.settings
    return GaitParameterization(robot.u_bounds, robot.mirror_map, int(s["n_prep"]), int(s["n_cycle"]),
                                int(s["n_keyframes"]), bool(s["symmetry"]))


def replay(res: Result, n_cycles: int | None = None):
    """(hooks, controls, trajectory) of a result played for ``n_cycles`` cycles (default: the
    optimised prep + 2 cycles). Keyframe results are re-expanded; others (RL) play ``u``."""
    hooks = hooks_for_result(res)
    if "keyframes" in res.settings and n_cycles is not None:
        param = parameterization_for(res, hooks.robot)
        u = param.controls(param.z_from_keyframes(np.asarray(res.settings["keyframes"])), n_cycles)
    else:
        u = res.u
    return hooks, u, hooks.rollout(u)


def _print_table(rows: list[tuple[str, str]]) -> None:
    w = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"  {k.ljust(w)}  {v}")


def run_optimize(args) -> int:
    task = args.task
    name = args.name or f"{Path(args.robot).stem if args.robot.endswith('.toml') else args.robot}_{task}"
    out = args.out / f"{name}.npz"
    incline = args.angle if task == "incline" else 0.0
    resume = None
    if args.resume and out.is_file():
        prev = Result.load(out)
        if prev.status not in ("running", "interrupted"):
            print(f"{out} is finished ({prev.status}); nothing to resume. {prev.summary()}")
            return 0
        wanted = {"n_keyframes": args.keyframes, "n_cycle": args.cycle_steps, "n_prep": args.prep_steps,
                  "heading_deg": args.heading, "turn": args.turn, "incline_deg": incline}
        if args.speed is not None:
            wanted["speed_bl_per_min"] = args.speed
        if args.symmetry is not None:
            wanted["symmetry"] = args.symmetry
        differ = {k: (prev.settings.get(k), v) for k, v in wanted.items() if prev.settings.get(k) != v}
        if prev.task != task or differ:
            raise ValueError(f"{out}: --resume needs the settings of the interrupted run; these differ "
                             f"(saved, asked): {differ or {'task': (prev.task, task)}}")
        resume = prev
        print(f"resuming {out} after iteration {len(prev.history)}")
    warm = Result.load(args.warm_start) if args.warm_start else None
    if warm is not None:
        warm.settings["source"] = str(args.warm_start)
    hooks = make_hooks(args.robot, incline_deg=incline, heading_deg=args.heading)
    print(f"{hooks.robot.summary()}; task {task}" + (f", slope {incline:g} deg" if incline else ""))
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
        res = optimize_gait(hooks, task, speed_bl_per_min=args.speed, heading_deg=args.heading,
                            turn=args.turn, symmetry=args.symmetry, n_keyframes=args.keyframes,
                            n_cycle=args.cycle_steps, n_prep=args.prep_steps,
                            options=options, warm_start=warm, n_seeds=args.seeds, eval_cycles=args.cycles,
                            robot_spec=args.robot, callback=checkpoint, resume=resume)
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
        ("speed", f"{ev['speed_bl_per_min']:.2f} BL/min over {ev['cycles']} cycles "
                  f"(target {res.settings['speed_bl_per_min']:g})"),
        ("per cycle", " ".join(f"{v:.2f}" for v in ev.get("speed_per_cycle_bl_per_min", []))),
        ("heading change", f"{ev.get('heading_change_deg', float('nan')):+.1f} deg"),
        ("upright", str(ev["upright"])),
        ("simulation steps", str(ev["optimization_sim_steps"])),
    ])
    return 0


def evaluate_result(res: Result, n_cycles: int | None = None) -> dict:
    """The metric of a saved gait over ``n_cycles`` cycles (default: as it was evaluated);
    keyframe results are re-expanded, others (like exported RL gaits) play their ``u``."""
    from .evaluation import evaluate_controls
    hooks = hooks_for_result(res)
    s = res.settings
    cycles = int(s.get("eval_cycles", 6)) if n_cycles is None else int(n_cycles)
    if cycles < 1:
        raise ValueError(f"the number of cycles must be >= 1, got {cycles}")
    if "keyframes" in s:
        param = parameterization_for(res, hooks.robot)
        u = param.controls(param.z_from_keyframes(np.asarray(s["keyframes"])), cycles)
        n_prep, n_cycle = param.n_prep, param.n_cycle
    else:
        u, n_prep, n_cycle = res.u, int(s.get("n_prep", 0)), int(s.get("n_cycle", len(res.u)))
    return evaluate_controls(hooks, u, n_prep=n_prep, n_cycle=n_cycle,
                             heading_deg_target=float(s.get("heading_deg", 0.0)))


def run_evaluate(args) -> int:
    res = Result.load(args.result)
    ev = evaluate_result(res, args.cycles)
    print(res.summary())
    _print_table([("speed", f"{ev['speed_bl_per_min']:.3f} BL/min over {ev['cycles']} cycles"),
                  ("per cycle", " ".join(f"{v:.2f}" for v in ev.get("speed_per_cycle_bl_per_min", []))),
                  ("heading change", f"{ev.get('heading_change_deg', float('nan')):+.1f} deg"),
                  ("max tilt", f"{ev.get('max_tilt_deg', float('nan')):.1f} deg"),
                  ("upright", str(ev["upright"]))])
    return 0 if ev["upright"] else 1


def run_render(args) -> int:
    from soft_envs.render import Renderer, write_animation
    if args.gif is None and args.mp4 is None:
        raise ValueError("give --gif PATH and/or --mp4 PATH")
    res = Result.load(args.result)
    hooks, u, traj = replay(res, args.cycles)
    robot = hooks.robot
    w, h = (int(v) for v in args.size.lower().split("x"))
    renderer = Renderer(robot.mesh.surface, width=w, height=h, body_length=robot.body_length)
    sim = hooks.simulator
    cd = robot.cable_data
    frames = []
    for k in range(0, len(traj.x), max(args.every, 1)):
        uk = u[min(max(k - 1, 0), len(u) - 1)]
        tens = sim.cable_tension(traj.x[k], uk)
        cables = []
        for t in range(len(robot.tendons)):
            nodes, wts = cd.pt_nodes[cd.ptr[t]:cd.ptr[t + 1]], cd.pt_w[cd.ptr[t]:cd.ptr[t + 1]]
            cables.append((np.einsum("pa,pai->pi", wts, traj.x[k][nodes]), float(tens[t])))
        frames.append(renderer.render(traj.x[k], cables=cables, com_trail=traj.com[:k + 1],
                                      gravity=sim.gravity, title=f"t = {k * hooks.dt:.2f} s"))
    fps = 1.0 / (hooks.dt * max(args.every, 1))
    for path in (args.gif, args.mp4):
        if path is not None:
            write_animation(frames, path, fps)
            print(f"wrote {path} ({len(frames)} frames)")
    return 0


def run_export(args) -> int:
    from soft_envs.sim.materials import fem_energy_density
    from .export import export_vtu_series
    res = Result.load(args.result)
    hooks, u, traj = replay(res, args.cycles)
    robot = hooks.robot
    mu, lam = robot.element_lame()
    sed = np.stack([fem_energy_density(x, robot.mesh.tets, robot.mesh.dN, mu, lam) for x in traj.x])
    cd = robot.cable_data
    cables = [np.einsum("pa,kpai->kpi", cd.pt_w[cd.ptr[t]:cd.ptr[t + 1]],
                        traj.x[:, cd.pt_nodes[cd.ptr[t]:cd.ptr[t + 1]]]) for t in range(len(robot.tendons))]
    pvd = export_vtu_series(args.vtu, robot.mesh.tets, robot.mesh.points, traj.x, hooks.dt,
                            cell_data={"strain_energy_density": sed}, cables=cables,
                            basename=Path(args.result).stem)
    print(f"wrote {pvd} ({len(traj.x)} steps)")
    return 0


def run_plot(args) -> int:
    from . import plots
    res = Result.load(args.result)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    stem = Path(args.result).stem
    hooks = hooks_for_result(res)
    x0, _ = hooks.reset_state()
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
