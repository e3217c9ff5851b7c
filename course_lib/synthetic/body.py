"""Full-body posing from targets: pelvis, trunk, head, feet (two-bone IK legs) and arms.

The generators (locomotion.py, actions.py) decide *where* things go -- pelvis
path, footholds, hand targets -- and this module turns those targets into
local joint rotations on a subject's skeleton:

- legs: hip -> knee -> ankle by analytic two-bone IK with the knee pole in
  front of the foot (no flips), foot and toe orientations given; when a foot
  is out of reach the pelvis is lowered (`reach_drop`) instead of stretching;
- head: stabilised, its world orientation is a target, shared by Neck and Head;
- arms: either local rotations (swing) or hand targets solved by IK, elbow pole behind.

Taught in notebooks/00_data_and_skeletons.ipynb.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from course_lib.skeleton import Skeleton
from course_lib.synthetic.ik import fk_matrices, limb_rotations, matrices_to_quats, mm, rot, scale_rotation, two_bone_ik

SIDES = ("Left", "Right")
MAX_KNEE_FLEXION = np.radians(140.0)  # deep squat / sprint heel kick; a swing foot closer than that stops short
MAX_REACH = 0.995  # fraction of l1 + l2 a leg may extend to: knees stay slightly bent, no popping
# Heel contact point relative to the ankle, in units of the canonical foot (x the ToeBase scale).
HEEL = np.array([0.0, -0.08, -0.045])


@dataclass(frozen=True)
class LegGeometry:
    """One leg of a skeleton: hip offset in the pelvis frame, bone lengths, foot vectors (metres)."""

    hip: np.ndarray        # (3,) hip joint in the pelvis frame
    l1: float              # thigh length
    l2: float              # shin length
    toe: np.ndarray        # (3,) ankle -> toe joint, foot frame
    heel: np.ndarray       # (3,) ankle -> heel contact point, foot frame
    toe_height: float      # toe joint height above the floor with the foot flat
    hips_height: float     # rest height of the Hips joint (standing straight, foot flat)


def leg_geometry(skel: Skeleton, side: str) -> LegGeometry:
    """The `side` ("Left"/"Right") leg of skel; the foot's rest proportions set the ankle height."""
    o = skel.offsets
    up, knee, ankle, toe = (skel.index(side + n) for n in ("UpLeg", "Leg", "Foot", "ToeBase"))
    s_foot = np.linalg.norm(o[toe]) / np.linalg.norm(Skeleton.canonical().offsets[toe])
    heel = HEEL * s_foot
    toe_height = -heel[1] + o[toe][1]  # heel point on the floor, foot flat
    hips_height = toe_height - (o[up][1] + o[knee][1] + o[ankle][1] + o[toe][1])
    return LegGeometry(o[up].copy(), float(np.linalg.norm(o[knee])), float(np.linalg.norm(o[ankle])),
                       o[toe].copy(), heel, float(toe_height), float(hips_height))


@dataclass
class BodyTargets:
    """Per-frame targets of a clip of T frames (world frame unless said otherwise)."""

    pelvis_pos: np.ndarray                 # (T, 3)
    pelvis_rot: np.ndarray                 # (T, 3, 3) global
    spine: np.ndarray                      # (T, 2, 3, 3) local Spine, Spine1
    head: np.ndarray                       # (T, 3, 3) desired global head orientation
    ankle: dict = field(default_factory=dict)      # side -> (T, 3)
    foot_rot: dict = field(default_factory=dict)   # side -> (T, 3, 3) global
    toe_rot: dict = field(default_factory=dict)    # side -> (T, 3, 3) local (toe relative to foot)
    knee_pole: dict = field(default_factory=dict)  # side -> (T, 3) direction
    arm_local: dict = field(default_factory=dict)  # side -> (T, 4, 3, 3) local Shoulder, Arm, ForeArm, Hand
    hand: dict = field(default_factory=dict)       # side -> (T, 3) hand targets (override arm_local's Arm, ForeArm)
    elbow_pole: dict = field(default_factory=dict)  # side -> (T, 3)


def reach_drop(skel: Skeleton, pelvis_pos: np.ndarray, pelvis_rot: np.ndarray, ankles: dict,
               fps: float, planted: dict | None = None) -> np.ndarray:
    """How far to lower the pelvis so the ankles are within MAX_REACH: -> (T,) metres >= the exact need.

    ankles: side -> (T, 3); planted: side -> (T,) bool, the frames where a foot must be reached
    (default all; swing feet are better lifted by `lift_into_reach`).

    Solves (dy - delta)^2 + h^2 = (MAX_REACH L)^2 per leg, then a running max and a Gaussian
    keep the drop smooth (no vertical pops) while never below what is needed.
    """
    need = np.zeros(len(pelvis_pos))
    for side in SIDES:
        g = leg_geometry(skel, side)
        hip = pelvis_pos + pelvis_rot @ g.hip
        d = hip - ankles[side]
        h2 = d[:, 0] ** 2 + d[:, 2] ** 2
        L = MAX_REACH * (g.l1 + g.l2) - 1e-3
        delta = d[:, 1] - np.sqrt(np.maximum(L ** 2 - h2, 0.0))
        if planted is not None:
            delta = np.where(planted[side], delta, 0.0)
        need = np.maximum(need, delta)
    w = max(int(0.12 * fps), 1)
    sm = gaussian_filter1d(maximum_filter1d(need, 2 * w + 1), w / 2.0)
    return np.maximum(sm, need)


