"""``trajopt play``: command-line hook for trajectory playback.

Hook into an argparse-based CLI::

    parser = argparse.ArgumentParser(prog="trajopt")
    sub = parser.add_subparsers(dest="command", required=True)
    add_play_parser(sub)                   # registers "play", sets func=run_play
    args = parser.parse_args()
    sys.exit(args.func(args))

Exit codes of :func:`run_play`:

* 0 -- played, every motor confirmed stopped;
* 1 -- hardware / communication / pre-flight / tracking error, every motor confirmed stopped
  (the CSV log is kept);
* 2 -- invalid input (result file, hardware TOML, trajectory limits): nothing was sent;
* 3 -- some motor was NOT confirmed stopped (whatever else happened): the message names it;
* 128 + the signal's number -- interrupted, every motor confirmed stopped: 130 Ctrl-C (SIGINT),
  143 SIGTERM, 129 SIGHUP, 131 Ctrl-\\ (SIGQUIT), 138 SIGUSR1 ... (every catchable signal whose
  default action ends the process; also when the signal came during the stop sequence, which
  it never cuts short).

Every way out -- the last step, an error, any exception, a signal, the port vanishing -- runs
the same stop sequence and prints the same report (``motors confirmed stopped: ...``).
SIGKILL (``kill -9``) cannot be caught: set the controllers' serial timeout as the failsafe
(docs/failure-modes.md).

Progress and pre-flight lines go to stderr, the summary to stdout; all are
plain lines (readable in a log file).  A stream that can no longer be written (a
closed terminal) is given up silently; the exit code still tells.
"""

from __future__ import annotations

import argparse
import sys
import time
import traceback
from pathlib import Path
from typing import Any

