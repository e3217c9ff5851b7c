"""Synthetic subjects: bone proportions and personal style parameters.

A subject is the canonical skeleton scaled per joint (overall height about
+-10% plus small per-segment variation, left/right symmetric so that
`Motion.mirror` stays exact) and a handful of style parameters that the
generators read.  Two style groups, "A" and "B", play the role of the gender
attribute of Ghorbani et al. 2020 (lesson 05): B has narrower shoulders and
wider hips, more hip sway, less arm swing and a higher cadence.

Taught in notebooks/00_data_and_skeletons.ipynb.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from course_lib.skeleton import Skeleton

# Style presets: multiplicative (x) or additive (+) adjustments applied on top of a subject's
# random personal variation.  Magnitudes are modest, as between real walkers.
STYLE_PRESETS = {
    "A": dict(hip_sway=0.8, arm_swing=1.15, cadence=0.98, step_length=1.03, torso_lean=1.5,
              shoulder_width=1.03, hip_width=0.97),
    "B": dict(hip_sway=1.6, arm_swing=0.75, cadence=1.05, step_length=0.96, torso_lean=-1.0,
              shoulder_width=0.93, hip_width=1.05),
}
# Segments that vary together (both sides share a factor): segment -> joints whose offset it scales.
_SEGMENTS = {
    "hip": ("LeftUpLeg", "RightUpLeg"), "thigh": ("LeftLeg", "RightLeg"), "shin": ("LeftFoot", "RightFoot"),
    "foot": ("LeftToeBase", "RightToeBase"), "spine": ("Spine", "Spine1", "Neck"), "head": ("Head",),
    "clavicle": ("LeftShoulder", "RightShoulder", "LeftArm", "RightArm"),
    "upper_arm": ("LeftForeArm", "RightForeArm"), "forearm": ("LeftHand", "RightHand"),
}
SEGMENT_SD = 0.025  # per-segment relative variation (sd) on top of the height scale


@dataclass(frozen=True)
class Subject:
    """A synthetic actor: name, style group, per-joint bone scale factors (J,), style parameters."""

    name: str
    style: str
    scale: np.ndarray = field(repr=False)
    hip_sway: float = 1.0        # x pelvis lateral sway and roll
    arm_swing: float = 1.0       # x shoulder swing amplitude
    cadence: float = 1.0         # x step frequency at a given speed
    step_length: float = 1.0     # x step length (speed / cadence)
    torso_lean: float = 0.0      # + degrees of forward trunk lean
    seed: int = 0

    def skeleton(self) -> Skeleton:
        """The canonical skeleton scaled by this subject's factors (End Sites scale with their joint)."""
        return Skeleton.canonical().scaled(self.scale)

    @property
    def height_scale(self) -> float:
        """Leg-length ratio to the canonical skeleton (hips height ratio)."""
        return float(self.scale[2])


def make_subject(subject_id: int, seed: int = 0, style: str | None = None) -> Subject:
    """Subject number `subject_id` of the population drawn by `seed` (named "s07" for 7).

    The style group alternates with the id (even "A", odd "B") unless `style` is given.
    """
    if subject_id < 0:
        raise ValueError(f"make_subject: subject_id must be >= 0, got {subject_id}")
    style = style or ("A" if subject_id % 2 == 0 else "B")
    if style not in STYLE_PRESETS:
        raise ValueError(f"make_subject: style must be one of {sorted(STYLE_PRESETS)}, got {style!r}")
    rng = np.random.default_rng([int(seed), int(subject_id), 7919])
    preset = STYLE_PRESETS[style]
    skel = Skeleton.canonical()
    height = float(np.clip(1 + 0.045 * rng.standard_normal(), 0.9, 1.1))  # about +-10%
    scale = np.full(skel.num_joints, height)
    for seg, joints in _SEGMENTS.items():
        f = float(np.clip(1 + SEGMENT_SD * rng.standard_normal(), 0.94, 1.06))
        f *= preset["shoulder_width"] if seg == "clavicle" else preset["hip_width"] if seg == "hip" else 1.0
        for n in joints:
            scale[skel.index(n)] *= f
    scale = np.clip(scale, 0.86, 1.14)  # about +-10% overall, a little more for single segments
    jitter = lambda sd: float(np.exp(sd * rng.standard_normal()))  # noqa: E731
    return Subject(
        name=f"s{subject_id:02d}", style=style, scale=scale, seed=int(seed),
        hip_sway=preset["hip_sway"] * jitter(0.15), arm_swing=preset["arm_swing"] * jitter(0.15),
        cadence=preset["cadence"] * jitter(0.025), step_length=preset["step_length"] * jitter(0.03),
        torso_lean=preset["torso_lean"] + 1.5 * float(rng.standard_normal()),
    )


def make_subjects(n: int, seed: int = 0) -> list[Subject]:
    """n subjects s00..s{n-1}, styles alternating A, B."""
    return [make_subject(i, seed) for i in range(n)]
