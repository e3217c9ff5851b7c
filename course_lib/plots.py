"""2-D plots with matplotlib: the course's conventions set once, so that lesson cells stay short.

Top views.  The course is Y up and the character faces +Z at rest, so its left is +X.
Plotting x to the right and z up the page, as `ax.plot(x, z)` does by default, is the
floor seen from *below*: a left turn (yaw increasing, counter-clockwise seen from above)
then bends to the right of the page.  `top_view(ax)` makes an Axes show the floor seen
from above, as `render.stick_figure(..., view="top")` does: forward (+Z) up the page and
the x axis reversed, so +X (the character's left at rest) is on the left and a left turn
bends to the left.  Data are still plotted as `ax.plot(x, z)`; only the axis changes.

Taught in notebooks/00b_synthetic_data.ipynb (knob sweep 3, the heading rate); used by
the top views of lessons 02 and 03.
"""

from __future__ import annotations

import numpy as np


def top_view(ax, *, title: str | None = None, xlabel: bool = True, ylabel: bool = True, equal: bool = True,
             adjustable: str = "box"):
    """Make a matplotlib Axes show the floor (x, z) seen from above, Y up -> the same Axes.

    Plot world points as `ax.plot(x, z)`.  The x axis is reversed (+X, the character's
    left, is on the left of the page) and z points up the page.  Idempotent, and safe on
    Axes that share their x axis (`set_inverted`, not the toggling `invert_xaxis`).
    equal: equal scale on both axes; adjustable: matplotlib's way of keeping it ("box" works on Axes
    that share both axes, "datalim" fills a fixed panel).
    """
    ax.xaxis.set_inverted(True)
    if equal:
        ax.set_aspect("equal", adjustable=adjustable)
    if xlabel:
        ax.set_xlabel("x (m), +x to the left")
    if ylabel:
        ax.set_ylabel("z (m), forward at rest")
    if title is not None:
        ax.set_title(title)
    return ax


def floor_xz(points) -> tuple[np.ndarray, np.ndarray]:
    """Points (..., 3) in metres -> (x, z), each (...): the arguments of `ax.plot` on a `top_view` Axes."""
    p = np.asarray(points)
    if p.shape[-1] != 3:
        raise ValueError(f"floor_xz expects points (..., 3), got shape {p.shape}")
    return p[..., 0], p[..., 2]
