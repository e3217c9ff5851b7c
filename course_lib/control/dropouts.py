"""Dropped frames of a capture: a frame the capture lost holds the last good frame's values, bit for bit
(data_scripts/make_noisy.py does the same, ``synthetic.add_noise``).  Two consecutive frames of real motion are
never bit-identical, so a held frame is found exactly; its values say nothing about the pose it hides.

`held_frames` finds them; `fill_held` replaces each run by the interpolation between the frames around it (slerp
of every joint's rotation, linear root position), the start denoising low-passes (denoise.py).

Taught in notebooks/04_map_control.ipynb.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from course_lib.motion import Motion
from course_lib.rotations import quat_slerp

__all__ = ["held_frames", "fill_held"]


def held_frames(motion: Motion) -> np.ndarray:
    """motion -> (T,) bool: frame t >= 1 whose rotations and root position equal frame t - 1's exactly."""
    if not isinstance(motion, Motion):
        raise ValueError(f"held_frames: motion must be a Motion, got {type(motion).__name__}")
    same_rot = (motion.rotations[1:] == motion.rotations[:-1]).all(axis=(1, 2))
    same_root = (motion.root_positions[1:] == motion.root_positions[:-1]).all(axis=1)
    return np.concatenate(([False], same_rot & same_root))


def fill_held(motion: Motion) -> Motion:
    """motion -> a copy with each run of held frames interpolated between the frame before it and the first frame
    after it; a run that reaches the last frame keeps holding (nothing after it to interpolate to)."""
    held = held_frames(motion)
    rot, root = motion.rotations.copy(), motion.root_positions.copy()
    T, t = len(motion), 1
    while t < T:
        if not held[t]:
            t += 1
            continue
        end = t
        while end < T and held[end]:
            end += 1
        if end == T:
            break
        a, b = t - 1, end  # the good frames around the run
        w = (np.arange(t, end) - a) / (b - a)  # (run,)
        q0 = torch.from_numpy(np.broadcast_to(rot[a], (len(w),) + rot[a].shape).copy())
        q1 = torch.from_numpy(np.broadcast_to(rot[b], (len(w),) + rot[b].shape).copy())
        rot[t:end] = quat_slerp(q0, q1, torch.from_numpy(w)[:, None]).numpy()  # t: (run, 1) over (run, J)
        root[t:end] = root[a] + w[:, None] * (root[b] - root[a])
        t = end
    return replace(motion, rotations=rot, root_positions=root)
