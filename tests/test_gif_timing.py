"""A GIF plays in real time (issue #31 item 5): ``trajopt render`` reports frames/s = 1 / (h x
every), and the durations stored in the GIF (hundredths of a second) add up to that rate, not
to a rounded constant (66 ms frames stored as 60 ms played 10 % fast)."""
from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from soft_envs.animation import gif_durations_ms, write_animation


@pytest.mark.parametrize("fps", [1 / 0.066, 1 / 0.033, 10.0, 7.0])
def test_gif_frame_durations_add_up_to_real_time(tmp_path, fps):
    n = 40
    frames = [np.full((8, 8, 3), (i * 6) % 256, dtype=np.uint8) for i in range(n)]   # all distinct
    path = write_animation(frames, tmp_path / "a.gif", fps)
    with Image.open(path) as im:
        durations = []
        for i in range(im.n_frames):
            im.seek(i)
            durations.append(im.info["duration"])
    assert len(durations) == n
    elapsed = np.cumsum(durations)
    real = 1000.0 * np.arange(1, n + 1) / fps
    assert np.abs(elapsed - real).max() <= 5.0 + 1e-9      # rounding to 10 ms, never accumulating
    assert durations == gif_durations_ms(n, fps)


def test_too_fast_frames_are_held_for_20_ms():
    assert gif_durations_ms(5, 200.0) == [20] * 5
