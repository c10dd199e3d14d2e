"""Renderer, animation writer and boundary extraction on synthetic meshes (no simulator needed)."""
from __future__ import annotations

import itertools
import sys

import numpy as np
import pytest
from PIL import Image

from soft_envs.render import Renderer, surface_triangles, write_animation
from soft_envs.sim.meshgen import graded, voxel_tet_mesh

W, H = 240, 180


def box_mesh(nx: int = 4, ny: int = 2, nz: int = 2, size=(0.1, 0.03, 0.05)) -> tuple[np.ndarray, np.ndarray]:
    """A block of nx*ny*nz cubes, each split into 6 positively oriented tets (Kuhn), resting on y = 0."""
    return voxel_tet_mesh(graded(0, size[0], nx), graded(0, size[1], ny), graded(-size[2] / 2, size[2] / 2, nz),
                          np.ones((nx, ny, nz), dtype=bool))


def outward(points: np.ndarray, faces: np.ndarray, centre: np.ndarray) -> np.ndarray:
    p = points[faces]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    return np.einsum("ij,ij->i", n, p.mean(axis=1) - centre) > 0


@pytest.fixture(scope="module")
def block():
    pts, tets = box_mesh()
    return pts, tets, surface_triangles(tets, pts)


@pytest.fixture(scope="module")
def renderer(block):
    return Renderer(block[2], width=W, height=H, body_length=0.1)


def bent(pts: np.ndarray) -> np.ndarray:
    x = pts.copy()
    x[:, 1] += 0.02 * np.sin(np.pi * x[:, 0] / 0.1)
    return x


def changed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.any(np.abs(a.astype(int) - b.astype(int)) > 30, axis=2)


# ----------------------------------------------------------------------------- surface_triangles
def test_single_tet_faces_are_outward():
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    for tet in ([0, 1, 2, 3], [0, 2, 1, 3]):            # positive and negative orientation
        f = surface_triangles(np.array([tet]), pts)
        assert f.shape == (4, 3)
        assert sorted(map(sorted, f.tolist())) == [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]
        assert np.all(outward(pts, f, pts.mean(axis=0)))
    # without points the tet is taken as positively oriented
    assert np.all(outward(pts, surface_triangles(np.array([[0, 1, 2, 3]])), pts.mean(axis=0)))


@pytest.mark.parametrize("split", ["five", "six"])
def test_cube_split_has_twelve_outward_triangles(split):
    pts = np.array(list(itertools.product([0.0, 1.0], repeat=3)))  # index = 4x + 2y + z
    if split == "five":
        tets = np.array([[0, 3, 5, 6], [1, 0, 3, 5], [2, 0, 6, 3], [4, 0, 5, 6], [7, 3, 6, 5]])
    else:
        tets = box_mesh(1, 1, 1, (1, 1, 1))[1]
        pts = box_mesh(1, 1, 1, (1, 1, 1))[0]
    f = surface_triangles(tets, pts)
    assert f.shape == (12, 3) and f.dtype == np.int64
    assert np.all(outward(pts, f, pts.mean(axis=0)))
    assert len({tuple(sorted(t)) for t in f.tolist()}) == 12


def test_block_surface_count_and_orientation(block):
    pts, tets, tris = block
    assert len(tris) == 2 * 2 * (4 * 2 + 2 * 2 + 4 * 2)       # two triangles per boundary square
    assert np.array_equal(tris, surface_triangles(tets))       # tets are positively oriented
    assert np.all(outward(pts, tris, pts.mean(axis=0)))
    with pytest.raises(ValueError, match="tets"):
        surface_triangles(np.zeros((3, 3), int))


# ----------------------------------------------------------------------------- Renderer
def test_frame_is_rgb_and_not_blank(renderer, block):
    frame = renderer.render(block[0])
    assert frame.dtype == np.uint8 and frame.shape == (H, W, 3)
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 50


