"""Contact handling for generated motion (Wang, Chai et al. 2021, sec. 4.3, with the "adjacent" and
"point-plane" parts of the contact term of eq. (18)).

Taught in notebooks/03_gmm_rnn_refiner.ipynb; lesson 04's planting (control/planting.py) reuses `plant_feet`.

The contact-aware models label every generated frame with contact bits c = [c_l, c_r].  The paper uses
them "to automatically enforce environmental contact constraints in output motion": a foot in contact
stays where it is (adjacent frames) and on the floor (point-plane).  Both functions here work on the state
features themselves, so the result is still a motion of the same skeleton (bone lengths kept).

`enforce_contacts` moves the root alone (joint angles untouched):
- stance foot: among the feet whose bit is on, the lower toe; a flagged toe more than ``max_above`` (5 cm)
  above the other toe is ignored, since the pose says that foot is in the air;
- point-plane: the root height moves so that the stance toe is at ``toe_floor``; frames without contact
  (flight) get the correction linearly interpolated from the nearest contact frames;
- adjacent: when the stance foot is in contact on frames t-1 and t, the root's floor step is replaced by
  the one that keeps that toe's world (x, z) fixed: p_t - p_{t-1} = -(R_y(yaw_t) l_t - R_y(yaw_{t-1}) l_{t-1}),
  l the toe's floor-frame (x, z); heading and pose are unchanged;
- ``smooth`` > 1 averages both corrections over that many frames (less jerk from a noisy toe, a little
  skate back).

`plant_feet` moves the given columns (lesson 03: the root's floor step and height and the hip, knee and ankle
angles, `leg_columns`) by L-BFGS on the same two terms as sharp soft penalties plus a cost on the change, so
both feet can be held at once, which the root alone cannot do.

Differs from the paper: it gives no algorithm for this step (its MAP control solves the same terms as soft
Gaussian penalties, eq. (18)); enforcing them after generation is our reading, see the lesson's table.
"""

from __future__ import annotations

import numpy as np
import torch

from course_lib.motion import STANCE_MAX_ABOVE, trusted_contacts
from course_lib.representations import _check_state_tensor, _turn, local_positions, root_trajectory
from course_lib.skeleton import Skeleton

__all__ = ["TOE_FLOOR", "enforce_contacts", "leg_columns", "plant_feet", "toe_floor_height"]

TOE_FLOOR = 0.025  # m: the synthetic skeletons' toe joint height when the foot is planted (`toe_floor_height`)


def toe_floor_height(motions) -> float:
    """The median toe height (m) over the frames where mocap labels that foot in contact."""
    heights = []
    for m in motions:
        p, c = m.positions(), m.contacts()
        for side, toe in enumerate(m.skeleton.feet[1::2]):
            heights.append(p[c[:, side], toe, 1])
    heights = np.concatenate(heights) if heights else np.zeros(0)
    if heights.size == 0:
        raise ValueError("toe_floor_height: no foot contact in the motions")
    return float(np.median(heights))


def _interpolate_gaps(values: np.ndarray, known: np.ndarray) -> np.ndarray:
    """values (T,), known (T,) bool -> values with the unknown frames linearly interpolated (held at the ends);
    all zeros if nothing is known."""
    if not known.any():
        return np.zeros_like(values)
    t = np.arange(len(values))
    return np.interp(t, t[known], values[known])


