"""Animations as H.264 MP4 with a player, labels that never overlap, frame/time labels on strips,
and a camera that follows the root (course_lib.render)."""

from __future__ import annotations

import base64
import re

import numpy as np
import pytest
import torch

from course_lib import render
from course_lib.motion import Motion
from course_lib.rotations import axis_angle_to_quat
from course_lib.skeleton import Skeleton


def walk(T: int, speed: float = 1.2, fps: float = 30.0) -> Motion:
    """T frames of legs swinging while the root moves forward at `speed` m/s."""
    sk = Skeleton.canonical()
    t = np.arange(T) / fps
    ang = np.zeros((T, 21))
    ang[:, 1], ang[:, 5] = 0.45 * np.sin(2 * np.pi * t), -0.45 * np.sin(2 * np.pi * t)
    q = axis_angle_to_quat(torch.tensor(np.tile([1.0, 0.0, 0.0], (T, 21, 1))), torch.tensor(ang)).numpy()
    return Motion(q, np.stack([np.zeros(T), np.full(T, 0.96), speed * t], -1), sk, fps)


def _boxes(size, left, labels, rows):
    w = [render._font(size).getlength(t) for t in labels]
    return [(r, x, x + wi) for r, x, wi in zip(rows, left, w, strict=True)]


def _overlap(boxes) -> bool:
    return any(ra == rb and a0 < b1 and b0 < a1
               for i, (ra, a0, a1) in enumerate(boxes) for (rb, b0, b1) in boxes[i + 1:])


# ----------------------------------------------------------------------------- labels


def test_label_layout_keeps_the_font_when_there_is_room():
    size, left, rows = render.label_layout([100, 500], ["walk", "run"], 600, 16)
    assert size == 16 and rows == [0, 0]
    assert left[0] == pytest.approx(100 - render._font(16).getlength("walk") / 2)  # centred on its column


def test_label_layout_separates_the_crowded_gaits_of_lesson_00b():
    labels = ["idle", "walk", "jog", "run", "sidestep", "backward", "turn"]
    centres = (np.arange(7) + 0.5) * 640 / 7  # seven characters across 640 px
    naive = [(0, c - render._font(22).getlength(t) / 2, c + render._font(22).getlength(t) / 2)
             for c, t in zip(centres, labels, strict=True)]
    assert _overlap(naive)  # the old layout: "sidestepbackward"
    size, left, rows = render.label_layout(centres, labels, 640, 22)
    assert render.LABEL_FONT_MIN <= size < 22
    assert not _overlap(_boxes(size, left, labels, rows))
    assert all(0 <= x for x in left) and max(x + render._font(size).getlength(t)
                                             for x, t in zip(left, labels, strict=True)) <= 640


def test_label_layout_staggers_when_the_smallest_font_does_not_fit():
    labels = ["sidestep backward", "sidestep forward", "backward turn"]
    size, left, rows = render.label_layout([40, 60, 80], labels, 200, 16)
    assert size == render.LABEL_FONT_MIN and max(rows) >= 1
    assert not _overlap(_boxes(size, left, labels, rows))


def test_label_band_draws_each_label_in_its_colour_over_its_column():
    band = render.label_band(400, [100, 300], ["aaaa", "bbbb"], [(1, 0, 0), (0, 0, 1)], font_px=16)
    assert band.dtype == np.uint8 and band.shape[1] == 400 and 16 <= band.shape[0] <= 30
    red = (band[..., 0] > 150) & (band[..., 2] < 100)
    blue = (band[..., 2] > 150) & (band[..., 0] < 100)
    assert np.flatnonzero(red.any(0)).mean() == pytest.approx(100, abs=6)
    assert np.flatnonzero(blue.any(0)).mean() == pytest.approx(300, abs=6)


def test_stick_strip_labels_each_panel_with_its_frame_and_time():
    m = walk(61)
    strip = render.stick_strip(m, frames=[0, 30, 60], size=(90, 120))
    assert strip.shape[:2][1] == 360 and strip.shape[0] > 90
    band = strip[90:]
    ink = (band < 128).any(-1)
    cols = np.flatnonzero(ink.any(0))
    assert [int(((cols >= 120 * k) & (cols < 120 * (k + 1))).any()) for k in range(3)] == [1, 1, 1]  # one per panel
    np.testing.assert_array_equal(strip[:90], render.stick_strip(m, frames=[0, 30, 60], size=(90, 120), labels=False))


# ----------------------------------------------------------------------------- MP4


