"""A noise model of raw motion capture, for the denoising lessons (Wang et al., lesson 04).

Three kinds of corruption, each seeded:
- jitter: small Gaussian rotations on every joint and frame, q' = q * exp(eps), eps ~ N(0, jitter_sd^2 I)
  (axis-angle, radians), and Gaussian noise N(0, root_sd^2) on the root position (m);
- spikes: on a fraction `spike_rate` of frames, 1-3 random joints get a large random rotation
  (sd `spike_sd` rad) -- outlier poses, like swapped or occluded markers;
- dropped frames: runs of 1-4 frames (a fraction `drop_rate` of frames in all) hold the last
  good frame's values, as when a capture system loses track.

`add_noise` returns the noisy Motion; the clean one is in meta["clean"], the corrupted frames in
meta["noise"] (spike_frames (S,), dropped (T,) bool, and the parameters).

Taught in notebooks/04_motion_control_map.ipynb (denoising).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from course_lib.motion import Motion
from course_lib.rotations import expmap_to_quat, quat_mul


def add_noise(motion: Motion, jitter_sd: float = 0.02, root_sd: float = 0.005, spike_rate: float = 0.01,
              spike_sd: float = 0.6, drop_rate: float = 0.02, seed: int = 0) -> Motion:
    """motion (T frames, J joints) -> noisy copy with meta["clean"] = motion and meta["noise"] (see module)."""
    for name, v in (("jitter_sd", jitter_sd), ("root_sd", root_sd), ("spike_sd", spike_sd)):
        if v < 0:
            raise ValueError(f"add_noise: {name} must be >= 0, got {v}")
    for name, v in (("spike_rate", spike_rate), ("drop_rate", drop_rate)):
        if not 0 <= v < 1:
            raise ValueError(f"add_noise: {name} must be in [0, 1), got {v}")
    rng = np.random.default_rng(seed)
    T, J = motion.rotations.shape[:2]
    eps = rng.normal(0.0, jitter_sd, (T, J, 3))  # (T, J, 3) axis-angle
    spikes = np.nonzero(rng.random(T) < spike_rate)[0]
    for f in spikes:
        joints = rng.choice(J, size=int(rng.integers(1, 4)), replace=False)
        eps[f, joints] += rng.normal(0.0, spike_sd, (len(joints), 3))
    q = quat_mul(torch.from_numpy(motion.rotations), expmap_to_quat(torch.from_numpy(eps))).numpy()
    root = motion.root_positions + rng.normal(0.0, root_sd, (T, 3))
    dropped = _dropped_frames(T, drop_rate, rng)
    src = np.maximum.accumulate(np.where(dropped, 0, np.arange(T)))  # last good frame at or before each frame
    meta = dict(motion.meta, clean=motion, noise=dict(
        spike_frames=spikes, dropped=dropped, jitter_sd=jitter_sd, root_sd=root_sd, spike_rate=spike_rate,
        spike_sd=spike_sd, drop_rate=drop_rate, seed=seed))
    return replace(motion, rotations=q[src], root_positions=root[src], meta=meta)


def _dropped_frames(T: int, rate: float, rng: np.random.Generator) -> np.ndarray:
    """(T,) bool: runs of 1-4 frames, about rate * T frames in all; frame 0 is never dropped."""
    out = np.zeros(T, bool)
    starts = np.nonzero(rng.random(T) < rate / 2.5)[0]  # mean run length 2.5
    for s in starts[starts > 0]:
        out[s:s + int(rng.integers(1, 5))] = True
    return out