def enforce_contacts(features, skeleton: Skeleton, toe_floor: float = TOE_FLOOR, threshold: float = 0.5,
                     smooth: int = 1, max_above: float | None = STANCE_MAX_ABOVE):
    """Raw state features (..., T, D) with contact bits -> the same with root height and floor steps corrected
    so that the stance toe stays on the floor and does not slide (see the module docstring).

    max_above: a flagged toe more than this (m) above the other toe is not trusted (the pose contradicts the
    bit: a foot in the air cannot be the stance foot); None trusts every bit.  Mocap's flagged toes are within
    4 cm of the other toe in 99 % of frames.
    smooth: the corrections (height lift, change of the floor step) are averaged over this many frames
    (centred, odd; 1 = exact constraints), trading some skate for less jerk from a noisy stance toe.
    Works on numpy arrays or torch tensors (returns the same type); joint angles, heading and contact
    bits are returned unchanged."""
    is_torch = torch.is_tensor(features)
    f = features.detach().double() if is_torch else torch.as_tensor(np.asarray(features, dtype=np.float64))
    _check_state_tensor(f, skeleton)
    if int(smooth) != smooth or smooth < 1 or smooth % 2 == 0:
        raise ValueError(f"enforce_contacts: smooth must be an odd int >= 1, got {smooth!r}")
    if f.shape[-2] < 2:
        raise ValueError(f"enforce_contacts needs T >= 2 frames, got {f.shape[-2]}")
    lead, (T, D) = f.shape[:-2], f.shape[-2:]
    flat = f.reshape(-1, T, D)
    with torch.no_grad():
        toes = local_positions(flat, skeleton)[..., list(skeleton.feet[1::2]), :].numpy()  # (N, T, 2, 3)
    out = flat.numpy().copy()
    bits = out[..., -2:] > threshold  # (N, T, 2)
    if max_above is not None:
        bits = trusted_contacts(bits, toes[..., 1], max_above)
    for n in range(len(out)):
        fixed = _enforce_one(out[n].copy(), toes[n], bits[n], toe_floor)
        out[n][:, [0, 1, 3]] += _moving_average(fixed[:, [0, 1, 3]] - out[n][:, [0, 1, 3]], int(smooth))
    out = out.reshape(*lead, T, D)
    return torch.as_tensor(out, dtype=features.dtype) if is_torch else out


def _moving_average(x: np.ndarray, k: int) -> np.ndarray:
    """x (T, C) -> centred k-frame moving average along T (edges averaged over the frames that exist)."""
    if k == 1:
        return x
    kernel = np.ones(k)
    num = np.stack([np.convolve(c, kernel, mode="same") for c in x.T], 1)
    den = np.convolve(np.ones(len(x)), kernel, mode="same")[:, None]
    return num / den


def _enforce_one(f: np.ndarray, toes: np.ndarray, bits: np.ndarray, toe_floor: float) -> np.ndarray:
    """One motion: f (T, D) raw features, toes (T, 2, 3) floor-frame toe positions, bits (T, 2) -> f corrected."""
    T = len(f)
    toe_y = np.where(bits, toes[..., 1], np.inf)  # only flagged feet can be the stance foot
    stance = toe_y.argmin(1)  # (T,) the lower flagged toe
    any_contact = bits.any(1)
    # point-plane: root height so that the stance toe sits at toe_floor (toes[..., 1] includes the root height)
    lift = _interpolate_gaps(toe_floor - toe_y[np.arange(T), np.where(any_contact, stance, 0)], any_contact)
    f[:, 3] += lift
    # adjacent: keep the stance toe's world (x, z) between consecutive contact frames
    yaw = np.concatenate(([0.0], np.cumsum(f[1:, 2])))  # relative headings suffice for the steps
    c, s = np.cos(yaw), np.sin(yaw)
    for t in range(1, T):
        k = stance[t]
        if not (bits[t, k] and bits[t - 1, k]):
            continue
        lx, lz = toes[t, k, 0], toes[t, k, 2]
        px, pz = toes[t - 1, k, 0], toes[t - 1, k, 2]
        step_x = -((c[t] * lx + s[t] * lz) - (c[t - 1] * px + s[t - 1] * pz))  # world step, R_y as in _turn
        step_z = -((-s[t] * lx + c[t] * lz) - (-s[t - 1] * px + c[t - 1] * pz))
        # back into frame t-1's floor frame: R_y(-yaw_{t-1})
        f[t, 0] = c[t - 1] * step_x - s[t - 1] * step_z
        f[t, 1] = s[t - 1] * step_x + c[t - 1] * step_z
    return f


def leg_columns(skeleton: Skeleton, fixed=None) -> list[int]:
    """The state-feature columns of the hip, knee and ankle angles (the joints named *UpLeg, *Leg, *Foot) that
    `plant_feet` may move to hold a foot without moving the root; fixed: (D,) bool, the columns the training data
    never vary (`datasets.FixedDofs`), left out (None: none left out)."""
    legs = [j for j, name in enumerate(skeleton.names) if j > 0 and name.endswith(("UpLeg", "Leg", "Foot"))]
    cols = [c for j in legs for c in range(3 * j + 3, 3 * j + 6)]
    if fixed is not None:
        fixed = np.asarray(fixed, bool)
        if fixed.shape != (6 + 3 * (skeleton.num_joints - 1) + 2,):
            raise ValueError(f"leg_columns: fixed must be one bool per state feature of {skeleton.num_joints} joints, "
                             f"got shape {fixed.shape}")
        cols = [c for c in cols if not fixed[c]]
    return cols


