"""Rendering, animations, plots and the ParaView export."""
from __future__ import annotations

import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest
from PIL import Image

from soft_envs.render import Renderer, write_animation
from soft_envs.sim.mesh import boundary_faces
from trajopt import plots
from trajopt.results.export import export_vtu_series

from .conftest import shipped


@pytest.fixture(scope="module")
def tripod_frames():
    robot, sim, x0 = shipped("tripod")
    u = np.linspace(0, 1, 20)[:, None] * robot.u_bounds[:, 1] * np.array([1.0, 0.0])
    traj = sim.rollout(u, x0=x0)
    return robot, traj


def robot_pixels(frame: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return np.any(np.abs(frame.astype(int) - ref.astype(int)) > 30, axis=2)


@pytest.mark.parametrize("name", ["tripod", "puppy"])
def test_frame_is_not_blank_and_robot_is_where_its_mesh_projects(name):
    robot, sim, x0 = shipped(name)
    r = Renderer(robot.mesh.surface, width=240, height=180, body_length=robot.body_length)
    frame = r.render(x0)
    assert frame.dtype == np.uint8 and frame.shape == (180, 240, 3)
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 50
    # the same camera without the robot: the robot's pixels are those that change, and they lie
    # where its projected nodes are (the camera follows the robot: near the image centre)
    far = x0 + np.array([0.0, -10.0, 0.0])             # below the ground, out of view
    empty = r.render(far, look_at=robot.com(x0))
    mask = robot_pixels(frame, empty)
    assert mask.mean() > 0.02
    pix, _ = r.project(x0, r.camera_target(x0))
    inside = (pix[:, 0] >= 0) & (pix[:, 0] < 240) & (pix[:, 1] >= 0) & (pix[:, 1] < 180)
    assert inside.mean() > 0.95
    cols, rows = pix[inside, 0].astype(int), pix[inside, 1].astype(int)
    near = np.zeros_like(mask)
    for dr in range(-3, 4):
        for dc in range(-3, 4):
            near[np.clip(rows + dr, 0, 179), np.clip(cols + dc, 0, 239)] = True
    assert mask[near].mean() > 0.5


def test_frames_differ_between_states_and_repeat_for_the_same(tripod_frames):
    robot, traj = tripod_frames
    r = Renderer(robot.mesh.surface, width=160, height=120, body_length=robot.body_length)
    a = r.render(traj.x[0])
    b = r.render(traj.x[-1], cables=[(traj.x[-1][:3], 5.0)], com_trail=traj.com)
    assert np.array_equal(a, r.render(traj.x[0]))
    assert np.abs(a.astype(int) - b.astype(int)).sum() > 0


def test_gif_has_expected_frame_count(tmp_path, tripod_frames):
    robot, traj = tripod_frames
    r = Renderer(robot.mesh.surface, width=96, height=72, body_length=robot.body_length)
    path = write_animation((r.render(x) for x in traj.x[::4]), tmp_path / "a.gif", fps=10)
    assert Image.open(path).n_frames == len(traj.x[::4])


def test_boundary_faces_of_cube_split():
    from soft_envs.sim.meshgen import voxel_tet_mesh
    p, t = voxel_tet_mesh([0, 1], [0, 1], [0, 1], np.ones((1, 1, 1), bool))
    f = boundary_faces(t)
    assert len(f) == 12
    n = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
    assert np.all(np.einsum("ij,ij->i", n, p[f].mean(axis=1) - 0.5) > 0)     # outward


def test_plots_are_written(tmp_path, tripod_frames):
    robot, traj = tripod_frames
    K = len(traj.u)
    target = np.stack([np.linspace(0, 0.05, K + 1), np.zeros(K + 1)], axis=1)
    hist = [{"iteration": 1, "objective": 1.0, "objective_after": 0.5, "step": 1e-3},
            {"iteration": 2, "objective": 0.5, "objective_after": 0.4, "step": 5e-4}]
    outs = [plots.plot_com_topdown(traj.com, target, tmp_path / "com.png", body_outline=traj.x[0], prep_steps=5),
            plots.plot_com_topdown(traj.com, None, tmp_path / "com.svg"),
            plots.plot_controls(traj.u, 0.033, robot.motor_names, tmp_path / "u.png", n_prep=5, n_cycle=5,
                                u_post=traj.u),
            plots.plot_controls(traj.u[:, :1], 0.033, ["one"], tmp_path / "u1.png"),
            plots.plot_convergence(hist, tmp_path / "conv.png"),
            plots.plot_speed_per_cycle(np.array([6.0, 6.5, 6.4]), tmp_path / "speed.png", reference=6.1),
            plots.plot_speed_vs_steps({"trajopt": ([1e3, 4e3], [2.0, 7.0]), "PPO": ([1e4, 1e5], [0.5, 1.0])},
                                      tmp_path / "rl.png")]
    for p in outs:
        assert p.stat().st_size > 1000
        if p.suffix == ".png":
            assert min(Image.open(p).size) > 100
    with pytest.raises(ValueError, match="motor names"):
        plots.plot_controls(traj.u, 0.033, ["a"], tmp_path / "bad.png")


def drawn(fig):
    """The figure drawn once (legend and text positions are known after a draw) and its renderer."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return canvas.get_renderer()


def test_controls_plot_explains_its_lines_and_keeps_legends_off_the_curves():
    """Mirror pairs get a panel each (motors 0 and 2 play the same signal, as the Puppy's fore
    and hind legs do, and would hide each other in one panel), the mirror motor is dashed, the
    dotted zero-slack controls and the phases are named, and no legend covers a panel."""
    rng = np.random.default_rng(3)
    K = 60
    u = rng.uniform(0.0, 0.016, size=(K, 4))
    u[:, 2] = u[:, 0]
    names = ["fore_left", "fore_right", "hind_left", "hind_right"]
    fig = plots.controls_figure(u, 0.033, names, n_prep=12, n_cycle=24, u_post=u + 1e-3, mirror_map=[1, 0, 3, 2])
    axes = fig.axes
    assert len(axes) == 2
    assert [[t.get_text() for t in ax.get_legend().get_texts()] for ax in axes] == [names[:2], names[2:]]
    styles = {ln.get_label(): ln.get_linestyle() for ax in axes for ln in ax.get_lines()
              if not ln.get_label().startswith("_")}
    assert styles == {"fore_left": "-", "fore_right": "--", "hind_left": "-", "hind_right": "--"}
    dotted = [ln for ax in axes for ln in ax.get_lines() if ln.get_linestyle() == ":"]
    assert len(dotted) == 4 and np.allclose(dotted[0].get_ydata(), 1000 * (u[:, 0] + 1e-3))
    below = [t.get_text() for lg in fig.legends for t in lg.get_texts()]
    assert below == [plots.U_LABEL, "mirror motor (dashed)", plots.U_POST_LABEL]
    assert "zero-slack" in plots.U_POST_LABEL and "III-B-2" in plots.U_POST_LABEL
    assert [t.get_text() for t in axes[0].texts] == ["prep", "cycle 1", "cycle 2"]
    renderer = drawn(fig)
    panels = [ax.get_window_extent(renderer) for ax in axes]
    for legend in [ax.get_legend() for ax in axes] + fig.legends:
        box = legend.get_window_extent(renderer)
        assert not any(box.overlaps(p) for p in panels), legend
    # without mirror pairs: one panel, every motor solid (the Tripod's two motors)
    one = plots.controls_figure(u[:, :2], 0.033, ["front", "back"], mirror_map=[0, 1])
    assert len(one.axes) == 1 and {ln.get_linestyle() for ln in one.axes[0].get_lines()} == {"-"}
    assert len(one.axes[0].texts) == 0                  # no phases given, none named
    with pytest.raises(ValueError, match="u_post"):
        plots.controls_figure(u, 0.033, names, u_post=u[:10])


def test_motor_groups_pair_the_puppys_mirrored_motors():
    robot, _, _ = shipped("puppy")
    groups = plots.motor_groups(robot.n_motors, robot.mirror_map)
    names = [[robot.motor_names[m] for m in g] for g in groups]
    assert len(groups) == 4 and sorted(m for g in groups for m in g) == list(range(8))
    for left, right in names:
        assert "left" in left and right == left.replace("left", "right")
    assert plots.motor_groups(3, None) == [[0, 1, 2]] == plots.motor_groups(3, [0, 1, 2])
    with pytest.raises(ValueError, match="mirror_map"):
        plots.motor_groups(3, [1, 2, 0])


def test_speed_and_com_legends_stay_off_the_data(tmp_path, tripod_frames):
    import matplotlib.figure
    _, traj = tripod_frames
    figs = []
    real = matplotlib.figure.Figure.savefig

    def keep(fig, *args, **kw):
        figs.append(fig)
        return real(fig, *args, **kw)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(matplotlib.figure.Figure, "savefig", keep)
        plots.plot_speed_per_cycle(np.array([6.0, 6.5, 6.4]), tmp_path / "s.png", reference=6.1)
        plots.plot_com_topdown(traj.com, None, tmp_path / "c.png", body_outline=traj.x[0], prep_steps=5)
    for fig in figs:
        renderer = drawn(fig)
        (ax,) = fig.axes
        assert not ax.get_legend().get_window_extent(renderer).overlaps(ax.get_window_extent(renderer))


def test_vtu_series_reads_back(tmp_path, tripod_frames):
    robot, traj = tripod_frames
    X = traj.x[:6]
    sed = np.random.default_rng(0).random((6, robot.mesh.n_tets))
    cable = [np.repeat(X[:, :3][:, None, 0], 2, axis=1) + np.array([0, 0.01, 0])]
    pvd = export_vtu_series(tmp_path / "out", robot.mesh.tets, robot.mesh.points, X, 0.033,
                            cell_data={"strain_energy_density": sed}, cables=cable, basename="t")
    root = ET.parse(pvd).getroot()
    entries = root.findall("./Collection/DataSet")
    assert [e.get("file") for e in entries] == [f"t_{k:05d}.vtu" for k in range(6)]
    assert [float(e.get("timestep")) for e in entries] == [0.033 * k for k in range(6)]   # exact
    m = meshio.read(tmp_path / "out" / "t_00003.vtu")
    assert np.allclose(m.points, X[3])
    assert np.allclose(m.point_data["displacement"], X[3] - robot.mesh.points)
    assert np.allclose(m.point_data["velocity"], (X[3] - X[2]) / 0.033)
    assert np.allclose(m.cell_data["strain_energy_density"][0], sed[3])
    assert np.array_equal(m.cells_dict["tetra"], robot.mesh.tets)
    lines = meshio.read(tmp_path / "out" / "t_cables_00003.vtu")
    assert lines.cells_dict["line"].shape == (1, 2)
    assert not list((tmp_path / "out").glob(".*"))
    with pytest.raises(ValueError, match="rest_points"):
        export_vtu_series(tmp_path / "bad", robot.mesh.tets, robot.mesh.points[:5], X, 0.033)
    with pytest.raises(ValueError, match="cell_data"):
        export_vtu_series(tmp_path / "bad", robot.mesh.tets, robot.mesh.points, X, 0.033,
                          cell_data={"e": sed[:, :3]})


def test_cli_render_plot_export(tmp_path):
    """End to end: a (short) result through trajopt render / plot / export / evaluate."""
    from soft_envs.envs import make_gradient_env
    from trajopt import GaitSpec, GaussNewtonOptions, optimize_gait
    from trajopt.cli import main
    res = optimize_gait(make_gradient_env("tripod"), "walk", gait=GaitSpec(n_prep=4, n_cycle=12), n_seeds=1,
                        eval_cycles=1, options=GaussNewtonOptions(max_iter=1), robot_spec="tripod")
    path = res.save(tmp_path / "r.npz")
    from soft_envs.render import Renderer
    made, titles = [], []
    real_init, real_render = Renderer.__init__, Renderer.render

    def init(self, *args, **kw):
        made.append(kw)
        real_init(self, *args, **kw)

    def render(self, x, **kw):
        titles.append(kw.get("title"))
        return real_render(self, x, **kw)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Renderer, "__init__", init)
        mp.setattr(Renderer, "render", render)
        assert main(["render", str(path), "--gif", str(tmp_path / "r.gif"), "--cycles", "1", "--every", "4",
                     "--size", "96x72"]) == 0
    (kw,) = made                                         # a self-explaining film: legend, colour bar, scale
    assert kw["legend"] and kw["scale_bar"] and kw["tension_max"] > 0   # one tension scale for all frames
    assert titles[0] == "tripod, walk: t = 0.00 s" and titles[1] == f"tripod, walk: t = {4 * res.dt:.2f} s"
    assert Image.open(tmp_path / "r.gif").n_frames == len(range(0, 4 + 12 + 1, 4))
    assert main(["plot", str(path), "--out", str(tmp_path / "plots")]) == 0
    assert len(list((tmp_path / "plots").glob("*.png"))) == 5          # com, controls, convergence, speed, motors
    assert main(["export", str(path), "--vtu", str(tmp_path / "vtu"), "--cycles", "1"]) == 0
    assert len(list((tmp_path / "vtu").glob("r_0*.vtu"))) == 4 + 12 + 1
    assert main(["evaluate", str(path), "--cycles", "1"]) == 0          # upright (1 would be: fell)
    assert main(["evaluate", str(tmp_path / "missing.npz")]) == 2
