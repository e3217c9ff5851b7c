"""Planting the feet after a search (ours, not the paper's): hold every toe that is in contact or below a height
still and on the floor by moving the leg angles alone, the root where the search put it.

Taught in notebooks/04_map_control.ipynb (section 6, then section 4).

Eq. (18) is a soft term inside the MAP energy (sigma_con 3 cm a frame); it cannot tell a toe that stands from one
that slides half a millimetre a frame, so motions it shapes skate several times as much as mocap.  Lesson 03's
contact handling (`contact_cleanup.plant_feet`) is the sharp version of the same two terms (adjacent frames,
point-plane), but it also moves the root, and a root moved after the search costs the data or the curve the search
fitted.  Here it may move only the hip, knee and ankle angles (`contact_cleanup.leg_columns`), and a toe is held when
the motion's own pose has it in contact (`motion.foot_contacts`: the foot low and slow, as `encode_state_features`
derives the contact bits) or when it is below ``height`` (design.py's stance rule: 5 cm, the foot-skate measure's own
height, `motion.CONTACT_HEIGHT`).  The search's own contact bits (the RNN's, the noisy input's) are not used.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from course_lib.evaluation import foot_skate_at_floor
from course_lib.models.contact_cleanup import leg_columns, plant_feet
from course_lib.motion import CONTACT_HEIGHT, Motion
from course_lib.representations import decode_state_features, encode_state_features, root_start

__all__ = ["plant_legs", "plant_with_prior"]


def plant_legs(motion: Motion, columns, height: float = CONTACT_HEIGHT["ToeBase"],
               sigma_slide: float = 0.001) -> Motion:
    """Hold every toe that is in contact (the contacts of the motion's own pose, `motion.foot_contacts`) or below
    ``height`` still and on the floor, moving only the state-feature ``columns`` (the leg angles,
    `contact_cleanup.leg_columns`): lesson 03's `contact_cleanup.plant_feet` with the root left where it is and
    design.py's low-toe rule for the stance.  sigma_slide: m a frame a held toe may slide (plant_feet's)."""
    columns = [int(c) for c in columns]
    if not columns or any(c < 6 for c in columns):
        raise ValueError(f"plant_legs: columns must be joint-angle columns (>= 6; the root stays), got {columns}")
    if not (np.isfinite(sigma_slide) and sigma_slide > 0 and np.isfinite(height) and height > 0):
        raise ValueError(f"plant_legs: sigma_slide and height must be > 0 (m), got {sigma_slide!r}, {height!r}")
    if len(motion) < 2:
        raise ValueError(f"plant_legs: need a motion of at least 2 frames, got {len(motion)}")
    sk = motion.skeleton
    f = encode_state_features(motion)
    low = motion.positions()[:, list(sk.feet[1::2]), 1] < height  # (T, 2), the toes in plant_feet's order
    f[:, -2:] = ((f[:, -2:] > 0.5) | low).astype(f.dtype)
    g = plant_feet(f[None], sk, columns, offsets=sk.offsets[None], sigma_slide=sigma_slide)[0]
    out = decode_state_features(g, sk, motion.fps, root_start(motion))
    return replace(out, action=motion.action, style=motion.style, subject=motion.subject,
                   meta=dict(motion.meta, planted=True))


def plant_with_prior(motion: Motion, prior, height: float = CONTACT_HEIGHT["ToeBase"],
                     sigma_slide: float = 0.001) -> Motion:
    """`plant_legs` on the leg angles that the prior's training data vary (``prior.fixed``: the columns it never
    varies, held at their constants), kept only if the planted motion's own foot skate (`foot_skate_at_floor`, at
    ``height``) is not above the motion's: a planting that slides the toes more is not kept (low toes that the pose
    calls swinging can move faster after planting).  The check reads the motion alone, no reference;
    motion.meta["planted"] says which was kept."""
    planted = plant_legs(motion, leg_columns(motion.skeleton, prior.fixed), height, sigma_slide)
    if foot_skate_at_floor([planted], height=height) <= foot_skate_at_floor([motion], height=height):
        return planted
    return replace(motion, meta=dict(motion.meta, planted=False))