def test_write_mp4_is_h264_and_round_trips():
    rng = np.random.default_rng(0)
    colours = rng.integers(30, 225, (6, 3))
    frames = np.broadcast_to(colours[:, None, None], (6, 100, 150, 3)).astype(np.uint8).copy()
    frames[:, 40:60, 60:90] = 255 - frames[:, 40:60, 60:90]  # a patch that must survive
    data = render.write_mp4(frames, fps=10)
    assert b"ftyp" in data[:32] and b"avc1" in data  # an ISO MP4 holding H.264
    assert data.index(b"moov") < data.index(b"mdat")  # faststart: plays before it is fully loaded
    back = render.read_mp4(data)
    assert back.shape == (6, 112, 160, 3)  # padded to multiples of 16, not rescaled
    assert (back[:, 100:] > 240).all() and (back[:, :, 150:] > 240).all()  # the padding is white
    err = np.abs(back[:, :100, :150].astype(int) - frames).mean(axis=(1, 2, 3))
    assert err.max() < 6  # every frame, in order: each colour stays its own
    other = np.abs(back[1:, :100, :150].astype(int) - frames[:-1]).mean(axis=(1, 2, 3))
    assert other.min() > 3 * err.max()


def test_video_html_is_a_player_with_controls_holding_the_bytes():
    data = render.write_mp4(np.zeros((3, 32, 32, 3), np.uint8), fps=5)
    html = render.video_html(data).data
    assert re.search(r"<video controls[^>]*>", html) and 'type="video/mp4"' in html
    src = re.search(r'src="data:video/mp4;base64,([^"]+)"', html).group(1)
    assert base64.b64decode(src) == data


def _fill(img: np.ndarray) -> float:
    """Height of the non-white, non-floor pixels' bounding box as a share of the image height."""
    char = (np.abs(img.astype(int) - img[..., :1]).max(-1) > 40) | (img.max(-1) < 120)  # coloured or dark
    rows = np.flatnonzero(char.any(1))
    return (rows[-1] - rows[0] + 1) / img.shape[0] if len(rows) else 0.0


def test_the_camera_follows_the_root_and_the_character_fills_the_frame():
    m = walk(121, speed=3.0)  # 12 m in 4 s
    follow, _ = render.render_frames(m, stride=60, size=(176, 320), trajectory=False, contacts=False)
    fixed, _ = render.render_frames(m, stride=60, size=(176, 320), trajectory=False, contacts=False, follow=False)
    assert follow.shape == (3, 176, 320, 3)
    assert min(_fill(f) for f in follow) > 0.6  # the character fills the picture on the first and last frame
    assert max(_fill(f) for f in fixed) < 0.45  # a camera framing the whole 12 m path shows it small
    data = render.render_mp4(m, stride=30, size=(176, 320), labels=["walk"])
    frames = render.read_mp4(data)
    assert frames.shape == (5, 176, 320, 3) and len(data) < 200_000


def test_render_rows_mp4_stacks_rows_cut_to_the_shortest():
    data = render.render_rows_mp4([[walk(31), walk(31)], [walk(21)]], labels=[["a", "b"], ["c"]], stride=10,
                                  size=(96, 160), trajectory=False)
    frames = render.read_mp4(data)
    assert frames.shape == (3, 192, 160, 3)  # two rows of 96 px, the second clip's 3 frames
    with pytest.raises(ValueError, match="label rows"):
        render.render_rows_mp4([[walk(3)]], labels=[["a"], ["b"]])


def test_stick_mp4_has_the_gif_frames():
    m = walk(13)
    video = render.read_mp4(render.stick_mp4(m, size=(64, 80), stride=4))
    gif = render.read_gif(render.stick_gif(m, size=(64, 80), stride=4))
    assert video.shape == (4, 64, 80, 3) and gif.shape == (4, 64, 80, 3)
    assert np.abs(video.astype(int) - gif).mean() < 8  # the same drawings, H.264's loss aside
    with pytest.raises(ValueError, match="stride"):
        render.stick_mp4(m, stride=0)


def test_write_mp4_does_not_warn_about_fork_once_jax_runs():
    import warnings

    import jax.numpy as jnp

    jnp.ones(3).block_until_ready()  # JAX's threads are up: it now warns at every os.fork
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        render.read_mp4(render.write_mp4(np.zeros((2, 32, 32, 3), np.uint8), fps=5))
    assert not [w for w in caught if "fork" in str(w.message)]
