"""The motors' torque-speed line in the optimiser: what it costs and what it changes.

    python benchmarks/bench_motor_model.py                       # Tripod and Puppy, both contact laws
    python benchmarks/bench_motor_model.py tripod --contact coulomb --out benchmarks/results

Prints, per robot and contact law:

(a) the cost of a Gauss-Newton iteration with the line's constraints against the speed limit's
    (and against none), measured in one run: from the same start (the torque-speed run's, inside
    both), one iteration (its Jacobian rollout, the constraints and the QP step, the line search,
    the next Jacobian rollout) under each model, alternately, ``--repeat`` times; the ratio of
    the medians (target <= 1.2x). The line search may take another number of trials under each
    model, so the parts the constraints change are also timed alone at that start (the Jacobian
    rollout, the line's rows, the QP step under each model's rows): their ratio is the cost of
    an iteration at equal trials;
(b) the shipped walk as ``trajopt optimize ROBOT --task walk`` makes it (the paper's 72-step
    gait, 4 keyframes, 10 Gauss-Newton iterations, 8 seeds, 6 evaluation cycles) under the
    torque-speed model and under the speed-limit model: the speeds, each motor's peak torque;
(c) an independent replay of both gaits at 8x finer physics steps (the controls joined by
    straight lines in time, ``make_gradient_env(robot, timestep=0.033 / 8, contact=...)`` from
    rest, prep + 6 cycles): the worst normalised line excess ``v / v0 + tau / stall - 1`` over
    every fine winding step (tau of the state before and after it), which must be <= 0.02 for
    the torque-speed gait, and the peak torque against ``max_torque``. (Once the environments'
    physics sub-steps land, this replay is the environment's ``substeps=8``.)

With ``--fastest BUDGET``, also (d): ``--speed max`` (:func:`trajopt.fastest.fastest_gait`, its
default search within BUDGET simulation steps, as the README's RL comparison) under each
model, and the 8x finer replay of both gaits.

Writes ``OUT/motor_model.md`` (a row per robot and law appended) and the gaits
(``OUT/ROBOT_LAW_MODEL.npz``) when ``--out`` is given.
"""
from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from soft_envs.envs import MotorLaw, make_gradient_env
from trajopt.optim.gait import GaitSpec
from trajopt.optim.gauss_newton import GaussNewtonOptions, gauss_newton
from trajopt.optim.motor_limit import max_step_of_env
from trajopt.optim.objectives import ObjectiveWeights
from trajopt.optim.optimize import DEFAULT_SPEED, build_problem, optimize_gait
from trajopt.optim.parameterization import GaitParameterization
from trajopt.optim.start import choose_start
from trajopt.results.files import atomic_write_bytes

FINE = 8                    # physics steps per control step of the independent replay
CYCLES = 6                  # cycles after the prep phase, as optimize evaluates


def _problem(robot: str, contact: str, model: str):
    env = make_gradient_env(robot, contact=contact)
    gait = GaitSpec.for_task("walk")
    return build_problem(env, "walk", gait, speed_bl_per_min=DEFAULT_SPEED[robot], heading_deg=0.0, turn="right",
                         target=None, weights=ObjectiveWeights.for_task("walk"), max_step=max_step_of_env(env),
                         motor_model=model)


def iteration_cost(robot: str, contact: str, repeat: int) -> dict[str, float]:
    """(a): median seconds of one Gauss-Newton iteration under each model from one start."""
    z0 = choose_start(_problem(robot, contact, "torque-speed"), n_seeds=8).z        # inside every model's limits
    times: dict[str, list[float]] = {"torque-speed": [], "speed": [], "ideal": []}
    for _ in range(repeat):
        for model in times:                     # alternately: the machine's load hits all alike
            problem = _problem(robot, contact, model)
            lo, hi = problem.param.bounds()
            t0 = time.perf_counter()
            gauss_newton(problem, z0, lo, hi, GaussNewtonOptions(max_iter=1, ftol=0.0, xtol=0.0),
                         constraints=problem.constraints)
            times[model].append(time.perf_counter() - t0)
    return {m: statistics.median(t) for m, t in times.items()}


