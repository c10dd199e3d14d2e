"""What ``trajopt render``, ``export`` and ``plot`` do (argument parsing lives in :mod:`trajopt.cli`;
the library functions in :mod:`trajopt.replay`, :mod:`trajopt.results.export` and :mod:`trajopt.plots`).

Each checks everything before it simulates or draws: the result file, the robot it was made for
(``--ignore-robot-mismatch`` overrides), the tools it needs (``--mp4``: the ``video`` extra), and
its outputs (an existing one is refused without ``--overwrite``). Every file is written
atomically (:mod:`trajopt.results.files`): an interrupted command leaves the previous file or none, never
half a file or a temporary. Defaults follow the results folder (:data:`trajopt.results.files.RESULTS_DIR`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from soft_envs.envs import MotorLaw, cable_points, strain_energy_density

from ..results.files import RESULTS_DIR, atomic_output, refuse_existing
from ..results.motor_load import motor_figures, recorded_torque
from ..replay import env_for_result, replay
from ..results.result import Result
from ..tasks.registry import speed_along_path

__all__ = ["run_render", "run_export", "run_plot", "check_video_writer"]


def check_video_writer() -> None:
    """A ValueError saying what to install when MP4 cannot be written (before any rendering)."""
    try:
        import imageio.v2  # noqa: F401
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        raise ValueError("--mp4 needs the video extra (imageio, imageio-ffmpeg): pip install 'soft-envs[video]'; "
                         "or write a GIF with --gif") from None


def run_render(args) -> int:
    from soft_envs.animation import write_animation
    from soft_envs.render import Renderer
    res = Result.load(args.result)
    gif = args.gif
    if gif is None and args.mp4 is None:
        gif = RESULTS_DIR / f"{Path(args.result).stem}.gif"
    outputs = [p for p in (gif, args.mp4) if p is not None]
    for path, ext in ((gif, ".gif"), (args.mp4, ".mp4")):
        if path is not None and path.suffix.lower() != ext:
            raise ValueError(f"{path}: the {ext[1:].upper()} file name must end in {ext}")
    if args.mp4 is not None:
        check_video_writer()
    refuse_existing(outputs, args.overwrite)
    env, u, traj = replay(res, args.cycles, ignore_robot_mismatch=args.ignore_robot_mismatch)
    robot = env.robot
    w, h = args.size
    steps = range(0, len(traj.x), args.every)
    tensions = [env.cable_tension(traj.x[k], u[min(max(k - 1, 0), len(u) - 1)]) for k in steps]
    top = max([float(np.max(t)) for t in tensions if len(t)] + [1e-3])      # one colour scale for the film
    renderer = Renderer(robot.mesh.surface, width=w, height=h, body_length=robot.body_length, tension_max=top,
                        legend=True, scale_bar=True)
    frames = []
    for k, tension in zip(steps, tensions):
        cables = [(pts, float(t)) for pts, t in zip(cable_points(robot, traj.x[k]), tension)]
        frames.append(renderer.render(traj.x[k], cables=cables, com_trail=traj.com[:k + 1], gravity=env.gravity,
                                      ground=robot.ground,        # a benchmark task's field (None: the plane)
                                      title=f"{robot.name}, {res.task}: t = {k * env.timestep:.2f} s"))
    fps = 1.0 / (env.timestep * args.every)
    for path in outputs:
        with atomic_output(path) as tmp:
            write_animation(frames, tmp, fps)
        print(f"wrote {path} ({len(frames)} frames, {fps:.1f} frames/s)")
    return 0


def _series_files(directory: Path, stem: str) -> list[Path]:
    """The files of an earlier export of ``stem`` into ``directory``."""
    if not directory.is_dir():
        return []
    return sorted(p for p in directory.iterdir()
                  if p.name in (f"{stem}.pvd", f"{stem}_cables.pvd")
                  or (p.name.startswith(f"{stem}_") and p.suffix == ".vtu"
                      and p.stem[len(stem) + 1:].removeprefix("cables_").isdigit()))


def run_export(args) -> int:
    from ..results.export import export_vtu_series
    res = Result.load(args.result)
    stem = Path(args.result).stem
    out = args.vtu if args.vtu is not None else RESULTS_DIR / "paraview" / stem
    old = _series_files(out, stem)
    refuse_existing(old, args.overwrite, "an earlier export")
    env, u, traj = replay(res, args.cycles, ignore_robot_mismatch=args.ignore_robot_mismatch)
    for p in old:                                   # --overwrite: no stale steps of a longer export
        p.unlink(missing_ok=True)
    robot = env.robot
    pvd = export_vtu_series(out, robot.mesh.tets, robot.mesh.points, traj.x, env.timestep,
                            cell_data={"strain_energy_density": strain_energy_density(robot, traj.x)},
                            cables=cable_points(robot, traj.x), basename=stem)
    print(f"wrote {pvd} ({len(traj.x)} steps; open it in ParaView)")
    return 0


def _plot_motors(res: Result, env, path: Path, subject: str) -> Path:
    """The motors' torque-speed line and the steps of ``res.u`` (from rest, every row, the
    wrap-around of a looped cycle) at the load torques of its rollout (recorded when it was
    made, else simulated on ``env``)."""
    from .. import plots
    torque = recorded_torque(res)
    if torque is None:
        torque = MotorLaw.of_robot(env.robot).torque(env.rollout(res.u).cable_deformation)
    fig = motor_figures(res.robot_fingerprint)
    u = np.asarray(res.u, dtype=np.float64)
    speed = np.diff(np.vstack([env.robot.u_rest, u]), axis=0) / res.dt
    tb, ta = torque[:-1], torque[1:]
    n_prep, n_cycle = res.settings.get("n_prep"), res.settings.get("n_cycle")
    if n_prep is not None and n_cycle and len(u) < int(n_prep) + 2 * int(n_cycle):   # one cycle: its wrap-around too
        speed = np.vstack([speed, (u[int(n_prep)] - u[-1]) / res.dt])
        tb, ta = np.vstack([tb, torque[-1]]), np.vstack([ta, torque[-1]])
    return plots.plot_motor_line(speed, tb, ta, fig.v0, fig.stall_torque, fig.max_torque, res.motor_names, path,
                                 subject=subject)


def _turn_series(res: Result, env) -> tuple:
    """A turn replayed as it was evaluated: time [s], heading change [deg] at every step, speed
    along the COM path in every cycle [BL/min] (:func:`trajopt.evaluation.measure_gait`'s)."""
    from soft_envs.envs import BodyFrame, yaw_of

    from ..evaluation import DEFAULT_EVAL_CYCLES, mps_to_bl_per_min
    from ..replay import result_controls
    cycles = int(res.settings.get("eval_cycles", DEFAULT_EVAL_CYCLES))
    u, n_prep, n_cycle = result_controls(res, env.robot, cycles)
    traj = env.rollout(u)
    frame = BodyFrame(traj.x[0], env.robot.node_masses)
    head = np.degrees(np.unwrap([yaw_of(frame.rotation(x)) for x in traj.x]))
    marks = n_prep + n_cycle * np.arange((len(u) - n_prep) // n_cycle + 1)
    chords = np.linalg.norm(np.diff(traj.com[marks][:, [0, 2]], axis=0), axis=1)
    speeds = [mps_to_bl_per_min(c / (n_cycle * env.timestep), env.robot.body_length) for c in chords]
    return np.arange(len(head)) * env.timestep, head - head[0], speeds, n_prep * env.timestep


def _plot_turn(res: Result, env, path: Path, subject: str) -> Path:
    from .. import plots
    t, heading, speeds, prep_time = _turn_series(res, env)
    return plots.plot_turn(t, heading, speeds, path, prep_time=prep_time, subject=subject)


def run_plot(args) -> int:
    from .. import plots
    res = Result.load(args.result)
    out = Path(args.out)
    stem = Path(args.result).stem
    ext = args.format
    names = {k: out / f"{stem}_{k}.{ext}" for k in ("com", "controls", "convergence", "speed", "turn", "motors")}
    speeds = res.evaluation.get("speed_per_cycle_bl_per_min")
    turn = speed_along_path(res.task)          # a turn: heading and speed along its path, not +x speed
    wanted = (["com", "controls"] + (["convergence"] if res.history else [])
              + ((["turn"] if turn else ["speed"]) if speeds else [])
              + (["motors"] if motor_figures(res.robot_fingerprint) is not None else []))
    refuse_existing([names[k] for k in wanted], args.overwrite)
    env = env_for_result(res, ignore_robot_mismatch=args.ignore_robot_mismatch)
    x0, _ = env.reset_state()
    s = res.settings
    subject = f"{res.robot}, task {res.task}: {Path(args.result).name}"     # every title names what it shows
    draw = {
        "com": lambda p: plots.plot_com_topdown(res.com, res.target, p, body_outline=x0, prep_steps=s.get("n_prep"),
                                                subject=subject),
        "controls": lambda p: plots.plot_controls(res.u, res.dt, res.motor_names, p, n_prep=s.get("n_prep"),
                                                  n_cycle=s.get("n_cycle"), u_post=res.u_post,
                                                  mirror_map=env.robot.mirror_map, subject=subject),
        "convergence": lambda p: plots.plot_convergence(res.history, p, subject=subject),
        "speed": lambda p: plots.plot_speed_per_cycle(np.asarray(speeds), p, subject=subject,
                                                      target=s.get("speed_bl_per_min"),
                                                      reference={"tripod": 6.1, "puppy": 8.6}.get(res.robot)),
        "turn": lambda p: _plot_turn(res, env, p, subject),
        "motors": lambda p: _plot_motors(res, env, p, subject),
    }
    for key in wanted:
        with atomic_output(names[key]) as tmp:
            draw[key](tmp)
        print(f"wrote {names[key]}")
    return 0
