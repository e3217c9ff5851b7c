"""Spikes of a capture: a joint whose rotation on one frame jumps far from its neighbours' and back (a marker
swap, a solver flip; data_scripts/make_noisy.py draws them as 0.6-rad-sd kicks on 1-3 joints of 1 % of frames).

Eq. (25)'s Gaussian data term cannot tell a spike from motion: with sigma_angle 0.03 rad a 0.6-rad kick costs 200
nats, and the filter follows it part of the way.  So a spike is found before the search and treated as a missing
observation, as a dropped frame is (dropouts.py): `spike_mask` flags each (frame, joint) whose rotation is more
than ``threshold`` rad from the median of the ``window`` frames around it (a Hampel test: the median of 3 frames
ignores one outlier, and on a smooth rotation it is the frame itself to second order), `despike` replaces the
flagged rotations by the slerp between that joint's nearest unflagged frames, and denoise.py leaves those joints'
columns out of eq. (25).  Limits: the first and last frame are never flagged (their median window repeats them),
nor are two spikes of one joint on consecutive frames (the median of 3 then follows them).

Taught in notebooks/04_map_control.ipynb.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from course_lib.control.lowpass import continuous_quaternions
from course_lib.motion import Motion
from course_lib.rotations import quat_slerp

__all__ = ["SPIKE_ANGLE", "SPIKE_WINDOW", "despike", "median_deviation", "spike_mask"]

SPIKE_ANGLE = 0.35  # rad: a joint this far from its running median is a spike: just above the largest deviation
# of the held-out clean walks and runs (a running knee's turn-around)
SPIKE_WINDOW = 3  # frames of the running median (odd; it ignores (window - 1) / 2 outliers in a row); 5 frames put
# a running knee's turn-around above SPIKE_ANGLE


def median_deviation(motion: Motion, window: int = SPIKE_WINDOW, frames: np.ndarray | None = None) -> np.ndarray:
    """motion -> (T, J) the angle (rad) between each joint's rotation and the running median of its
    sign-continuous quaternions over ``window`` frames (component-wise, renormalised; the ends repeat, so the first
    and last frame deviate by 0 and are never flagged).  frames (T,) bool: only these frames are compared, with
    each other (a capture's held frames left out); the others get 0."""
    from scipy.ndimage import median_filter

    if not isinstance(motion, Motion):
        raise ValueError(f"spikes: motion must be a Motion, got {type(motion).__name__}")
    if window < 3 or window % 2 == 0:
        raise ValueError(f"spikes: window must be an odd number of frames >= 3, got {window}")
    if not np.isfinite(motion.rotations).all():
        raise ValueError("spikes: motion contains NaN or inf")
    keep = np.ones(len(motion), bool) if frames is None else np.asarray(frames, bool)
    if keep.shape != (len(motion),):
        raise ValueError(f"spikes: frames must be a ({len(motion)},) bool array, got shape {keep.shape}")
    out = np.zeros(motion.rotations.shape[:2])
    if keep.any():
        q = continuous_quaternions(motion.rotations[keep])
        med = median_filter(q, size=(window, 1, 1), mode="nearest")
        med /= np.linalg.norm(med, axis=-1, keepdims=True)
        out[keep] = 2 * np.arccos(np.clip(np.abs((q * med).sum(-1)), 0.0, 1.0))
    return out


def spike_mask(motion: Motion, threshold: float = SPIKE_ANGLE, window: int = SPIKE_WINDOW,
               frames: np.ndarray | None = None) -> np.ndarray:
    """motion -> (T, J) bool: the (frame, joint) rotations more than ``threshold`` rad from their running median
    (`median_deviation`; frames: only those frames are tested, with each other)."""
    if not (np.isfinite(threshold) and threshold > 0):
        raise ValueError(f"spikes: threshold must be an angle > 0 (rad), got {threshold!r}")
    return median_deviation(motion, window, frames) > threshold


def despike(motion: Motion, mask: np.ndarray) -> Motion:
    """motion, mask (T, J) bool -> a copy whose flagged rotations are the slerp between the same joint's nearest
    unflagged frames before and after (the nearest one at an end of the clip); other values unchanged."""
    T, J = motion.rotations.shape[:2]
    mask = np.asarray(mask)
    if mask.shape != (T, J) or mask.dtype != bool:
        raise ValueError(f"despike: mask must be a ({T}, {J}) bool array, got {mask.shape} {mask.dtype}")
    rot = motion.rotations.copy()
    for j in np.nonzero(mask.any(0))[0]:
        good = np.nonzero(~mask[:, j])[0]
        if len(good) == 0:
            raise ValueError(f"despike: joint {j} is flagged on every frame; nothing to interpolate from")
        for t in np.nonzero(mask[:, j])[0]:
            after = np.searchsorted(good, t)
            a = good[max(after - 1, 0)]
            b = good[min(after, len(good) - 1)]
            w = 0.0 if a == b else (t - a) / (b - a)
            rot[t, j] = quat_slerp(torch.from_numpy(rot[a, j]), torch.from_numpy(rot[b, j]), w).numpy()
    return replace(motion, rotations=rot)
