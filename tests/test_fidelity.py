"""The converged default physics (docs/fidelity.md): which physics each id and each law runs,
results that record theirs, ``trajopt evaluate --fidelity``, and closed forms the default
integration matches."""
from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import soft_envs  # noqa: F401  (registers the ids)
from soft_envs.envs import make_gradient_env
from soft_envs.sim import Simulator, incline_gravity
from soft_envs.sim.contact import CONTACT_LAWS
from soft_envs.sim.substeps import SUBSTEP_TOLERANCE
from trajopt import GaitSpec, optimize_gait
from trajopt.cli import main
from trajopt.fidelity import fidelity
from trajopt.results import Result

from .test_coulomb import G, slide_along_slope, soft_cube

SHORT = GaitSpec(n_prep=4, n_cycle=8, n_cycles=2, n_keyframes=4, symmetry=False, interpolation="linear")


@pytest.mark.parametrize("env_id, contact, substeps", [
    ("SoftTripod-v0", "paper", 1), ("SoftTripod-v1", "coulomb", 1), ("SoftTripod-v2", "coulomb", 4),
    ("SoftPuppy-v2", "coulomb", 4)])
def test_each_id_runs_its_physics(env_id, contact, substeps):
    env = gym.make(env_id).unwrapped
    assert (env.contact_model, env.substeps) == (contact, substeps)
    assert env.simulator.physics_dt == pytest.approx(0.033 / substeps) and env.timestep == 0.033


def test_each_law_defaults_to_its_own_physics():
    """The paper's law keeps the paper's integration (Table I, bit for bit: one step of 33 ms);
    the Coulomb law gets 4 physics steps per control step, also as the paper's law's sibling on -v2."""
    assert CONTACT_LAWS["paper"].default_substeps == 1 and CONTACT_LAWS["coulomb"].default_substeps == 4
    assert make_gradient_env("tripod", contact="paper").substeps == 1
    assert make_gradient_env("tripod").substeps == 4
    assert gym.make("SoftTripod-v2", contact="paper").unwrapped.substeps == 1
    assert gym.make("SoftTripod-v2", substeps=2).unwrapped.substeps == 2
    with pytest.raises(ValueError, match="substeps"):
        gym.make("SoftTripod-v2", substeps=0)


def test_the_paper_law_under_v0_is_the_single_step_simulator_bit_for_bit():
    env = gym.make("SoftTripod-v0", reset_noise_scale=0.0).unwrapped
    env.reset(seed=0)
    robot = env.robot
    u = np.linspace(0.0, 0.01, 30)[:, None] * np.ones(robot.n_motors)
    sim = Simulator(robot, dt=0.033)
    ref = sim.rollout(u, x0=sim.rest_state(robot.u_rest))
    assert np.array_equal(env.rollout(u).x, ref.x)


def test_env_steps_follow_the_rollout_through_substeps():
    """Stepping the -v2 environment (4 physics steps a control step) is its rollout of the
    applied controls, and the observed velocity is over the last physics step."""
    env = gym.make("SoftTripod-v2", reset_noise_scale=0.0).unwrapped
    env.reset(seed=0)
    rng = np.random.default_rng(1)
    us, obs = [], None
    for _ in range(6):
        obs, _, _, _, info = env.step(rng.uniform(-1, 1, size=2))
        us.append(info["u"])
    traj = env.rollout(np.array(us))
    assert np.abs(traj.x[-1] - env.get_state()["x"]).max() < 3 * SUBSTEP_TOLERANCE    # the Newton tolerance
    com_prev = env.robot.com(env.get_state()["x_prev"])
    assert np.allclose(obs[3:6], (env.com() - com_prev) / (0.033 / 4))


def test_results_record_their_physics_and_fidelity_replays_finer(tmp_path, capsys):
    env = make_gradient_env("tripod")
    res = optimize_gait(env, "walk", gait=SHORT, n_seeds=1, eval_cycles=2, robot_spec="tripod",
                        options=__import__("trajopt").GaussNewtonOptions(max_iter=1))
    assert res.settings["substeps"] == 4 and res.settings["contact"] == "coulomb"
    path = res.save(tmp_path / "walk.npz")
    fid = fidelity(Result.load(path), factors=(0.5, 2))                # 16.5 ms (coarser) and 4.125 ms
    assert [r["substeps"] for r in fid["rows"]] == [4, 2, 8]
    assert [r["physics_dt_ms"] for r in fid["rows"]] == pytest.approx([8.25, 16.5, 4.125])
    assert fid["rows"][0]["speed_bl_per_min"] == pytest.approx(res.evaluation["speed_bl_per_min"], abs=1e-9)
    s = [r["speed_bl_per_min"] for r in fid["rows"]]
    assert fid["spread"] == pytest.approx((max(s) - min(s)) / abs(s[0]))
    with pytest.raises(ValueError, match="a factor of 0.3 on 4 physics step"):
        fidelity(Result.load(path), factors=(0.3,))
    assert main(["evaluate", str(path), "--fidelity"]) in (0, 1)
    out = capsys.readouterr().out
    assert "the same controls at finer physics steps" in out and "8.250 ms (its own)" in out
    for ms in ("4.125 ms", "2.062 ms", "1.031 ms"):
        assert ms in out
    assert "spread" in out


