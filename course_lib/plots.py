"""2-D plots with matplotlib: the course's conventions set once, so that lesson cells stay short.

Top views.  The course is Y up and the character faces +Z at rest, so its left is +X.
Plotting x to the right and z up the page, as `ax.plot(x, z)` does by default, is the
floor seen from *below*: a left turn (yaw increasing, counter-clockwise seen from above)
then bends to the right of the page.  `top_view(ax)` makes an Axes show the floor seen
from above, as `render.stick_figure(..., view="top")` does: forward (+Z) up the page and
the x axis reversed, so +X (the character's left at rest) is on the left and a left turn
bends to the left.  Data are still plotted as `ax.plot(x, z)`; only the axis changes.

Timelines.  `control_timeline` puts a clip generated from a control program on one time axis:
its stick strip, speed, heading rate, gait and stance (`stance_bars`, from `contact_runs`).

Taught in notebooks/00b_synthetic_data.ipynb (knob sweep 3, the heading rate; the random control
program); used by the top views of lessons 02 and 03.
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


def contact_runs(contacts) -> list[tuple[int, int]]:
    """(T,) bool -> [(start, stop)) frame ranges where it is True, in order."""
    c = np.asarray(contacts, bool).astype(int)
    if c.ndim != 1:
        raise ValueError(f"contact_runs expects a (T,) array, got shape {c.shape}")
    edges = np.flatnonzero(np.diff(np.r_[0, c, 0]))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def stance_bars(ax, rows, fps: float, colors=("tab:blue", "tab:red"), names=("left", "right")):
    """Stance timelines: rows is a list of (T, 2) bool contacts (left, right), drawn as bars per foot, the first
    row solid and thick, later rows lighter and thinner (e.g. ground truth, then derived) -> the Axes."""
    for k, col in enumerate(colors):
        for r, c in enumerate(rows):
            runs = contact_runs(np.asarray(c)[:, k])
            ax.broken_barh([(a / fps, (b - a) / fps) for a, b in runs], (1 - k - 0.35 * r, 0.3 if r == 0 else 0.1),
                           color=col, alpha=1 if r == 0 else 0.5)
    ax.set(yticks=[1.0 - k for k in range(len(names))], yticklabels=list(names), ylim=(-0.6, 1.4), ylabel="stance")
    return ax


def control_timeline(clip, gaits, derived=None, n_panels: int = 9, title: str | None = None, figsize=(13, 8.5)):
    """A Motion generated from a control program (meta: speed, heading_rate, gait, contacts) on one time axis:
    a side-view stick strip with each panel centred on its frame's time, hips speed against the target, heading
    rate, gait, and stance (ground truth; `derived` (T, 2) contacts under it, lighter) -> the Figure."""
    import matplotlib.pyplot as plt

    from course_lib.render import stick_strip

    fps, T = clip.fps, len(clip)
    t = np.arange(T) / fps
    fig, ax = plt.subplots(5, 1, figsize=figsize, sharex=True, gridspec_kw=dict(height_ratios=[2.6, 1, 1, 1, 0.9]))
    half = clip.duration / (2 * (n_panels - 1))
    ax[0].imshow(stick_strip(clip, view="side", n=n_panels, size=(120, 100)),
                 extent=(-half, clip.duration + half, 0, 1), aspect="auto")  # panel centres on their frames' times
    ax[0].set_yticks([])
    ax[0].set_title(title)
    hips = np.linalg.norm(np.gradient(clip.root_positions[:, [0, 2]], axis=0), axis=-1) * fps
    ax[1].plot(t, hips, color="0.7", lw=1, label="hips (measured)")
    ax[1].plot(t, clip.meta["speed"], label="target")
    ax[1].set(ylabel="speed (m/s)")
    ax[1].legend(loc="upper left", fontsize=8)
    ax[2].plot(t, np.degrees(clip.meta["heading_rate"]))
    ax[2].set(ylabel="heading rate\n(deg/s)")
    ax[3].step(t, clip.meta["gait"], where="mid")
    ax[3].set(yticks=range(len(gaits)), yticklabels=list(gaits), ylabel="gait")
    ax[3].tick_params(axis="y", labelsize=7)
    stance_bars(ax[4], [clip.meta["contacts"]] + ([derived] if derived is not None else []), fps)
    ax[4].set_xlabel("time (s)")
    fig.tight_layout()
    return fig
