"""Every quaternion and rotation formula of the course, in one place.

Conventions (stated once, used everywhere):
- quaternions are (w, x, y, z), unit norm, Hamilton product; ``q`` and ``-q``
  are the same rotation;
- all functions are torch, batched over any leading dimensions ``(...)``,
  differentiable, and have no NaN values or gradients at the identity or at
  180 degrees (the small-angle branches use Taylor series, never 0/0);
- rotation matrices act on column vectors: ``v' = R v``;
- numpy arrays are accepted wherever a tensor is (converted, same dtype); results are tensors;
- invalid rotations raise ValueError instead of giving a silent wrong answer: a zero, NaN or
  clearly non-unit quaternion (| |q| - 1 | > UNIT_TOL) where a unit one is needed
  (`quat_to_matrix`, `quat_to_expmap`, `quat_to_euler`, `quat_to_sixd`, FK), a reflection
  (determinant -1) in `matrix_to_quat`, a zero axis with a non-zero angle in
  `axis_angle_to_quat`.  Norms within UNIT_TOL are used as given, so results for unit inputs
  are exactly those of the plain formulas.

Taught in notebooks/00_skeletons_and_rotations.ipynb.
"""

from __future__ import annotations

import functools

import numpy as np
import torch

_EPS = 1e-8
UNIT_TOL = 1e-2  # | |q| - 1 | above this is not a unit quaternion (rounding, normalised model outputs: far below)


def _tensor_args(fn):
    """Let `fn` take numpy arrays wherever it takes tensors (students pass ``motion.rotations``)."""
    def conv(a):
        return torch.from_numpy(np.ascontiguousarray(a)) if isinstance(a, np.ndarray) else a

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        return fn(*map(conv, args), **{k: conv(v) for k, v in kwargs.items()})
    return wrapper


def check_unit(q: torch.Tensor, name: str, dim: int = -1) -> None:
    """Raise ValueError unless every quaternion of q (components along `dim`) is finite with norm 1 +- UNIT_TOL."""
    with torch.no_grad():
        n = torch.linalg.vector_norm(q.detach(), dim=dim)
        if n.numel() == 0:
            return
        lo, hi = torch.aminmax(n)  # NaN anywhere gives NaN here, which fails both tests
        if not (bool(lo >= 1 - UNIT_TOL) and bool(hi <= 1 + UNIT_TOL)):
            bad = ~((n >= 1 - UNIT_TOL) & (n <= 1 + UNIT_TOL))
            where = tuple(int(i) for i in bad.nonzero()[0])
            norm = float(n[where])
            what = "0 (a zero quaternion is no rotation)" if norm < _EPS else f"{norm:.6g}"
            at = f" at index {where}" if where else ""
            raise ValueError(f"{name}: the quaternion{at} has norm {what}; expected unit quaternions "
                             f"(w, x, y, z) with | |q| - 1 | <= {UNIT_TOL}: normalise with quat_normalize, or look "
                             "for NaN or a zero")


def _check_last(x: torch.Tensor, n: int, name: str) -> None:
    if x.shape[-1] != n:
        raise ValueError(f"{name}: expected last dimension {n}, got shape {tuple(x.shape)}")


def _check_dim(x: torch.Tensor, n: int, name: str, dim: int) -> None:
    if x.dim() == 0 or x.shape[dim] != n:
        raise ValueError(f"{name}: expected size {n} in dimension {dim}, got shape {tuple(x.shape)}")


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


@_tensor_args
def quat_mul(a: torch.Tensor, b: torch.Tensor, dim: int = -1) -> torch.Tensor:
    """Hamilton product a * b: (..., 4), (..., 4) -> (..., 4); b is applied first.

    ``dim`` names the component axis (forward_kinematics uses a (J, 4, B) layout).
    """
    _check_dim(a, 4, "quat_mul a", dim)
    _check_dim(b, 4, "quat_mul b", dim)
    aw, ax, ay, az = a.unbind(dim)
    bw, bx, by, bz = b.unbind(dim)
    return torch.stack(
        (
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ),
        dim=dim,
    )


@_tensor_args
def quat_conjugate(q: torch.Tensor) -> torch.Tensor:
    """(..., 4) -> (..., 4) conjugate (w, -x, -y, -z), the inverse of a unit quaternion."""
    _check_last(q, 4, "quat_conjugate")
    return q * q.new_tensor([1.0, -1.0, -1.0, -1.0])


