"""Implicit Euler dynamics: free fall, energy decay without contact, rest on the ground,
failure handling."""
from __future__ import annotations

import numpy as np
import pytest

from soft_envs.sim import NewtonOptions, SimulationError, Simulator, State

from .conftest import small_robot


def test_free_fall_matches_discrete_solution():
    """With no contact, a body falls rigidly: x_k = x_0 + h^2 g k (k + 1) / 2 exactly."""
    robot = small_robot(tendons=[], motors=[])
    sim = Simulator(robot, dt=0.02, newton=NewtonOptions(tol=1e-12))
    x0 = np.array(robot.mesh.points)
    x0[:, 1] += 1.0                       # high above the ground
    traj = sim.rollout(np.zeros((20, 0)), x0=x0)
    k = np.arange(21)
    expected = x0[None, :, 1] - 9.81 * 0.02**2 * (k * (k + 1) / 2)[:, None]
    assert np.abs(traj.x[:, :, 1] - expected).max() < 1e-10
    assert np.abs(traj.x[:, :, [0, 2]] - x0[None, :, [0, 2]]).max() < 1e-12


def total_energy(sim, traj):
    m = sim.system.mass
    out = []
    for k in range(1, len(traj.x)):
        v = (traj.x[k] - traj.x[k - 1]).ravel() / sim.dt
        out.append(0.5 * v @ (m * v) + sim.energy(traj.x[k], traj.x[k - 1], np.zeros(sim.n_motors)))
    return np.array(out)


def test_energy_never_increases_without_contact():
    """Implicit Euler dissipates: kinetic + elastic + gravitational energy is non-increasing for
    a released, pre-stretched body in free flight."""
    robot = small_robot(tendons=[], motors=[])
    sim = Simulator(robot, dt=0.01, newton=NewtonOptions(tol=1e-12))
    X = np.array(robot.mesh.points)
    x0 = X * np.array([1.15, 0.9, 1.0]) + np.array([0, 1.0, 0])     # stretched, in the air
    traj = sim.rollout(np.zeros((60, 0)), x0=x0)
    e = total_energy(sim, traj)
    assert (np.diff(e) <= 1e-12 * np.abs(e).max()).all()
    assert e[-1] < e[0]


def test_block_resting_on_ground_stays_at_rest():
    robot = small_robot(tendons=[], motors=[])
    sim = Simulator(robot)
    x0 = sim.rest_positions()
    assert x0[:, 1].min() < 0 < x0[:, 1].max()       # it sinks slightly into the penalty layer
    traj = sim.rollout(np.zeros((100, 0)), x0=x0)
    assert np.abs(traj.x - x0).max() < 1e-7
    # the ground carries the weight
    N = sim.system.contact.normal_forces(x0)
    assert np.isclose(N.sum(), robot.total_mass * 9.81, rtol=1e-6)


def test_failed_step_raises_and_leaves_inputs_untouched():
    robot = small_robot()
    sim = Simulator(robot, newton=NewtonOptions(max_iter=1, tol=1e-14))
    x0 = sim.rest_positions()
    before = x0.copy()
    with pytest.raises(SimulationError) as err:
        sim.rollout(np.full((3, 1), 0.008), x0=x0)
    assert err.value.step == 0 and "converge" in err.value.reason
    assert np.array_equal(x0, before)


def test_inverted_input_state_raises():
    robot = small_robot()
    sim = Simulator(robot)
    x = np.array(robot.mesh.points)
    x[robot.mesh.tets[0, 3]] = x[robot.mesh.tets[0, 0]] - 0.05       # turns elements inside out
    with pytest.raises(SimulationError, match="inverted") as err:
        sim.step(sim.state_at_rest(x).replace(k=4), np.zeros(1))
    assert err.value.step == 4


def test_bad_controls_and_states_are_rejected():
    sim = Simulator(small_robot())
    x0 = sim.rest_positions()
    with pytest.raises(ValueError, match="NaN"):
        sim.rollout(np.array([[np.nan]]), x0=x0)
    with pytest.raises(ValueError, match=r"shape \(K, 1\)"):
        sim.rollout(np.zeros((3, 2)), x0=x0)
    with pytest.raises(ValueError, match="x0 must have shape"):
        sim.rollout(np.zeros((3, 1)), x0=x0[:5])
    tsim = Simulator(small_robot(), control="tension")
    with pytest.raises(ValueError, match=">= 0"):
        tsim.rollout(-np.ones((2, 1)), x0=x0)


