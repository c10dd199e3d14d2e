"""trajopt: optimise, evaluate, render, export and play gaits of cable-driven soft robots.

    trajopt optimize tripod --task walk                    # results/tripod_walk.npz (+ .json)
    trajopt optimize puppy --task turn --warm-start results/puppy_walk.npz
    trajopt optimize puppy --task incline --angle 10
    trajopt evaluate results/tripod_walk.npz [--cycles 10]
    trajopt render results/tripod_walk.npz                 # results/tripod_walk.gif [--mp4 PATH]
    trajopt export results/tripod_walk.npz                 # results/paraview/tripod_walk/
    trajopt plot results/tripod_walk.npz                   # results/plots/
    trajopt play results/tripod_walk.npz --hardware hw.toml [--dry-run]
    trajopt rl train tripod --algo ppo --timesteps 20000   # results/runs/tripod_ppo_seed0/
    trajopt mesh examples/data/quadruped.obj --scale 0.001 --up +z --out results/my_robot
    trajopt check results/my_robot/robot.toml
    trajopt sweep examples/sweep_speeds.toml --out results/sweeps/speeds [--workers N] [--address auto]
    trajopt calibrate tripod --markers examples/data/tripod_tracks.csv --controls examples/data/tripod_gait.npz --marker-points examples/data/tripod_markers.csv --fit youngs_modulus --contact paper --out results/calib
    trajopt robustness results/tripod_walk.npz --samples 64 --cycles 4 --out results/robustness [--overwrite]
    trajopt codesign tripod --vary routing,stiffness,legs --out results/tripod_codesign   # robot + gait + report

The package holds the command line only (parsing, printing, exit codes): each command calls
library functions (optimize_run, evaluation, replay, robustness_report, sweep, rl, hardware).
Everything the commands write goes under results/ by default (RESULTS_DIR). A file that exists
is never replaced without --overwrite; a result is only used with the robot it was made for
(--ignore-robot-mismatch overrides). Bad arguments end in one line naming them, exit code 2.
"""
from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

from ..argtypes import (contact_law, cycles, difficulty_level, file_name, frame_size, integer, number, output_dir,
                       output_file, positive_float, positive_int, slope_deg, speed, steps)
from ..results.files import RESULTS_DIR
from ..optim.gait import DEFAULT_EVAL_CYCLES, INTERPOLATIONS, GaitSpec
from ..optim.motor_limit import MOTOR_MODELS, TORQUE_SPEED
from ..tasks.registry import TURN_KEYFRAMES, command_line_tasks

__all__ = ["main", "build_parser", "RESULTS_DIR"]

_IGNORE_HELP = "use a result with a robot other than the one it was made for (another or an edited robot.toml)"
_OVERWRITE_HELP = "replace existing output files"


