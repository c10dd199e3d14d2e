"""Play a cable trajectory on an *emulated* Tripod -- no hardware needed.

This is the last step of the pipeline (optimise -> ``u_post`` -> motors) run
against ``RoboClawEmulator``, a stand-in for the RoboClaw motor controller
that speaks the same packet-serial protocol on a pseudo-terminal.  With a real
robot you would skip the emulator and keep the port from the TOML file
(e.g. ``/dev/ttyACM0``), or use the CLI::

    trajopt play result.npz --hardware trajopt/hardware/example_tripod.toml

The second run shows a fault: the 'front' cable is snagged (the emulated
motor cannot move), so its tracking error grows; playback aborts, stops every
motor, and says which stops it confirmed by reading the encoders back.

Run:  python examples/play_on_emulator.py      (plays for ~3 s)

SOFT_ENVS_QUICK=1 (the project's convention for CI) shrinks the work to a smoke test.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import numpy as np

try:
    import trajopt  # noqa: F401
except ImportError:  # running from a source checkout without `pip install -e .`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from trajopt.hardware import EXAMPLE_TRIPOD, RoboClawEmulator, TrackingError, load_hardware_config, play_trajectory


def main() -> None:
    # 1. Hardware description: which motor is wired to which controller/channel,
    #    spool radius, encoder resolution and speed/acceleration limits.
    config = load_hardware_config(EXAMPLE_TRIPOD)
    print(f"robot {config.robot!r}: motors {list(config.motors)}")

    # 2. A trajectory as trajopt would produce it: contracted cable lengths u [m]
    #    (positive = cable pulled in) per motor on a grid of step dt.  Here: two
    #    gait cycles of a smooth sinusoidal contraction, 'back' motor half a cycle late.
    dt, n_steps = 0.033, 60
    phase = 2 * np.pi * 2 * np.arange(n_steps) / n_steps
    u_post = 0.004 * np.stack([1 - np.cos(phase), 1 - np.cos(phase - np.pi)], axis=1) / 2
    u_post[:, 1] *= np.minimum(1.0, np.arange(n_steps) / 10)  # ease the 'back' motor in from rest
    if os.environ.get("SOFT_ENVS_QUICK") == "1":               # CI smoke test: one cycle only
        u_post = u_post[:n_steps // 2]

    # 3. Start an emulated controller (address 0x80) and play on its pty.  The
    #    playback checks the limits, runs the pre-flight checks (firmware, battery,
    #    encoder reset -- the robot is assumed to be at its assembly pose, u = 0),
    #    streams one position command per motor per step, reads the encoders back
    #    and logs commanded vs measured counts, then stops the motors.
    log_dir = Path(tempfile.mkdtemp(prefix="play_on_emulator_"))   # playback never overwrites a log
    log_path = log_dir / "play.csv"
    with RoboClawEmulator(addresses=(0x80,)) as emulator:
        summary = play_trajectory(u_post, dt, ["front", "back"], config,
                                  port_override=emulator.port, log_path=log_path)

    # 4. What happened: steps sent, worst tracking error (includes ~1 step of lag),
    #    how far the schedule drifted (in steps), where the CSV log is, and which
    #    motors were confirmed stopped (duty 0 acknowledged, encoder read back at rest).
    print(summary)

    # 5. A fault: the 'front' cable snags.  When a motor stays further than
    #    settings.max_tracking_error (beyond the lag its speed/accel limits explain)
    #    for settings.max_tracking_error_time, playback aborts and stops every motor.
    with RoboClawEmulator(addresses=(0x80,)) as emulator:
        emulator.jam(1)  # channel M1 = 'front'
        try:
            play_trajectory(u_post, dt, ["front", "back"], config, port_override=emulator.port,
                            log_path=log_dir / "play_jammed.csv")
        except TrackingError as exc:
            print(f"aborted: {exc}")
            print(exc.stop_report)  # type: ignore[attr-defined]


if __name__ == "__main__":
    main()
