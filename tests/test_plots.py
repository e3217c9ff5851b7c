"""plots.top_view: a left turn (counter-clockwise seen from above, Y up) must look like a left turn.

Known answer from the course's conventions: the character faces +Z, its left is +X
(the canonical skeleton's LeftUpLeg offset), and a positive yaw rate about +Y turns the
heading from +Z towards +X.  On the page, a path turning left bends counter-clockwise
(positive cross product of successive steps in display coordinates, y up) and ends on the
left of where it started.  Plain `ax.plot(x, z)` shows the same path turning right.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import torch  # noqa: E402

from course_lib import render  # noqa: E402
from course_lib.plots import floor_xz, top_view  # noqa: E402
from course_lib.rotations import axis_angle_to_quat, quat_rotate  # noqa: E402
from course_lib.skeleton import Skeleton  # noqa: E402


def _left_turn(n: int = 60) -> np.ndarray:
    """(n, 3) root path: 1 m straight along +Z, then a quarter circle with the yaw increasing (a left turn)."""
    yaw = np.r_[np.zeros(n // 2), np.linspace(0, np.pi / 2, n - n // 2)]  # radians about +Y
    q = axis_angle_to_quat(torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64).expand(n, 3),
                           torch.from_numpy(yaw))
    heading = quat_rotate(q, torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64).expand(n, 3)).numpy()  # (n, 3)
    return np.cumsum(heading * (2.0 / n), axis=0)


def _display_path(ax, path: np.ndarray) -> np.ndarray:
    """(n, 3) world points plotted as (x, z) -> (n, 2) display pixels (x right, y up the page)."""
    ax.plot(*floor_xz(path))
    ax.figure.canvas.draw()
    return ax.transData.transform(np.stack(floor_xz(path), -1))


def _turn_sign(px: np.ndarray) -> float:
    """Total signed turning of a display path, radians: > 0 counter-clockwise on the page (a left turn)."""
    d = np.diff(px, axis=0)
    ang = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    return float(ang[-1] - ang[0])


def test_the_known_answer_is_a_left_turn():
    # the character's left is +X, and the turning path ends towards +X having started along +Z
    assert Skeleton.canonical().offsets[Skeleton.canonical().index("LeftUpLeg"), 0] > 0
    path = _left_turn()
    assert path[-1, 0] > 0.5 and abs(path[0, 0]) < 1e-9
    assert np.allclose(np.diff(path[:, 2])[:5], 2.0 / 60)


def test_top_view_shows_a_left_turn_as_a_left_turn():
    fig, ax = plt.subplots(figsize=(4, 4))
    top_view(ax, title="from above")
    px = _display_path(ax, _left_turn())
    plt.close(fig)
    assert _turn_sign(px) == pytest.approx(np.pi / 2, abs=0.05)  # a quarter turn, counter-clockwise
    assert px[-1, 0] < px[0, 0] - 20  # ends on the left of the page
    assert px[-1, 1] > px[0, 1] + 20  # having walked up the page (forward, +Z)
    assert ax.get_xlabel().startswith("x (m)") and ax.get_ylabel().startswith("z (m)")


def test_plain_axes_show_the_view_from_below():
    # the bug top_view fixes: x right and z up is the floor seen from below, the turn goes clockwise
    fig, ax = plt.subplots(figsize=(4, 4))
    ax.set_aspect("equal")
    px = _display_path(ax, _left_turn())
    plt.close(fig)
    assert _turn_sign(px) == pytest.approx(-np.pi / 2, abs=0.05)


def test_top_view_matches_the_stick_figure_top_view():
    # render's 2-D "top" view (image right, image up) and a top_view Axes put a step in the same direction
    fig, ax = plt.subplots(figsize=(4, 4))
    top_view(ax)
    steps = np.array([[0.0, 0, 0], [1.0, 0, 0], [0.0, 0, 1.0], [1.0, 0, 1.0]])
    ax.set(xlim=(2, -2), ylim=(-2, 2))
    fig.canvas.draw()
    px = ax.transData.transform(np.stack(floor_xz(steps), -1))
    plt.close(fig)
    uv = render.project(steps, "top")
    assert np.array_equal(np.sign(np.diff(px, axis=0)), np.sign(np.diff(uv, axis=0)))


def test_top_view_is_idempotent_on_shared_axes():
    fig, axes = plt.subplots(1, 3, sharex=True, sharey=True)
    for a in axes:  # invert_xaxis would toggle the shared axis back and forth
        top_view(a)
    top_view(axes[0])
    fig.canvas.draw()  # "datalim" would raise here on Axes that share both axes; the default "box" does not
    plt.close(fig)
    assert all(a.xaxis_inverted() and not a.yaxis_inverted() for a in axes)


def test_floor_xz_checks_its_input():
    x, z = floor_xz(np.arange(12.0).reshape(2, 2, 3))
    assert x.shape == (2, 2) and np.array_equal(z, [[2, 5], [8, 11]])
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        floor_xz(np.zeros((4, 2)))


def test_contact_runs_known_answers():
    from course_lib.plots import contact_runs

    assert contact_runs([0, 1, 1, 0, 0, 1]) == [(1, 3), (5, 6)]
    assert contact_runs([1, 1, 1]) == [(0, 3)]
    assert contact_runs(np.zeros(4, bool)) == []
    with pytest.raises(ValueError, match=r"\(T,\)"):
        contact_runs(np.zeros((4, 2)))


def test_stance_bars_draw_one_bar_per_stance_run_at_its_time():
    from course_lib.plots import stance_bars

    c = np.zeros((30, 2), bool)
    c[0:10, 0], c[20:30, 0], c[5:15, 1] = True, True, True  # left: two stances, right: one
    fig, ax = plt.subplots()
    stance_bars(ax, [c], fps=10.0)
    left, right = ax.collections  # one collection of bars per foot (and row)
    spans = [[(round(float(p.vertices[:, 0].min()), 6), round(float(np.ptp(p.vertices[:, 0])), 6))
              for p in coll.get_paths()] for coll in (left, right)]
    assert spans == [[(0.0, 1.0), (2.0, 1.0)], [(0.5, 1.0)]]  # (start, duration) in seconds per stance run
    plt.close(fig)
