"""The terms of the MAP energy of Wang, Chai et al. 2021, eq. (19), that are not the prior: the curve term of
offline design (eq. 17) and the contact term (eq. 18).  The prior and noise terms are in `rnn_prior.py`.

Taught in notebooks/04_map_control.ipynb.

    E_curve   = sum_i ||root(s_i) - c_near,i||^2 / sigma_fit^2                                      -- eq. (17)
    E_contact = sum_i sum_feet c_i [ ||f(s_{i-1}) - f(s_i)||^2 / sigma_con^2
                                     + (n . (f(s_i) - p_plane))^2 / sigma_con,y^2 ]                  -- eq. (18)

root(s_i) is the root's floor projection (x, z), integrated through eq. (4); c_near,i the nearest point of the
user's polyline; f(s_i) a foot's contact point (its toe joint), c_i the frame's contact bit.

Differs from the paper:
- sigma_con = sigma_con,y = 0.03 m (the paper gives none): at 0.01 m the contact term of the RNN's own samples,
  which skate a little, outweighed the curve term.
- eq. (18) prints the plane distance of f(s_{i-1}); we use f(s_i), the frame whose bit says it is in contact.
- the plane is y = p_plane, the data's stance toe height (`stance_plane`; the toe joint sits above the floor),
  not y = 0.
- offline design uses sigma_fit^2 = 0.0025 m^2, not the paper's 0.5 (``SIGMA_FIT2``, this module's default):
  design.py says why.
"""

from __future__ import annotations

import numpy as np
import torch

from course_lib.motion import Motion

__all__ = ["SIGMA_FIT2", "SIGMA_CON", "SIGMA_CON_Y", "check_curve", "nearest_on_polyline", "arc_lengths",
           "polyline_between", "arc_position", "arc_length_at", "curve_energy",
           "contact_energy", "stance_plane"]

SIGMA_FIT2 = 0.5  # sigma_fit^2 of eq. (17), m^2: the paper's setting
SIGMA_CON = 0.03  # m, eq. (18) stillness (not given in the paper)
SIGMA_CON_Y = 0.03  # m, eq. (18) point-plane distance (not given in the paper)


def check_curve(curve, name: str = "curve") -> np.ndarray:
    """A user polyline -> (K, 2) float64 floor points (x, z); clear errors for anything else."""
    try:
        c = np.asarray(curve, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name} must be a (K, 2) array of floor points (x, z), got {type(curve).__name__}") from e
    if c.ndim != 2 or c.shape[1] != 2:
        raise ValueError(f"{name} must be a (K, 2) array of floor points (x, z) in metres, got shape {c.shape}")
    if len(c) < 2:
        raise ValueError(f"{name} needs at least 2 points, got {len(c)}")
    if not np.isfinite(c).all():
        raise ValueError(f"{name} contains NaN or inf")
    if np.linalg.norm(np.diff(c, axis=0), axis=1).sum() <= 1e-9:
        raise ValueError(f"{name} has zero length (all its points coincide)")
    return c


def nearest_on_polyline(points: torch.Tensor, curve: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """points (..., 2), curve (K, 2) -> c_near (..., 2), the nearest point of the polyline, and the
    distance (...).  Each segment a->b: t = clamp((p - a).(b - a) / |b - a|^2, 0, 1), c = a + t (b - a);
    the nearest over segments.  Differentiable in points (c_near moves with p along a segment)."""
    a, b = curve[:-1], curve[1:]  # (K-1, 2)
    ab = b - a
    L2 = (ab ** 2).sum(-1).clamp(min=1e-12)  # (K-1,)
    t = (((points[..., None, :] - a) * ab).sum(-1) / L2).clamp(0.0, 1.0)  # (..., K-1)
    c = a + t[..., None] * ab  # (..., K-1, 2)
    dist2 = ((points[..., None, :] - c) ** 2).sum(-1)  # (..., K-1)
    k = dist2.argmin(-1, keepdim=True)  # (..., 1)
    near = c.gather(-2, k[..., None].expand(*k.shape, 2))[..., 0, :]
    return near, dist2.gather(-1, k)[..., 0].clamp(min=0).sqrt()


def arc_lengths(curve: np.ndarray) -> np.ndarray:
    """curve (K, 2) -> (K,) the arc length at each vertex, from 0."""
    return np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(curve, axis=0), axis=1))))