def _add_optimize(sub) -> None:
    p = sub.add_parser("optimize", help="optimise a gait (paper III) and save a result")
    p.add_argument("robot", help="shipped robot (tripod, puppy, hexapod, inchworm) or path to a robot.toml")
    p.add_argument("--task", choices=command_line_tasks(), default="walk",
                   help="what the gait does (trajopt.tasks): walk straight, turn a quarter circle, incline: walk "
                        "up the --angle slope; the benchmark's tasks (docs/tasks.md) slope_up, slope_down, "
                        "rough_terrain, climb_step, cross_trench: the walk on their slope or ground at --difficulty; "
                        "carry, push_box: the walk with the task's box (a payload on top, a box ahead) at "
                        "--difficulty; reach_goal: the walk along --heading")
    p.add_argument("--speed", type=speed, default=None,
                   help="target speed [body lengths/min], or max: the fastest walk within the motors' limits "
                        "whose speed holds within 5 %% at half, twice and four times the physics steps (searches "
                        "the cycle length and keyframes; writes NAME.search.csv/.md beside the result; "
                        "--cycle-steps pins the cycle)")
    p.add_argument("--heading", type=number(), default=0.0, help="walking direction [deg from +x to +z]")
    p.add_argument("--turn", choices=["right", "left"], default="right", help="turn direction (task turn)")
    p.add_argument("--angle", type=slope_deg, default=20.0, help="slope [deg] (task incline)")
    p.add_argument("--difficulty", type=difficulty_level, default=None, metavar="LEVEL",
                   help="a benchmark task's level, which sets its slope or ground: easy, medium (default) or hard")
    p.add_argument("--contact", type=contact_law, default=None, metavar="LAW",
                   help="ground contact law: coulomb (friction bounded by mu N, feet that stick) or paper "
                        "(II-C, viscous-like friction, Table I); default: the robot file's (the shipped "
                        "robots': coulomb), coulomb for the turn (it pivots on a foot that sticks); any law "
                        "registered in soft_envs.sim.contact.CONTACT_LAWS")
    p.add_argument("--substeps", type=positive_int, default=None, metavar="N",
                   help="physics steps per 0.033 s control step (default: the contact law's, 4 for coulomb, "
                        "1 for paper, where the gaits' speeds converge: docs/fidelity.md)")
    p.add_argument("--ensemble", type=positive_int, nargs="*", default=None, metavar="N",
                   help="optimise on other physics as well, N physics steps per control step each (alone: 2 and 8, "
                        "2x coarser and finer than the default), and rank --speed max's gaits by the slowest "
                        "member's speed, the credible one (docs/fidelity.md)")
    sym = p.add_mutually_exclusive_group()
    sym.add_argument("--symmetry", dest="symmetry", action="store_true", default=None,
                     help="bilateral symmetry on (default for walk and incline)")
    sym.add_argument("--no-symmetry", dest="symmetry", action="store_false", help="symmetry off (default for turn)")
    p.add_argument("--warm-start", type=Path, default=None,
                   help="start from this result's keyframes (moved into the motors' limits when outside them)")
    motors = p.add_mutually_exclusive_group()
    motors.add_argument("--motor-model", choices=MOTOR_MODELS, default=TORQUE_SPEED,
                        help="the motors' law every step of the controls obeys: torque-speed (default: a DC "
                             "gearmotor's speed falls linearly with the load torque of its cables' tensions, from "
                             "robot.toml max_speed_rpm at no load to 0 at stall_torque, and the torque stays below "
                             "max_torque), speed (the speed limit max_speed_rpm alone: the results of before the "
                             "line), ideal (no limit: the results of before the limit)")
    motors.add_argument("--no-motor-limit", action="store_true",
                        help="the same as --motor-model ideal (kept for scripts of before --motor-model)")
    p.add_argument("--iterations", type=integer(0, 100_000), default=10,
                   help="Gauss-Newton iterations at most (0: evaluate the starting gait)")
    paper = GaitSpec()
    p.add_argument("--keyframes", type=steps, default=None,
                   help=f"spline keyframes per cycle (default {paper.n_keyframes}, the paper's; turn {TURN_KEYFRAMES})")
    p.add_argument("--interpolation", choices=INTERPOLATIONS, default=None,
                   help="how a cycle passes through its keyframes: hermite, the paper's zero-tangent spline (its "
                        "slope peaks at 1.5x its mean, so under the motor limit a cable averages 2/3 of the motor's "
                        "speed), or linear, straight lines (the full speed); default: the task's (hermite; "
                        "the turn and --speed max: linear)")
    p.add_argument("--cycle-steps", type=steps, default=None,
                   help=f"simulation steps per gait cycle (default {paper.n_cycle}, the paper's; with --speed max: "
                        "searched unless given)")
    p.add_argument("--prep-steps", type=integer(0, 100_000), default=paper.n_prep,
                   help=f"simulation steps of the preparatory phase (default {paper.n_prep}, the paper's)")
    p.add_argument("--seeds", type=integer(0, 10_000), default=8,
                   help="random starting patterns tried (no warm start)")
    p.add_argument("--cycles", type=cycles, default=DEFAULT_EVAL_CYCLES, help="cycles played for the evaluation")
    p.add_argument("--max-sim-steps", type=positive_int, default=None,
                   help="--speed max: simulation steps the search may spend at most (default: no budget)")
    p.add_argument("--out", type=output_dir, default=RESULTS_DIR, help=f"output directory (default {RESULTS_DIR}/)")
    p.add_argument("--name", type=file_name, default=None,
                   help="result file name (default ROBOT_TASK; ROBOT a robot file's [robot] name)")
    p.add_argument("--resume", action="store_true",
                   help="continue the interrupted run of this name (from its NAME.partial.npz checkpoint)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace a finished result (or an interrupted run's checkpoint) of this name "
                        "when the new run finishes")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=_lazy("commands", "run_optimize"))


