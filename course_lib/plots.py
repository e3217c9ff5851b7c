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

The benchmark's figures (lesson 07): `benchmark_panels` and `benchmark_quality_speed` draw every model in one
colour of its own (`MODEL_COLOURS`) in every figure; C2ST's panel marks its target, 0.5 (chance).
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


# ----------------------------------------------------------------------------- lesson 07: the benchmark's figures

# one colour per benchmark row, the same in every figure (matplotlib's tab10, then two greys for the extra rows)
MODEL_COLOURS = {
    "Mocap": "black", "ERD": "tab:brown", "LSTM-3LR": "tab:pink", "cRBM (CD-15)": "tab:olive",
    "VAE-LSTM": "tab:blue", "GMM-RNN": "tab:orange", "GMM-RNN + refiner (GAN2 + contacts)": "tab:red",
    "GMM-RNN, online control": "tab:purple", "HVRNN (Proposed)": "tab:green", "QuaterNet-style GRU": "tab:gray",
    "MoGlow": "tab:cyan", "Motion matching": "goldenrod", "Motion matching, control": "navy",
}
SHORT_NAMES = {"cRBM (CD-15)": "cRBM", "GMM-RNN + refiner (GAN2 + contacts)": "GMM+GAN2",
               "GMM-RNN, online control": "GMM online", "HVRNN (Proposed)": "HVRNN", "QuaterNet-style GRU": "QuaterNet",
               "Motion matching": "MM", "Motion matching, control": "MM control"}
_LOG_SCALE = ("foot_skate", "foot_skate_auto", "nn_distance",
              "jitter", "fid", "bone_length", "penetration", "apd", "fps", "params", "train_seconds")
_TARGETS = {"c2st": (0.5, "target 0.5 (chance): the sets cannot be told apart")}  # a fixed target, not the Mocap row


def model_colour(name: str, k: int = 0) -> str:
    """The benchmark row's colour (MODEL_COLOURS); a row not listed gets a colour of its own from tab20 by ``k``."""
    import matplotlib.pyplot as plt

    return MODEL_COLOURS.get(name, plt.cm.tab20(k % 20))


def _spread(row: dict, key: str) -> np.ndarray | float:
    """The error bar of a row's cell: its 95 % interval where recorded ([[below], [above]] the mean), else the sd."""
    m, ci = row["mean"][key], row.get("ci", {}).get(key)
    if ci is None:
        return row["sd"].get(key, 0.0)
    return np.array([[max(m - ci[0], 0.0)], [max(ci[1] - m, 0.0)]])


def _goal(key: str, better: str) -> str:
    if key in _TARGETS:
        return _TARGETS[key][1]
    return {"low": "lower is better", "high": "higher is better", "ref": "target: the Mocap row (dashed)"}[better]


def benchmark_panels(results: dict, measures=None, cols: int = 4, width: float = 16.0):
    """Lesson 07's results as one panel per measure: a bar per row in its MODEL_COLOURS colour (mean over the
    seeds, its 95 % interval as an error bar, or the seeds' sd for results without intervals), the Mocap row's
    value dashed, a fixed target (C2ST: 0.5) dotted, "n/a" for
    a blank.  results: `course_lib.benchmark.run`'s dict (its "measures": key -> (label, unit, better)).
    -> the matplotlib Figure."""
    import matplotlib.pyplot as plt

    info = results["measures"]
    measures = list(measures or info)
    names = list(results["rows"])
    rows_n = -(-len(measures) // cols)
    fig, axes = plt.subplots(rows_n, cols, figsize=(width, 3.9 * rows_n), squeeze=False)
    for ax, key in zip(axes.flat, measures, strict=False):
        label, unit, better = info[key]
        log = key in _LOG_SCALE
        for i, name in enumerate(names):
            row = results["rows"][name]
            m = row["mean"].get(key)
            if m is not None and not (log and m <= 0):
                ax.bar(i, m, yerr=_spread(row, key), color=model_colour(name, i), capsize=3)
            else:  # a blank, or a 0 that a log axis cannot draw
                ax.text(i, 0.03, "n/a" if m is None else "0", ha="center", va="bottom", fontsize=10,
                        transform=ax.get_xaxis_transform(), color="0.3")
        if key in _TARGETS:
            ax.axhline(_TARGETS[key][0], color="k", ls=":", lw=1.5)
        else:
            mocap = results["rows"].get("Mocap", {}).get("mean", {}).get(key)
            if mocap is not None and not (log and mocap <= 0):
                ax.axhline(mocap, color="k", ls="--", lw=1)
        if log:
            ax.set_yscale("log")
        ax.set_title(f"{label}" + (f" ({unit})" if unit else "") + f"\n{_goal(key, better)}", fontsize=11)
        ax.set_xticks(range(len(names)), [SHORT_NAMES.get(n, n) for n in names], rotation=60, ha="right",
                      fontsize=10)
    for ax in list(axes.flat)[len(measures):]:
        ax.axis("off")
    fig.tight_layout()
    return fig


def benchmark_quality_speed(results: dict, qualities=("fid", "foot_skate"), size=(16.0, 6.0), real_time: float = 30.0):
    """Each quality (log) against generation speed (frames per second on one core, log), one panel each: a point
    per row in its MODEL_COLOURS colour with its 95 % intervals (or the seeds' sd) as error bars, the Mocap row
    dashed, real time (``real_time`` frames/s) dotted.  -> the matplotlib Figure."""
    import matplotlib.pyplot as plt

    info = results["measures"]
    fig, axes = plt.subplots(1, len(qualities), figsize=size, squeeze=False)
    for ax, quality in zip(axes[0], qualities, strict=True):
        for i, (name, row) in enumerate(results["rows"].items()):
            m = row["mean"]
            if quality in m and "fps" in m:
                ax.errorbar(m["fps"], m[quality], xerr=_spread(row, "fps"), yerr=_spread(row, quality), fmt="o",
                            ms=8, capsize=3, color=model_colour(name, i))
                ax.annotate(SHORT_NAMES.get(name, name), (m["fps"], m[quality]), textcoords="offset points",
                            xytext=(6, 4), fontsize=10, color=model_colour(name, i))
        mocap = results["rows"].get("Mocap", {}).get("mean", {}).get(quality)
        if mocap:
            ax.axhline(mocap, color="k", ls="--", lw=1, label=f"Mocap (half vs half): {mocap:.3g}")
        ax.axvline(real_time, color="0.5", ls=":", lw=1, label=f"real time ({real_time:g} frames/s)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        label, unit, _ = info[quality]
        ax.set_xlabel(f"generation speed, {real_time:g}-fps frames per second on one core")
        ax.set_ylabel(label + (f" ({unit})" if unit else ""))
        ax.legend(loc="lower left", fontsize=10)
        ax.set_title(f"{label} against speed: lower right is better")
    fig.tight_layout()
    return fig
