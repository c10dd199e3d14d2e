"""The motors the robots really have: a torque-speed line, not a speed limit alone.

Run:  python examples/motor_line.py      (about two minutes on two cores)

A Pololu 298:1 gearmotor winds its cable more slowly the harder the cable pulls: at most
``v0 (1 - tau / stall_torque)`` with the load torque ``tau`` = spool radius x the tendons'
tension, and never beyond its gearbox's ``max_torque`` (robot.toml ``[[motors]]``; the law is
``soft_envs.sim.motors``). The same Tripod walk is optimised twice, under the speed limit alone
(``motor_model="speed"``, the law before the line) and under the line (``"torque-speed"``, the
default), and each is played by an environment whose motors follow the line: the gait made for
the line is played as optimised, the other one's motors fall behind where it winds too fast
under load. The line and the steps of the gait made for it are drawn per motor.

From the shell: `trajopt optimize tripod --motor-model speed` / `--motor-model torque-speed`,
`trajopt plot RESULT` (NAME_motors.png), `trajopt play RESULT --hardware HW.toml --dry-run`
(each motor's peak torque and its margin to the line).

SOFT_ENVS_QUICK=1 (the project's convention for CI) runs short gaits with one Gauss-Newton
iteration and writes results/motor_line_example_quick.png instead of results/motor_line_example.png.
"""
import os

import numpy as np

from soft_envs.envs import MotorLaw, SoftRobotEnv, load_robot
from trajopt import GaitParameterization, GaitSpec, measure_gait, optimize_gait
from trajopt.optim.gauss_newton import GaussNewtonOptions
from trajopt.plots import plot_motor_line

QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"
GAIT = GaitSpec(n_prep=6 if QUICK else 24, n_cycle=24, n_keyframes=4, interpolation="linear")
CYCLES = 2 if QUICK else 4
ROBOT = load_robot("tripod")
PARAM = GaitParameterization.for_robot(ROBOT, GAIT)


def played_by_motors_on_their_line(u: np.ndarray):
    """Step an environment whose motors follow the torque-speed line through the controls ``u``:
    ``(env, its states, how many motor-steps the line held back)``."""
    env = SoftRobotEnv(ROBOT, motor_model="torque-speed", reset_noise_scale=0.0)
    env.reset(seed=0)
    xs, coms, held = [env.get_state()["x"]], [env.com()], 0
    for row in u:
        _, _, _, _, info = env.step(env.control_to_action(row))
        xs.append(env.get_state()["x"])
        coms.append(env.com())
        held += int(info["motor_limited"].sum())

    class States:
        x, com = np.array(xs), np.array(coms)
    return env, States, held


for model in ("speed", "torque-speed"):
    res = optimize_gait("tripod", "walk", gait=GAIT, speed_bl_per_min=20.0, n_seeds=1, eval_cycles=CYCLES,
                        options=GaussNewtonOptions(max_iter=1 if QUICK else 8), motor_model=model)
    env, states, held = played_by_motors_on_their_line(PARAM.controls(res.z, CYCLES))
    played = measure_gait(states, env, n_prep=GAIT.n_prep, n_cycle=GAIT.n_cycle)["speed_bl_per_min"]
    optimised = res.evaluation["speed_bl_per_min"]
    load = res.evaluation["motor_load"]
    print(f"{model:12s}: {optimised:5.2f} BL/min as optimised, {played:5.2f} BL/min played by motors on their line "
          f"(off by {100 * abs(played - optimised) / abs(optimised):.2f} %, {held} motor-steps held back); "
          f"peak torque {max(load['peak_torque_nm']):.3f} N m, worst line excess "
          f"{100 * max(load['worst_line_excess']):+.1f} %")

law = MotorLaw.of_robot(ROBOT)
torque = np.array(load["torque_nm"])           # the gait made under the line: its states' load torques
speed = np.diff(np.vstack([ROBOT.u_rest, res.u]), axis=0) / res.dt
path = plot_motor_line(speed, torque[:-1], torque[1:], law.no_load_speed, law.stall_torque, law.max_torque,
                       res.motor_names, "results/motor_line_example_quick.png" if QUICK
                       else "results/motor_line_example.png", subject="Tripod walk made under the torque-speed line")
print(f"wrote {path}")