def test_robot_is_where_its_mesh_projects_near_the_centre(renderer, block):
    pts = block[0]
    target = renderer.camera_target(pts)
    frame = renderer.render(pts)
    empty = renderer.render(pts - [0.0, 10.0, 0.0], look_at=target)   # same camera, robot out of view
    mask = changed(frame, empty)
    assert 0.02 < mask.mean() < 0.6
    rows, cols = np.nonzero(mask)
    assert abs(cols.mean() - W / 2) < 0.15 * W and abs(rows.mean() - H / 2) < 0.15 * H
    pix, depth = renderer.project(pts, target)
    assert np.all(depth > 0)
    c, r = np.clip(pix[:, 0].round().astype(int), 0, W - 1), np.clip(pix[:, 1].round().astype(int), 0, H - 1)
    near = np.zeros_like(mask)
    for dr, dc in itertools.product(range(-2, 3), repeat=2):
        near[np.clip(r + dr, 0, H - 1), np.clip(c + dc, 0, W - 1)] = True
    assert mask[near].mean() > 0.8
    # every robot pixel lies inside the projected bounding box of its nodes (plus the shadow below)
    assert cols.min() >= pix[:, 0].min() - 3 and cols.max() <= pix[:, 0].max() + 3
    assert rows.min() >= pix[:, 1].min() - 3


def test_camera_follows_the_robot(renderer, block):
    pts = block[0]
    moved = pts + [0.37, 0.0, -0.21]
    frame = renderer.render(moved)
    empty = renderer.render(moved - [0.0, 10.0, 0.0], look_at=renderer.camera_target(moved))
    rows, cols = np.nonzero(changed(frame, empty))
    assert abs(cols.mean() - W / 2) < 0.15 * W and abs(rows.mean() - H / 2) < 0.15 * H
    assert not np.array_equal(frame, renderer.render(pts))          # the ground moved under it


def test_deterministic_and_state_dependent(renderer, block):
    pts = block[0]
    a, b = renderer.render(pts), renderer.render(bent(pts))
    assert np.array_equal(a, renderer.render(pts))
    other = Renderer(block[2], width=W, height=H, body_length=0.1)
    assert np.array_equal(a, other.render(pts))
    assert changed(a, b).sum() > 100


def test_cables_trail_gravity_and_title(renderer, block):
    pts = block[0]
    plain = renderer.render(pts)
    cables = [(np.array([[0.0, 0.01, 0.0], [0.05, 0.015, 0.0], [0.1, 0.01, 0.0]]), 4.0),
              (np.array([[0.0, 0.02, 0.02], [0.1, 0.02, 0.02]]), 0.0)]
    trail = np.stack([np.linspace(-0.1, 0.05, 40), np.full(40, 0.015), 0.01 * np.sin(np.linspace(0, 6, 40))], 1)
    full = renderer.render(pts, cables=cables, com_trail=trail, gravity=(0.0, -9.81, 0.0), title="t = 1.0 s")
    assert full.shape == (H, W, 3)
    assert changed(plain, full).sum() > 50
    for kw in (dict(cables=cables), dict(com_trail=trail), dict(gravity=(1.0, -9.0, 0.0)), dict(title="x")):
        assert not np.array_equal(plain, renderer.render(pts, **kw)), kw
    assert np.array_equal(plain, renderer.render(pts, cables=[], com_trail=trail[:1], gravity=None))
    # a tension colour scale fixed across frames: same cable, different tension -> different colour
    fixed = Renderer(block[2], width=W, height=H, body_length=0.1, tension_max=10.0)
    lo = fixed.render(pts, cables=[(cables[0][0], 1.0)])
    hi = fixed.render(pts, cables=[(cables[0][0], 9.0)])
    assert not np.array_equal(lo, hi)