def test_cable_contraction_bends_and_tension_control():
    """Contracting the top tendon arches the bar (ends lift relative to the middle); in
    tension mode a prescribed tension produces the same kind of motion; tension read-out is
    Q'(Gamma)."""
    robot = small_robot()
    for control, u in (("length", 0.004), ("tension", 20.0)):
        sim = Simulator(robot, control=control)
        x0 = sim.rest_positions()
        traj = sim.rollout(np.full((30, 1), u), x0=x0)
        gam = traj.cable_deformation[-1]
        tens = sim.cable_tension(traj.x[-1], np.array([u]))
        if control == "length":
            assert gam[0] > 0 and tens[0] > 1.0
        else:
            assert np.isclose(tens[0], u)
        # the tendon runs along the top: contraction shortens the top fibre
        top = robot.mesh.points[:, 1] > 0.019
        span0 = np.ptp(x0[top, 0])
        assert np.ptp(traj.x[-1][top, 0]) < span0 - 1e-4


def test_lu_fallback_solver_matches_cholmod_and_reports_indefinite():
    """The SuperLU path gives the same rollout and, like Cholesky, refuses indefinite matrices
    (so the projected-Hessian fallback is used), while accepting them when asked to."""
    import scipy.sparse as sp
    from soft_envs.sim.linsolve import LUSolver
    robot = small_robot()
    u = np.linspace(0, 0.006, 25)[:, None]
    ref = Simulator(robot, newton=NewtonOptions(solver="cholmod", tol=1e-11))
    lu = Simulator(robot, newton=NewtonOptions(solver="lu", tol=1e-11))
    x0 = ref.rest_positions()
    assert np.abs(ref.rollout(u, x0=x0).x - lu.rollout(u, x0=x0).x).max() < 1e-9
    pat = lu.system.pattern
    data = np.zeros(pat.nnz + 1)
    data[pat.diag] = 1.0
    data[pat.diag[0]] = -1.0                  # one negative eigenvalue
    solver = LUSolver(pat)
    assert not solver.factorize(data)
    assert solver.factorize(data, require_pd=False)
    assert np.allclose(sp.diags(data[pat.diag]) @ solver.solve(np.ones(pat.n)), np.ones(pat.n))


def test_newton_options_are_validated():
    with pytest.raises(ValueError, match="max_iter"):
        NewtonOptions(max_iter=0)
    with pytest.raises(ValueError, match="tol"):
        NewtonOptions(tol=-1.0)
    with pytest.raises(ValueError, match="solver"):
        NewtonOptions(solver="qr")


@pytest.mark.parametrize("name", ["tripod", "puppy"])
def test_newton_error_estimate_holds_along_a_gait(name):
    """The step's stopping rule keeps the error of x_k below tol: against a reference solved to
    1e-14 from the same inputs, every step of a gait is within tol (measured: at most 0.7 tol,
    median 0.03 tol), with or without the x_{k-3} extrapolation."""
    import dataclasses

    from soft_envs.sim import load_robot
    robot = load_robot(name)
    robot = robot.replace(contact=dataclasses.replace(robot.contact, model="paper"))   # no history to carry
    sim = Simulator(robot)
    ref = Simulator(robot, newton=NewtonOptions(tol=1e-14, reuse_factor=False))
    x0 = sim.rest_positions()
    t = np.arange(40) * 0.033
    u = 0.5 * robot.u_bounds[:, 1] * (1 - np.cos(2 * np.pi * t[:, None] / 1.2 + np.arange(robot.n_motors)))
    traj = sim.rollout(u, x0=x0)
    tol = sim.newton.options.tol
    worst = 0.0
    none = (None,) * len(sim.system.terms)           # the paper's law keeps no history
    for k in range(2, 40):
        xr = ref.step(State(traj.x[k], traj.x[k - 1], None, none), u[k]).x
        worst = max(worst, np.abs(sim.step(State(traj.x[k], traj.x[k - 1], traj.x[k - 2], none), u[k]).x - xr).max(),
                    np.abs(sim.step(State(traj.x[k], traj.x[k - 1], None, none), u[k]).x - xr).max())
    assert worst <= tol, worst
    with pytest.raises(ValueError, match="x_prev2"):
        sim.step(State(traj.x[3], traj.x[2], np.zeros((2, 3)), none), u[3])


