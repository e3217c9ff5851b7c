"""Every quaternion and rotation formula of the course, in one place.

Conventions (stated once, used everywhere):
- quaternions are (w, x, y, z), unit norm, Hamilton product; ``q`` and ``-q``
  are the same rotation;
- all functions are torch, batched over any leading dimensions ``(...)``,
  differentiable, and have no NaN values or gradients at the identity or at
  180 degrees (the small-angle branches use Taylor series, never 0/0);
- rotation matrices act on column vectors: ``v' = R v``.

Taught in notebooks/00_skeletons_and_rotations.ipynb.
"""

from __future__ import annotations

import torch

_EPS = 1e-8


def _check_last(x: torch.Tensor, n: int, name: str) -> None:
    if x.shape[-1] != n:
        raise ValueError(f"{name}: expected last dimension {n}, got shape {tuple(x.shape)}")


def _safe_norm(v: torch.Tensor, eps: float = 1e-12) -> tuple[torch.Tensor, torch.Tensor]:
    """(..., D) -> (norm (...), small (...) bool).  The norm's gradient is finite at 0."""
    sq = (v * v).sum(-1)
    small = sq < eps
    return torch.sqrt(torch.where(small, torch.ones_like(sq), sq)), small


def quat_identity(shape: tuple[int, ...] = (), dtype=torch.float32) -> torch.Tensor:
    """-> (*shape, 4) identity quaternions (1, 0, 0, 0)."""
    q = torch.zeros(*shape, 4, dtype=dtype)
    q[..., 0] = 1.0
    return q


def quat_mul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Hamilton product a * b: (..., 4), (..., 4) -> (..., 4); b is applied first."""
    _check_last(a, 4, "quat_mul a")
    _check_last(b, 4, "quat_mul b")
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack(
        (
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ),
        dim=-1,
    )


def quat_conjugate(q: torch.Tensor) -> torch.Tensor:
    """(..., 4) -> (..., 4) conjugate (w, -x, -y, -z), the inverse of a unit quaternion."""
    _check_last(q, 4, "quat_conjugate")
    return q * q.new_tensor([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q: torch.Tensor) -> torch.Tensor:
    """(..., 4) -> (..., 4) unit quaternions; raises on (near) zero quaternions."""
    _check_last(q, 4, "quat_normalize")
    n = torch.linalg.vector_norm(q, dim=-1, keepdim=True)
    if bool((n < _EPS).any()):
        raise ValueError("quat_normalize: a quaternion has (near) zero norm and no direction")
    return q / n


def quat_canonical(q: torch.Tensor) -> torch.Tensor:
    """(..., 4) -> (..., 4) the representative of q / -q with w >= 0."""
    return torch.where(q[..., :1] < 0, -q, q)


def quat_rotate(q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Rotate vectors: q (..., 4) unit, v (..., 3) -> (..., 3).  v' = q v q*."""
    _check_last(q, 4, "quat_rotate q")
    _check_last(v, 3, "quat_rotate v")
    w, u = q[..., :1], q[..., 1:]
    # v' = v + 2w (u x v) + 2 u x (u x v)   (expanded q v q*, fewer flops)
    t = 2.0 * torch.linalg.cross(u.expand_as(v), v, dim=-1)
    return v + w * t + torch.linalg.cross(u.expand_as(t), t, dim=-1)


def quat_to_matrix(q: torch.Tensor) -> torch.Tensor:
    """(..., 4) unit quaternions -> (..., 3, 3) rotation matrices."""
    _check_last(q, 4, "quat_to_matrix")
    w, x, y, z = q.unbind(-1)
    rows = (
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    )
    return torch.stack(rows, dim=-1).reshape(*q.shape[:-1], 3, 3)