def constraint_overhead(robot: str, contact: str, repeat: int) -> dict[str, float]:
    """(a'): the parts of an iteration the constraints change, timed alone at one start: the
    Jacobian rollout, the line's rows from it, and the QP step under each model's constraints.
    ``ratio``: (rollout + rows + QP with the line) / (rollout + QP with the speed limit), the cost
    of an iteration with the same number of line-search trials."""
    from trajopt.optim.gauss_newton import _constrained_direction
    line_problem, speed_problem = _problem(robot, contact, "torque-speed"), _problem(robot, contact, "speed")
    z = choose_start(line_problem, n_seeds=8).z
    lo, hi = line_problem.param.bounds()
    t = {"rollout": [], "rows": [], "qp_line": [], "qp_speed": []}
    for _ in range(repeat):
        t0 = time.perf_counter()
        r, J, _ = line_problem(z, True)
        t["rollout"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        rows = line_problem.linearised_constraints(z)
        t["rows"].append(time.perf_counter() - t0)
        for key, cons in (("qp_line", rows), ("qp_speed", speed_problem.speed_limit)):
            t0 = time.perf_counter()
            _constrained_direction(J, J.T @ r, z, 1e-4, lo, hi, cons)
            t[key].append(time.perf_counter() - t0)
    med = {k: statistics.median(v) for k, v in t.items()}
    med["ratio"] = (med["rollout"] + med["rows"] + med["qp_line"]) / (med["rollout"] + med["qp_speed"])
    med["line_rows"] = float(len(rows.h))
    return med


def fine_replay(res, robot: str, contact: str) -> tuple[float, float, float]:
    """(c): ``(worst line excess, peak torque / max_torque - 1, horizon-only worst excess)`` of
    ``res`` replayed at ``FINE`` physics steps per control step."""
    env = make_gradient_env(robot, contact=contact, timestep=res.dt / FINE)
    gait = GaitSpec.from_settings(res.settings)
    param = GaitParameterization.for_robot(env.robot, gait)
    u = np.vstack([env.robot.u_rest, param.controls(res.z, CYCLES)])          # u_{-1} = rest at t = 0
    t = res.dt * np.arange(len(u))                                            # u_k reached at t = (k + 1) h
    tf = res.dt / FINE * np.arange(1, FINE * (len(u) - 1) + 1)
    uf = np.stack([np.interp(tf, t, u[:, m]) for m in range(u.shape[1])], axis=1)
    traj = env.rollout(uf)
    law = MotorLaw.of_robot(env.robot)
    tau = law.torque(traj.cable_deformation)                                  # (n + 1, M)
    v = np.diff(np.vstack([u[0], uf]), axis=0) / (res.dt / FINE)
    winding = v > 0
    excess = np.maximum(v / law.no_load_speed + tau[:-1] / law.stall_torque,
                        v / law.no_load_speed + tau[1:] / law.stall_torque) - 1
    excess = np.where(winding, excess, -np.inf)
    horizon = FINE * gait.n_steps()
    return (float(excess.max()), float((tau / law.max_torque).max() - 1), float(excess[:horizon].max()))


def fastest(robot: str, contact: str, budget: int, out: Path | None) -> str:
    """(d): ``--speed max`` within ``budget`` steps under each model, and the fine replay."""
    from dataclasses import replace

    from trajopt.fastest import SearchSettings, fastest_gait
    parts = []
    for model in ("torque-speed", "speed"):
        t0 = time.perf_counter()
        res, _ = fastest_gait(make_gradient_env(robot, contact=contact), robot_spec=robot, quiet=True,
                              settings=replace(SearchSettings(), max_sim_steps=budget), motor_model=model)
        worst, torque, _ = fine_replay(res, robot, contact)
        if out is not None:
            res.save(out / f"{robot}_{contact}_max_{model}.npz")
        parts.append(f"{model}: {res.evaluation['speed_bl_per_min']:.2f} BL/min ({res.settings['n_cycle']}-step cycle, "
                     f"{res.settings['n_keyframes']} keyframes), peak torque "
                     f"{max(res.evaluation['motor_load']['peak_torque_nm']):.3f} N m, worst line excess at 8x "
                     f"{worst:+.4f}, {time.perf_counter() - t0:.0f} s")
    return f"  (d) {robot}, {contact}, --speed max within {budget:,} steps: " + "; ".join(parts)


def run(robot: str, contact: str, repeat: int, out_dir: Path | None = None) -> dict:
    cost = iteration_cost(robot, contact, repeat)
    parts = constraint_overhead(robot, contact, repeat)
    print(f"  {robot}, {contact}: Jacobian rollout {parts['rollout']:.2f} s, the line's {parts['line_rows']:.0f} rows "
          f"{1e3 * parts['rows']:.0f} ms, QP step {1e3 * parts['qp_line']:.0f} ms with them / "
          f"{1e3 * parts['qp_speed']:.0f} ms with the speed limit's: {parts['ratio']:.2f}x per iteration at equal "
          f"line-search trials", flush=True)
    out = {"robot": robot, "contact": contact, "iteration_s": cost, "parts": parts,
           "ratio_vs_speed": cost["torque-speed"] / cost["speed"],
           "ratio_vs_ideal": cost["torque-speed"] / cost["ideal"]}
    for model in ("torque-speed", "speed"):
        t0 = time.perf_counter()                # trajopt optimize ROBOT --task walk [--contact paper]
        res = optimize_gait(make_gradient_env(robot, contact=contact), "walk", options=GaussNewtonOptions(max_iter=10),
                            n_seeds=8, robot_spec=robot, motor_model=model)
        ev = res.evaluation
        worst, torque, horizon = fine_replay(res, robot, contact)
        if out_dir is not None:
            out_dir.mkdir(parents=True, exist_ok=True)
            res.save(out_dir / f"{robot}_{contact}_{model}.npz")
        out[model] = {"speed_bl_per_min": ev["speed_bl_per_min"], "upright": ev["upright"],
                      "peak_torque_nm": max(ev["motor_load"]["peak_torque_nm"]),
                      "worst_line_excess": max(ev["motor_load"]["worst_line_excess"]),
                      "fine_worst_excess": worst, "fine_horizon_excess": horizon, "fine_torque_excess": torque,
                      "wall_s": time.perf_counter() - t0, "status": res.status,
                      "refused_trials": ev["motor_load"].get("refused_trials", 0),
                      "trials": sum(h.get("trials", 0) for h in res.history)}
    return out


def _row(r: dict) -> str:
    ts, sp = r["torque-speed"], r["speed"]
    it = r["iteration_s"]
    return (f"| {r['robot']} | {r['contact']} | {it['torque-speed']:.2f} / {it['speed']:.2f} / {it['ideal']:.2f} s | "
            f"**{r['ratio_vs_speed']:.2f}x** ({r['ratio_vs_ideal']:.2f}x); {r['parts']['ratio']:.2f}x at equal trials | "
            f"{ts['speed_bl_per_min']:.2f} | {sp['speed_bl_per_min']:.2f} | {ts['peak_torque_nm']:.3f} / "
            f"{sp['peak_torque_nm']:.3f} | {ts['fine_worst_excess']:+.4f} ({ts['fine_horizon_excess']:+.4f}) | "
            f"{sp['fine_worst_excess']:+.4f} | {ts['fine_torque_excess']:+.3f} |")


HEADER = ("| robot | law | (a) one GN iteration: torque-speed / speed / ideal | (a) ratio vs speed (vs none) | "
          "(b) speed, torque-speed [BL/min] | (b) speed, speed limit [BL/min] | peak torque [N m] (ts / speed) | "
          "(c) worst line excess at 8x, torque-speed gait (horizon) | (c) the same, speed-limit gait | "
          "(c) torque-speed gait's peak / max_torque - 1 |\n|---|---|---|---|---|---|---|---|---|---|")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("robots", nargs="*", default=["tripod", "puppy"])
    ap.add_argument("--contact", nargs="+", default=["coulomb", "paper"])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--fastest", type=int, default=None, metavar="BUDGET",
                    help="also --speed max within BUDGET simulation steps under each model (d)")
    ap.add_argument("--only-fastest", action="store_true", help="(d) alone")
    args = ap.parse_args()
    if args.only_fastest:
        for robot in args.robots:
            for contact in args.contact:
                print(fastest(robot, contact, args.fastest or 30_720, args.out), flush=True)
        return
    print(HEADER)
    for robot in args.robots:
        for contact in args.contact:
            r = run(robot, contact, args.repeat, args.out)
            print(_row(r), flush=True)
            print(f"  wall: torque-speed {r['torque-speed']['wall_s']:.0f} s, speed {r['speed']['wall_s']:.0f} s; "
                  f"status {r['torque-speed']['status']} / {r['speed']['status']}; upright "
                  f"{r['torque-speed']['upright']} / {r['speed']['upright']}; line-search trials refused by the line: "
                  f"{r['torque-speed']['refused_trials']} of {r['torque-speed']['trials']}", flush=True)
            if args.out is not None:
                path = args.out / "motor_model.md"
                args.out.mkdir(parents=True, exist_ok=True)
                text = path.read_text() if path.is_file() else HEADER + "\n"
                atomic_write_bytes(path, (text + _row(r) + "\n").encode())
            if args.fastest:
                print(fastest(robot, contact, args.fastest, args.out), flush=True)


if __name__ == "__main__":
    main()
