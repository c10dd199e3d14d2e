"""The task suite in a nutshell: one task (climb a step), an open-loop gait and a policy, each
scored with the task's own score on its Gymnasium id.

Run:  python examples/task_suite.py          (under a minute; needs pip install soft-envs[rl])

What it shows: every benchmark task is also a trajopt objective on the task's own ground
(``trajopt optimize tripod --task climb_step --difficulty medium``: the step of
``SoftTripodClimbStep-v0`` at that level under the gait), RL trains on the task id itself
(``trajopt rl train SoftTripodClimbStep-v0 --difficulty medium``), and both are played on the id
and scored the same way (``trajopt.tasks.play``: the COM's advance in body lengths over the
300-step episodes, seeds 0-2, and whether it got past the finish). Last, each score is checked
the way the suite checks it (``trajopt.tasks.play.gait_task_hold`` / ``policy_task_hold``): played
again with half, twice and four times the physics steps per control step, a score that holds
changes by at most 5 %; the lowest is the credible one. The whole suite, every task
on both robots with PPO and SAC over three seeds, is ``python benchmarks/bench_suite.py``
(benchmarks/results/suite.md). The budgets here are a demonstration, not the suite's.

SOFT_ENVS_QUICK=1 (the project's convention for CI) shrinks the work to a smoke test (one episode,
replays at half and twice the physics steps only).
"""
import os

from trajopt.optimize_run import OptimizeRun, run_optimization
from trajopt.rl import train
from trajopt.tasks.play import gait_on_task, gait_task_hold, policy_on_task, policy_task_hold

QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"
SUFFIX = "_quick" if QUICK else ""                 # a quick run never replaces a full one's files
ITERATIONS = 1 if QUICK else 2                      # Gauss-Newton iterations of the gait
STEPS = 128 if QUICK else 2048                      # PPO's environment steps
HP = dict(n_steps=64, batch_size=64, n_epochs=2) if QUICK else {}
FACTORS = (0.5, 2.0) if QUICK else None             # the replays' physics steps per control step (x own)

# 1. trajopt: the walk's objective on the step's ground, played open loop on the id
run_optimization(OptimizeRun("tripod", task="climb_step", difficulty="medium", iterations=ITERATIONS, seeds=0,
                             out="results", name=f"tripod_climb_step_example{SUFFIX}", overwrite=True, quiet=True))
gait = gait_on_task(f"results/tripod_climb_step_example{SUFFIX}.npz")

# 2. PPO on the task id (its observation sees the step ahead), played closed loop on it
run = train("SoftTripodClimbStep-v0", "ppo", STEPS, seed=0, out="results/runs", name=f"climb_step_ppo_example{SUFFIX}",
            n_envs=2, vec_env="dummy", max_episode_steps=300, env_kwargs={"difficulty": "medium"}, hyperparams=HP,
            progress_bar=False, overwrite=True)
policy = policy_on_task(run.run_dir)

for name, ev in (("trajopt, open loop", gait), (f"PPO, {run.timesteps} steps", policy)):
    print(f"{name:20s}: {ev['score_name']} {ev['score']:+.3f} {ev['score_unit']} on {ev['env_id']} "
          f"({len(ev['episodes'])} episodes, success {ev['success_rate']:.0%}, {ev['sim_steps']:,} simulation steps)")

# 3. does each score hold at other physics steps (16.5, 4.125 and 2.06 ms around the 8.25 ms it was made at)?
for name, hold in (("trajopt", gait_task_hold(f"results/tripod_climb_step_example{SUFFIX}.npz", factors=FACTORS,
                                              reference=gait)),
                   ("PPO", policy_task_hold(run.run_dir, factors=FACTORS, reference=policy))):
    scores = " / ".join(f"{v:+.3f}" for v in hold["scores"])
    print(f"{name:20s}: {scores} {hold['score_unit']} at {' / '.join(f'{d:g}' for d in hold['physics_dt_ms'])} ms: "
          f"credible {hold['slowest']:+.3f}, spread {hold['spread']:.1%}, {'holds' if hold['holds'] else 'does not hold'}")