def lift_into_reach(skel: Skeleton, side: str, pelvis_pos: np.ndarray, pelvis_rot: np.ndarray,
                    ankle: np.ndarray, free: np.ndarray) -> np.ndarray:
    """ankle (T, 3) -> ankle raised (and if need be pulled in) to within MAX_REACH of the hip on frames
    where free (T,) is True: a swinging foot trailing behind flexes the knee, like a heel kick."""
    g = leg_geometry(skel, side)
    hip = pelvis_pos + pelvis_rot @ g.hip
    d = ankle - hip
    L = MAX_REACH * (g.l1 + g.l2)  # reach_drop aims 1 mm inside this: planted frames are never lifted
    h = np.linalg.norm(d[:, [0, 2]], axis=-1)
    hmax = np.minimum(h, 0.98 * L)
    y_low = -np.sqrt(L ** 2 - hmax ** 2)  # lowest reachable ankle height relative to the hip
    out = d.copy()
    out[:, [0, 2]] *= (hmax / np.maximum(h, 1e-9))[:, None]
    out[:, 1] = np.maximum(d[:, 1], y_low)
    return np.where(free[:, None], hip + out, ankle)


def pose_body(skel: Skeleton, tg: BodyTargets) -> np.ndarray:
    """BodyTargets of T frames -> (T, J, 4) local quaternions of skel."""
    T = len(tg.pelvis_pos)
    idx = skel.index
    L = np.broadcast_to(np.eye(3), (T, skel.num_joints, 3, 3)).copy()
    L[:, 0] = tg.pelvis_rot
    L[:, idx("Spine")], L[:, idx("Spine1")] = tg.spine[:, 0], tg.spine[:, 1]
    g_s1 = mm(tg.pelvis_rot, tg.spine[:, 0], tg.spine[:, 1])
    # head stabilisation: Neck takes 40% of the rotation from the chest to the desired head, Head the rest
    rel = np.swapaxes(g_s1, -1, -2) @ tg.head
    L[:, idx("Neck")] = scale_rotation(rel, 0.4)
    L[:, idx("Head")] = np.swapaxes(L[:, idx("Neck")], -1, -2) @ rel
    for side in SIDES:
        _pose_leg(skel, tg, side, L)
        for k, n in enumerate(("Shoulder", "Arm", "ForeArm", "Hand")):
            if side in tg.arm_local:
                L[:, idx(side + n)] = tg.arm_local[side][:, k]
    if tg.hand:
        G, P = fk_matrices(L, tg.pelvis_pos, skel.offsets, skel.parents)
        for side, target in tg.hand.items():
            _pose_arm(skel, side, target, tg.elbow_pole[side], G, P, L)
    return matrices_to_quats(L)


def _pose_leg(skel: Skeleton, tg: BodyTargets, side: str, L: np.ndarray) -> None:
    g = leg_geometry(skel, side)
    hip = tg.pelvis_pos + tg.pelvis_rot @ g.hip
    knee, ankle = two_bone_ik(hip, tg.ankle[side], tg.knee_pole[side], g.l1, g.l2, max_reach=0.9999,
                              max_bend=MAX_KNEE_FLEXION)
    thigh, shin = limb_rotations(hip, knee, ankle, tg.knee_pole[side], (0.0, -1.0, 0.0), (0.0, 0.0, 1.0))
    t = np.swapaxes
    L[:, skel.index(side + "UpLeg")] = t(tg.pelvis_rot, -1, -2) @ thigh
    L[:, skel.index(side + "Leg")] = t(thigh, -1, -2) @ shin
    L[:, skel.index(side + "Foot")] = t(shin, -1, -2) @ tg.foot_rot[side]
    L[:, skel.index(side + "ToeBase")] = tg.toe_rot[side]


def _pose_arm(skel: Skeleton, side: str, target, pole, G, P, L) -> None:
    """Arm -> ForeArm -> Hand by two-bone IK towards target (T, 3), elbow towards pole (T, 3)."""
    arm, fore, hand = (skel.index(side + n) for n in ("Arm", "ForeArm", "Hand"))
    l1, l2 = np.linalg.norm(skel.offsets[fore]), np.linalg.norm(skel.offsets[hand])
    elbow, wrist = two_bone_ik(P[:, arm], target, pole, l1, l2, max_reach=0.98)
    rest_bone = np.sign(skel.offsets[fore][0]) * np.array([1.0, 0.0, 0.0])
    upper, lower = limb_rotations(P[:, arm], elbow, wrist, pole, rest_bone, (0.0, 0.0, -1.0))
    parent = G[:, skel.parents[arm]]
    L[:, arm] = np.swapaxes(parent, -1, -2) @ upper
    L[:, fore] = np.swapaxes(upper, -1, -2) @ lower
    L[:, hand] = np.eye(3)


def arm_swing_local(swing, elbow, down, side: str) -> np.ndarray:
    """Local arm rotations from angles (T,) radians: shoulder flexion `swing` (forward +), elbow flexion,
    arm lowered from the T-pose by `down` -> (T, 4, 3, 3) Shoulder, Arm, ForeArm, Hand.

    Left side: Arm = Rx(-swing) Rz(-down), ForeArm = Ry(-elbow); the right side is its mirror image
    (reflection x -> -x maps Rx(a) -> Rx(a), Ry(a) -> Ry(-a), Rz(a) -> Rz(-a)).
    """
    s = 1.0 if side == "Left" else -1.0
    T = len(swing)
    out = np.broadcast_to(np.eye(3), (T, 4, 3, 3)).copy()
    out[:, 1] = rot("x", -np.asarray(swing)) @ rot("z", -s * np.asarray(down))
    out[:, 2] = rot("y", -s * np.asarray(elbow))
    return out
