"""Labelled, non-periodic actions for classification / style lessons: walk, jog, jump, lift, in two styles.

- walk / jog: steady locomotion (locomotion.py) along a gentle curve;
- jump: stand, crouch, push-off (heels rise about the balls of the feet), ballistic flight,
  landing on the balls of the feet with knee flexion to absorb, stand up (style scales the arm
  swing and sets the trunk lean, as in walking).  In flight the
  root follows y(t) = y0 + v0 t - g t^2 / 2 with g = 9.81 m/s^2; take-off and touch-down
  happen in the same leg configuration, so flight time t_f = 2 v0 / g and apex height
  h = v0^2 / (2 g) = g t_f^2 / 8 hold exactly;
- lift: walk up to a box, stop, bend (style A squats: hips low, trunk fairly upright; style B
  stoops: hips high, trunk flexed), reach both hands to the box handles 0.25 m above the floor, grasp,
  stand up and carry it a few steps with the arms held in front.

The style argument plays the role of the gender label of Ghorbani et al. 2020 (lesson 05):
it sets the subject's style parameters (subjects.STYLE_PRESETS) and, for lift, the technique.

Taught in notebooks/00_data_and_skeletons.ipynb and notebooks/05_hierarchical_vrnn.ipynb.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from course_lib.motion import Motion
from course_lib.skeleton import forward_kinematics
from course_lib.synthetic.body import BodyTargets, arm_swing_local, leg_geometry, lift_into_reach, pose_body
from course_lib.synthetic.ik import apply, rot
from course_lib.synthetic.locomotion import (
    FPS,
    GAIT_PARAMS,
    ControlProgram,
    G,
    _min_jerk,
    _smooth,
    generate_locomotion,
    locomotion_targets,
    resample_motion,
)
from course_lib.synthetic.subjects import STYLE_PRESETS, Subject

ACTIONS = ("walk", "jog", "jump", "lift")


def styled(subject: Subject, style: str | None) -> Subject:
    """The subject moving in `style` ("A"/"B"): its personal variation kept, the group preset swapped."""
    if style is None or style == subject.style:
        return subject
    if style not in STYLE_PRESETS:
        raise ValueError(f"style must be one of {sorted(STYLE_PRESETS)}, got {style!r}")
    a, b = STYLE_PRESETS[subject.style], STYLE_PRESETS[style]
    ratio = {k: b[k] / a[k] for k in ("hip_sway", "arm_swing", "cadence", "step_length")}
    return replace(subject, style=style, hip_sway=subject.hip_sway * ratio["hip_sway"],
                   arm_swing=subject.arm_swing * ratio["arm_swing"], cadence=subject.cadence * ratio["cadence"],
                   step_length=subject.step_length * ratio["step_length"],
                   torso_lean=subject.torso_lean - a["torso_lean"] + b["torso_lean"])


def generate_action(subject: Subject, action: str, style: str | None = None, duration: float | None = None,
                    fps: float = FPS, seed: int = 0) -> Motion:
    """One clip of `action` in ACTIONS by `subject` in `style` (default: the subject's own).

    duration: seconds (default: walk/jog 4 s, jump ~3 s, lift ~6 s; jump and lift hold the final
    pose to fill a longer duration and raise if it is too short for the action).
    -> Motion labelled action / style / subject, meta: seed, contacts (T, 2) ground truth, and for
    jump: takeoff / landing frame, v0 (m/s), flight_time (s), apex (m); for lift: object (T, 3).
    """
    if action not in ACTIONS:
        raise ValueError(f"generate_action: action must be one of {ACTIONS}, got {action!r}")
    rng = np.random.default_rng(seed)
    sub = styled(subject, style)
    if action in ("walk", "jog"):
        lo, hi = GAIT_PARAMS[action].speed
        program = ControlProgram.constant(action, float(rng.uniform(lo, hi)), duration or 4.0,
                                          heading_rate=float(rng.uniform(-0.3, 0.3)))
        motion = generate_locomotion(sub, program, duration or 4.0, FPS, seed)
    elif action == "jump":
        motion = _jump(sub, rng, duration)
    else:
        motion = _lift(sub, rng, duration)
    motion.action, motion.style, motion.subject = action, sub.style, sub.name
    motion.meta["seed"] = seed
    return resample_motion(motion, fps)


def keyframes(t: np.ndarray, times, values) -> np.ndarray:
    """t (T,), key times (K,), key values (K,) -> (T,) minimum-jerk between keys, held outside."""
    times, values = np.asarray(times, np.float64), np.asarray(values, np.float64)
    k = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    u = (t - times[k]) / (times[k + 1] - times[k])
    return values[k] + (values[k + 1] - values[k]) * _min_jerk(u)


def _hermite(u, p0, v0, p1, v1, dur):
    """Cubic Hermite on u in [0, 1]: positions p0 -> p1, velocities v0 -> v1 (per second) over dur s."""
    u = np.clip(u, 0.0, 1.0)
    return ((2 * u ** 3 - 3 * u ** 2 + 1) * p0 + (u ** 3 - 2 * u ** 2 + u) * dur * v0
            + (-2 * u ** 3 + 3 * u ** 2) * p1 + (u ** 3 - u ** 2) * dur * v1)


def _upper_body(t, lean, spine, swing, elbow, head_pitch) -> tuple:
    """Pelvis pitch, trunk and arm rotations of a symmetric (both arms alike) action."""
    prot = rot("x", lean)
    chest = rot("x", spine)
    head = rot("x", head_pitch)
    arms = {side: arm_swing_local(swing, elbow, np.full(len(t), np.radians(80.0)), side) for side in ("Left", "Right")}
    return prot, np.stack([chest, chest], 1), head, arms


def _jump(sub: Subject, rng: np.random.Generator, duration: float | None) -> Motion:
    """A standing jump in place or forward; see the module docstring."""
    skel = sub.skeleton()
    geo = {s: leg_geometry(skel, s) for s in ("Left", "Right")}
    h = float(rng.uniform(0.12, 0.4))                 # apex of the root above take-off (m)
    v0 = np.sqrt(2 * G * h)                           # h = v0^2 / 2g
    t_f = 2 * v0 / G                                  # flight time, so h = g t_f^2 / 8
    dist = float(rng.choice([0.0, rng.uniform(0.2, 0.5)]))  # forward distance covered in flight
    vx = dist / t_f
    depth, land_depth = float(rng.uniform(0.18, 0.3)), float(rng.uniform(0.15, 0.28))
    t_c0 = float(rng.uniform(0.3, 0.6))               # crouch starts
    t_p0 = t_c0 + float(rng.uniform(0.4, 0.55))       # push-off starts
    t_to = t_p0 + float(rng.uniform(0.2, 0.28))       # take-off
    t_ld = t_to + t_f                                 # touch-down
    t_a1 = t_ld + float(rng.uniform(0.28, 0.38))      # deepest landing squat
    t_r1 = t_a1 + float(rng.uniform(0.5, 0.7))        # standing again
    total = t_r1 + 0.4 if duration is None else duration
    if total < t_r1:
        raise ValueError(f"generate_action: a jump needs {t_r1:.2f} s, duration={duration}")
    t = np.arange(int(np.floor(total * FPS + 1e-9)) + 1) / FPS
    lean_to = 0.12
    p_to = np.radians(45.0)                            # heels up at take-off and touch-down
    keys = [0.0, t_c0, t_p0, t_to, t_ld, t_a1, t_r1, t_r1 + 1.0]
    # style: the arm swing scales with the subject's (A swings wide, B close), the trunk carries its lean
    lean = keyframes(t, keys, [0.04, 0.04, 0.5, lean_to, lean_to, 0.4, 0.04, 0.04]) + np.radians(sub.torso_lean)
    spine = keyframes(t, keys, [0.03, 0.03, 0.15, 0.0, 0.03, 0.15, 0.03, 0.03])
    swing = sub.arm_swing * keyframes(t, keys, [0.05, 0.05, -0.9, 1.7, 1.0, 0.4, 0.05, 0.05])
    elbow = keyframes(t, keys, [0.2, 0.2, 0.5, 0.25, 0.4, 0.5, 0.2, 0.2])
    prot, chest, head, arms = _upper_body(t, lean, spine, swing, elbow, np.full(len(t), 0.05))
    # feet: standing toe joints, the take-off ankle, its mirror image (in z) at touch-down
    w = 1.1 * abs(geo["Left"].hip[0])
    foot_to = rot("x", p_to)
    y_s = geo["Left"].hips_height - 0.01
    ank0, y_to, x_to = {}, None, None
    for side, sgn in (("Left", 1.0), ("Right", -1.0)):
        g = geo[side]
        toe0 = np.array([sgn * w, g.toe_height, g.toe[2]])
        ank0[side] = (toe0, toe0 - foot_to @ g.toe)  # toe, ankle at take-off
    x_to = ank0["Left"][1][2] + 0.1 + 0.15 * (dist > 0)  # pelvis ahead of the ankles at take-off
    hip_off = rot("x", lean_to) @ geo["Left"].hip
    ankle = ank0["Left"][1]
    dxz = np.hypot(hip_off[0] - ankle[0], x_to + hip_off[2] - ankle[2])
    y_to = ankle[1] - hip_off[1] + np.sqrt((0.97 * (geo["Left"].l1 + geo["Left"].l2)) ** 2 - dxz ** 2)
    x_ld = x_to + vx * t_f
    # root: stand, crouch, push (Hermite to the take-off velocity), ballistic flight, absorb, stand up
    y = np.select(
        [t < t_p0, t < t_to, t < t_ld, t < t_a1],
        [keyframes(t, [t_c0, t_p0], [y_s, y_s - depth]),
         _hermite((t - t_p0) / (t_to - t_p0), y_s - depth, 0.0, y_to, v0, t_to - t_p0),
         y_to + v0 * (t - t_to) - 0.5 * G * (t - t_to) ** 2,   # y = y0 + v0 t - g t^2 / 2
         _hermite((t - t_ld) / (t_a1 - t_ld), y_to, -v0, y_s - land_depth, 0.0, t_a1 - t_ld)],
        keyframes(t, [t_a1, t_r1], [y_s - land_depth, y_s]))
    ank_ld = {s: np.array([ank0[s][1][0], ank0[s][1][1], x_ld - (x_to - ank0[s][1][2])]) for s in ank0}
    toe_ld = {s: ank_ld[s] + foot_to @ geo[s].toe for s in ank0}
    x_end = ank_ld["Left"][2] - 0.0  # settle with the hips over the ankles
    z = np.select(
        [t < t_p0, t < t_to, t < t_ld, t < t_a1],
        [keyframes(t, [t_c0, t_p0], [0.0, -0.06]),
         _hermite((t - t_p0) / (t_to - t_p0), -0.06, 0.0, x_to, vx, t_to - t_p0),
         x_to + vx * (t - t_to),
         _hermite((t - t_ld) / (t_a1 - t_ld), x_ld, vx, x_end, 0.0, t_a1 - t_ld)], np.full(len(t), x_end))
    pos = np.stack([np.zeros_like(t), y, z], -1)
    tg = BodyTargets(pos, prot, chest, head, arm_local=arms)
    ground_before, ground_after = t < t_to, t >= t_ld
    for side in ("Left", "Right"):
        g = geo[side]
        heel_up = np.where(ground_before, _smooth((t - (t_p0 + 0.3 * (t_to - t_p0))) / (0.7 * (t_to - t_p0))),
                           np.where(ground_after, 1 - _smooth((t - t_ld) / 0.12), 1.0))
        pitch = -p_to * heel_up
        fr = rot("x", -pitch)
        toe_pos = np.where(ground_before[:, None], ank0[side][0], toe_ld[side])
        ankle = toe_pos - apply(fr, g.toe)
        # flight: ankle relative to the root, from the take-off pose to the landing pose, knees tucked
        tau = np.clip((t - t_to) / t_f, 0, 1)
        rel0, rel1 = ank0[side][1] - np.array([0, y_to, x_to]), ank_ld[side] - np.array([0, y_to, x_ld])
        fly = pos + rel0 + (rel1 - rel0) * _min_jerk(tau)[:, None]
        fly[:, 1] += min(0.25, 0.7 * h) * np.sin(np.pi * tau)
        air = ~(ground_before | ground_after)
        tg.ankle[side] = np.where(air[:, None], fly, ankle)
        tg.ankle[side] = lift_into_reach(skel, side, pos, prot, tg.ankle[side], air)
        tg.foot_rot[side], tg.toe_rot[side] = fr, rot("x", pitch)
        tg.knee_pole[side] = np.tile([0.0, 0.0, 1.0], (len(t), 1))
    meta = dict(contacts=np.stack([~air, ~air], -1), takeoff=int(np.ceil(t_to * FPS)), landing=int(np.ceil(t_ld * FPS)),
                v0=float(v0), flight_time=float(t_f), apex=float(h), distance=dist)
    return Motion(pose_body(skel, tg), pos, skel, FPS, meta=meta)


def _lift(sub: Subject, rng: np.random.Generator, duration: float | None) -> Motion:
    """Walk to a box, bend, grasp, stand up and carry it; see the module docstring."""
    walk1, stop = float(rng.uniform(1.2, 1.8)), 3.4
    walk2 = float(rng.uniform(1.2, 1.6)) if duration is None else duration - walk1 - stop
    if walk2 < 0.6:
        raise ValueError(f"generate_action: a lift needs at least {walk1 + stop + 0.6:.2f} s, duration={duration}")
    v1, v2 = float(rng.uniform(0.9, 1.3)), float(rng.uniform(0.7, 1.0))
    program = ControlProgram(np.cumsum([0.0, walk1, stop, walk2]), ("walk", "idle", "walk"), [v1, 0.0, v2],
                             [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    tg, meta = locomotion_targets(sub, program, walk1 + stop + walk2, rng)
    skel = sub.skeleton()
    t = np.arange(len(tg.pelvis_pos)) / FPS
    both = meta["contacts"].all(-1) & (np.abs(np.gradient(meta["phase"])) < 1e-9)
    parked = np.nonzero(both & (t > walk1))[0]
    t1 = t[parked[0]] + 0.15                           # start bending once both feet are down
    t2, t3 = t1 + float(rng.uniform(0.7, 0.9)), None
    t3 = t2 + float(rng.uniform(0.3, 0.45))            # grasp
    t4 = t3 + float(rng.uniform(0.8, 1.0))             # standing with the box
    squat = sub.style == "A"
    b = keyframes(t, [t1, t2, t3, t4], [0.0, 1.0, 1.0, 0.0])  # bend amount
    yaw = meta["root_path"][:, 2]
    fwd = np.stack([np.sin(yaw), 0 * yaw, np.cos(yaw)], -1)
    left = np.stack([np.cos(yaw), 0 * yaw, -np.sin(yaw)], -1)
    drop, back, pitch, flex = (0.47, 0.12, 0.62, 0.32) if squat else (0.27, 0.16, 1.0, 0.4)
    tg.pelvis_pos = tg.pelvis_pos - drop * b[:, None] * np.array([0, 1, 0]) - back * b[:, None] * fwd
    tg.pelvis_rot = tg.pelvis_rot @ rot("x", pitch * b)
    tg.spine = tg.spine @ rot("x", flex * b)[:, None]
    tg.head = tg.head @ rot("x", 0.45 * b)
    # the box: 0.3 m in front of the toes, handles 0.25 m above the floor; then carried at the waist
    i1 = int(np.searchsorted(t, t1))
    toes = np.mean([tg.ankle[s][i1] + tg.foot_rot[s][i1] @ leg_geometry(skel, s).toe for s in ("Left", "Right")], 0)
    grasp = np.array([toes[0], 0.25, toes[2]]) + 0.3 * fwd[i1]
    carry = tg.pelvis_pos + 0.32 * fwd + np.array([0.0, 0.12, 0.0])
    up = _smooth((t - t3) / (t4 - t3))[:, None]
    box = np.where((t < t3)[:, None], grasp, grasp + (carry - grasp) * up)
    reach = keyframes(t, [t1, t2], [0.0, 1.0])[:, None]
    natural = _hands(skel, tg)
    for side, sgn in (("Left", 1.0), ("Right", -1.0)):
        hold = box + sgn * 0.17 * left
        tg.hand[side] = natural[side] + (hold - natural[side]) * reach
        tg.elbow_pole[side] = sgn * 0.6 * left - 0.4 * np.array([0, 1.0, 0]) - fwd
    meta.update(object=box, walk_gait=meta.pop("gait"))  # per-frame labels are the action's, not the gait's
    meta.pop("gait_names")
    return Motion(pose_body(skel, tg), tg.pelvis_pos, skel, FPS, meta=meta)


def _hands(skel, tg: BodyTargets) -> dict:
    """World hand positions (T, 3) per side of the targets' pose without hand IK."""
    plain = replace(tg, hand={}, elbow_pole={})
    q = pose_body(skel, plain)
    P = forward_kinematics(torch.from_numpy(q), torch.from_numpy(tg.pelvis_pos), torch.from_numpy(skel.offsets),
                           skel.parents)[0].numpy()
    return {s: P[:, skel.index(s + "Hand")] for s in ("Left", "Right")}
