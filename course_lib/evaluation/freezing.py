"""Does a long generated motion freeze?  Joint speed per frame and the freezing threshold from mocap.

An autoregressive model that "gradually converges to a static pose" (Wang, Chai et al. 2021, sec.
4.1.3) keeps a nearly constant joint speed; walking mocap never does.  A motion is frozen when the
variance over time of its mean joint speed falls under `freeze_floor`, a tenth of the least-varying
mocap clip's.  Taught in notebooks/03_gmm_rnn_refiner.ipynb; lesson 06 (MoGlow) uses the same test.
"""

from __future__ import annotations

import numpy as np

from course_lib.motion import Motion

__all__ = ["freeze_floor", "joint_speed"]


def joint_speed(positions, fps: float) -> np.ndarray:
    """positions (..., T, J, 3) world, metres -> mean joint speed per frame pair (..., T-1), m/s, root motion
    included: mean_j ||x_{t+1, j} - x_{t, j}|| * fps."""
    pos = np.asarray(positions)
    if pos.ndim < 3 or pos.shape[-1] != 3 or pos.shape[-3] < 2:
        raise ValueError(f"joint_speed: positions must be (..., T >= 2, J, 3), got {pos.shape}")
    if not fps > 0:
        raise ValueError(f"joint_speed: fps must be > 0, got {fps}")
    return np.linalg.norm(np.diff(pos, axis=-3), axis=-1).mean(-1) * fps


def freeze_floor(mocap: list[Motion]) -> float:
    """The freezing threshold, (m/s)^2: a tenth of the smallest per-clip variance over time of `joint_speed`
    among the mocap clips (each at its own fps)."""
    if not mocap:
        raise ValueError("freeze_floor: no mocap clips given")
    return 0.1 * float(min(joint_speed(m.positions(), m.fps).var() for m in mocap))
