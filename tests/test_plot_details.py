"""Figures name what they show and hide nothing (issue #31 item 5): the calibration figure's
legend sits beside the tracks, never over them, and its title names the robot and the tracks
file; the sweep summary's title says what each run's "main figure" is and which sweep it is.
The figures are inspected as matplotlib objects (text, window extents) after drawing."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from trajopt.calibration import files as calibrate_command
from trajopt.calibration.files import tracks_figure
from trajopt.sweep import load_spec, summary, write_summary

from .test_sweep import tiny_block, write


def drawn_extents(fig):
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    return renderer, fig.bbox


def calibration_inputs(n_markers: int = 8, K: int = 40):
    """Stand-ins with the fields the figure reads: markers whose tracks fill every axes."""
    rng = np.random.default_rng(0)
    dt = 0.05
    t = dt * np.arange(K + 1)
    names = [f"m{i}" for i in range(n_markers)]
    pred = 0.01 * np.sin(t[:, None, None] + np.arange(n_markers)[None, :, None] + np.arange(3)[None, None, :])
    times = np.repeat(t, n_markers)
    index = np.tile(np.arange(n_markers), K + 1)
    values = pred.reshape(-1, 3) + 1e-4 * rng.standard_normal((len(times), 3))
    data = SimpleNamespace(dt=dt, u=np.zeros((K, 3)), markers=SimpleNamespace(names=names), marker_index=index,
                           times=times, values=values, robot=SimpleNamespace(name="tripod"))
    fit = SimpleNamespace(predicted_before=pred * 1.3, predicted_after=pred, rms_before_mm=3.0, rms_after_mm=0.1)
    return data, fit


def test_calibration_legend_lies_beside_every_axes_inside_the_figure_and_the_title_names_robot_and_file(tmp_path):
    data, fit = calibration_inputs()
    fig = tracks_figure(data, fit, tracks_file=tmp_path / "walk_tracks.csv")
    renderer, figure_box = drawn_extents(fig)
    legends = [leg for ax in fig.axes if (leg := ax.get_legend()) is not None]
    assert len(legends) == 1
    box = legends[0].get_window_extent(renderer)
    assert len(legends[0].get_texts()) == 8
    for ax in fig.axes:
        assert not box.overlaps(ax.get_window_extent(renderer)), f"the legend covers the axes {ax.get_title()!r}"
    assert figure_box.x0 <= box.x0 and box.x1 <= figure_box.x1 and figure_box.y0 <= box.y0 and box.y1 <= figure_box.y1, \
        "the legend is cut off by the figure's edge"
    title = fig._suptitle.get_text()
    assert "tripod" in title and "walk_tracks.csv" in title
    import matplotlib.pyplot as plt
    plt.close(fig)


def test_plot_tracks_writes_the_png_with_the_tracks_file(tmp_path, monkeypatch):
    seen = {}
    real = calibrate_command.atomic_write_png

    def capture(fig, path, *, dpi):
        seen["title"] = fig._suptitle.get_text()
        return real(fig, path, dpi=dpi)

    monkeypatch.setattr(calibrate_command, "atomic_write_png", capture)
    data, fit = calibration_inputs(n_markers=3)
    path = calibrate_command.plot_tracks(data, fit, tmp_path / "tracks.png", tracks_file="dir/mocap.csv")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "mocap.csv" in seen["title"] and "tripod" in seen["title"]


def test_sweep_summary_title_says_what_the_main_figure_is_and_fits_the_figure(tmp_path, monkeypatch):
    spec = load_spec(write(tmp_path, tiny_block("v{speed:g}", "speed = [3.0, 4.0]"), name="speeds.toml"), tmp_path / "out")
    statuses = {"v3": {"status": "done", "metrics": {"speed_bl_per_min": 2.9, "target_bl_per_min": 3.0, "upright": True}},
                "v4": {"status": "failed", "reason": "boom"}}
    seen = {}
    real = summary.atomic_write_png

    def capture(fig, path, *, dpi):
        ax = fig.axes[0]
        renderer, figure_box = drawn_extents(fig)
        seen["title"] = ax.get_title()
        t = ax.title.get_window_extent(renderer)
        seen["inside"] = figure_box.x0 <= t.x0 and t.x1 <= figure_box.x1 and t.y1 <= figure_box.y1
        return real(fig, path, dpi=dpi)

    monkeypatch.setattr(summary, "atomic_write_png", capture)
    written = write_summary(spec, statuses, tmp_path / "out")
    assert written[-1].name == "summary.png" and written[-1].is_file()
    assert "speeds.toml" in seen["title"]
    assert "main figure" in seen["title"] and "speed along the target" in seen["title"] and "BL/min" in seen["title"]
    assert seen["inside"], f"the title {seen['title']!r} is cut off by the figure's edge"
