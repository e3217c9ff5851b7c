"""Dropped frames of a capture: a frame the capture lost holds the last good frame's values, bit for bit
(data_scripts/make_noisy.py does the same, ``synthetic.add_noise``).  Two consecutive frames of real motion are
never bit-identical, so a held frame is found exactly; its values say nothing about the pose it hides.

`held_frames` finds them; `fill_held` replaces each run by the interpolation between the frames around it (slerp
of every joint's rotation, linear root position), the start denoising low-passes (denoise.py), which also leaves
those frames out of its data term (`dropped_mask`).  A run longer than ``MAX_RUN`` frames, or one that reaches the
last frame, is left alone: a body can truly stand still, and a static clip must not lose all its data.

Taught in notebooks/04_map_control.ipynb.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from course_lib.motion import Motion
from course_lib.rotations import quat_slerp

__all__ = ["MAX_RUN", "dropped_mask", "dropped_runs", "fill_held", "held_frames"]


def held_frames(motion: Motion) -> np.ndarray:
    """motion -> (T,) bool: frame t >= 1 whose rotations and root position equal frame t - 1's exactly."""
    if not isinstance(motion, Motion):
        raise ValueError(f"held_frames: motion must be a Motion, got {type(motion).__name__}")
    same_rot = (motion.rotations[1:] == motion.rotations[:-1]).all(axis=(1, 2))
    same_root = (motion.root_positions[1:] == motion.root_positions[:-1]).all(axis=1)
    return np.concatenate(([False], same_rot & same_root))


MAX_RUN = 15  # frames (0.5 s at 30 fps): a longer run of identical frames is taken as a real stillness, kept


def dropped_runs(motion: Motion, max_run: int = MAX_RUN) -> list[tuple[int, int]]:
    """motion -> the runs [start, end) of held frames that `fill_held` interpolates: at most ``max_run`` frames
    long and followed by a good frame (a run that reaches the last frame, or a longer one, is left as it is)."""
    held = held_frames(motion)
    runs, T, t = [], len(motion), 1
    while t < T:
        if not held[t]:
            t += 1
            continue
        end = t
        while end < T and held[end]:
            end += 1
        if end < T and end - t <= max_run:
            runs.append((t, end))
        t = end
    return runs


def dropped_mask(motion: Motion, max_run: int = MAX_RUN) -> np.ndarray:
    """motion -> (T,) bool: the frames of `dropped_runs` (denoise leaves them out of its data term)."""
    mask = np.zeros(len(motion), bool)
    for a, b in dropped_runs(motion, max_run):
        mask[a:b] = True
    return mask


def fill_held(motion: Motion, max_run: int = MAX_RUN) -> Motion:
    """motion -> a copy with each run of `dropped_runs` interpolated between the frame before it and the first
    frame after it (slerp of the rotations, linear root); other frames unchanged."""
    runs = dropped_runs(motion, max_run)  # checks that motion is a Motion
    rot, root = motion.rotations.copy(), motion.root_positions.copy()
    for t, end in runs:
        a, b = t - 1, end  # the good frames around the run
        w = (np.arange(t, end) - a) / (b - a)  # (run,)
        q0 = torch.from_numpy(np.broadcast_to(rot[a], (len(w),) + rot[a].shape).copy())
        q1 = torch.from_numpy(np.broadcast_to(rot[b], (len(w),) + rot[b].shape).copy())
        rot[t:end] = quat_slerp(q0, q1, torch.from_numpy(w)[:, None]).numpy()  # t: (run, 1) over (run, J)
        root[t:end] = root[a] + w[:, None] * (root[b] - root[a])
    return replace(motion, rotations=rot, root_positions=root)