def matrix_to_quat(m: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) rotation matrices -> (..., 4) unit quaternions with w >= 0.

    Shepperd's method: of the four algebraically equal formulas, use the one
    whose denominator is largest (>= 1/2), so nothing divides by ~0 at 180 degrees.
    """
    if m.shape[-2:] != (3, 3):
        raise ValueError(f"matrix_to_quat: expected (..., 3, 3), got {tuple(m.shape)}")
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    # 4 q_i^2 for i = w, x, y, z
    four_sq = torch.stack(
        (1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22), -1
    )
    # 2 |q_i|; clamp keeps the sqrt (and its gradient) finite for the unused candidates
    two_abs = torch.sqrt(four_sq.clamp_min(0.1))
    cand = torch.stack(
        (
            torch.stack((four_sq[..., 0], m21 - m12, m02 - m20, m10 - m01), -1),
            torch.stack((m21 - m12, four_sq[..., 1], m10 + m01, m02 + m20), -1),
            torch.stack((m02 - m20, m10 + m01, four_sq[..., 2], m12 + m21), -1),
            torch.stack((m10 - m01, m20 + m02, m21 + m12, four_sq[..., 3]), -1),
        ),
        dim=-2,
    ) / (2.0 * two_abs[..., None])  # (..., 4 candidates, 4)
    best = four_sq.argmax(-1)  # (...)
    q = torch.gather(cand, -2, best[..., None, None].expand(*best.shape, 1, 4)).squeeze(-2)
    return quat_canonical(q / torch.linalg.vector_norm(q, dim=-1, keepdim=True))


def quat_to_expmap(q: torch.Tensor) -> torch.Tensor:
    """(..., 4) unit quaternions -> (..., 3) axis * angle, angle in [0, pi]."""
    _check_last(q, 4, "quat_to_expmap")
    q = quat_canonical(q)
    w, u = q[..., 0], q[..., 1:]
    n, small = _safe_norm(u)
    # angle = 2 atan2(|u|, w);  expmap = u * angle / |u|;  |u| -> 0: factor -> 2/w (1 - |u|^2 / 3w^2)
    w_safe = torch.where(small, w.clamp_min(0.5), w)
    factor = torch.where(small, 2.0 / w_safe * (1 - (u * u).sum(-1) / (3 * w_safe**2)),
                         2.0 * torch.atan2(n, w) / n)
    return u * factor[..., None]


def expmap_to_quat(r: torch.Tensor) -> torch.Tensor:
    """(..., 3) axis * angle -> (..., 4) unit quaternions."""
    _check_last(r, 3, "expmap_to_quat")
    a, small = _safe_norm(r)
    sq = (r * r).sum(-1)
    # q = (cos(a/2), sin(a/2)/a * r);  sin(a/2)/a -> 1/2 - a^2/48 near 0
    sinc = torch.where(small, 0.5 - sq / 48.0, torch.sin(a / 2) / a)
    w = torch.where(small, 1 - sq / 8.0, torch.cos(a / 2))
    return torch.cat((w[..., None], r * sinc[..., None]), -1)


def axis_angle_to_quat(axis: torch.Tensor, angle: torch.Tensor) -> torch.Tensor:
    """axis (..., 3) (any nonzero length), angle (...) radians -> (..., 4)."""
    _check_last(axis, 3, "axis_angle_to_quat")
    axis = axis / torch.linalg.vector_norm(axis, dim=-1, keepdim=True)
    half = 0.5 * angle
    return torch.cat((torch.cos(half)[..., None], axis * torch.sin(half)[..., None]), -1)


def quat_slerp(q0: torch.Tensor, q1: torch.Tensor, t: torch.Tensor | float) -> torch.Tensor:
    """Spherical interpolation along the short arc: (..., 4), (..., 4), t (...) -> (..., 4)."""
    _check_last(q0, 4, "quat_slerp q0")
    _check_last(q1, 4, "quat_slerp q1")
    t = torch.as_tensor(t, dtype=q0.dtype)
    dot = (q0 * q1).sum(-1)
    q1 = torch.where(dot[..., None] < 0, -q1, q1)  # short arc
    dot = dot.abs().clamp(max=1.0)
    theta = torch.acos(torch.where(dot > 0.9995, torch.zeros_like(dot), dot))
    sin_theta = torch.sin(theta)
    near = dot > 0.9995  # nearly parallel: linear interpolation, then normalise
    s = torch.where(near, torch.ones_like(sin_theta), sin_theta)
    w0 = torch.where(near, 1 - t, torch.sin((1 - t) * theta) / s)
    w1 = torch.where(near, t * torch.ones_like(theta), torch.sin(t * theta) / s)
    q = w0[..., None] * q0 + w1[..., None] * q1
    return q / torch.linalg.vector_norm(q, dim=-1, keepdim=True)
