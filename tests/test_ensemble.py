"""A gait optimised on an ensemble of physics (:mod:`trajopt.optim.ensemble`): the default
physics and 2x finer steps, their residuals stacked.

Finite differences: Newton tolerance 1e-12 m per physics step in every member, central
differences of the ensemble's residual along random directions of z (perturbations of 3e-7 m of
keyframe: larger ones meet the kinks of the cables' C2 blend, see tests/test_motor_torque.py);
required relative error <= 1e-6 (measured 5e-8 - 6e-7).
"""
from __future__ import annotations

import numpy as np
import pytest

from soft_envs.envs import make_gradient_env
from soft_envs.sim import NewtonOptions
from trajopt import GaitSpec, optimize_gait
from trajopt.evaluation import evaluate_controls
from trajopt.optim.ensemble import EnsembleProblem, credible_speed, member_env
from trajopt.optim.gauss_newton import GaussNewtonOptions
from trajopt.optim.motor_limit import max_step_of_env
from trajopt.optim.objectives import ObjectiveWeights
from trajopt.optim.optimize import build_problem
from trajopt.replay import result_controls

from .gradcheck import relative_error

GAIT = GaitSpec(n_prep=4, n_cycle=8, n_cycles=2, n_keyframes=4, interpolation="linear")
TIGHT = NewtonOptions(tol=1e-12)


def _ensemble(counts=(8,)):
    env = make_gradient_env("tripod", contact="coulomb")
    envs = [env] + [member_env(env, n) for n in counts]
    members = []
    for e in envs:
        e.simulator.newton.options = TIGHT
        members.append(build_problem(e, "walk", GAIT, speed_bl_per_min=20.0, heading_deg=0.0, turn="right",
                                     target=None, weights=ObjectiveWeights.for_task("walk"),
                                     max_step=max_step_of_env(env), motor_model="torque-speed"))
    return EnsembleProblem(members), members


def test_member_env_is_the_same_physics_with_finer_steps():
    env = make_gradient_env("puppy", incline_deg=10.0, heading_deg=90.0, contact="coulomb")
    fine = member_env(env, 8)
    assert fine.substeps == 2 * env.substeps == 8 and fine.timestep == env.timestep
    assert fine.incline_deg == 10.0 and np.allclose(fine._heading, env._heading, atol=1e-15)
    assert fine.contact_model == env.contact_model and fine.motor_model == env.motor_model
    assert fine.robot is env.robot


def test_the_ensemble_stacks_its_members_and_its_jacobian_matches_central_differences():
    ens, members = _ensemble()
    rng = np.random.default_rng(3)
    lo, hi = ens.param.bounds()
    z = lo + (hi - lo) * rng.uniform(0.2, 0.6, ens.param.nz)
    r, J, info = ens(z, True)
    parts = [m.evaluate(z, True) for m in members]
    np.testing.assert_allclose(r, np.concatenate([p[0] for p in parts]) / np.sqrt(2), rtol=1e-15, atol=0)
    np.testing.assert_allclose(J, np.vstack([p[1] for p in parts]) / np.sqrt(2), rtol=1e-15, atol=0)
    assert 0.5 * r @ r == pytest.approx(np.mean([0.5 * p[0] @ p[0] for p in parts]), rel=1e-12)
    assert not np.allclose(parts[0][0], parts[1][0])            # two physics, two residuals
    h, errs = 3e-7, []
    for _ in range(2):
        d = rng.normal(size=ens.param.nz)
        d /= np.linalg.norm(d)
        fd = (ens.evaluate(z + h * d, False, check=False)[0] - ens.evaluate(z - h * d, False, check=False)[0]) / (2 * h)
        errs.append(relative_error(J @ d, fd))
    assert max(errs) <= 1e-6, errs


def test_a_trial_is_stopped_by_the_mean_objective_and_steps_count_in_default_physics():
    """A bound on the mean objective stops the second member's rollout once the first member
    and it make the mean exceed it; a member with 2x finer steps counts 2 steps per control
    step; the line's rows of every member are linearised (two members: twice the rows)."""
    from soft_envs.envs import RolloutStopped
    ens, members = _ensemble()
    z = np.clip(ens.param.initial_z(0.5), *ens.param.bounds())
    before = ens.sim_steps
    r, _, _ = ens.evaluate(z, False, check=False)
    K = ens.param.n_steps()
    assert ens.sim_steps - before == K + 2 * K
    f = 0.5 * float(r @ r)
    r0 = members[0].evaluate(z, False, check=False)[0]
    f0 = 0.5 * float(r0 @ r0)
    with pytest.raises(RolloutStopped):
        ens.evaluate(z, False, check=False, bound=0.5 * (f + f0 / 2))     # exceeded only once member 2 adds
    ens(z, True)
    one = members[0].linearised_constraints(z)
    both = ens.linearised_constraints(z)
    assert len(both.h) == len(one.h) + len(members[1].line.linearised(
        z, members[1].last_traj.cable_deformation, members[1].last_traj.dgammadz).h)


def test_optimize_gait_on_an_ensemble_records_every_member_and_the_credible_speed():
    res = optimize_gait("tripod", gait=GAIT, speed_bl_per_min=20.0, options=GaussNewtonOptions(max_iter=1),
                        n_seeds=0, eval_cycles=2, ensemble=(8, 4))
    ev = res.evaluation
    assert res.settings["ensemble"] == [4, 8]
    assert [m["substeps"] for m in ev["ensemble"]] == [4, 8]
    env = make_gradient_env("tripod", contact="coulomb")
    u, n_prep, n_cycle = result_controls(res, env.robot, 2)
    fine = evaluate_controls(member_env(env, 8), u, n_prep=n_prep, n_cycle=n_cycle)
    assert ev["ensemble"][1]["speed_bl_per_min"] == pytest.approx(fine["speed_bl_per_min"], rel=1e-6)
    assert ev["ensemble"][0]["speed_bl_per_min"] == ev["speed_bl_per_min"]
    assert ev["credible_bl_per_min"] == min(m["speed_bl_per_min"] for m in ev["ensemble"])
    assert credible_speed([{"speed_bl_per_min": 3.0, "upright": True}, {"speed_bl_per_min": 5.0, "upright": False}]) \
        != credible_speed([{"speed_bl_per_min": 3.0, "upright": True}])
    for bad in (0, 2.5, -4):
        with pytest.raises(ValueError, match="ensemble"):
            optimize_gait("tripod", gait=GAIT, options=GaussNewtonOptions(max_iter=1), n_seeds=0, ensemble=(bad,))
