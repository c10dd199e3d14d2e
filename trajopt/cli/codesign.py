"""``trajopt codesign ROBOT --vary routing,stiffness,legs --out DIR``: the command line of
co-design; what it does is :func:`trajopt.codesign.run.run_codesign`."""
from __future__ import annotations

import sys
from pathlib import Path

from ..argtypes import contact_law, integer, output_dir

__all__ = ["add_codesign_parser", "vary_kinds", "ensemble_counts"]

#: the design kinds, in the order of their columns (soft_envs.envs.design.KINDS, without importing it)
_KINDS = ("stiffness", "routing", "legs")


def vary_kinds(text: str) -> tuple[str, ...]:
    """``--vary``: comma-separated design kinds (routing, stiffness, legs)."""
    import argparse
    kinds = tuple(dict.fromkeys(k.strip() for k in text.split(",") if k.strip()))
    bad = [k for k in kinds if k not in _KINDS]
    if not kinds or bad:
        raise argparse.ArgumentTypeError(f"{text!r}: give design kinds, comma-separated, from {', '.join(_KINDS)}")
    return tuple(k for k in _KINDS if k in kinds)


def ensemble_counts(text: str) -> tuple[int, ...]:
    """``--joint-ensemble``: comma-separated physics steps per control step (``2,8``), or ``off``."""
    import argparse
    if text.strip().lower() == "off":
        return ()
    try:
        counts = tuple(int(n) for n in text.split(","))
    except ValueError:
        counts = ()
    if not counts or any(n < 1 or n > 64 for n in counts):
        raise argparse.ArgumentTypeError(f"{text!r}: give physics steps per control step, comma-separated whole "
                                         "numbers from 1 to 64 (e.g. 2,8), or off")
    return counts


def add_codesign_parser(sub) -> None:
    p = sub.add_parser("codesign", help="optimise a robot's design and its gait together (writes a new robot folder)")
    p.add_argument("robot", help="shipped robot (tripod, puppy, hexapod, inchworm) or path to a robot.toml with a [design] table")
    p.add_argument("--vary", type=vary_kinds, default=_KINDS, metavar="KINDS",
                   help="what may change, comma-separated: routing (via points), stiffness (Young's modulus per "
                        "region), legs (leg lengths); as the robot's [design] table declares them (default: all)")
    p.add_argument("--out", type=output_dir, required=True,
                   help="output directory: the designed robot (robot.toml, mesh.vtu), its gait NAME_walk.npz, "
                        "codesign.md / .png / .json")
    p.add_argument("--contact", type=contact_law, default=None, metavar="LAW",
                   help="ground contact law, as for optimize (default: the robot file's)")
    p.add_argument("--baseline", type=Path, default=None,
                   help="the shipped design's fastest gait (a result of optimize --speed max on the same robot and "
                        "law); default: run that search first")
    p.add_argument("--motor-model", choices=("torque-speed", "speed"), default="torque-speed",
                   help="the motors' law every gait obeys, as for optimize: torque-speed (default: the torque-speed "
                        "line and the gearbox's torque limit) or speed (the speed limit alone)")
    p.add_argument("--stages", type=integer(1, 100), default=None, help="co-design stages (rising targets; default 4)")
    p.add_argument("--iterations", type=integer(1, 10_000), default=None,
                   help="Gauss-Newton iterations per stage at most (default 8)")
    p.add_argument("--joint-ensemble", type=ensemble_counts, default=None, metavar="N[,N...]|off",
                   help="the joint Gauss-Newton's ensemble: the default physics and these physics steps per control "
                        "step, their residuals stacked (default 2,8: 2x coarser and 2x finer; off: the default "
                        "physics alone; every stage is accepted by its credible speed either way)")
    p.add_argument("--screen-rank", choices=("slowest", "holds-first"), default=None,
                   help="how the screening ranks its candidates: slowest (default), by the slowest speed over the "
                        "hold replays (the credible speed); holds-first, a gait that holds within 5 %% first")
    p.add_argument("--screen", choices=("warm", "scratch"), default=None,
                   help="how the screening scores a candidate design: warm, its gait warm-started from the current "
                        "keyframes (default; the fastest pairs), or scratch, as --speed max finds a gait for it "
                        "on the same cycle (the design's own merit; slower to run)")
    p.add_argument("--rounds", type=integer(0, 100), default=None,
                   help="screening rounds at most (default 4; 0: no screening, joint Gauss-Newton only)")
    p.add_argument("--workers", type=integer(1, 1024), default=None,
                   help="processes scoring the screening's candidates (default: one per core); the result "
                        "is the same for any number")
    p.add_argument("--no-reoptimise", action="store_true",
                   help="skip re-optimising the gait of the written robot from scratch (--speed max)")
    p.add_argument("--quick", action="store_true", help="a tiny run (tests, CI; also SOFT_ENVS_QUICK=1)")
    p.add_argument("--resume", action="store_true", help="continue an interrupted run in --out")
    p.add_argument("--overwrite", action="store_true", help="replace a finished co-design in --out")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=_cmd_codesign)


def _cmd_codesign(args) -> int:
    import dataclasses

    from ..codesign.run import CodesignRun, run_codesign
    from ..sweep import quick_requested
    kw = dict(vary=args.vary, contact=args.contact, baseline=args.baseline, reoptimise=not args.no_reoptimise,
              resume=args.resume, overwrite=args.overwrite, quiet=args.quiet,
              workers=args.workers, motor_model=args.motor_model)          # workers None: one per core
    run = (CodesignRun.quick(args.robot, Path(args.out), **kw) if quick_requested(args.quick)
           else CodesignRun(args.robot, Path(args.out), **kw))
    joint = {k: v for k, v in (("stages", args.stages), ("iterations", args.iterations),
                               ("ensemble", args.joint_ensemble))
             if v is not None}
    if joint:
        run.joint = dataclasses.replace(run.joint, **joint)
    screen = {k: v for k, v in (("score", args.screen), ("rounds", args.rounds), ("rank", args.screen_rank))
              if v is not None}
    if screen:
        run.screen = dataclasses.replace(run.screen, **screen)
    from ..codesign.run import PARTIAL
    from ..codesign.screen import WorkerDied
    from ..hardware.signals import Terminated
    try:
        outcome = run_codesign(run)
    except WorkerDied as err:              # one line, the advice of the command line (no script here)
        print(f"trajopt: error: {err.command_line_text()}", file=sys.stderr)
        return 1
    except (KeyboardInterrupt, Terminated):   # Ctrl-C, SIGTERM, SIGHUP: the workers are ended; the way on
        partial = Path(args.out) / PARTIAL
        if partial.is_file():
            print(f"trajopt codesign: the run is checkpointed in {partial}: the same command with --resume "
                  "continues it", file=sys.stderr)
        raise
    s = outcome.summary
    if outcome.finished:
        print(f"{args.out} holds a finished co-design (--vary {','.join(args.vary)}); nothing to resume")
    from ..codesign.summary import describe_credible
    credible = describe_credible(s) if "credible_ratio" in s else (      # a co-design made before they were
        f"{s['before_bl_per_min']:.2f} -> {s['after_bl_per_min']:.2f} BL/min ({s['ratio']:.2f}x)")
    print(f"{outcome.robot_file}: {credible}; gait {outcome.result_file}; report {outcome.report_file}")
    return 0
