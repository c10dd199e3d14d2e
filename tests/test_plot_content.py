"""Plots show the data they are given (not only "a file of some size was written").

The plots are written as SVG with path simplification off, the drawn polylines and bars are
read back (matplotlib's default colours identify them), and their vertices must be an affine
image of the data: the COM path and its target in the top view (same scale on both axes, z
downwards), each motor's contraction and zero-slack contraction over time, one bar per cycle
with heights proportional to the speeds.
"""
from __future__ import annotations

import re

import matplotlib
import numpy as np
import pytest

from trajopt import plots

TAB = {"blue": "#1f77b4", "orange": "#ff7f0e", "green": "#2ca02c", "grey30": "#4c4c4c"}


def svg_paths(path) -> list[tuple[str, np.ndarray]]:
    """(style, vertices (m, 2)) of every <path> with a style in an SVG written by matplotlib."""
    out = []
    for m in re.finditer(r'<path d="([^"]*)"[^>]*?style="([^"]*)"', path.read_text()):
        nums = re.findall(r"[-+]?\d*\.?\d+(?:[eE][-+]?\d+)?", m.group(1))
        if len(nums) % 2 == 0 and nums:
            out.append((m.group(2), np.array(nums, dtype=float).reshape(-1, 2)))
    return out


def lines_of(paths, colour: str, n_vertices: int, dashed: bool = False) -> list[np.ndarray]:
    return [v for style, v in paths if f"stroke: {colour}" in style and "fill: none" in style
            and ("stroke-dasharray" in style) == dashed and len(v) == n_vertices]


def affine_fit(data: np.ndarray, pixels: np.ndarray) -> tuple[np.ndarray, float]:
    """Per-axis ``pixel = a data + b`` by least squares: (a (2,), largest residual [px])."""
    a, res = np.zeros(2), 0.0
    for j in range(2):
        A = np.stack([data[:, j], np.ones(len(data))], axis=1)
        coef = np.linalg.lstsq(A, pixels[:, j], rcond=None)[0]
        a[j] = coef[0]
        res = max(res, float(np.abs(A @ coef - pixels[:, j]).max()))
    return a, res


@pytest.fixture
def no_simplify():
    with matplotlib.rc_context({"path.simplify": False}):
        yield


def test_com_top_view_draws_the_path_and_the_target(tmp_path, no_simplify):
    rng = np.random.default_rng(5)
    K, prep = 40, 8
    com = np.cumsum(rng.normal(scale=2e-3, size=(K + 1, 3)), axis=0) + [0.0, 0.03, 0.0]
    target = np.stack([np.linspace(0, 0.05, K + 1), 0.02 * np.sin(np.linspace(0, 3, K + 1))], axis=1)
    svg = plots.plot_com_topdown(com, target, tmp_path / "com.svg", prep_steps=prep)
    paths = svg_paths(svg)
    (walk,) = lines_of(paths, TAB["blue"], K + 1 - prep)
    data = 100 * com[prep:][:, [0, 2]]                          # cm, after the prep phase
    scale, res = affine_fit(data, walk)
    assert res < 0.01, f"the blue line is not the COM path (off by {res:.3g} px; seed 5)"
    assert scale[0] > 0 and scale[1] > 0                         # x to the right, z downwards
    assert scale[0] == pytest.approx(scale[1], rel=1e-3)         # equal aspect
    (tgt,) = lines_of(paths, TAB["grey30"], K + 1, dashed=True)
    b = walk[0] - scale * data[0]
    np.testing.assert_allclose(tgt, scale * 100 * target + b, atol=0.01)   # same axes as the COM
    (prep_line,) = lines_of(paths, "#999999", prep + 1)                      # the prep phase, grey
    np.testing.assert_allclose(prep_line, scale * 100 * com[:prep + 1][:, [0, 2]] + b, atol=0.01)


def test_controls_plot_draws_every_motor_and_its_zero_slack_version(tmp_path, no_simplify):
    rng = np.random.default_rng(6)
    K, dt = 30, 0.033
    u = rng.uniform(0, 0.02, size=(K, 2))
    u_post = np.clip(u + rng.uniform(0, 0.002, size=(K, 2)), 0, 0.02)
    svg = plots.plot_controls(u, dt, ["front", "back"], tmp_path / "u.svg", n_prep=6, n_cycle=12, u_post=u_post)
    paths = svg_paths(svg)
    t = np.arange(K) * dt
    scales = []
    for m, colour in enumerate((TAB["blue"], TAB["orange"])):
        (solid,) = lines_of(paths, colour, K)
        (dotted,) = lines_of(paths, colour, K, dashed=True)
        for series, drawn in ((u[:, m], solid), (u_post[:, m], dotted)):
            scale, res = affine_fit(np.stack([t, 1000 * series], axis=1), drawn)
            assert res < 0.01, f"motor {m}: the line is not its contraction (seed 6)"
            scales.append(scale)
    assert np.allclose(scales, scales[0], rtol=1e-6)             # one time axis, one mm axis
    assert scales[0][0] > 0 and scales[0][1] < 0                 # time to the right, u upwards


def test_speed_bars_have_the_heights_of_the_speeds(tmp_path):
    speeds = np.array([6.0, 6.5, 3.0, 7.25])
    svg = plots.plot_speed_per_cycle(speeds, tmp_path / "s.svg", reference=6.1)
    bars = [v for style, v in svg_paths(svg) if f"fill: {TAB['green']}" in style and len(v) == 4]
    assert len(bars) == 4
    bars.sort(key=lambda v: v[:, 0].min())                       # cycle 1, 2, ... left to right
    heights = np.array([np.ptp(v[:, 1]) for v in bars])
    np.testing.assert_allclose(heights / heights[0], speeds / speeds[0], rtol=1e-4)
