"""Zero-phase low-pass filters of a Motion: the denoising baselines a reader tries first, and where the MAP
filter's search starts (denoise.py).

Each channel a capture stores is filtered in time: the root's world position (x, y, z) and every joint's local
rotation as a quaternion, its sign made continuous in time first (q and -q are one rotation; a sign flip is not
motion) and the result normalised.  Absolute channels, not the per-frame steps of eq. (3): a filtered heading
change integrated over a clip drifts, so the filter would be scored on its integration, not on its smoothing.

Taught in notebooks/04_map_control.ipynb.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from course_lib.motion import Motion

__all__ = ["BUTTER_MIN_FRAMES", "KINDS", "lowpass", "continuous_quaternions"]

KINDS = ("butter", "savgol")
BUTTER_MIN_FRAMES = 16  # filtfilt pads 3 x (order + 1) = 15 frames at each end of a 4th-order filter


def continuous_quaternions(q: np.ndarray) -> np.ndarray:
    """(T, J, 4) unit quaternions -> the same rotations with each q_t's sign chosen so that q_t . q_{t-1} >= 0."""
    q = np.asarray(q, dtype=np.float64)
    if q.ndim != 3 or q.shape[-1] != 4:
        raise ValueError(f"continuous_quaternions: q must be (T, J, 4), got shape {q.shape}")
    flip = np.concatenate((np.zeros((1, q.shape[1]), bool), (q[1:] * q[:-1]).sum(-1) < 0))
    return q * np.where(np.cumsum(flip, axis=0) % 2, -1.0, 1.0)[..., None]


def lowpass(motion: Motion, kind: str = "butter", param: float = 6.0) -> Motion:
    """motion -> a copy filtered channel by channel in time (zero phase), same length and skeleton.

    kind "butter": a 4th-order Butterworth low-pass with cutoff `param` Hz, run forward and backward
    (scipy.signal.filtfilt); kind "savgol": a cubic Savitzky-Golay filter over `param` frames (odd, >= 5)."""
    from scipy.signal import butter, filtfilt, savgol_filter

    if not isinstance(motion, Motion):
        raise ValueError(f"lowpass: motion must be a Motion, got {type(motion).__name__}")
    if not (np.isfinite(motion.rotations).all() and np.isfinite(motion.root_positions).all()):
        raise ValueError("lowpass: motion contains NaN or inf")
    T = len(motion)
    if kind == "butter":
        nyquist = motion.fps / 2
        if not 0 < param < nyquist:
            raise ValueError(f"lowpass: a Butterworth cutoff must be in (0, {nyquist}) Hz at {motion.fps} fps, "
                             f"got {param}")
        b, a = butter(4, param / nyquist)
        if T < BUTTER_MIN_FRAMES:
            raise ValueError(f"lowpass: a 4th-order Butterworth needs at least {BUTTER_MIN_FRAMES} frames, got {T}")

        def run(x):
            return np.ascontiguousarray(filtfilt(b, a, x, axis=0))
    elif kind == "savgol":
        if param != int(param) or int(param) % 2 == 0 or not 5 <= param <= T:
            raise ValueError(f"lowpass: a Savitzky-Golay window must be an odd number of frames in [5, {T}], "
                             f"got {param}")

        def run(x):
            return np.ascontiguousarray(savgol_filter(x, int(param), 3, axis=0))
    else:
        raise ValueError(f"lowpass: kind must be one of {KINDS}, got {kind!r}")
    q = run(continuous_quaternions(motion.rotations))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return replace(motion, rotations=q, root_positions=run(motion.root_positions),
                   meta=dict(motion.meta, lowpass=(kind, param)))
