"""The fastest gait within the motors' speed limit (``trajopt optimize ROBOT --speed max``, issue #28).

    python benchmarks/bench_fastest_gait.py tripod --contact coulomb        # one robot, one law
    python benchmarks/bench_fastest_gait.py tripod puppy --contact coulomb paper --out benchmarks/results/fastest

Runs :func:`trajopt.fastest.fastest_gait` under the motors' speed limit alone (``motor_model="speed"``,
the law of the RL baseline's environments; ``benchmarks/bench_motor_model.py`` measures it under
the torque-speed line) with its default search and the step budget of one
PPO seed of ``benchmarks/results/rl_vs_trajopt_coulomb.md`` (``--budget``: another; 0: none),
and prints per robot and contact law:

* the best speed [BL/min] (trajopt's ``evaluate_controls``, 10 cycles after the prep phase), its
  cycle and keyframes, upright over the 10 cycles;
* the same gait measured over at least 432 steps after the prep phase (the RL report's window);
* every simulation step of the search (optimisations with line searches, Jacobian rollouts and
  seed screening, and the evaluations) against the budget, and the wall time;
* the gait stepped through the Gymnasium environment with its motor speed limit on (speed
  within 1 % of ``evaluate_controls``?);
* an independent check of the limit: the controls rebuilt from the keyframes for 10 cycles,
  every step from rest to the last wrap-around, against ``max_speed_rpm * 2 pi / 60 *
  spool_radius * h`` of the robot file (1e-9 m).

Writes ``OUT/ROBOT_CONTACT.npz`` (+ the search table) and ``OUT/summary.md`` (one row per run
appended; default OUT results/fastest). Targets (Coulomb): >= 23.6 BL/min Tripod, >= 22.9 Puppy; budgets 30,720 / 15,360.
"""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import soft_envs  # noqa: F401  (registers the environments)
from soft_envs.envs import make_gradient_env
from soft_envs.sim import load_robot
from trajopt.evaluation import evaluate_controls
from trajopt.fastest import SearchSettings, fastest_gait, write_search_table
from trajopt.optim.gait import GaitSpec
from trajopt.optim.motor_limit import played_steps
from trajopt.optim.parameterization import GaitParameterization
from trajopt.rl.envs import env_id
from trajopt.rl.evaluate import play_controls_in_env, run_metric

#: simulation steps of one PPO seed (benchmarks/results/rl_vs_trajopt_coulomb.md)
BUDGET = {"tripod": 30_720, "puppy": 15_360}
#: the best RL seed under the Coulomb law (the same report)
TARGET = {"tripod": 23.6, "puppy": 22.9}
RL_WINDOW = 432             # steps after the prep phase the RL report measures


def independent_limit_check(res, robot_name: str) -> float:
    """Largest ``|u[k+1] - u[k]| - v_max h`` [m] over 10 cycles, rest and wrap-around included,
    from the keyframes and the robot file alone."""
    robot = load_robot(robot_name)
    gait = GaitSpec.from_settings(res.settings)
    param = GaitParameterization.for_robot(robot, gait)
    u = param.controls(param.z_from_keyframes(np.asarray(res.settings["keyframes"])), 10)
    v_max = np.array([m.max_speed_rpm * 2 * math.pi / 60 * m.spool_radius for m in robot.motors])
    return float((np.abs(played_steps(u, robot.u_rest, gait.n_prep, gait.n_cycle)) - v_max * res.dt).max())


def env_replay(res, contact: str, n_cycles: int) -> float:
    """The gait stepped through the Gymnasium env (motor limit on), speed [BL/min]."""
    physics = make_gradient_env(res.robot, contact=contact)
    param = GaitParameterization.for_robot(physics.robot, GaitSpec.from_settings(res.settings))
    u = param.controls(res.z, n_cycles)
    env = gym.make(env_id(res.robot), contact=physics.contact_model, reset_noise_scale=0.0,
                   terminate_when_unhealthy=False, max_episode_steps=len(u))
    acts = env.unwrapped.control_to_action(u)
    rec = play_controls_in_env(env, lambda obs, k: acts[k], len(u), seed=0)
    m = run_metric(env, rec["u"], rec["x"], gait=GaitSpec.from_settings(res.settings))
    env.close()
    return float(m["speed_bl_per_min"])


