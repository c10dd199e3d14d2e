"""The optimiser obeys the motors' torque-speed line (issue #38, :mod:`trajopt.optim.motor_torque`):
the load torque's sensitivity and the constraint rows against central differences of whole
rollouts, the wrap-around step of a looped cycle, a constrained optimum that sits on the line,
and optimised gaits against the line and against the environments that step with it.

Finite differences: Newton tolerance 1e-12 m per step, perturbations of 3e-7 m of keyframe
along random unit directions (larger ones meet the kinks of Q'' at the ends of the cables' C2
blend: 3e-6 gives 3e-6 relative error under the Coulomb law, 3e-7 gives 2e-8); required relative
error <= 1e-6 (Frobenius norm over every state and motor, worst of two directions).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from soft_envs.envs import MotorLaw, SimulationError, SoftRobotEnv, make_gradient_env
from soft_envs.sim import NewtonOptions
from soft_envs.sim.substeps import SUBSTEP_TOLERANCE
from trajopt import GaitSpec, optimize_gait
from trajopt.evaluation import measure_gait
from trajopt.optim.gauss_newton import GaussNewtonOptions, gauss_newton
from trajopt.optim.motor_torque import LINE_TOLERANCE, MotorLine, played_step_maps
from trajopt.optim.parameterization import GaitParameterization

from .gradcheck import relative_error
from .test_motor_model import _spring_robot

QUICK = GaitSpec(n_prep=6, n_cycle=24, n_cycles=2, n_keyframes=4)
TIGHT = NewtonOptions(tol=1e-12)


def _setup(contact: str, gait: GaitSpec = QUICK, robot="tripod"):
    env = make_gradient_env(robot, contact=contact)
    env.simulator.newton.options = TIGHT
    param = GaitParameterization.for_robot(env.robot, gait)
    law = MotorLaw.of_robot(env.robot)
    return env, param, law, MotorLine(param, law, env.timestep)


def _rollout(env, param, z, sensitivities=False):
    dudz = param.dudz()
    return env.rollout(param.offset() + dudz @ z, dudz=dudz if sensitivities else None)


def _flat(excess: dict) -> np.ndarray:
    return np.concatenate([v.ravel() for v in excess.values()])


@pytest.mark.parametrize("contact", ["coulomb", "paper"])
def test_the_torque_and_the_rows_match_central_differences(contact):
    """``d tau / dz = r sum Q''(Gamma) dGamma/dz`` and the rows ``G`` of the linearised line
    (``G z0 - h`` is every condition's excess at z0, exactly) against central differences."""
    env, param, law, line = _setup(contact)
    rng = np.random.default_rng(0)
    lo, hi = param.bounds()
    z = lo + (hi - lo) * rng.uniform(0.2, 0.6, param.nz)
    traj = _rollout(env, param, z, True)
    gamma = traj.cable_deformation
    assert (gamma[1:] > 0).mean() > 0.9           # the regime: taut cables, most in their C2 blend
    J = law.torque_jacobian(gamma, traj.dgammadz)
    lin = line.linearised(z, gamma, traj.dgammadz, clamp=False)
    assert np.abs(lin.G @ z - lin.h - _flat(line.excess(z, gamma))).max() < 1e-14
    h = 1e-7              # truncation error O(h^2) across the blends' kinks: 6e-6 at 3e-7 with 4 physics steps
    for _ in range(2):
        d = rng.normal(size=param.nz)
        d /= np.linalg.norm(d)
        tp, tm = _rollout(env, param, z + h * d), _rollout(env, param, z - h * d)
        fd_tau = (law.torque(tp.cable_deformation) - law.torque(tm.cable_deformation)) / (2 * h)
        assert relative_error(J @ d, fd_tau) <= 1e-6
        fd_rows = (_flat(line.excess(z + h * d, tp.cable_deformation))
                   - _flat(line.excess(z - h * d, tm.cable_deformation))) / (2 * h)
        assert relative_error(lin.G @ d, fd_rows) <= 1e-6


def test_the_played_steps_are_every_step_of_the_horizon_and_the_wrap_around():
    for gait in (QUICK, QUICK.replace(n_cycles=1), QUICK.replace(n_prep=0)):
        param = GaitParameterization.for_robot(make_gradient_env("tripod").robot, gait)
        D, c, before, after = played_step_maps(param)
        z = np.random.default_rng(1).uniform(*param.bounds())
        u = param.controls(z, 3)                     # three cycles played
        K = gait.n_steps()
        played = np.diff(np.vstack([param.u_rest, u]), axis=0)
        changes = np.einsum("smz,z->sm", D, z) + c
        assert np.allclose(changes[:K], played[:K], rtol=0, atol=1e-15)
        if gait.n_cycles == 1:                        # the wrap-around beyond the horizon
            assert np.allclose(changes[K], played[K], atol=1e-15) and after[K] == -1 and before[K] == K
        assert list(before[:K]) == list(range(K)) and list(after[:K]) == list(range(1, K + 1))


def test_the_constraints_cover_the_wrap_around_step_of_a_looped_cycle():
    """One keyframe per cycle step, straight lines: the cycle holds motor 0 at 10 mm, drops it by
    1.7 mm at its last step and winds it back at the wrap-around (cycle 1's last row -> cycle
    2's first), under load: that step alone breaks the line. The linearised rows see it: their
    worst ``G z - h`` is that step's excess, measured independently from the rollout (without
    the wrap-around row the gait would look feasible)."""
    gait = GaitSpec(n_prep=24, n_cycle=8, n_cycles=2, n_keyframes=8, interpolation="linear", symmetry=False)
    env, param, law, line = _setup("coulomb", gait)
    kf = np.array([[0.010] * 7 + [0.0083], [0.004] * 8])
    z = param.z_from_keyframes(kf)
    u = param.controls(z)
    traj = _rollout(env, param, z, True)
    tau = law.torque(traj.cable_deformation)                     # (K+1, M), state k before step k
    s = law.no_load_speed * env.timestep
    du = np.diff(np.vstack([param.u_rest, u]), axis=0)           # every step of the horizon, from rest
    excess = np.maximum(du / s + tau[:-1] / law.stall_torque - 1, du / s + tau[1:] / law.stall_torque - 1)
    wrap = gait.n_prep + gait.n_cycle                            # cycle 1's last row -> cycle 2's first
    assert du[wrap, 0] == pytest.approx(0.0017, abs=1e-12)
    k, m = np.unravel_index(np.argmax(excess), excess.shape)
    assert (k, m) == (wrap, 0) and excess[k, m] > 0.05
    others = np.delete(excess, wrap, axis=0)
    assert others.max() < 0 and (tau[1:] / law.max_torque).max() < 1     # nothing else breaks anything
    lin = line.linearised(z, traj.cable_deformation, traj.dgammadz, clamp=False)
    assert lin.violation(z) == pytest.approx(excess[wrap, 0], abs=1e-14)
    worst = line.worst(z, traj.cable_deformation)
    assert (worst.step, worst.motor) == (wrap, 0) and worst.excess == pytest.approx(excess[wrap, 0], abs=1e-14)


def test_a_constrained_optimum_on_the_line():
    """One motor winding a cable against a known spring (a held bar: ``tau = r k (Q'(u) / k)``,
    the cables' law of u alone). Gauss-Newton pulls the keyframes towards a gait that winds too
    fast under load, with the line linearised at every iterate from the rollouts' sensitivities;
    it ends where an independent solver (SLSQP on the closed-form conditions) ends, on the line."""
    k_c, r, stall = 2000.0, 0.005, 0.39
    robot = _spring_robot(k_c, max_torque=0.15)
    env = SoftRobotEnv(robot, reset_noise_scale=0.0)
    env.reset(seed=0)
    gait = GaitSpec(n_prep=4, n_cycle=8, n_cycles=2, n_keyframes=4, interpolation="linear", symmetry=False)
    param = GaitParameterization.for_robot(robot, gait)
    law = MotorLaw.of_robot(robot)
    line = MotorLine(param, law, env.timestep)
    target = np.array([0.004, 0.013, 0.005, 0.014])            # winds 9 mm in two steps under ~0.1 N m
    last = {}

    def fun(z, need_jac=True):
        traj = _rollout(env, param, z, need_jac)
        if not need_jac and line.worst(z, traj.cable_deformation).excess > LINE_TOLERANCE:
            raise SimulationError("outside the line")
        last["traj"] = traj
        return z - target, np.eye(len(z)), {}

    def linearise(z):
        return line.linearised(z, last["traj"].cable_deformation, last["traj"].dgammadz)

    lo, hi = param.bounds()
    z0 = np.full(4, 0.004)
    res = gauss_newton(fun, z0, lo, hi, GaussNewtonOptions(max_iter=40, ftol=0.0, xtol=1e-9), constraints=linearise)

    eps = robot.cable_blend
    s = law.no_load_speed[0] * env.timestep

    def conditions(z):            # closed form: Gamma = u (the cable just taut at rest), tau = r Q'(u)
        u = np.concatenate([[0.0], param.controls(z)[:, 0]])
        tension = np.where(u >= eps, k_c * (u - eps / 2), np.where(u > 0, k_c * u ** 2 / (2 * eps), 0.0))
        tau, du = r * tension, np.diff(u)
        return np.concatenate([1 - du / s - tau[:-1] / stall, 1 - du / s - tau[1:] / stall, 1 - tau[1:] / 0.15])

    mm = 1e3                                       # SLSQP in millimetres (its tolerances are absolute)
    ref = minimize(lambda y: 0.5 * np.sum((y - mm * target) ** 2), mm * z0, jac=lambda y: y - mm * target,
                   method="SLSQP", bounds=list(zip(mm * lo, mm * hi)),
                   constraints=[{"type": "ineq", "fun": lambda y: conditions(y / mm)}],
                   options={"ftol": 1e-12, "maxiter": 500})
    assert ref.success, ref.message
    assert res.z == pytest.approx(ref.x / mm, abs=2e-7)
    assert conditions(res.z).min() == pytest.approx(0.0, abs=1e-4)            # on the line
    assert np.abs(res.z - target).max() > 1e-3                                # which binds


@pytest.mark.parametrize("task, contact", [("walk", "paper"), ("walk", "coulomb"), ("turn", None),
                                           ("incline", None)])
def test_every_optimised_result_obeys_the_line(task, contact):
    """Quick optimisations of every task under both laws: the result's rollout obeys the line
    and the torque limit at every played step within 1 %, and records its model and load."""
    env = make_gradient_env("tripod", contact=contact, incline_deg=10.0 if task == "incline" else 0.0)
    gait = QUICK.replace(n_keyframes=8) if task == "turn" else QUICK
    res = optimize_gait(env, task, gait=gait, speed_bl_per_min=20.0, options=GaussNewtonOptions(max_iter=2),
                        n_seeds=1, eval_cycles=1)
    assert res.settings["motor_model"] == "torque-speed"
    assert res.settings["motor_line"]["stall_torque_nm"] == [0.39, 0.39]
    param = GaitParameterization.for_robot(env.robot, GaitSpec.from_settings(res.settings))
    line = MotorLine(param, MotorLaw.of_robot(env.robot), env.timestep)
    traj = env.rollout(res.u)
    assert line.worst(res.z, traj.cable_deformation).excess <= LINE_TOLERANCE
    load = res.evaluation["motor_load"]
    tau = line.law.torque(traj.cable_deformation)     # a new rollout: equal to the Newton tolerance (1e-6 m per
    tol = 1e-8 if env.substeps == 1 else SUBSTEP_TOLERANCE     # physics step) x 1e5 N/m x 5 mm, x 40 at a foot's
    assert np.abs(np.array(load["torque_nm"]) - tau).max() < 200 * tol    # stick-slip (measured: 8e-5 at 1e-6)
    assert max(load["worst_line_excess"]) <= LINE_TOLERANCE


def test_the_environment_replays_an_optimised_gait_at_the_speed_trajopt_reports():
    """A quick Tripod gait made under the line, played by stepping an environment with
    ``motor_model="torque-speed"`` (its actions the gait's contractions): the motors keep up,
    and the measured speed is the optimiser's within 1 %."""
    env = make_gradient_env("tripod")
    res = optimize_gait(env, "walk", gait=QUICK, speed_bl_per_min=20.0, options=GaussNewtonOptions(max_iter=3),
                        n_seeds=1, eval_cycles=3)
    param = GaitParameterization.for_robot(env.robot, QUICK)
    u = param.controls(res.z, 3)
    play = SoftRobotEnv("tripod", motor_model="torque-speed", reset_noise_scale=0.0)
    play.reset(seed=0)
    xs, coms, held = [play.unwrapped._x.copy()], [play.com()], 0
    for row in u:
        _, _, _, _, info = play.step(play.control_to_action(row))
        xs.append(play.unwrapped._x.copy())
        coms.append(play.com())
        held += int(info["motor_limited"].sum())

    class Played:
        x, com = np.array(xs), np.array(coms)

    speed = measure_gait(Played, env, n_prep=QUICK.n_prep, n_cycle=QUICK.n_cycle)["speed_bl_per_min"]
    assert speed == pytest.approx(res.evaluation["speed_bl_per_min"], rel=0.01)
    assert abs(res.evaluation["speed_bl_per_min"]) > 1.0
    assert max(res.evaluation["motor_load"]["worst_line_excess"]) > -0.01, "the line never binds: no test"
