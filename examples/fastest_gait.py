"""The fastest walk the Tripod's motors allow: a search over cycle length and keyframes.

Run:  python examples/fastest_gait.py      (about three minutes on two cores)

The paper plays a hand-set 72-step cycle (2.4 s). Under the motors' speed limit (robot.toml
``max_speed_rpm``: at most 1.73 mm of cable per 0.033 s step) a faster walk needs shorter,
quicker strides. ``trajopt.fastest.fastest_gait`` searches the cycle length (8-72 steps) and
the keyframe count with Gauss-Newton, coarse to fine, each candidate warm-started from its
neighbour, every step of the controls inside the limit (linear inequalities on the keyframes,
a QP in each Gauss-Newton step). Keyframes are joined by straight lines here, so a cable can
move at the motor's full speed (the paper's zero-tangent spline peaks at 1.5 times its mean
slope). Each candidate is evaluated over 10 cycles. The three fastest are refined, then replayed
with half, twice and four times the physics steps: the result is the fastest whose speed holds
within 5 % at all of them (a fast gait that only works at one physics step is the model's, not
the robot's), else the fastest upright one. The table lists every run with the simulation steps
each cost, and each refined gait's slowest speed and spread.

From the shell: `trajopt optimize tripod --speed max --contact coulomb` (writes
results/tripod_walk.npz and results/tripod_walk.search.csv / .md; `--cycle-steps N` pins the cycle).

SOFT_ENVS_QUICK=1 (the project's convention for CI) searches two short cycles with one iteration
each and saves results/tripod_fastest_example_quick.npz instead of results/tripod_fastest_example.npz.
"""
import os

from trajopt.fastest import SearchSettings, fastest_gait, write_search_table

QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"

result, table = fastest_gait("tripod", contact="coulomb", settings=SearchSettings.quick() if QUICK else SearchSettings(),
                             quiet=QUICK)
for row in table:
    print(f"{row['stage']:6s} cycle {row['n_cycle']:3d} steps, {row['n_keyframes']} keyframes: "
          f"{row['speed_bl_per_min']:6.2f} BL/min, upright {row['upright']}, {row['total_sim_steps']:,} steps so far"
          + (f"; at other physics steps {row['slowest_bl_per_min']:.2f} at the slowest, spread "
             f"{100 * row['spread']:.1f} %" if row["holds"] != "" and row["holds"] is not None else "")
          + ("  <- chosen" if row["chosen"] else ""))
ev = result.evaluation
print(f"chosen: {ev['speed_bl_per_min']:.2f} BL/min on a {result.settings['n_cycle']}-step cycle of "
      f"{result.settings['n_keyframes']} keyframes, upright over {ev['cycles']} cycles: {ev['upright']} "
      f"({result.settings['search']['chosen_by']})")
print(f"simulation steps of the whole search: {ev['search_sim_steps']:,}")
path = result.save("results/tripod_fastest_example_quick.npz" if QUICK else "results/tripod_fastest_example.npz")
csv_path, _ = write_search_table(table, path)
print(f"saved {path} and {csv_path}; play it in the env with: trajopt evaluate {path} --cycles 10")
