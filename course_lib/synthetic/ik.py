"""Kinematic building blocks of the synthetic generator: axis rotations, two-bone IK, FK on matrices.

Everything is numpy, batched over a leading time axis (T, ...), so a clip is
posed with a few array operations rather than a loop over frames.  Rotation
matrices act on column vectors (v' = R v), the convention of rotations.py; the
final conversion to quaternions goes through `rotations.matrix_to_quat`.

Taught in notebooks/00_skeletons_and_rotations.ipynb (the data lesson).
"""

from __future__ import annotations

import numpy as np
import torch

from course_lib.rotations import expmap_to_quat, matrix_to_quat, quat_to_expmap, quat_to_matrix


def rot(axis: str, angle) -> np.ndarray:
    """Rotation about a coordinate axis: angle (...) radians -> (..., 3, 3)."""
    a = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]  # the rotated plane, i -> j for positive angles
    out = np.zeros(a.shape + (3, 3))
    k = 3 - i - j
    out[..., k, k] = 1.0
    out[..., i, i], out[..., j, j] = c, c
    out[..., j, i], out[..., i, j] = s, -s
    return out


def mm(*ms: np.ndarray) -> np.ndarray:
    """Product of (..., 3, 3) matrices, left to right."""
    out = ms[0]
    for m in ms[1:]:
        out = out @ m
    return out


def apply(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """m (..., 3, 3), v (..., 3) -> (..., 3)."""
    return np.einsum("...ij,...j->...i", m, v)


def unit(v: np.ndarray) -> np.ndarray:
    """(..., 3) -> (..., 3) unit vectors."""
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def bone_frame(bone_dir: np.ndarray, pole: np.ndarray, rest_bone: np.ndarray, rest_pole: np.ndarray) -> np.ndarray:
    """Global rotation taking a bone's rest direction to bone_dir, its rest pole side towards pole.

    bone_dir, pole: (T, 3); rest_bone, rest_pole: (3,) orthogonal unit vectors -> (T, 3, 3).
    """
    b = unit(bone_dir)
    p = unit(pole - np.sum(pole * b, -1, keepdims=True) * b)  # Gram-Schmidt
    target = np.stack([b, p, np.cross(b, p)], -1)  # columns
    rest = np.stack([rest_bone, rest_pole, np.cross(rest_bone, rest_pole)], -1)
    return target @ rest.T


def two_bone_ik(root: np.ndarray, target: np.ndarray, pole: np.ndarray, l1: float, l2: float,
                max_reach: float = 0.9995, max_bend: float = np.pi) -> tuple[np.ndarray, np.ndarray]:
    """Analytic two-bone IK (law of cosines) in the plane of root, target and pole.

    root, target, pole: (T, 3) (pole is a direction the middle joint bends towards)
    -> mid (T, 3), end (T, 3).  The distance is clamped to [d(max_bend), max_reach (l1 + l2)],
    d(theta) = sqrt(l1^2 + l2^2 + 2 l1 l2 cos theta) for a middle-joint flexion theta, so a knee
    never snaps straight (no popping), never over-flexes, and never flips (it stays on the pole side).
    """
    d = target - root
    dist = np.linalg.norm(d, axis=-1)
    u = d / dist[:, None]
    d_min = np.sqrt(max(l1 ** 2 + l2 ** 2 + 2 * l1 * l2 * np.cos(max_bend), 0.0))
    dist = np.clip(dist, max(d_min, abs(l1 - l2) + 1e-4), max_reach * (l1 + l2))
    # cos(alpha) = (l1^2 + d^2 - l2^2) / (2 l1 d), alpha the angle at the root joint
    cos_a = np.clip((l1 ** 2 + dist ** 2 - l2 ** 2) / (2 * l1 * dist), -1.0, 1.0)
    f = unit(pole - np.sum(pole * u, -1, keepdims=True) * u)
    mid = root + l1 * (cos_a[:, None] * u + np.sqrt(1 - cos_a ** 2)[:, None] * f)
    return mid, root + dist[:, None] * u


def limb_rotations(root, mid, end, pole, rest_bone, rest_pole) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations of the two bones of a limb solved by `two_bone_ik`.

    root, mid, end, pole: (T, 3); rest_bone: (3,) rest direction of both bones, rest_pole: (3,)
    the side the middle joint bends towards at rest -> (upper (T, 3, 3), lower (T, 3, 3)).
    Both bones share one hinge axis n = u x f, taken from the IK plane (u: root -> end, f: the
    pole projected off u, as in `two_bone_ik`), so the middle joint is a pure hinge.  Projecting
    the pole off each bone instead flips the frame by 180 degrees when a bone nears the pole
    direction (a high knee in a run).
    """
    rb, rp = np.asarray(rest_bone, np.float64), np.asarray(rest_pole, np.float64)
    u = unit(end - root)
    n = np.cross(u, unit(pole - np.sum(pole * u, -1, keepdims=True) * u))  # (T, 3) hinge axis
    upper, lower = unit(mid - root), unit(end - mid)
    # each bone's bend side is n x b: for the upper bone it is the pole side of the IK plane
    return bone_frame(upper, np.cross(n, upper), rb, rp), bone_frame(lower, np.cross(n, lower), rb, rp)


def fk_matrices(local: np.ndarray, root: np.ndarray, offsets: np.ndarray, parents) -> tuple[np.ndarray, np.ndarray]:
    """local (T, J, 3, 3), root (T, 3), offsets (J, 3) -> global (T, J, 3, 3), positions (T, J, 3)."""
    G = np.empty_like(local)
    P = np.empty(local.shape[:2] + (3,))
    G[:, 0], P[:, 0] = local[:, 0], root
    for j in range(1, len(parents)):
        p = parents[j]
        G[:, j] = G[:, p] @ local[:, j]
        P[:, j] = P[:, p] + G[:, p] @ offsets[j]
    return G, P


def local_from_global(G: np.ndarray, parents) -> np.ndarray:
    """global (T, J, 3, 3) -> local (T, J, 3, 3):  L_j = G_parent^T G_j."""
    L = G.copy()
    for j in range(1, len(parents)):
        L[:, j] = np.swapaxes(G[:, parents[j]], -1, -2) @ G[:, j]
    return L


def matrices_to_quats(m: np.ndarray) -> np.ndarray:
    """(T, J, 3, 3) -> (T, J, 4) unit quaternions, signs made continuous over time (q_t . q_{t-1} >= 0)."""
    q = matrix_to_quat(torch.from_numpy(np.ascontiguousarray(m))).numpy()
    if len(q) > 1:
        flip = np.sum(q[1:] * q[:-1], -1) < 0  # (T-1, J)
        sign = np.concatenate([np.ones((1, q.shape[1])), np.cumprod(np.where(flip, -1.0, 1.0), 0)], 0)
        q = q * sign[..., None]
    return q


def scale_rotation(m: np.ndarray, k) -> np.ndarray:
    """m (..., 3, 3), k (...) or float -> the rotation by k times m's angle about m's axis."""
    r = quat_to_expmap(matrix_to_quat(torch.from_numpy(np.ascontiguousarray(m))))
    r = r * torch.as_tensor(np.asarray(k, np.float64))[..., None]
    return quat_to_matrix(expmap_to_quat(r)).numpy()