@_tensor_args
def quat_normalize(q: torch.Tensor) -> torch.Tensor:
    """(..., 4) -> (..., 4) unit quaternions; raises on (near) zero quaternions."""
    _check_last(q, 4, "quat_normalize")
    n = torch.linalg.vector_norm(q, dim=-1, keepdim=True)
    if bool((n < _EPS).any()):
        raise ValueError("quat_normalize: a quaternion has (near) zero norm and no direction")
    return q / n


@_tensor_args
def quat_canonical(q: torch.Tensor) -> torch.Tensor:
    """(..., 4) -> (..., 4) the representative of q / -q with w >= 0."""
    return torch.where(q[..., :1] < 0, -q, q)


@_tensor_args
def quat_rotate(q: torch.Tensor, v: torch.Tensor, dim: int = -1) -> torch.Tensor:
    """Rotate vectors: q (..., 4) unit, v (..., 3) -> (..., 3).  v' = q v q*.

    ``dim`` names the component axis; q and v broadcast against each other.
    """
    _check_dim(q, 4, "quat_rotate q", dim)
    _check_dim(v, 3, "quat_rotate v", dim)
    w, x, y, z = q.unbind(dim)
    vx, vy, vz = v.unbind(dim)
    # v' = v + w t + u x t,  t = 2 u x v   (expanded q v q*, fewer flops)
    tx, ty, tz = 2 * (y * vz - z * vy), 2 * (z * vx - x * vz), 2 * (x * vy - y * vx)
    return torch.stack((vx + w * tx + y * tz - z * ty, vy + w * ty + z * tx - x * tz,
                        vz + w * tz + x * ty - y * tx), dim=dim)


@_tensor_args
def quat_to_matrix(q: torch.Tensor) -> torch.Tensor:
    """(..., 4) unit quaternions -> (..., 3, 3) rotation matrices."""
    _check_last(q, 4, "quat_to_matrix")
    check_unit(q, "quat_to_matrix")
    w, x, y, z = q.unbind(-1)
    rows = (
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    )
    return torch.stack(rows, dim=-1).reshape(*q.shape[:-1], 3, 3)


