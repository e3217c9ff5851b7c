"""Feet and floor: how high the lower toe is, and whether a model's contact labels match its poses.

Taught in notebooks/03_gmm_rnn_refiner.ipynb (the contact-aware model of Wang, Chai et al. 2021,
sec. 4.3, labels every generated frame with two contact bits).  Foot skate and ground penetration,
the other foot measures, are in `metrics` (`foot_skate`, `ground_penetration`).
"""

from __future__ import annotations

import numpy as np

from course_lib.motion import STANCE_MAX_ABOVE, Motion, trusted_contacts
from course_lib.skeleton import Skeleton

__all__ = ["contact_agreement", "lower_toe", "skate_sources"]


def lower_toe(positions, skeleton: Skeleton) -> np.ndarray:
    """positions (..., T, J, 3) world, metres -> the height of the lower of the two toes per frame (..., T), m.

    0 when a toe is on the floor (y = 0); a motion whose lower toe stays high is floating."""
    pos = np.asarray(positions)
    if pos.ndim < 3 or pos.shape[-1] != 3 or pos.shape[-2] != skeleton.num_joints:
        raise ValueError(f"lower_toe: positions must be (..., T, {skeleton.num_joints}, 3), got {pos.shape}")
    toes = [skeleton.index(f"{side}ToeBase") for side in ("Left", "Right")]
    return pos[..., toes, 1].min(-1)


def skate_sources(positions, bits, skeleton: Skeleton, fps: float, max_above: float = STANCE_MAX_ABOVE) -> dict:
    """Where a motion's foot skate comes from: flagged toes vs toes near the floor whose bit is off.

    positions (N, T, J, 3) world, m; bits (N, T, 2) bool contact labels (left, right toe).  A toe pair of frames
    (t-1, t) is *flagged* when its bit is on in both and the toe is within max_above of the lower toe (the
    contact handling's rule), and *unflagged low* when it is below `metrics.foot_skate`'s height (5 cm) on both
    frames but not flagged.  -> {"flagged_speed", "unflagged_low_speed"} (mean horizontal toe speed over those
    pairs, m/s; nan when there are none), {"flagged_fraction", "unflagged_low_fraction"} (of all toe-frame
    pairs) and "skate_from_unflagged" (the unflagged pairs' share of the foot-skate sum, 0-1)."""
    from course_lib.motion import CONTACT_HEIGHT

    pos, b = np.asarray(positions, dtype=float), np.asarray(bits, dtype=bool)
    if pos.ndim != 4 or pos.shape[-2:] != (skeleton.num_joints, 3) or pos.shape[1] < 2:
        raise ValueError(f"skate_sources: positions must be (N, T >= 2, {skeleton.num_joints}, 3), got {pos.shape}")
    if b.shape != pos.shape[:2] + (2,):
        raise ValueError(f"skate_sources: bits must be (N, T, 2) = {pos.shape[:2] + (2,)}, got {b.shape}")
    toes = pos[:, :, [skeleton.index(f"{side}ToeBase") for side in ("Left", "Right")]]  # (N, T, 2, 3)
    y = toes[..., 1]
    flagged = trusted_contacts(b, y, max_above)
    flagged = flagged[:, 1:] & flagged[:, :-1]
    low = y < CONTACT_HEIGHT["ToeBase"]
    low = low[:, 1:] & low[:, :-1]
    speed = np.linalg.norm(np.diff(toes[..., [0, 2]], axis=1), axis=-1) * fps  # (N, T-1, 2)
    unflagged = low & ~flagged
    mean = lambda sel: float(speed[sel].mean()) if sel.any() else float("nan")  # noqa: E731
    total = float(speed[low].sum())
    return {"flagged_speed": mean(flagged), "unflagged_low_speed": mean(unflagged),
            "flagged_fraction": float(flagged.mean()), "unflagged_low_fraction": float(unflagged.mean()),
            "skate_from_unflagged": float(speed[unflagged].sum()) / total if total > 0 else 0.0}


def contact_agreement(motions: list[Motion], bits, threshold: float = 0.5) -> float:
    """Fraction of (frame, foot) pairs whose contact label equals the contact derived from the pose itself.

    motions: N Motions of T frames; bits: (N, T, 2) labels (left, right) in raw units, a label is "in
    contact" when > threshold -> float in [0, 1].  The derived contact is `Motion.contacts` (a foot low
    and slow, course_lib.motion.CONTACT_HEIGHT / CONTACT_SPEED), so mocap's own labels score 1.0 and
    labels that ignore the pose score about 0.5."""
    b = np.asarray(bits)
    if b.shape != (len(motions), len(motions[0]) if motions else 0, 2):
        raise ValueError(f"contact_agreement: bits must be (N={len(motions)}, T, 2) for the motions, got {b.shape}")
    derived = np.stack([m.contacts() for m in motions])  # (N, T, 2)
    if derived.shape != b.shape:
        raise ValueError(f"contact_agreement: motions have {derived.shape[:2]} frames, bits {b.shape[:2]}")
    return float(((b > threshold) == derived).mean())
