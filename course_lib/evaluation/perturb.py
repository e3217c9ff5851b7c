"""Known changes to real motion, for testing measures: a measure must score a change a person would not
see (a small turn of every joint) far below one they would (time reversal, classes removed, noise).

Taught in notebooks/05_hierarchical_vrnn.ipynb (the known-answer section); used by tests/test_known_answers.py.
Each function returns new Motions and leaves its input untouched.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import torch

from course_lib.datasets import time_reversed
from course_lib.motion import Motion
from course_lib.rotations import axis_angle_to_quat, expmap_to_quat, quat_mul

__all__ = ["drop_labels", "joint_noise", "time_reversed", "turn_joints"]


def _check(motions) -> list[Motion]:
    if not motions or not all(isinstance(m, Motion) for m in motions):
        raise ValueError("expected a non-empty list of Motions")
    return list(motions)


def turn_joints(motions: list[Motion], degrees: float, seed: int = 0, joints=None) -> list[Motion]:
    """Every joint's local rotation (root included; or only those named in `joints`) turned by a constant
    `degrees` about a random axis (one axis per joint, the same for every clip and frame, seeded):
    q_j <- q_j r_j.  A few degrees are invisible; every quaternion channel moves, fixed degrees of freedom
    included."""
    motions = _check(motions)
    J = motions[0].skeleton.num_joints
    axes = np.random.default_rng(seed).standard_normal((J, 3))
    angles = np.full(J, np.radians(degrees))
    if joints is not None:
        chosen = [motions[0].skeleton.index(name) for name in joints]
        angles[np.setdiff1d(np.arange(J), chosen)] = 0.0
    r = axis_angle_to_quat(torch.from_numpy(axes / np.linalg.norm(axes, axis=1, keepdims=True)),
                           torch.from_numpy(angles))  # (J, 4)
    return [dataclasses.replace(m, rotations=quat_mul(torch.from_numpy(m.rotations), r.expand(len(m), J, 4)).numpy())
            for m in motions]


def joint_noise(motions: list[Motion], degrees: float, seed: int = 0) -> list[Motion]:
    """Independent per-frame jitter: every joint turned by a random angle of sd `degrees` per axis (i.i.d.
    over joints and frames, seeded) -- visible as shaking from a few degrees on."""
    motions = _check(motions)
    rng = np.random.default_rng(seed)
    out = []
    for m in motions:
        v = np.radians(degrees) * rng.standard_normal((len(m), m.skeleton.num_joints, 3))  # (T, J, 3) expmaps
        r = expmap_to_quat(torch.from_numpy(v))
        out.append(dataclasses.replace(m, rotations=quat_mul(torch.from_numpy(m.rotations), r).numpy()))
    return out


def drop_labels(motions: list[Motion], attribute: str = "action", keep: int | None = None) -> list[Motion]:
    """Only the clips whose `attribute` label is among the first `keep` distinct values (sorted; default
    half of them): a set that lost part of its classes."""
    motions = _check(motions)
    values = sorted({getattr(m, attribute) for m in motions})
    kept = set(values[: keep if keep is not None else max(1, len(values) // 2)])
    return [m for m in motions if getattr(m, attribute) in kept]