def test_legend_colour_bar_and_scale_bar_explain_the_frame(block):
    """The legend names the slack grey and the COM trail's red, the colour bar runs from 0 to
    ``tension_max`` newtons in the colours the cables get, and the scale bar is as long on the
    image as its length at the robot's depth."""
    from soft_envs.render_overlays import LEGEND_LABELS, TENSION_LABEL
    pts = block[0]
    r = Renderer(block[2], width=W * 2, height=H * 2, body_length=0.1, tension_max=8.0, legend=True, scale_bar=True)
    taut = np.array([[0.0, 0.02, 0.0], [0.1, 0.02, 0.0]])
    slack = taut + [0.0, 0.0, 0.02]
    frame = r.render(pts, cables=[(taut, 8.0), (slack, 0.0)])
    assert len(r.figure.axes) == 1                                     # the scene; overlays on their own figure
    ax, cax = r.overlay_figure.axes
    legend = ax.get_legend()
    assert [t.get_text() for t in legend.get_texts()] == list(LEGEND_LABELS)
    grey, red = (np.round(255 * np.array(h.get_color()[:3])) for h in legend.legend_handles)
    assert cax.get_title() == TENSION_LABEL and cax.get_xlim() == (0.0, 8.0)
    # colours on the image: the colour bar's right end is the taut cable's colour, the slack
    # cable is the legend's grey
    box = cax.get_window_extent()
    row = int(2 * H - 0.5 * (box.y0 + box.y1))
    bar_end = frame[row, int(box.x1) - 3].astype(int)
    bar_start = frame[row, int(box.x0) + 3].astype(int)
    assert np.abs(bar_end - bar_start).max() > 100                     # a colour scale, not a blank box

    def colour_on(line):
        pix, _ = r.project(line.mean(axis=0), r.camera_target(pts))
        return frame[int(round(pix[1])), int(round(pix[0]))].astype(int)

    assert np.abs(colour_on(taut) - bar_end).max() <= 12
    assert np.abs(colour_on(slack) - grey).max() <= 12
    assert red[0] > 200 and red[1] < 80                                # the trail's colour, named
    # scale bar: a round length, its dark pixels as long as that length seen at the robot
    assert r.scale_bar_length == 0.02                                  # 5 cm would be > 22 % of the width
    target = r.camera_target(pts)
    forward = target - r.camera_position(target)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    ends, _ = r.project(np.stack([target, target + 0.02 * right / np.linalg.norm(right)]), target)
    expected = np.linalg.norm(ends[1] - ends[0])
    dark = np.all(frame[int(0.85 * 2 * H):, : W] < 60, axis=2)
    longest = max(np.diff(np.flatnonzero(np.diff(np.r_[0, d.astype(int), 0]))).max(initial=0) for d in dark)
    assert abs(longest - expected) <= 3, (longest, expected)
    # without the options nothing of it is drawn
    plain = Renderer(block[2], width=W * 2, height=H * 2, body_length=0.1, tension_max=8.0)
    assert plain.overlay_figure is None and plain.scale_bar_length is None
    tiny = Renderer(block[2], width=96, height=72, body_length=0.1, legend=True, scale_bar=True)
    assert tiny.overlay_figure is None and tiny.scale_bar_length is None     # would cover the robot


def test_colour_bar_follows_the_frames_tension_without_a_fixed_scale(block):
    r = Renderer(block[2], width=W, height=H, body_length=0.1, legend=True)
    cable = np.array([[0.0, 0.02, 0.0], [0.1, 0.02, 0.0]])
    a = r.render(block[0], cables=[(cable, 3.0)])
    assert r.overlay_figure.axes[1].get_xlim() == (0.0, 3.0)
    b = r.render(block[0], cables=[(cable, 5.5)])
    assert r.overlay_figure.axes[1].get_xlim() == (0.0, 5.5)
    title = r.overlay_figure.axes[1].title                              # the label stays above the bar
    assert title.get_window_extent().y0 >= r.overlay_figure.axes[1].get_window_extent().y1
    box = r.overlay_figure.axes[1].get_window_extent()                  # the tick labels below the bar changed
    below = (slice(int(H - box.y0), H), slice(int(box.x0), int(box.x1)))
    assert not np.array_equal(a[below], b[below])


def test_ground_height_and_non_finite_nodes(renderer, block):
    pts = block[0]
    up = renderer.render(pts + [0, 0.05, 0], ground_height=0.05)
    assert up.shape == (H, W, 3)
    bad = pts.copy()
    bad[3] = np.nan
    assert renderer.render(bad).shape == (H, W, 3)      # triangles touching a NaN node are skipped


def test_input_validation(renderer, block):
    with pytest.raises(ValueError, match="x must be"):
        renderer.render(block[0][:, :2])
    with pytest.raises(ValueError, match="nodes"):
        renderer.render(block[0][:5])
    with pytest.raises(ValueError, match="surface_tris"):
        Renderer(np.zeros((4, 4), int))
    with pytest.raises(ValueError, match="cables"):
        renderer.render(block[0], cables=[(np.zeros((3, 2)), 1.0)])


def test_odd_image_size(block):
    frame = Renderer(block[2], width=123, height=77, body_length=0.1).render(block[0])
    assert frame.shape == (77, 123, 3)


# ----------------------------------------------------------------------------- write_animation
def frames_of(renderer, pts, n):
    return [renderer.render(pts + [0.01 * k, 0.0, 0.0], title=f"{k}") for k in range(n)]