def plant_feet(features, skeleton: Skeleton, columns, offsets=None, toe_floor: float = TOE_FLOOR,
               threshold: float = 0.5, max_above: float | None = STANCE_MAX_ABOVE, sigma_slide: float = 0.003,
               sigma_floor: float = 0.01, sigma_angle: float = 0.1, sigma_root: float = 0.02,
               smoothness: float = 4.0, iterations: int = 60):
    """Raw state features (N, T, D) with contact bits -> the same with ``columns`` (e.g. the root's floor steps
    and height and the free leg angles) moved so that every flagged foot stays still and on the floor: the
    contact term of eq. (18) as a soft constraint, solved with L-BFGS by back-propagating through forward
    kinematics and the eq. (4) integration (both feet may be pinned at once, which the root alone cannot do).

    Minimises, per motion, sum over frame pairs where a foot is flagged on both frames of
    ||toe_xz(t) - toe_xz(t-1)||^2 / sigma_slide^2, plus (toe_y - toe_floor)^2 / sigma_floor^2 on flagged frames,
    plus the change of each column (sigma_angle for angles, sigma_root for the six root columns) and of its
    frame-to-frame difference (those sigmas / ``smoothness``).  Flagged feet as in `enforce_contacts` (bit >
    threshold, the toe within max_above of the lower toe).  offsets: (N, J, 3) each motion's rest offsets.
    Heading and contact bits are unchanged; returns the input's type (numpy or torch)."""
    is_torch = torch.is_tensor(features)
    f = features.detach().double() if is_torch else torch.as_tensor(np.asarray(features, dtype=np.float64))
    _check_state_tensor(f, skeleton)
    if f.ndim != 3 or f.shape[1] < 2:
        raise ValueError(f"plant_feet: features must be (N, T >= 2, D), got {tuple(f.shape)}")
    cols = torch.as_tensor(sorted({int(c) for c in columns}), dtype=torch.long)
    if cols.numel() == 0 or cols.min() < 0 or cols.max() >= f.shape[-1] - 2 or bool((cols == 2).any()):
        raise ValueError("plant_feet: columns must be pose columns (not the heading 2 or the contact bits), "
                         f"got {cols.tolist()}")
    off = None if offsets is None else torch.as_tensor(np.asarray(offsets), dtype=torch.float64)
    toes_idx = list(skeleton.feet[1::2])
    with torch.no_grad():
        toes = local_positions(f, skeleton, off)[..., toes_idx, :]  # (N, T, 2, 3)
    bits = f[..., -2:] > threshold
    if max_above is not None:
        bits = trusted_contacts(bits, toes[..., 1], max_above)
    pinned = (bits[:, 1:] & bits[:, :-1]).double()  # (N, T-1, 2)
    flagged = bits.double()
    scale = torch.where(cols < 6, sigma_root, sigma_angle).double()
    delta = torch.zeros(f.shape[0], f.shape[1], len(cols), dtype=torch.float64, requires_grad=True)
    opt = torch.optim.LBFGS([delta], lr=1.0, max_iter=int(iterations), line_search_fn="strong_wolfe")

    def moved() -> torch.Tensor:
        return f.index_add(-1, cols, delta)

    def energy() -> torch.Tensor:
        g = moved()
        local = local_positions(g, skeleton, off)[..., toes_idx, :]  # (N, T, 2, 3)
        root, yaw = root_trajectory(g)
        world_xz = _turn(local[..., [0, 2]], yaw[..., None]) + root[..., None, [0, 2]]  # (N, T, 2, 2)
        slide = ((world_xz[:, 1:] - world_xz[:, :-1]).pow(2).sum(-1) * pinned).sum() / sigma_slide ** 2
        floor = ((local[..., 1] - toe_floor).pow(2) * flagged).sum() / sigma_floor ** 2
        near = (delta / scale).pow(2).sum() + (smoothness * (delta[:, 1:] - delta[:, :-1]) / scale).pow(2).sum()
        return (slide + floor + near) / f.shape[0]

    def closure():
        opt.zero_grad()
        e = energy()
        e.backward()
        return e

    opt.step(closure)
    out = moved().detach()
    return out.to(features.dtype) if is_torch else out.numpy()