def bench(robot: str, contact: str, budget: int | None, out: Path) -> dict:
    settings = SearchSettings(max_sim_steps=budget)
    t0 = time.perf_counter()
    res, rows = fastest_gait(robot, contact=contact, settings=settings, quiet=True, log=print,
                             motor_model="speed")      # RL's environments (-v0, -v1): the speed limit alone
    wall = time.perf_counter() - t0
    path = res.save(out / f"{robot}_{contact}.npz")
    write_search_table(rows, path)
    s, ev = res.settings, res.evaluation
    env = make_gradient_env(robot, contact=contact)
    param = GaitParameterization.for_robot(env.robot, GaitSpec.from_settings(s))
    long_cycles = max(10, math.ceil(RL_WINDOW / s["n_cycle"]))
    long = evaluate_controls(env, param.controls(res.z, long_cycles), n_prep=s["n_prep"], n_cycle=s["n_cycle"])
    in_env = env_replay(res, contact, int(s["eval_cycles"]))
    excess = independent_limit_check(res, robot)
    row = {"robot": robot, "contact": contact, "speed": ev["speed_bl_per_min"], "upright": ev["upright"],
           "n_cycle": s["n_cycle"], "n_keyframes": s["n_keyframes"], "long_cycles": long_cycles,
           "long_speed": long["speed_bl_per_min"], "long_upright": long["upright"],
           "steps": ev["search_sim_steps"], "budget": budget, "wall": wall, "runs": len(rows),
           "in_env": in_env, "env_rel": abs(in_env - ev["speed_bl_per_min"]) / abs(ev["speed_bl_per_min"]),
           "limit_excess_m": excess}
    target = TARGET[robot] if contact == "coulomb" else None
    print(f"\n{robot}, {contact} law: {row['speed']:.2f} BL/min (10 cycles, upright {row['upright']}), cycle "
          f"{row['n_cycle']} steps, {row['n_keyframes']} keyframes"
          + (f"; target {target} BL/min {'reached' if row['speed'] >= target else 'NOT reached'}" if target else ""))
    print(f"  over {long_cycles} cycles ({long_cycles * s['n_cycle']} steps): {row['long_speed']:.2f} BL/min, "
          f"upright {row['long_upright']}")
    print(f"  simulation steps {row['steps']:,} (budget {budget:,})" if budget else
          f"  simulation steps {row['steps']:,} (no budget)")
    print(f"  wall time {wall:.0f} s, {len(rows)} optimisations")
    print(f"  env replay, motor limit on: {in_env:.2f} BL/min ({100 * row['env_rel']:.2f} % from evaluate_controls)")
    print(f"  independent limit check over 10 cycles: largest step minus v_max h = {excess:+.2e} m "
          f"({'obeyed' if excess <= 1e-9 else 'BROKEN'})")
    summary = out / "summary.md"
    if not summary.exists():
        summary.write_text("| robot | law | BL/min (10 cycles) | upright | cycle / keyframes | BL/min (>= 432 steps) | "
                           "simulation steps (budget) | wall [s] | env replay, limit on | largest step - v_max h [m] |\n"
                           "|---|---|---:|---|---|---:|---|---:|---:|---:|\n")
    with summary.open("a") as f:
        f.write(f"| {robot} | {contact} | {row['speed']:.2f} | {row['upright']} | {row['n_cycle']} / "
                f"{row['n_keyframes']} | {row['long_speed']:.2f} | {row['steps']:,} "
                f"({f'{budget:,}' if budget else 'none'}) | {wall:.0f} | "
                f"{in_env:.2f} ({100 * row['env_rel']:.2f} %) | {excess:+.2e} |\n")
    return row


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("robots", nargs="+", choices=sorted(BUDGET))
    p.add_argument("--contact", nargs="+", default=["coulomb"], choices=["coulomb", "paper"])
    p.add_argument("--budget", type=int, default=None, help="simulation steps (default: one PPO seed's; 0: none)")
    p.add_argument("--out", type=Path, default=Path("results/fastest"))
    a = p.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    for robot in a.robots:
        for contact in a.contact:
            budget = BUDGET[robot] if a.budget is None else (a.budget or None)
            bench(robot, contact, budget, a.out)


if __name__ == "__main__":
    main()
