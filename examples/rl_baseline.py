"""RL baseline in a nutshell: train PPO on SoftTripod-v2 (Coulomb law) briefly, score it with trajopt's metric.

Run:  python examples/rl_baseline.py [TRAJOPT_RESULT.npz]     (a minute or two; needs
      pip install soft-envs[rl])

With a trajopt result (e.g. from `trajopt optimize tripod --task walk --out results/`), its speed
is printed next to the policy's, measured the same way: mean COM speed along the target in
body lengths per minute over 6 gait cycles of 72 steps after 24 prep steps. What the policy is
compared against is printed beside it: the default walk tracks an 8 BL/min COM path on a 72-step
cycle, so a policy trained for speed may beat it; the headline
(benchmarks/results/rl_vs_trajopt_coulomb.md) compares RL with the fastest gait,
`trajopt optimize tripod --speed max`.
The same from the shell: `trajopt rl train tripod --algo ppo --timesteps 8000`, then
`trajopt rl evaluate results/runs/tripod_ppo_seed0`. This example's run is named
`tripod_ppo_example` (results/runs/tripod_ppo_example), so it never collides with that command's.

SOFT_ENVS_QUICK=1 (the project's convention for CI) shrinks the work to a smoke test, named
`tripod_ppo_example_quick` so that it never replaces a full run's files.
"""
import os
import sys

from trajopt import Result
from trajopt.rl import evaluate_policy_metric, evaluate_trajopt_result, export_result, train

# CI smoke test: 64 steps of PPO in one process with tiny batches, scored over one cycle
QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"
TRAIN = (dict(timesteps=64, n_envs=1, vec_env="dummy", progress_bar=False,
              hyperparams=dict(n_steps=32, batch_size=32, n_epochs=1, policy_kwargs=dict(net_arch=[8])))
         if QUICK else dict(timesteps=8000, progress_bar=True))
CYCLES = dict(n_cycles=1) if QUICK else {}
NAME = "tripod_ppo_example_quick" if QUICK else "tripod_ppo_example"   # a quick run never replaces a full one
HEADLINE = ("the headline (benchmarks/results/rl_vs_trajopt_coulomb.md) compares PPO and SAC with the fastest "
            "gait within the motors' limits, `trajopt optimize tripod --speed max`, at a like budget of steps")


def comparison(result_file: str | None) -> str:
    """What the policy's speed is compared against here, and how that relates to the headline."""
    if result_file is None:
        return f"nothing here (pass a trajopt result to measure it the same way); {HEADLINE}"
    s = Result.load(result_file).settings
    if "search" in s:
        return f"{result_file}, a --speed max gait (the fastest within the motors' limits), as in the headline"
    return (f"{result_file}, a gait that tracks a {s.get('speed_bl_per_min', 8):g} BL/min COM path on a "
            f"{s.get('n_cycle')}-step cycle: it is not the fastest gait, so a policy trained for speed may beat it; "
            f"{HEADLINE}")


def main() -> None:
    # 1. Train. Episodes are 168 steps (trajopt's horizon); the hyper-parameters are the documented
    #    defaults of trajopt/rl/hyperparams.py; n_envs defaults to the number of CPU cores.
    #    8000 steps take about a minute on two cores (the simulator does ~150 Tripod steps/s/core).
    run = train("tripod", "ppo", seed=0, out="results/runs", name=NAME, overwrite=True, **TRAIN)
    print(f"trained {run.timesteps} steps in {run.wall_time_s:.0f} s -> {run.run_dir}")

    # 2. Evaluate: deterministic policy, closed loop, from the exact rest state (like trajopt).
    ev = evaluate_policy_metric(run.run_dir, **CYCLES)    # the same model and seed -> the same number
    print(f"PPO     : {ev['speed_bl_per_min']:6.2f} BL/min, upright: {ev['upright']} "
          f"(per cycle: {', '.join(f'{v:.1f}' for v in ev['speed_per_cycle_bl_per_min'])})")
    print(f"compared against: {comparison(sys.argv[1] if len(sys.argv) > 1 else None)}")

    # 3. Export the policy's controls as a trajopt Result (render / play it like an optimised gait).
    result = export_result(run.run_dir, f"results/{NAME}.npz", overwrite=True, **CYCLES)
    print(f"exported: {result.summary()}  (try: trajopt render results/{NAME}.npz --overwrite)")

    # 4. Optional: a trajopt gait, measured the same way.
    if len(sys.argv) > 1:
        tj = evaluate_trajopt_result(sys.argv[1], **CYCLES)
        print(f"trajopt : {tj['speed_bl_per_min']:6.2f} BL/min, upright: {tj['upright']}  ({sys.argv[1]})")


# The guard matters: training uses subprocess environments (SubprocVecEnv, forkserver), whose
# workers import this file again.
if __name__ == "__main__":
    main()