def polyline_between(curve: np.ndarray, s0: float, s1: float) -> np.ndarray:
    """The part of the polyline (K, 2) between arc lengths s0 < s1 (clipped to the curve) -> (M, 2), M >= 2."""
    c = np.asarray(curve, np.float64)
    s = arc_lengths(c)
    s0, s1 = float(np.clip(s0, 0, s[-1])), float(np.clip(s1, 0, s[-1]))
    at = [np.array([np.interp(v, s, c[:, 0]), np.interp(v, s, c[:, 1])]) for v in (s0, s1)]
    inner = c[(s > s0) & (s < s1)]
    out = np.concatenate((at[0][None], inner, at[1][None]), 0)
    return out if s1 - s0 > 1e-9 else np.stack((at[0], at[0] + 1e-6))  # a stub at the end


def arc_position(curve: np.ndarray, point, s0: float = 0.0, s1: float = np.inf) -> float:
    """The arc length of the point of the polyline nearest to ``point`` (2,), among arc lengths [s0, s1]."""
    part = polyline_between(curve, s0, min(s1, arc_lengths(curve)[-1]))
    near, _ = nearest_on_polyline(torch.as_tensor(np.asarray(point, np.float64))[None], torch.from_numpy(part))
    near = near[0].numpy()
    seg_start = arc_lengths(part)
    a, b = part[:-1], part[1:]
    t = np.clip(((near - a) * (b - a)).sum(-1) / np.maximum(((b - a) ** 2).sum(-1), 1e-12), 0, 1)
    k = int(np.argmin(np.linalg.norm(a + t[:, None] * (b - a) - near, axis=1)))
    return float(max(s0, 0.0) + seg_start[k] + t[k] * np.linalg.norm(b[k] - a[k]))


def arc_length_at(points: torch.Tensor, curve: torch.Tensor) -> torch.Tensor:
    """points (..., 2), curve (K, 2) -> (...) the arc length (from the curve's first point) of each point's nearest
    point on the polyline.  Differentiable in points along the nearest segment (s = s_k + t |b - a|)."""
    curve = curve.to(points.dtype)
    a, b = curve[:-1], curve[1:]  # (K-1, 2)
    ab = b - a
    lens = (ab ** 2).sum(-1).clamp(min=1e-12).sqrt()  # (K-1,)
    start = torch.cat((lens.new_zeros(1), torch.cumsum(lens, 0)[:-1]))  # (K-1,) arc length at each a
    t = (((points[..., None, :] - a) * ab).sum(-1) / lens ** 2).clamp(0.0, 1.0)  # (..., K-1)
    dist2 = ((points[..., None, :] - (a + t[..., None] * ab)) ** 2).sum(-1)
    k = dist2.argmin(-1, keepdim=True)
    return (start + t * lens).gather(-1, k)[..., 0]


def curve_energy(root_xz: torch.Tensor, curve: torch.Tensor, sigma_fit2: float = SIGMA_FIT2) -> torch.Tensor:
    """-log p_curve of eq. (17) up to a constant: root_xz (N, T, 2), curve (K, 2) -> (N,)."""
    near, _ = nearest_on_polyline(root_xz, curve.to(root_xz.dtype))
    return ((root_xz - near) ** 2).sum((-1, -2)) / sigma_fit2


def contact_energy(toes: torch.Tensor, bits: torch.Tensor, prev_toes: torch.Tensor, plane: float,
                   sigma_con: float = SIGMA_CON, sigma_con_y: float = SIGMA_CON_Y) -> torch.Tensor:
    """-log P_contact of eq. (18) up to a constant.

    toes (N, T, 2, 3) world toe positions (left, right), bits (N, T, 2) contact bits (0/1, raw units),
    prev_toes (N, 2, 3) the toes on the frame before row 0, plane: the contact plane's height (normal +Y)
    -> (N,).  A foot in contact on frame i pays for moving since frame i-1 and for leaving the plane."""
    before = torch.cat((prev_toes[:, None], toes[:, :-1]), 1)  # (N, T, 2, 3) f(s_{i-1})
    still = ((before - toes) ** 2).sum(-1) / sigma_con ** 2  # (N, T, 2)
    on_plane = (toes[..., 1] - plane) ** 2 / sigma_con_y ** 2  # (N, T, 2), n = (0, 1, 0)
    return (bits * (still + on_plane)).sum((-1, -2))


def stance_plane(motion: Motion, default: float = 0.0244) -> float:
    """The contact plane's height of eq. (18): the median height of motion's toes on contact frames (m)."""
    sk = motion.skeleton
    toes = motion.positions()[:, [sk.index("LeftToeBase"), sk.index("RightToeBase")], 1]  # (T, 2)
    bits = motion.contacts()
    return float(np.median(toes[bits])) if bits.any() else default
