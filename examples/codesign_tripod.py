"""Co-design the Tripod: where its tendons run, how stiff each part is and how long each leg is,
optimised together with its gait through the same exact sensitivities.

Run:  python examples/codesign_tripod.py      (about ten minutes on two cores)

`trajopt codesign` first finds the shipped Tripod's fastest gait within the motors' speed limit
(`trajopt optimize tripod --speed max`), then runs Gauss-Newton on that gait's keyframes and the
design parameters the robot file's `[design]` table declares (assets/tripod/robot.toml: the via
points of the tendons, Young's modulus of the three legs and the body, the three legs' lengths),
with the motors' limit, the design's bounds, 2 mm of clearance around every via point and at
least 98 % of the shipped mass as constraints. It writes a robot folder that every command loads
unchanged, the gait made on it, and a report with the shipped and the designed robot side by
side. The written robot's gait is then optimised again from scratch with --speed max, so that the
gain is the design's, not a lucky gait's.

From the shell: `trajopt codesign tripod --vary routing,stiffness,legs --out results/tripod_codesign`
(`--resume` continues an interrupted run; `--contact paper` for the paper's law).

SOFT_ENVS_QUICK=1 (the project's convention for CI) runs a tiny search and one short stage into
results/tripod_codesign_example_quick/ instead of results/tripod_codesign_example/.
"""
import os
from pathlib import Path

from trajopt.codesign.run import CodesignRun, run_codesign


def main() -> None:
    quick = os.environ.get("SOFT_ENVS_QUICK") == "1"
    out = Path("results/tripod_codesign_example_quick" if quick else "results/tripod_codesign_example")
    # workers=None: the screening scores its candidate designs in one process per core (the result
    # is the same as workers=1); spawn imports this script in each, hence the __main__ guard below
    run = (CodesignRun.quick("tripod", out, contact="coulomb", overwrite=True, quiet=True, workers=None) if quick
           else CodesignRun("tripod", out, contact="coulomb", overwrite=True, workers=None))
    outcome = run_codesign(run)
    s = outcome.summary
    def credible(gait: str) -> str:      # the slowest over 16.5-2.06 ms physics steps, and whether it holds
        return (f"slowest {s[gait + '_slowest_bl_per_min']:.2f}, spread {100 * s[gait + '_spread']:.1f} % "
                f"({'holds' if s[gait + '_holds'] else 'does not hold'})")

    print(f"shipped design, fastest gait: {s['before_bl_per_min']:.2f} BL/min ({s['n_cycle']}-step cycle), "
          f"{credible('before')}")
    print(f"co-designed robot and gait:   {s['after_bl_per_min']:.2f} BL/min, {credible('after')}: "
          f"{s['credible_ratio']:.2f}x at the slowest step; {s['iterations']} Gauss-Newton iterations")
    if "reoptimised_bl_per_min" in s:
        print(f"its gait re-optimised from scratch: {s['reoptimised_bl_per_min']:.2f} BL/min, "
              f"{credible('reoptimised')}: {s['reoptimised_credible_ratio']:.2f}x at the slowest step")
    print(f"constraints checked in the written files: {'all hold' if s['checks_passed'] else 'FAILED'}")
    print(f"robot {outcome.robot_file}, gait {outcome.result_file}, report {outcome.report_file}")
    print(f"walk it: trajopt evaluate {outcome.result_file} --cycles 10")


if __name__ == "__main__":
    main()