@_tensor_args
def matrix_to_quat(m: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) rotation matrices -> (..., 4) unit quaternions with w >= 0.

    Raises ValueError on a matrix whose determinant is not 1 (+- UNIT_TOL): a reflection (-1)
    has no quaternion.  Shepperd's method: of the four algebraically equal formulas, use the one
    whose denominator is largest (>= 1/2), so nothing divides by ~0 at 180 degrees.
    """
    if m.shape[-2:] != (3, 3):
        raise ValueError(f"matrix_to_quat: expected (..., 3, 3), got {tuple(m.shape)}")
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    with torch.no_grad():
        det = m00 * (m11 * m22 - m12 * m21) - m01 * (m10 * m22 - m12 * m20) + m02 * (m10 * m21 - m11 * m20)
        bad = ~((det - 1).abs() <= UNIT_TOL)
        if bool(bad.any()):
            where = tuple(int(i) for i in bad.nonzero()[0])
            at = f" at index {where}" if where else ""
            raise ValueError(f"matrix_to_quat: the matrix{at} has determinant {float(det[where]):.6g}, "
                             "not 1: not a rotation (a reflection has -1, NaN entries give NaN); a rotation "
                             "nearby: gram_schmidt(m)")
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


@_tensor_args
def quat_to_expmap(q: torch.Tensor) -> torch.Tensor:
    """(..., 4) unit quaternions -> (..., 3) axis * angle, angle in [0, pi]."""
    _check_last(q, 4, "quat_to_expmap")
    check_unit(q, "quat_to_expmap")
    q = quat_canonical(q)
    w, u = q[..., 0], q[..., 1:]
    n, small = _safe_norm(u)
    # angle = 2 atan2(|u|, w);  expmap = u * angle / |u|;  |u| -> 0: factor -> 2/w (1 - |u|^2 / 3w^2)
    w_safe = torch.where(small, w.clamp_min(0.5), torch.ones_like(w))  # unused branch stays finite at w = 0
    factor = torch.where(small, 2.0 / w_safe * (1 - (u * u).sum(-1) / (3 * w_safe**2)),
                         2.0 * torch.atan2(n, w) / n)
    return u * factor[..., None]


@_tensor_args
def expmap_to_quat(r: torch.Tensor) -> torch.Tensor:
    """(..., 3) axis * angle -> (..., 4) unit quaternions."""
    _check_last(r, 3, "expmap_to_quat")
    a, small = _safe_norm(r)
    sq = (r * r).sum(-1)
    # q = (cos(a/2), sin(a/2)/a * r);  sin(a/2)/a -> 1/2 - a^2/48 near 0
    sinc = torch.where(small, 0.5 - sq / 48.0, torch.sin(a / 2) / a)
    w = torch.where(small, 1 - sq / 8.0, torch.cos(a / 2))
    return torch.cat((w[..., None], r * sinc[..., None]), -1)


@_tensor_args
def expmap_to_matrix(r: torch.Tensor) -> torch.Tensor:
    """(..., 3) axis * angle -> (..., 3, 3), Rodrigues' formula R = cos(a) I + sin(a)/a [r]x + (1 - cos(a))/a^2 r r^T
    (a = |r|); the same rotation as ``quat_to_matrix(expmap_to_quat(r))`` in fewer operations (FK chains)."""
    _check_last(r, 3, "expmap_to_matrix")
    a, small = _safe_norm(r)
    sq = (r * r).sum(-1)
    # near 0: sin(a)/a -> 1 - a^2/6, (1 - cos a)/a^2 -> 1/2 - a^2/24, cos a -> 1 - a^2/2
    sinc = torch.where(small, 1 - sq / 6.0, torch.sin(a) / a)
    cosc = torch.where(small, 0.5 - sq / 24.0, (1 - torch.cos(a)) / (a * a))
    cos = torch.where(small, 1 - sq / 2.0, torch.cos(a))
    x, y, z = r.unbind(-1)
    zero = torch.zeros_like(x)
    cross = torch.stack((zero, -z, y, z, zero, -x, -y, x, zero), -1).unflatten(-1, (3, 3))  # [r]x
    eye = torch.eye(3, dtype=r.dtype)
    return (cos[..., None, None] * eye + sinc[..., None, None] * cross
            + cosc[..., None, None] * (r[..., :, None] * r[..., None, :]))


@_tensor_args
def axis_angle_to_quat(axis: torch.Tensor, angle: torch.Tensor | float) -> torch.Tensor:
    """axis (..., 3) (any nonzero length), angle (...) radians -> (..., 4).

    A zero axis has no direction: ValueError, unless its angle is 0 (then the identity).
    """
    _check_last(axis, 3, "axis_angle_to_quat")
    angle = angle if isinstance(angle, torch.Tensor) else torch.as_tensor(angle, dtype=axis.dtype)
    n = torch.linalg.vector_norm(axis, dim=-1, keepdim=True)
    zero = n[..., 0] < 1e-12
    if bool(zero.any()):
        if bool((zero & (angle != 0)).any()) or not bool(torch.isfinite(axis).all()):
            raise ValueError("axis_angle_to_quat: an axis has zero length (no direction) and a non-zero angle")
        n = torch.where(zero[..., None], torch.ones_like(n), n)
    if not bool(torch.isfinite(n).all()):
        raise ValueError("axis_angle_to_quat: an axis contains NaN or inf")
    axis = axis / n
    half = 0.5 * angle
    return torch.cat((torch.cos(half)[..., None], axis * torch.sin(half)[..., None]), -1)


@_tensor_args
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


# ---------------------------------------------------------------------------
# Euler angles
# ---------------------------------------------------------------------------

_AXES = "XYZ"


def _parse_order(order: str) -> tuple[tuple[int, int, int], bool]:
    """'ZYX' (intrinsic, BVH channel order) or 'xyz' (extrinsic) -> axis indices in intrinsic order, extrinsic flag."""
    if not isinstance(order, str) or len(order) != 3 or len(set(order.upper())) != 3 \
            or not set(order.upper()) <= set(_AXES) or not (order.isupper() or order.islower()):
        raise ValueError(f"Euler order must be a permutation of 'XYZ' (intrinsic, as BVH channels) or of 'xyz' "
                         f"(extrinsic), got {order!r}")
    extrinsic = order.islower()
    axes = tuple(_AXES.index(c) for c in order.upper())
    return (axes[::-1] if extrinsic else axes), extrinsic


def _axis_quat(angle: torch.Tensor, axis: int) -> torch.Tensor:
    """angle (...) radians about coordinate axis 0/1/2 -> (..., 4)."""
    half = 0.5 * angle
    parts = [torch.cos(half)] + [torch.zeros_like(half)] * 3
    parts[1 + axis] = torch.sin(half)
    return torch.stack(parts, -1)


@_tensor_args
def euler_to_quat(angles: torch.Tensor, order: str) -> torch.Tensor:
    """angles (..., 3) radians -> (..., 4).

    Intrinsic orders are BVH channel lists: 'ZYX' means channels Zrotation Yrotation
    Xrotation, R = Rz(a0) Ry(a1) Rx(a2), as scipy's ``from_euler('ZYX', a)``; lowercase
    orders are extrinsic (scipy ``'xyz'`` = intrinsic ``'ZYX'`` with the angles reversed).
    """
    _check_last(angles, 3, "euler_to_quat")
    axes, extrinsic = _parse_order(order)
    a = angles.flip(-1) if extrinsic else angles
    q0, q1, q2 = (_axis_quat(a[..., i], ax) for i, ax in enumerate(axes))
    return quat_mul(quat_mul(q0, q1), q2)


@_tensor_args
def euler_to_matrix(angles: torch.Tensor, order: str) -> torch.Tensor:
    """angles (..., 3) radians -> (..., 3, 3); order as in `euler_to_quat`."""
    return quat_to_matrix(euler_to_quat(angles, order))


def _safe_atan2(y: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """atan2 whose gradient is 0 (not NaN) at the undefined point (0, 0)."""
    zero = (x == 0) & (y == 0)
    return torch.where(zero, torch.zeros_like(x), torch.atan2(y, torch.where(zero, torch.ones_like(x), x)))


def _norm(v: torch.Tensor, dim: int = -1) -> torch.Tensor:
    """(..., D) -> (...) exact Euclidean norm whose gradient is 0 (not NaN) at v = 0."""
    sq = (v * v).sum(dim)
    pos = sq > 0
    return torch.where(pos, torch.sqrt(torch.where(pos, sq, torch.ones_like(sq))), torch.zeros_like(sq))


@_tensor_args
def matrix_to_euler(m: torch.Tensor, order: str) -> torch.Tensor:
    """(..., 3, 3) rotation matrices -> (..., 3) angles; the middle angle lies in [-pi/2, pi/2].

    With R = R_i(a) R_j(b) R_k(c) and s = +1 for an even permutation (i, j, k):
    sin b = s R_ik, tan a = -s R_jk / R_kk, tan c = -s R_ij / R_ii.  At gimbal lock
    (cos b = 0) a and c are not unique: c = 0 and tan a = s R_kj / R_jj (scipy's choice).
    """
    if m.shape[-2:] != (3, 3):
        raise ValueError(f"matrix_to_euler: expected (..., 3, 3), got {tuple(m.shape)}")
    (i, j, k), extrinsic = _parse_order(order)
    s = 1.0 if (j - i) % 3 == 1 else -1.0
    cos_b = _norm(torch.stack((m[..., i, i], m[..., i, j]), -1))
    b = torch.atan2(s * m[..., i, k], cos_b)
    lock = cos_b < 1e-7
    a = torch.where(lock, _safe_atan2(s * m[..., k, j], m[..., j, j]), _safe_atan2(-s * m[..., j, k], m[..., k, k]))
    c = torch.where(lock, torch.zeros_like(b), _safe_atan2(-s * m[..., i, j], m[..., i, i]))
    angles = torch.stack((a, b, c), -1)
    return angles.flip(-1) if extrinsic else angles


@_tensor_args
def quat_to_euler(q: torch.Tensor, order: str) -> torch.Tensor:
    """(..., 4) unit quaternions -> (..., 3) angles, see `matrix_to_euler` and `euler_to_quat`."""
    _check_last(q, 4, "quat_to_euler")
    return matrix_to_euler(quat_to_matrix(q), order)


# ---------------------------------------------------------------------------
# 6-D representation (Zhou et al. 2019, "On the continuity of rotation representations")
# ---------------------------------------------------------------------------

def _unit(v: torch.Tensor) -> torch.Tensor:
    return v / torch.linalg.vector_norm(v, dim=-1, keepdim=True).clamp_min(_EPS)


def _frame_from_two(a1: torch.Tensor, a2: torch.Tensor) -> torch.Tensor:
    """Two (..., 3) vectors -> (..., 3, 3) rotation whose columns are b1, b2, b1 x b2."""
    # b1 = a1/|a1|;  b2 = unit(a2 - (b1 . a2) b1);  b3 = b1 x b2   -- Zhou et al. eq. (16)
    b1 = _unit(a1)
    b2 = _unit(a2 - (b1 * a2).sum(-1, keepdim=True) * b1)
    b3 = torch.linalg.cross(b1, b2, dim=-1)
    return torch.stack((b1, b2, b3), -1)


@_tensor_args
def gram_schmidt(m: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) -> (..., 3, 3) nearby rotation: Gram-Schmidt on columns 0 and 1, column 2 = c0 x c1.

    Equals full Gram-Schmidt for matrices with positive determinant, and always returns det +1.
    """
    if m.shape[-2:] != (3, 3):
        raise ValueError(f"gram_schmidt: expected (..., 3, 3), got {tuple(m.shape)}")
    return _frame_from_two(m[..., :, 0], m[..., :, 1])


@_tensor_args
def matrix_to_sixd(m: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) -> (..., 6): first column then second column of R."""
    if m.shape[-2:] != (3, 3):
        raise ValueError(f"matrix_to_sixd: expected (..., 3, 3), got {tuple(m.shape)}")
    return torch.cat((m[..., :, 0], m[..., :, 1]), -1)


@_tensor_args
def sixd_to_matrix(d6: torch.Tensor) -> torch.Tensor:
    """(..., 6) any two non-parallel 3-vectors -> (..., 3, 3) rotation (Gram-Schmidt)."""
    _check_last(d6, 6, "sixd_to_matrix")
    return _frame_from_two(d6[..., :3], d6[..., 3:])


@_tensor_args
def quat_to_sixd(q: torch.Tensor) -> torch.Tensor:
    """(..., 4) unit quaternions -> (..., 6)."""
    return matrix_to_sixd(quat_to_matrix(q))


@_tensor_args
def sixd_to_quat(d6: torch.Tensor) -> torch.Tensor:
    """(..., 6) -> (..., 4) unit quaternions with w >= 0."""
    return matrix_to_quat(sixd_to_matrix(d6))


# ---------------------------------------------------------------------------
# Geodesic distances (Ghorbani et al. 2020, eq. 16-21)
# ---------------------------------------------------------------------------

@_tensor_args
def quat_geodesic(q1: torch.Tensor, q2: torch.Tensor, kind: str = "d1") -> torch.Tensor:
    """(..., 4), (..., 4) unit quaternions -> (...) distance.

    d1 = 2 arccos|q1 . q2| (radians, exact)   -- Ghorbani eq. (17)
    d2 = 1 - |q1 . q2|                         -- eq. (18)
    d3 = min(|q1 - q2|^2, |q1 + q2|^2)         -- eq. (20)
    d1 is computed as 2 atan2(|vec(q1* q2)|, |q1 . q2|): the same angle, but with finite
    gradients at distance 0, where arccos'(1) is infinite.
    """
    _check_last(q1, 4, "quat_geodesic q1")
    _check_last(q2, 4, "quat_geodesic q2")
    if kind == "d1":
        r = quat_mul(quat_conjugate(q1), q2)  # w(r) = q1 . q2
        return 2.0 * torch.atan2(_norm(r[..., 1:]), r[..., 0].abs())
    if kind == "d2":
        return 1.0 - (q1 * q2).sum(-1).abs()
    if kind == "d3":
        return torch.minimum(((q1 - q2) ** 2).sum(-1), ((q1 + q2) ** 2).sum(-1))
    raise ValueError(f"quat_geodesic: kind must be 'd1', 'd2' or 'd3', got {kind!r}")


@_tensor_args
def matrix_geodesic(m1: torch.Tensor, m2: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3), (..., 3, 3) rotations -> (...) angle in [0, pi] of R1 R2^T.

    Ghorbani eq. (21), d = ||log(R1 R2^T)||, with the norm of the rotation vector (the angle;
    the Frobenius norm of the skew matrix log(.) is sqrt(2) times it).  Computed as
    atan2(sin, cos): cos = (tr - 1) / 2, sin = |vee(R - R^T)| / 2, stable at 0 and pi.
    """
    for m, name in ((m1, "m1"), (m2, "m2")):
        if m.shape[-2:] != (3, 3):
            raise ValueError(f"matrix_geodesic {name}: expected (..., 3, 3), got {tuple(m.shape)}")
    r = m1 @ m2.transpose(-1, -2)
    cos = 0.5 * (r[..., 0, 0] + r[..., 1, 1] + r[..., 2, 2] - 1.0)
    vee = torch.stack((r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]), -1)
    return torch.atan2(0.5 * _norm(vee), cos)