def test_newton_options_extrapolation_is_validated():
    with pytest.raises(ValueError, match="extrapolation"):
        NewtonOptions(extrapolation=3)
    with pytest.raises(ValueError, match="refactor_ratio"):
        NewtonOptions(refactor_ratio=1.5)


def test_slow_chord_settings_still_stop():
    """With refactor_ratio > 1/2 a chord step below tol can contract by more than 1/2 (too
    slowly for the stopping rule to certify it): the solver must refresh, not loop until
    max_iter (it did at step 6 of this gait with refactor_ratio 0.85, max_chord 16). The
    states stay within the tolerance of the default solver's."""
    from soft_envs.sim import load_robot
    robot = load_robot("tripod")
    sim = Simulator(robot)
    slow = Simulator(robot, newton=NewtonOptions(refactor_ratio=0.85, max_chord=16.0))
    x0 = sim.rest_positions()
    t = np.arange(30) * 0.033
    u = 0.5 * robot.u_bounds[:, 1] * (1 - np.cos(2 * np.pi * t[:, None] / 2.4 + np.pi * np.arange(robot.n_motors)))
    a, b = sim.rollout(u, x0=x0), slow.rollout(u, x0=x0)
    assert np.abs(a.x - b.x).max() < 1e-6


def test_controls_outside_the_motor_range_are_refused_with_the_motor_named():
    """A unit slip (mm for m) must not be simulated silently; finite differences across a bound
    opt out with check_bounds=False. NaN in dudz is refused too."""
    robot = small_robot()
    sim = Simulator(robot)
    x0 = sim.rest_positions()
    u = np.full((3, 1), 0.004)
    u[1, 0] = 4.0                                   # 4 "mm" given in metres
    with pytest.raises(ValueError, match=r"u\[1, 0\] = 4\.0 m lie outside motor 'm0'"):
        sim.rollout(u, x0=x0)
    ok = sim.rollout(np.full((3, 1), -1e-9), x0=x0, check_bounds=False)
    assert ok.x.shape == (4, robot.mesh.n_nodes, 3)
    dudz = np.ones((3, 1, 2))
    dudz[2, 0, 1] = np.nan
    with pytest.raises(ValueError, match="dudz contains NaN"):
        sim.rollout(np.full((3, 1), 0.004), x0=x0, dudz=dudz)


def test_steps_depend_on_their_inputs_only():
    """No hidden solver state: the same step gives the same state whatever was simulated before,
    and two rollouts interleaved step by step on one simulator (each with its own FactorCache)
    reproduce their separate runs exactly."""
    from soft_envs.sim import FactorCache
    robot = small_robot()
    sim = Simulator(robot)
    x0 = sim.rest_positions()
    ua, ub = np.full((12, 1), 0.006), np.linspace(0.0, 0.009, 12)[:, None]
    ta, tb = sim.rollout(ua, x0=x0), sim.rollout(ub, x0=x0)
    mid = State(ta.x[5], ta.x[4], None, sim.initial_history(ta.x[5]))
    first = sim.step(mid, ua[5]).x
    sim.rollout(ub, x0=x0)                            # something else in between
    assert np.array_equal(sim.step(mid, ua[5]).x, first)
    ca, cb = FactorCache(), FactorCache()
    sa = sb = sim.state_at_rest(x0).replace(x_prev2=None)
    xa, xb = [x0, x0], [x0, x0]
    for k in range(12):
        sa = sim.step(sa, ua[k], factor_cache=ca)
        sb = sim.step(sb, ub[k], factor_cache=cb)
        xa.append(sa.x)
        xb.append(sb.x)
        assert cb.holds(sim.newton.solver) and not ca.holds(sim.newton.solver)
    # the caches never reuse each other's factorisations: both match a fresh-per-step run to
    # within the Newton tolerance (a reused factorisation changes results only at that level)
    tol = sim.newton.options.tol
    assert np.abs(np.array(xa[1:]) - ta.x).max() < 10 * tol
    assert np.abs(np.array(xb[1:]) - tb.x).max() < 10 * tol