def _add_result_commands(sub) -> None:
    p = sub.add_parser("evaluate", help="re-simulate a result and report its speed")
    p.add_argument("result", type=Path)
    p.add_argument("--cycles", type=cycles, default=None, help="cycles to play (default: as optimised)")
    p.add_argument("--ignore-robot-mismatch", action="store_true", help=_IGNORE_HELP)
    p.add_argument("--json", action="store_true", help="print the evaluation as one JSON object (for scripts)")
    p.add_argument("--fidelity", action="store_true",
                   help="also replay it with 2x, 4x and 8x finer physics steps and print each speed and the "
                        "spread (how much the speed is the robot's and not the time step's: docs/fidelity.md)")
    p.set_defaults(func=_lazy("commands", "run_evaluate"))
    n_cycles = GaitSpec().n_cycles
    p = sub.add_parser("render", help="animate a result (GIF through Pillow, MP4 with imageio-ffmpeg)",
                       description="Replay a result and draw it: grey cables are slack, coloured ones "
                                   "taut (plasma colour map: tension), the red line is the centre of mass's path.")
    p.add_argument("result", type=Path)
    p.add_argument("--gif", type=output_file, default=None,
                   help=f"animated GIF to write (default {RESULTS_DIR}/RESULT_NAME.gif when --mp4 is not given)")
    p.add_argument("--mp4", type=output_file, default=None,
                   help="MP4 video to write (needs the video extra: pip install 'soft-envs[video]')")
    p.add_argument("--cycles", type=cycles, default=n_cycles,
                   help=f"gait cycles played after the prep phase (default {n_cycles}; RL results play "
                        "their own controls)")
    p.add_argument("--every", type=positive_int, default=2, help="render every n-th simulation step")
    p.add_argument("--size", type=frame_size, default=(480, 360), help="frame size WIDTHxHEIGHT (default 480x360)")
    p.add_argument("--overwrite", action="store_true", help=_OVERWRITE_HELP)
    p.add_argument("--ignore-robot-mismatch", action="store_true", help=_IGNORE_HELP)
    p.set_defaults(func=_lazy("output_commands", "run_render"))
    p = sub.add_parser("export", help="ParaView time series (.vtu per step + .pvd)")
    p.add_argument("result", type=Path)
    p.add_argument("--vtu", type=output_dir, default=None,
                   help=f"output directory (default {RESULTS_DIR}/paraview/RESULT_NAME/)")
    p.add_argument("--cycles", type=cycles, default=n_cycles,
                   help=f"gait cycles played after the prep phase (default {n_cycles}; RL results play "
                        "their own controls)")
    p.add_argument("--overwrite", action="store_true", help=_OVERWRITE_HELP)
    p.add_argument("--ignore-robot-mismatch", action="store_true", help=_IGNORE_HELP)
    p.set_defaults(func=_lazy("output_commands", "run_export"))
    p = sub.add_parser("plot", help="COM path, controls, convergence, speed (a turn: heading and path speed) "
                                    "and motor plots")
    p.add_argument("result", type=Path)
    p.add_argument("--out", type=output_dir, default=RESULTS_DIR / "plots",
                   help=f"output directory (default {RESULTS_DIR}/plots/)")
    p.add_argument("--format", choices=["png", "svg"], default="png")
    p.add_argument("--overwrite", action="store_true", help=_OVERWRITE_HELP)
    p.add_argument("--ignore-robot-mismatch", action="store_true", help=_IGNORE_HELP)
    p.set_defaults(func=_lazy("output_commands", "run_plot"))