EXIT_OK, EXIT_HARDWARE, EXIT_INPUT, EXIT_NOT_STOPPED, EXIT_INTERRUPTED = 0, 1, 2, 3, 130
#: Exit code of a playback ended by signal ``signum`` with every motor confirmed stopped (shell convention).
EXIT_SIGNAL_BASE = 128


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def add_play_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register ``play RESULT --hardware HW.toml [--dry-run] [--verbose] [--loops N] [--log CSV]
    [--port-override PORT]``."""
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "play", help="play an optimised trajectory on the robot's RoboClaw motor controllers",
        description="Stream the optimised cable trajectory u_post of RESULT to the motors described in "
                    "the hardware TOML. The robot must rest at its assembly pose (u = 0): encoders are "
                    "zeroed before playing.",
        epilog="exit codes: 0 played, every motor confirmed stopped; 1 error, every motor confirmed stopped; "
               "2 bad input, nothing sent; 3 some motor NOT confirmed stopped (cut its power); "
               "128+N ended by signal N (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP, 131 SIGQUIT ...), every motor "
               "confirmed stopped")
    parser.add_argument("result", metavar="RESULT", help="trajectory-optimisation result (trajopt.results.Result)")
    parser.add_argument("--hardware", required=True, metavar="HW.toml", help="hardware description (TOML)")
    parser.add_argument("--dry-run", action="store_true", help="check and describe the plan, open no port")
    parser.add_argument("--verbose", action="store_true",
                        help="dry run: list every packet (hex); playback: a progress line per step")
    parser.add_argument("--loops", type=_positive_int, default=1, metavar="N",
                        help="play N times (default 1); an optimised gait plays its prep phase once and its "
                             "cycles N times")
    parser.add_argument("--log", metavar="CSV", default=None,
                        help="CSV log of commanded vs measured counts (default: play_<RESULT>_<time>.csv)")
    parser.add_argument("--port-override", metavar="PORT", default=None,
                        help="use PORT (device or pyserial URL) for every motor")
    parser.add_argument("--ignore-robot-mismatch", action="store_true",
                        help="play a result made for another robot than the hardware file's, or for an "
                             "edited robot.toml")
    parser.add_argument("--force", action="store_true",
                        help="play a gait whose predicted load torque exceeds a motor's robot.toml max_torque "
                             "(its gearbox's limit; refused otherwise)")
    parser.set_defaults(func=run_play)
    return parser


def _say(text: str) -> None:
    """One line on stderr; a closed terminal (SIGHUP) is no reason to fail."""
    try:
        print(f"trajopt play: {text}", file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


def _report_stop(exc: BaseException, code: int) -> int:
    """Print what the stop sequence confirmed; the exit code is EXIT_NOT_STOPPED if it did not confirm all."""
    report = getattr(exc, "stop_report", None)
    if report is not None:
        _say(str(report))
        if not report.all_confirmed:
            return EXIT_NOT_STOPPED
    return code


def _loop_start(res: Any) -> int:
    """Where ``--loops`` starts repeating: an optimised gait's cycles, after its prep phase
    (``settings["n_prep"]``, when the rest of ``u_post`` is whole cycles of ``n_cycle``); 0
    (the whole trajectory) for anything else."""
    s = getattr(res, "settings", None) or {}
    try:
        n_prep, n_cycle, k = int(s["n_prep"]), int(s["n_cycle"]), len(res.u_post)
    except (KeyError, TypeError, ValueError):
        return 0
    return n_prep if 0 < n_prep < k and n_cycle > 0 and (k - n_prep) % n_cycle == 0 else 0


def _as_streamed(res: Any, loops: int, loop_start: int) -> Any:
    """``res`` with ``u_post`` as streamed as far as every step shows (the loop's wrap-around
    from the last sample back to ``loop_start`` included), for the motor-limit note."""
    import types

    import numpy as np
    u = np.asarray(res.u_post)
    looped = np.vstack([u, u[loop_start:]]) if loops > 1 else u
    return types.SimpleNamespace(u_post=looped, dt=res.dt, motor_names=res.motor_names,
                                 robot_fingerprint=getattr(res, "robot_fingerprint", None))


def _check_motor_load(res: Any, args: argparse.Namespace) -> str | None:
    """Print each motor's predicted peak torque and its margin to the torque-speed line
    (:mod:`trajopt.results.motor_load`: recorded when the result was made, else simulated when
    ``soft_envs`` is installed); the reason to refuse a gait beyond a motor's ``max_torque``
    (None: play it; ``--force`` plays it anyway)."""
    from trajopt.results.motor_load import load_report, recorded_torque, simulated_torque
    torque = recorded_torque(res)
    if torque is None:
        try:
            torque = simulated_torque(res)
        except Exception as exc:  # noqa: BLE001 - a prediction only: say why there is none
            _say(f"the motors' load is not checked: {args.result} records none and it cannot be simulated here "
                 f"({type(exc).__name__}: {exc})")
            return None
    report = load_report(res, torque, args.loops)
    if report is None:
        return None
    _say(report.describe())
    if report.over_line.any():
        names = [n for n, o in zip(report.names, report.over_line) if o]
        _say(f"warning: {', '.join(names)} beyond the torque-speed line: the motor cannot wind that fast under "
             "that load and falls behind the trajectory")
    if report.over_max_torque.any() and not getattr(args, "force", False):
        over = [f"{n} {p:.3f} N m > {m:g}" for n, p, m, o in zip(report.names, report.peak_torque,
                                                               report.figures.max_torque, report.over_max_torque) if o]
        return (f"the gait loads motor(s) beyond their gearbox's max_torque ({'; '.join(over)}): "
                "re-optimise it under --motor-model torque-speed, or pass --force to play it anyway")
    return None


def run_play(args: argparse.Namespace) -> int:
    """Handler of ``trajopt play``; returns the process exit code (messages go to stderr)."""
    from ..hardware.config import load_hardware_config
    from ..hardware.errors import PlaybackError, RoboClawError
    from ..hardware.playback import play_trajectory
    from ..hardware.signals import Terminated, signal_of

    try:
        from trajopt.results import Result  # numpy-only modules, imported lazily on purpose

        res = Result.load(args.result)
        config = load_hardware_config(args.hardware)
    except (ValueError, OSError, ImportError) as exc:
        print(f"trajopt play: cannot load inputs: {type(exc).__name__}: {exc}", file=sys.stderr)
        return EXIT_INPUT
    try:
        from trajopt.results.robot_match import check_for_play
        for note in check_for_play(res, config.robot, config.path, src=str(args.result),
                                   ignore=getattr(args, "ignore_robot_mismatch", False)):
            print(f"trajopt play: warning: {note}", file=sys.stderr)
    except ValueError as exc:
        print(f"trajopt play: refused: {exc}", file=sys.stderr)
        return EXIT_INPUT
    from trajopt.optim.motor_limit import playback_note
    loop_start = _loop_start(res)
    note = playback_note(_as_streamed(res, args.loops, loop_start))    # the motor limit (robot.toml max_speed_rpm)
    if note:
        print(f"trajopt play: {note}", file=sys.stderr)
    refusal = _check_motor_load(res, args)
    if refusal:
        print(f"trajopt play: refused: {refusal}", file=sys.stderr)
        return EXIT_INPUT
    log_path = args.log
    if log_path is None and not args.dry_run:
        log_path = f"play_{Path(args.result).stem}_{time.strftime('%Y%m%d-%H%M%S')}.csv"
    kept = f"log kept at {log_path}"
    try:
        summary = play_trajectory(res.u_post, float(res.dt), list(res.motor_names), config, loops=args.loops,
                                  loop_start=loop_start, log_path=log_path, dry_run=args.dry_run, port_override=args.port_override,
                                  verbose=getattr(args, "verbose", False), progress=sys.stderr)
    except (KeyboardInterrupt, Terminated) as exc:
        _say("interrupted" if isinstance(exc, KeyboardInterrupt) else f"{exc}")
        if exc.__context__ is not None and signal_of(exc.__context__) is None:
            _say(f"(the signal came while stopping after {type(exc.__context__).__name__}: {exc.__context__})")
        code = _report_stop(exc, EXIT_SIGNAL_BASE + (signal_of(exc) or 0))
        if log_path is not None and Path(log_path).exists():
            _say(kept)
        return code
    except (RoboClawError, PlaybackError, OSError, ImportError) as exc:
        _say(f"hardware error: {type(exc).__name__}: {exc}")
        code = _report_stop(exc, EXIT_HARDWARE)
        if log_path is not None and Path(log_path).exists():
            _say(kept)
        return code
    except ValueError as exc:
        if getattr(exc, "stop_report", None) is None:  # refused before any port was opened
            _say(f"refused: {type(exc).__name__}: {exc}")
            return EXIT_INPUT
        _say(f"error: {type(exc).__name__}: {exc}")
        return _report_stop(exc, EXIT_HARDWARE)
    except Exception as exc:  # noqa: BLE001 - a bug: the motors were stopped all the same; say so, keep the code
        _say(f"unexpected error (please report it): {type(exc).__name__}: {exc}")
        try:
            traceback.print_exception(exc, file=sys.stderr)
        except (OSError, ValueError):
            pass
        return _report_stop(exc, EXIT_HARDWARE)
    print(summary)
    if summary.stop is not None and not summary.stop.all_confirmed:
        _say(str(summary.stop))
        return EXIT_NOT_STOPPED
    return EXIT_OK
