"""Writing rendered frames to animation files: GIF through Pillow, MP4 through imageio-ffmpeg
(the ``video`` extra). Frames come from :class:`soft_envs.render.Renderer`."""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import numpy as np

__all__ = ["write_animation"]


def write_animation(frames: Iterable[np.ndarray], path: str | Path, fps: float) -> Path:
    """Write RGB frames to ``.gif`` (Pillow, loops forever) or ``.mp4``.

    MP4 needs ``imageio`` and ``imageio-ffmpeg``; without them a
    ``RuntimeError`` says what to install.  Frames must all have the same
    ``(H, W, 3)`` uint8 shape.  A GIF plays in real time (:func:`gif_durations_ms`).  Note: Pillow merges *consecutive identical*
    GIF frames into one (summing their durations), so a GIF's ``n_frames``
    can be smaller than the number of frames given when some repeat.

    Returns:
        The written path.
    """
    path = Path(path)
    if not fps > 0:
        raise ValueError("fps must be positive")
    suffix = path.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise ValueError(f"unsupported animation format {path.suffix!r}; use .gif or .mp4")
    shape: list[tuple[int, ...]] = []

    def checked(it: Iterable[np.ndarray]) -> Iterable[np.ndarray]:
        for i, f in enumerate(it):
            f = np.asarray(f)
            if f.ndim != 3 or f.shape[2] != 3:
                raise ValueError(f"frame {i} must be (H, W, 3), got {f.shape}")
            if not shape:
                shape.append(f.shape)
            elif f.shape != shape[0]:
                raise ValueError(f"frame {i} has shape {f.shape}, expected {shape[0]}")
            yield f.astype(np.uint8, copy=False)

    stream = iter(checked(frames))
    if suffix == ".mp4":
        try:
            import imageio.v2 as iio
            import imageio_ffmpeg  # noqa: F401
        except ImportError as exc:
            raise RuntimeError(
                "writing .mp4 needs imageio and imageio-ffmpeg: `pip install imageio imageio-ffmpeg` "
                "(or write a .gif instead)"
            ) from exc
        path.parent.mkdir(parents=True, exist_ok=True)
        with iio.get_writer(path, fps=fps, codec="libx264", macro_block_size=2, quality=7) as writer:
            n = 0
            for f in stream:
                writer.append_data(f)
                n += 1
        if n == 0:
            raise ValueError("no frames given")
        return path

    first = next(stream, None)
    if first is None:
        raise ValueError("no frames given")
    path.parent.mkdir(parents=True, exist_ok=True)
    rest = [_palette_frame(f) for f in stream]
    _palette_frame(first).save(path, save_all=True, append_images=rest, duration=gif_durations_ms(1 + len(rest), fps),
                               loop=0, optimize=False)
    return path


def gif_durations_ms(n_frames: int, fps: float) -> list[int]:
    """Per-frame durations [ms] that play ``n_frames`` at ``fps`` in real time. A GIF stores
    durations in hundredths of a second, so one constant duration is off (15.2 frames/s would
    be 60 ms frames, 16.7 frames/s: 8 % fast); frame i lasts from ``round(i / fps)`` to
    ``round((i + 1) / fps)`` in those units, so the time elapsed after any frame is within
    10 ms of the real one. At least 20 ms each (players slow down faster frames)."""
    ends = [max(2 * (i + 1), int(round((i + 1) * 100.0 / fps))) for i in range(n_frames)]
    return [10 * (e - s) for s, e in zip([0] + ends[:-1], ends)]


def _palette_frame(frame: np.ndarray):
    """A GIF frame (256 colours) of an RGB frame. Octree quantisation keeps small saturated
    areas (a red trail, a colour bar) their colour, where Pillow's default median cut turns the
    red into pink and bands the colour bar; it is also several times faster."""
    from PIL import Image
    return Image.fromarray(frame).quantize(256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
