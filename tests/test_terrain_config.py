"""Ground that is not flat, from the user's side: ``robot.toml``'s ``[ground]`` table (every bad
value a ValueError naming the file and the field), the environments' ``ground=`` keyword, the
initial placement on a field, and a block resting on a step edge."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from soft_envs.envs.factory import make_gradient_env
from soft_envs.sim import HeightField, Robot, Simulator, load_robot

from .conftest import block_mesh


def _with_ground(robot_dir, table: str):
    path = robot_dir / "robot.toml"
    path.write_text(path.read_text() + "\n[ground]\n" + table)
    return path


def test_ground_table_builds_the_field(robot_dir):
    path = _with_ground(robot_dir, 'type = "rough"\namplitude = 0.002\nwavelength = 0.05\nseed = 3\n')
    robot = load_robot(path)
    assert isinstance(robot.ground, HeightField)
    expected = HeightField.rough(0.002, 0.05, seed=3)
    assert np.array_equal(robot.ground.heights, expected.heights)
    assert load_robot("tripod").ground is None                         # no table: the plane
    sim = Simulator(robot)
    assert type(sim.system.contact).__name__ == "CoulombFieldContact"
    x = sim.initial_placement()                                          # the lowest node touches the field
    assert abs((x[:, 1] - robot.ground.height(x[:, 0], x[:, 2])).min()) < 1e-15


@pytest.mark.parametrize("table,field", [
    ('type = "lava"\n', "[ground].type"),
    ('amplitude = 0.002\n', "[ground].type"),
    ('type = "rough"\namplitude = -0.002\nwavelength = 0.05\n', "[ground].amplitude"),
    ('type = "rough"\namplitude = 0.002\nwavelength = 0\n', "[ground].wavelength"),
    ('type = "rough"\namplitude = 0.002\nwavelength = 0.05\nseed = 1.5\n', "[ground].seed"),
    ('type = "rough"\namplitude = 0.002\nwavelength = 0.05\nheight = 1\n', "[ground].height"),
    ('type = "rough"\nwavelength = 0.05\n', "[ground].amplitude is missing"),
    ('type = "step"\nheight = "high"\nposition = 0.1\n', "[ground].height"),
    ('type = "step"\nheight = 0.01\nposition = 0.1\nwidth = -1\n', "[ground].width"),
    ('type = "incline"\nangle_deg = 85\n', "[ground].angle_deg"),
    ('type = "incline"\nangle_deg = 10\nuphill = [0, 0]\n', "[ground].uphill"),
    ('type = "incline"\nangle_deg = 10\nuphill = [1]\n', "[ground].uphill"),
    ('type = "trench"\ndepth = 0.01\nstart = 0.2\nlength = 0\n', "[ground].length"),
    ('type = "grid"\nheights = [[0.0, 0.1], [0.2]]\nspacing = [0.01, 0.01]\n', "[ground].heights"),
    ('type = "grid"\nheights = [[0.0, 0.1]]\nspacing = [0.01, 0.0]\n', "[ground].spacing"),
    ('type = "grid"\nspacing = [0.01, 0.01]\n', "[ground].heights"),
    ('type = "flat"\nheight = nan\n', "[ground].height"),
])
def test_bad_ground_table_names_file_and_field(robot_dir, table, field):
    path = _with_ground(robot_dir, table)
    with pytest.raises(ValueError) as info:
        load_robot(path)
    assert str(info.value).startswith(str(path)) and field in str(info.value), str(info.value)


def test_grid_table_and_robot_field_checks(robot_dir):
    path = _with_ground(robot_dir, 'type = "grid"\nheights = [[0.0, 0.01], [0.02, 0.03]]\n'
                                   'origin = [0.0, 0.0]\nspacing = [0.1, 0.1]\nslope = [0.1, 0.0]\n')
    ground = load_robot(path).ground
    assert ground.height(0.1, 0.1) == pytest.approx(0.03 + 0.01, abs=1e-12)
    with pytest.raises(ValueError, match="ground must be a HeightField"):
        load_robot("tripod").replace(ground="bumpy")


def test_environment_ground_keyword():
    step = HeightField.step(0.004, position=0.3)
    env = make_gradient_env("tripod", ground=step)
    assert env.unwrapped._sim.robot.ground is step
    obs, *_ = env.step(np.zeros(env.action_space.shape))
    assert np.isfinite(obs).all()
    assert make_gradient_env("tripod")._sim.robot.ground is None


@pytest.mark.parametrize("model", ["coulomb", "paper"])
def test_block_on_a_step_edge(model):
    """A 6 cm block (nodes every 5 mm) with its centre 1 cm beyond a 5 mm step up (smoothed over
    4 mm): it rests on the upper level with its end over the edge. The Coulomb law holds it
    still (it has a rest state there); the paper's viscous-like friction cannot hold the edge's
    horizontal push, so it only creeps (bounded, finite, above the ground)."""
    step = HeightField.step(0.005, position=0.02, width=0.004)
    robot = Robot.from_mesh(block_mesh(12, 2, 2), youngs_modulus=1e5, poisson_ratio=0.3, density=100.0,
                            contact={"model": model}, ground=step)
    sim = Simulator(robot)
    start = sim.rest_state() if model == "coulomb" else sim.state_at_rest(sim.initial_placement())
    traj = sim.rollout(np.zeros((60, 0)), x0=start)
    assert np.isfinite(traj.x).all()
    gap = traj.x[..., 1] - step.height(traj.x[..., 0], traj.x[..., 2])
    assert gap.min() > -2e-4                                            # 0.2 mm into it at most
    assert traj.x[:, :, 1].min() > 0.004                                # still on the upper level
    moved = np.abs(traj.x - traj.x[0]).max()
    assert moved < (1e-9 if model == "coulomb" else 1e-3), moved


def test_paper_law_has_a_rest_state_on_ground_that_is_not_flat():
    """The paper's lagged friction creeps on any slope, so its relaxation on a field that is not
    flat holds the feet by Coulomb friction (soft_envs.sim.rest._held_on_ground); the rest state
    keeps the paper law's (empty) history, and its derivative by the friction weight is refused."""
    tripod = load_robot("tripod")
    robot = tripod.replace(contact=dataclasses.replace(tripod.contact, model="paper"))
    for ground in (HeightField.incline(5.0), HeightField.rough(0.003, 0.05, seed=1)):
        sim = Simulator(robot.replace(ground=ground))
        rest = sim.rest_state()
        assert rest.history == (None,) * len(sim.system.terms)
        gap = rest.x[:, 1] - ground.height(rest.x[:, 0], rest.x[:, 2])
        assert -1e-3 < gap.min() < 0.0                       # standing on it
    with pytest.raises(ValueError, match="friction"):
        sim.rest_sensitivity(["friction"])
    x0, _, dx0, _ = sim.rest_sensitivity(["youngs_modulus"])
    assert np.isfinite(dx0).all() and np.array_equal(x0, rest.x)