def test_gif_frame_count_and_loop(tmp_path, block):
    r = Renderer(block[2], width=96, height=72, body_length=0.1)
    frames = frames_of(r, block[0], 5)
    path = write_animation(iter(frames), tmp_path / "sub" / "a.gif", fps=10)
    with Image.open(path) as im:
        assert im.n_frames == 5 and im.size == (96, 72)
        assert im.info.get("loop") == 0 and im.info.get("duration") == 100
    with pytest.raises(ValueError, match="frame 1"):
        write_animation([frames[0], frames[1][:10]], tmp_path / "b.gif", fps=10)
    with pytest.raises(ValueError, match="format"):
        write_animation(frames, tmp_path / "a.avi", fps=10)
    with pytest.raises(ValueError, match="no frames"):
        write_animation([], tmp_path / "c.gif", fps=10)


def _video_extra_missing() -> str | None:
    import importlib.util
    missing = [m for m in ("imageio", "imageio_ffmpeg") if importlib.util.find_spec(m) is None]
    return f"the video extra is not installed ({', '.join(missing)} missing)" if missing else None


@pytest.mark.skipif(_video_extra_missing() is not None, reason=str(_video_extra_missing()))
def test_mp4_frames_read_back_as_written(tmp_path, block):
    """With the video extra: the MP4 has every frame, at the requested rate, and each decoded
    frame shows what was rendered (lossy codec: mean error below 3 grey levels, and the
    block's pixels where they were)."""
    import imageio.v2 as iio
    r = Renderer(block[2], width=96, height=72, body_length=0.1)
    frames = frames_of(r, block[0], 5)
    path = write_animation(frames, tmp_path / "a.mp4", fps=10)
    reader = iio.get_reader(path)
    assert reader.get_meta_data()["fps"] == pytest.approx(10.0)
    decoded = [np.asarray(f) for f in reader]
    reader.close()
    assert len(decoded) == 5
    for k, (want, got) in enumerate(zip(frames, decoded)):
        assert got.shape == want.shape
        assert np.abs(got.astype(int) - want.astype(int)).mean() < 3.0, f"frame {k}"
        moved = block[0] + [0.01 * k, 0.0, 0.0]                          # as in frames_of
        empty = r.render(moved - [0.0, 10.0, 0.0], look_at=r.camera_target(moved), title=f"{k}")
        body = changed(want, empty)
        assert body.mean() > 0.02
        assert changed(got, empty)[body].mean() > 0.9, f"frame {k}"


def test_gif_keeps_the_trail_red_and_the_colour_bar(tmp_path, block):
    """A GIF has 256 colours a frame: the few red pixels of the COM trail and legend, and the
    colour bar's gradient, keep their colours (Pillow's default quantisation turned that red
    pink)."""
    r = Renderer(block[2], width=W * 2, height=H * 2, body_length=0.1, tension_max=8.0, legend=True, scale_bar=True)
    trail = np.stack([np.linspace(-0.1, 0.05, 40), np.full(40, 0.015), 0.01 * np.sin(np.linspace(0, 6, 40))], 1)
    frame = r.render(block[0], cables=[(np.array([[0.0, 0.02, 0.0], [0.1, 0.02, 0.0]]), 4.0)], com_trail=trail)
    path = write_animation([frame], tmp_path / "a.gif", fps=10)
    with Image.open(path) as im:
        back = np.asarray(im.convert("RGB")).astype(int)
    red = np.all(np.abs(frame.astype(int) - [217, 51, 25]) <= 12, axis=2)
    assert red.sum() > 20
    assert np.abs(back[red] - frame[red].astype(int)).max() <= 10          # median cut: 13
    box = r.overlay_figure.axes[1].get_window_extent()
    row = int(2 * H - 0.5 * (box.y0 + box.y1))
    bar = slice(int(box.x0) + 2, int(box.x1) - 2)
    assert np.abs(back[row, bar] - frame[row, bar].astype(int)).max() <= 16  # median cut: 32 (bands)


def test_mp4_without_the_video_extra_says_what_to_install(tmp_path, block, monkeypatch):
    r = Renderer(block[2], width=96, height=72, body_length=0.1)
    frames = frames_of(r, block[0], 3)
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # as if it were not installed
    with pytest.raises(RuntimeError, match=r"pip install imageio imageio-ffmpeg"):
        write_animation(frames, tmp_path / "b.mp4", fps=10)
    assert not (tmp_path / "b.mp4").exists()