def test_a_result_made_before_substeps_replays_with_one():
    from trajopt.replay import result_substeps
    res = Result(robot="tripod", task="walk", motor_names=["front", "back"], dt=0.033, z=np.zeros(1),
                 u=np.zeros((4, 2)), u_post=np.zeros((4, 2)), target=np.zeros((5, 2)), com=np.zeros((5, 3)),
                 settings={"contact": "coulomb"})
    assert result_substeps(res) == 1


def test_a_block_slides_down_a_slope_as_coulomb_says_at_the_default_physics():
    """Released on a 35-degree slope with mu = 0.5 it slides with g (sin a - mu cos a): at the
    default physics (4 steps a control step) the distance after 1.5 s is within 3 % of
    a t^2 / 2 counted from the end of the bristles' loading (the fit's acceleration)."""
    a_deg, mu = 35.0, 0.5
    robot = soft_cube(mu)
    sim = Simulator(robot, gravity=incline_gravity(a_deg, uphill=(-1.0, 0.0)),
                    substeps=CONTACT_LAWS["coulomb"].default_substeps)
    t, s = slide_along_slope(sim, 1.5, released=True)
    expected = G * (math.sin(math.radians(a_deg)) - mu * math.cos(math.radians(a_deg)))
    late = t >= 0.3
    acc = 2.0 * np.polyfit(t[late], s[late], 2)[0]
    assert abs(acc - expected) <= 0.03 * expected, (acc, expected)


def _apex_oscillator():
    """One tetrahedron, three nodes clamped, the apex free, no gravity: a 3-DOF linear oscillator
    for small amplitudes, its softest mode at 25 rad/s (4 Hz: the fastest gaits' stride rate)."""
    import meshio
    from soft_envs.sim import Robot
    p = np.array([[0, 10, 0], [0.02, 10, 0], [0, 10, 0.02], [0.007, 10.02, 0.007]], float)   # far above the ground
    robot = Robot.from_mesh(meshio.Mesh(p, [("tetra", np.array([[0, 2, 1, 3]]))]), youngs_modulus=1e3,
                            poisson_ratio=0.3, density=6150.0, fixed_nodes=[0, 1, 2])
    H = Simulator(robot, gravity=(0, 0, 0)).hessian(p, p, np.zeros(0)).toarray()[9:12, 9:12]
    lam, V = np.linalg.eigh(H)
    return robot, p, math.sqrt(lam[0] / robot.node_masses[3]), V[:, 0]


@pytest.mark.parametrize("substeps", [4, 1])
def test_an_oscillator_at_the_stride_rate_against_its_closed_forms(substeps):
    """The body's own vibrations are undamped in the model; implicit Euler damps them (docs/
    fidelity.md). An oscillator at the fastest gaits' stride rate (omega = 25 rad/s), released
    from 10 um: at the default physics (4 steps of 8.25 ms per control step) its period is within
    3 % of the closed form 2 pi / omega (at one step of 33 ms it is 19 % long), and at either step
    its damped motion is implicit Euler's closed form: per step, the amplitude times
    (1 + (omega h)^2)^(-1/2) and the phase advanced by atan(omega h), within 3 %."""
    robot, p, w, v = _apex_oscillator()
    assert w == pytest.approx(25.0, rel=0.02)
    sim = Simulator(robot, gravity=(0, 0, 0), substeps=substeps)
    x0 = p.copy()
    x0[3] += 1e-5 * v
    traj = sim.rollout(np.zeros((60, 0)), x0=sim.state_at_rest(x0), keep_substeps=True)
    q = (traj.info["substep_x"][:, 3] - p[3]) @ v
    h = sim.physics_dt
    t = np.arange(len(q)) * h
    down = [t[i] - q[i] * h / (q[i + 1] - q[i]) for i in range(len(q) - 1) if q[i] > 0 >= q[i + 1]]
    period = float(np.diff(down).mean())
    assert period == pytest.approx(2 * math.pi * h / math.atan(w * h), rel=0.03)      # implicit Euler's phase
    if substeps == 4:
        assert period == pytest.approx(2 * math.pi / w, rel=0.03)                    # the physical period
    else:
        assert period > 1.15 * 2 * math.pi / w
    peaks = [i for i in range(1, len(q) - 1) if q[i] > q[i - 1] and q[i] >= q[i + 1]]
    i0, i1 = peaks[0], peaks[1]
    assert q[i1] / q[i0] == pytest.approx((1 + (w * h) ** 2) ** (-(i1 - i0) / 2), rel=0.03)