def _add_robot_commands(sub) -> None:
    p = sub.add_parser("mesh", help="tet-mesh a closed surface (STL/OBJ/PLY...) and write a robot.toml skeleton")
    p.add_argument("surface", type=Path, help="closed surface, any format meshio reads")
    p.add_argument("--out", type=output_dir, required=True, help="output directory (<name>.vtu, robot.toml)")
    p.add_argument("--name", default=None, help="robot name (default: the surface file's stem)")
    p.add_argument("--scale", type=positive_float, default=1.0, help="surface units -> metres (0.001 for mm)")
    axes = ["+x", "-x", "+y", "-y", "+z", "-z"]
    p.add_argument("--forward", default="+x", choices=axes, metavar="AXIS",
                   help="surface axis pointing forward: +x -x +y -y +z -z (negative: --forward=-y)")
    p.add_argument("--up", default="+y", choices=axes, metavar="AXIS",
                   help="surface axis pointing up (default +y; Z-up CAD: --up +z)")
    p.add_argument("--edge-length", type=positive_float, default=None,
                   help="target tet edge length [m, after --scale] (default: body length / 6)")
    p.add_argument("--keep-surface", action="store_true", help="keep the surface triangles (no re-meshing)")
    p.add_argument("--max-elements", type=positive_int, default=None,
                   help="refuse an --edge-length whose estimated tet count (6 sqrt(2) volume / edge^3) is above "
                        "this, before meshing (default 200000, soft_envs.meshing.MAX_ELEMENTS)")
    p.add_argument("--tendons", choices=["example", "legs"], default="example",
                   help="one example tendon pair, or a pair on the front and back of every leg")
    p.add_argument("--density", type=positive_float, default=None, help="[kg/m^3] (default 220)")
    p.add_argument("--youngs-modulus", type=positive_float, default=None, help="[Pa] (default 1e5)")
    p.add_argument("--payload-mass", type=number(0.0), default=None, help="[kg] (default 1.5 x body mass)")
    p.add_argument("--force", action="store_true", help="replace an existing robot.toml")
    p.set_defaults(func=_lazy("robot_commands", "run_mesh"))
    p = sub.add_parser("check", help="validate a robot, print its summary and draw it")
    p.add_argument("robot", help="shipped robot (tripod, puppy, hexapod, inchworm) or path to a robot.toml")
    p.add_argument("--picture", type=output_file, default=None,
                   help="PNG to write (default: <robot name>.png beside the robot.toml, or here)")
    p.add_argument("--no-picture", action="store_true", help="do not draw")
    p.set_defaults(func=_lazy("robot_commands", "run_check"))
def _add_sweep(sub) -> None:
    from .sweep import add_sweep_parser     # imports Ray only when a sweep runs
    add_sweep_parser(sub)


class _Parser(argparse.ArgumentParser):
    """argparse, with a bad argument reported in one line (and where to find the usage)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (usage: {self.prog} --help)\n")


def _add_identification_commands(sub) -> None:
    p = sub.add_parser("calibrate", help="fit physical parameters to tracked markers (writes a new robot.toml)")
    p.add_argument("robot", help="shipped robot (tripod, puppy, hexapod, inchworm) or path to a robot.toml")
    p.add_argument("--markers", type=Path, required=True, help="tracks CSV: t,marker,x,y,z [s, m]")
    p.add_argument("--controls", type=Path, required=True, help="the result whose controls were played")
    p.add_argument("--fit", required=True, help="comma-separated parameters, e.g. youngs_modulus,poisson_ratio,friction")
    p.add_argument("--out", type=output_dir, required=True, help="output directory (robot.toml, calibration.json, tracks.png)")
    p.add_argument("--marker-points", type=Path, default=None,
                   help="CSV marker,x,y,z of rest positions [m, robot frame] (default: the robot's [[markers]])")
    p.add_argument("--frame", choices=["robot", "camera"], default="robot",
                   help="frame of the tracks; camera: a rigid transform is fitted too")
    p.add_argument("--play", choices=["u_post", "u"], default="u_post",
                   help="which controls of the result were played (u_post: what trajopt play streams)")
    p.add_argument("--max-evaluations", type=int, default=30, help="rollouts per fitting stage at most")
    p.add_argument("--noise", type=positive_float, default=1e-3,
                   help="the tracker's noise [m, standard deviation per coordinate]; a fit whose RMS marker error is "
                        "above 3x what it explains is refused (docs/calibration.md)")
    p.add_argument("--force", action="store_true",
                   help="write the robot even when a check of the tracks or the fit fails (printed as warnings)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace a calibration in --out (robot.toml, calibration.json, tracks.png)")
    p.add_argument("--contact", type=contact_law, default=None, metavar="LAW",
                   help="ground contact law of the fit: coulomb or paper (default: the robot file's; the "
                        "shipped examples/data tracks were made under the paper's law); written to the new robot.toml")
    p.set_defaults(func=_lazy("calibrate_command", "run_calibrate"))
    p = sub.add_parser("robustness", help="replay a gait under perturbed physics and report its speed spread")
    p.add_argument("result", type=Path)
    p.add_argument("--samples", type=int, default=32, help="perturbed replays")
    p.add_argument("--cycles", type=int, default=4, help="gait cycles per replay")
    p.add_argument("--out", type=output_dir, required=True, help="output directory (report.json, samples.csv, robustness.png)")
    p.add_argument("--seed", type=int, default=0, help="seed of the perturbations")
    p.add_argument("--workers", type=int, default=1, help="parallel workers (Ray, when installed with trajopt sweep)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace a robustness run with other settings in --out (its samples are discarded)")
    p.set_defaults(func=_lazy("robustness_command", "run_robustness"))


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="trajopt", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    _add_optimize(sub)
    _add_result_commands(sub)
    _add_robot_commands(sub)
    _add_identification_commands(sub)
    try:
        from .play import add_play_parser
        add_play_parser(sub)
    except ImportError:   # pragma: no cover
        pass
    try:
        from .rl import add_rl_parser
        add_rl_parser(sub)
    except ImportError:
        pass
    _add_sweep(sub)
    from .codesign import add_codesign_parser
    add_codesign_parser(sub)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"trajopt: warning: {message}", file=sys.stderr)


def _is_simulation_error(exc: BaseException) -> bool:
    if "soft_envs" not in sys.modules:
        return False
    from soft_envs.envs import SimulationError
    return isinstance(exc, SimulationError)


def _stdout_gone() -> int:
    """The reader of stdout went away (``trajopt evaluate R | head -1``): end quietly, as a
    command-line tool ended by SIGPIPE does (exit 141), and keep Python's exit-time flush of
    stdout from complaining."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):
        pass
    return 128 + int(getattr(signal, "SIGPIPE", 13))


