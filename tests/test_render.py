"""Rendering: 3-D image regression with SSIM, 2-D stick-figure geometry, GIF frame counts, bad input.

Reference images live in tests/data/render_*.png (160 x 160).  After an intended
change of the renderer's look, rewrite them with either of

    REGEN_RENDER_REFS=1 .venv/bin/python -m pytest tests/test_render.py
    .venv/bin/python tests/test_render.py --regen

(with VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow PYVISTA_OFF_SCREEN=true set on
headless machines), look at the PNGs, and commit them.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
import torch
from skimage.metrics import structural_similarity

from course_lib import render
from course_lib.motion import Motion
from course_lib.rotations import axis_angle_to_quat
from course_lib.skeleton import Skeleton

DATA = Path(__file__).parent / "data"
SIZE = (160, 160)
SAME_POSE_SSIM = 0.95  # renders of one pose on another GL driver still score above this
OTHER_POSE_SSIM = 0.90  # a different pose must score below this


def _motion(angles: dict[str, tuple[tuple[float, float, float], float]], root=(0.0, 0.96, 0.0)) -> Motion:
    """A one-frame canonical Motion with {joint: (axis, radians)} local rotations."""
    sk = Skeleton.canonical()
    axis = np.tile([1.0, 0.0, 0.0], (21, 1))
    ang = np.zeros(21)
    for name, (ax, a) in angles.items():
        axis[sk.index(name)], ang[sk.index(name)] = ax, a
    q = axis_angle_to_quat(torch.tensor(axis), torch.tensor(ang)).numpy()[None]
    return Motion(q, np.array([root]), sk, 30.0)


def rest() -> Motion:
    return _motion({})


def posed() -> Motion:
    """Left arm stretched forward, right arm down, right knee bent, bowing a little: a frame unlike the T-pose."""
    x, z = (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)
    return _motion({"LeftArm": ((0.0, 1.0, 0.0), -1.4), "RightArm": (z, 1.3), "RightForeArm": (z, 0.5),
                    "RightUpLeg": (x, -0.6), "RightLeg": (x, 1.0), "Spine": (x, 0.25)}, root=(0.0, 0.93, 0.0))


def walk(T: int = 9, fps: float = 30.0) -> Motion:
    """T frames of legs swinging while the root moves forward 1.2 m/s."""
    sk = Skeleton.canonical()
    t = np.arange(T) / fps
    ang = np.zeros((T, 21))
    ang[:, 1], ang[:, 5] = 0.45 * np.sin(2 * np.pi * t), -0.45 * np.sin(2 * np.pi * t)
    axis = np.tile([1.0, 0.0, 0.0], (T, 21, 1))
    q = axis_angle_to_quat(torch.tensor(axis), torch.tensor(ang)).numpy()
    return Motion(q, np.stack([np.zeros(T), np.full(T, 0.96), 1.2 * t], -1), sk, fps)


REFS = {"render_rest.png": rest, "render_posed.png": posed}


def _render(motion: Motion) -> np.ndarray:
    return render.render_frame(motion, size=SIZE, view="three_quarter")


def regen() -> None:
    DATA.mkdir(exist_ok=True)
    for name, make in REFS.items():
        iio.imwrite(DATA / name, _render(make()))


def ssim(a: np.ndarray, b: np.ndarray) -> float:
    return float(structural_similarity(a, b, channel_axis=2, data_range=255))


@pytest.fixture(scope="module")
def refs() -> dict[str, np.ndarray]:
    if os.environ.get("REGEN_RENDER_REFS") == "1":
        regen()
    return {name: iio.imread(DATA / name)[..., :3] for name in REFS}


@pytest.mark.parametrize("name", sorted(REFS))
def test_render_matches_reference(refs, name):
    img = _render(REFS[name]())
    assert img.shape == (*SIZE, 3) and img.dtype == np.uint8
    assert ssim(img, refs[name]) > SAME_POSE_SSIM


def test_ssim_drops_for_a_different_pose(refs):
    assert ssim(_render(posed()), refs["render_rest.png"]) < OTHER_POSE_SSIM
    assert ssim(_render(rest()), refs["render_posed.png"]) < OTHER_POSE_SSIM


def test_render_is_framed_and_up_is_up():
    img = _render(rest()).astype(int)
    char = np.argwhere(np.abs(img - [255, 255, 255]).sum(-1) > 0)  # non-background, incl. the floor
    assert char[:, 0].min() > 2 and char[:, 1].min() >= 0  # nothing cut at the top
    dark = np.argwhere(img.sum(-1) < 400)  # the blue character, not the light floor
    rows = dark[:, 0]
    assert rows.min() < SIZE[0] * 0.3 and rows.max() > SIZE[0] * 0.6  # tall figure spanning the picture


def test_raw_positions_render_like_the_motion():
    m = posed()
    a = render.render_frame(m, size=SIZE, contacts=False)
    b = render.render_frame(m.positions()[0], m.skeleton.parents, size=SIZE, contacts=False)
    assert ssim(a, b) > 0.99


def test_side_by_side_puts_default_colours_apart():
    img = render.render_side_by_side([rest(), posed()], labels=["ground truth", "generated"], size=(120, 240))
    assert img.shape == (120, 240, 3)
    f = img.astype(int)
    blue = (f[..., 2] - f[..., 0] > 60)
    orange = (f[..., 0] - f[..., 2] > 60)
    assert blue.sum() > 50 and orange.sum() > 50
    assert np.argwhere(blue)[:, 1].mean() < 120 < np.argwhere(orange)[:, 1].mean()


def test_render_gif_has_one_frame_per_stride():
    data = render.render_gif(walk(9), stride=2, size=(64, 80))
    frames = render.read_gif(data)
    assert frames.shape == (5, 64, 80, 3)


# ----------------------------------------------------------------------------- stick figures

def _px(motion: Motion, view: str, size=(200, 200)) -> np.ndarray:
    """Pixel (row, col) of every joint as stick_figure draws it."""
    uv = render.project(motion.positions()[0], view)
    fr = render._Frame2D(size, *render._fit(uv, size, view != "top"))
    return fr.to_px(uv)


def _colour_cols(img: np.ndarray, rgb) -> np.ndarray:
    target = (np.asarray(rgb) * 255)
    return np.argwhere(np.abs(img.astype(float) - target).sum(-1) < 30)[:, 1]


def test_stick_front_head_above_feet_and_left_on_the_right():
    m, sk = rest(), Skeleton.canonical()
    img = render.stick_figure(m, view="front", size=(200, 200))
    assert img.shape == (200, 200, 3) and img.dtype == np.uint8
    px = _px(m, "front")
    assert px[sk.index("Head"), 0] < px[sk.index("LeftFoot"), 0] - 100
    # seen from the front, the character's left hand (+X) is on the image's right
    assert px[sk.index("LeftHand"), 1] > 150 > 50 > px[sk.index("RightHand"), 1]
    assert _colour_cols(img, render.STICK_COLORS["left"]).mean() > 110
    assert _colour_cols(img, render.STICK_COLORS["right"]).mean() < 90


def test_stick_side_forward_is_right():
    m, sk = posed(), Skeleton.canonical()  # left arm points forward (+Z)
    px = _px(m, "side")
    assert px[sk.index("LeftHand"), 1] > px[sk.index("Hips"), 1] + 30
    assert px[sk.index("Head"), 0] < px[sk.index("RightToeBase"), 0]
    img = render.stick_figure(m, view="side")
    assert (np.abs(img.astype(int) - 255).sum(-1) > 0).sum() > 300  # something was drawn


def test_stick_top_forward_is_up_and_left_is_left():
    m, sk = rest(), Skeleton.canonical()
    px = _px(m, "top")
    assert px[sk.index("LeftToeBase"), 0] < px[sk.index("LeftFoot"), 0]  # toes point forward = up
    assert px[sk.index("LeftHand"), 1] < px[sk.index("RightHand"), 1]  # from above, facing up: left is left


def test_stick_strip_and_gif_shapes():
    m = walk(9)
    strip = render.stick_strip(m, frames=[0, 4, 8], view="side", size=(80, 60), labels=False)
    assert strip.shape == (80, 180, 3)
    assert not np.array_equal(strip[:, :59], strip[:, 120:179])  # different poses
    frames = render.read_gif(render.stick_gif(m, view="side", size=(64, 64), stride=4))
    assert frames.shape == (3, 64, 64, 3)


# ----------------------------------------------------------------------------- bad input

@pytest.mark.parametrize("positions, parents, match", [
    (np.zeros((5, 21, 2)), Skeleton.canonical().parents, r"\(J, 3\) or \(T, J, 3\)"),
    (np.zeros(3), Skeleton.canonical().parents, r"\(J, 3\) or \(T, J, 3\)"),
    (np.zeros((21, 3)), Skeleton.canonical().parents[:20], "20 parents for 21 joints"),
    (np.full((21, 3), np.nan), Skeleton.canonical().parents, "NaN"),
    (np.zeros((21, 3)), None, "parents"),
])
def test_bad_input_raises_clearly(positions, parents, match):
    with pytest.raises(ValueError, match=match):
        render.stick_figure(positions, parents)
    with pytest.raises(ValueError, match=match):
        render.render_frame(positions, parents)


def test_bad_view_and_frame():
    with pytest.raises(ValueError, match="view"):
        render.stick_figure(rest(), view="back")
    with pytest.raises(ValueError, match="view"):
        render.render_frame(rest(), view="back")
    with pytest.raises(IndexError, match="frame 3"):
        render.stick_figure(rest(), frame=3)


if __name__ == "__main__" and "--regen" in sys.argv:
    regen()
    print(f"rewrote {', '.join(REFS)} in {DATA}")