def main(argv: list[str] | None = None) -> int:
    """Run a command; exit codes: 0 done, 1 a fault (a failed simulation, an I/O error, a gait
    that fell), 2 a bad input (one line naming the argument, file or field), 130 Ctrl-C,
    143 SIGTERM and 129 SIGHUP (ended as Ctrl-C ends them: checkpoints saved, workers and locks
    released), 141 stdout closed by its reader (quietly)."""
    from ..hardware.signals import COMMAND_SIGNALS, StopSignals, Terminated
    args = build_parser().parse_args(argv)       # bad arguments: usage + one line, exit 2
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning     # warnings as one plain line each
        try:
            with StopSignals(signals=COMMAND_SIGNALS):   # SIGTERM, SIGHUP: raised as Terminated
                code = int(args.func(args) or 0)
                sys.stdout.flush()               # a closed pipe shows here, not at exit
            return code
        except BrokenPipeError:
            return _stdout_gone()
        except ValueError as exc:                # bad input: files, fields, values
            print(f"trajopt: error: {exc}", file=sys.stderr)
            return 2
        except OSError as exc:                   # I/O fault while working (disk full, device gone)
            print(f"trajopt: error: {exc}", file=sys.stderr)
            return 1
        except KeyboardInterrupt:
            print("trajopt: interrupted (no output file is left half-written)", file=sys.stderr)
            return 130
        except Terminated as exc:
            print(f"trajopt: {exc} (no output file is left half-written)", file=sys.stderr)
            return 128 + exc.signum
        except RuntimeError as exc:
            if not _is_simulation_error(exc):
                raise
            print(f"trajopt: error: simulation failed: {exc}", file=sys.stderr)
            return 1


# ---------------------------------------------------------------------- commands
if TYPE_CHECKING:       # the command modules, each imported only when its command runs (_lazy)
    from . import calibrate_command, commands, output_commands, robot_commands, robustness_command  # noqa: F401


def _lazy(module: str, function: str):
    """The command ``function`` of ``trajopt.cli.<module>``, imported only when it runs (building
    the parser, and ``--help``, import none of the commands' work)."""
    def run(args) -> int:
        return getattr(importlib.import_module(f"{__name__}.{module}"), function)(args)
    run.__name__ = run.__qualname__ = function
    return run
