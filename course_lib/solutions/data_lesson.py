"""Reference answers and self-checks for the exercises of notebooks/00b_synthetic_data.ipynb.

Students write their own version in the notebook; each ``check_*`` runs it on fixed clips and
compares it with the reference here (and with the library), raising an AssertionError that says
what is wrong.
"""

from __future__ import annotations

import numpy as np

from course_lib.evaluation import foot_skate_at_floor
from course_lib.motion import CONTACT_HEIGHT, CONTACT_SPEED, Motion
from course_lib.representations import encode, root_yaw_pitch_roll
from course_lib.skeleton import Skeleton
from course_lib.synthetic import ControlProgram, generate_locomotion, make_subject

__all__ = ["cadence", "check_cadence", "check_control_from_root", "check_detect_contacts", "check_foot_skate",
           "control_from_root", "detect_contacts", "exercise_clips"]


# ----------------------------------------------------------------------------- reference answers


def control_from_root(root_xz: np.ndarray, yaw: np.ndarray, fps: float) -> np.ndarray:
    """root_xz (T, 2) world (x, z) m, yaw (T,) rad heading -> (T, 3) (vel_forward, vel_sideways, yaw_rate).

    The displacement from frame t-1 to t, rotated into frame t-1's floor frame, R_y(-yaw_{t-1}) dp,
    times fps (m/s); the yaw change wrapped to [-pi, pi) times fps (rad/s).  Frame 0 repeats frame 1.
    Local +Z is forward, local +X the character's left (so "sideways" is positive to the left).
    """
    root_xz, yaw = np.asarray(root_xz, np.float64), np.asarray(yaw, np.float64)
    if root_xz.ndim != 2 or root_xz.shape[1] != 2 or yaw.shape != (len(root_xz),) or len(yaw) < 2:
        raise ValueError(f"control_from_root: root_xz must be (T, 2) and yaw (T,) with T >= 2, "
                         f"got {root_xz.shape}, {yaw.shape}")
    dp = np.diff(root_xz, axis=0)  # (T-1, 2) world
    c, s = np.cos(yaw[:-1]), np.sin(yaw[:-1])
    side = c * dp[:, 0] - s * dp[:, 1]  # R_y(-yaw) (x, z): x' = c x - s z
    fwd = s * dp[:, 0] + c * dp[:, 1]   #                  z' = s x + c z
    dyaw = (np.diff(yaw) + np.pi) % (2 * np.pi) - np.pi
    out = np.stack([fwd, side, dyaw], -1) * fps  # (T-1, 3)
    return np.concatenate([out[:1], out])


def detect_contacts(positions: np.ndarray, skeleton: Skeleton, fps: float) -> np.ndarray:
    """positions (T, J, 3) -> (T, 2) bool (left, right): ankle or toe joint low AND slow.

    Low: below CONTACT_HEIGHT (ankle 0.12 m, toe joint 0.05 m); slow: speed (central differences,
    one-sided at the ends) below CONTACT_SPEED (0.3 m/s).
    """
    positions = np.asarray(positions, np.float64)
    if positions.ndim != 3 or positions.shape[1:] != (skeleton.num_joints, 3) or len(positions) < 2:
        raise ValueError(f"detect_contacts: positions must be (T >= 2, {skeleton.num_joints}, 3), "
                         f"got {positions.shape}")
    speed = np.linalg.norm(np.gradient(positions, axis=0) * fps, axis=-1)  # (T, J)
    out = np.zeros((len(positions), 2), bool)
    for k, side in enumerate(("Left", "Right")):
        for part, h in CONTACT_HEIGHT.items():
            j = skeleton.index(side + part)
            out[:, k] |= (positions[:, j, 1] < h) & (speed[:, j] < CONTACT_SPEED)
    return out


def cadence(contacts: np.ndarray, fps: float) -> float:
    """contacts (T, 2) bool (left, right) -> steps per minute: touch-downs of both feet per minute.

    A touch-down is a frame t >= 1 with contact[t] and not contact[t-1]; the clip lasts T / fps seconds.
    """
    contacts = np.asarray(contacts, bool)
    if contacts.ndim != 2 or contacts.shape[1] != 2 or len(contacts) < 2:
        raise ValueError(f"cadence: contacts must be (T >= 2, 2) bool, got {contacts.shape}")
    downs = int((contacts[1:] & ~contacts[:-1]).sum())
    return 60.0 * downs / (len(contacts) / fps)


# ----------------------------------------------------------------------------- fixed test clips


def exercise_clips(fps: float = 30.0) -> list[Motion]:
    """Three seeded clips the checks use: a turning walk, a side-step and a random program."""
    sub = make_subject(3, seed=0)
    programs = [ControlProgram.constant("walk", 1.3, 3.0, heading_rate=0.6),
                ControlProgram.constant("sidestep", 0.4, 3.0), None]
    return [generate_locomotion(sub, p, duration=3.0, fps=fps, seed=11 + i) for i, p in enumerate(programs)]


# ----------------------------------------------------------------------------- self-checks


def check_control_from_root(fn, clips: list[Motion] | None = None) -> float:
    """Exercise 1: fn(root_xz (T, 2), yaw (T,), fps) -> (T, 3).  Returns the largest error (m/s or rad/s)."""
    worst = 0.0
    for m in clips or exercise_clips():
        yaw = root_yaw_pitch_roll(m)[:, 0]
        xz = m.root_positions[:, [0, 2]]
        got = np.asarray(fn(xz, yaw, m.fps))
        ref = control_from_root(xz, yaw, m.fps)
        assert got.shape == ref.shape, f"{m.action}: expected shape {ref.shape}, got {got.shape}"
        lib = encode(m, "positions_control")[:, -3:]
        assert np.allclose(ref, lib, atol=1e-9), "reference and library disagree (report this to the lead)"
        err = np.abs(got[1:] - ref[1:]).max(0)
        assert err[2] < 1e-6, f"{m.action}: yaw rate off by up to {err[2]:.3g} rad/s (wrap the yaw change?)"
        assert err[:2].max() < 1e-6, (
            f"{m.action}: velocities off by up to {err[:2].max():.3g} m/s -- rotate the world displacement "
            "by MINUS the previous frame's yaw; forward is local +Z, sideways local +X")
        worst = max(worst, float(err.max()))
    print(f"check_control_from_root passed on {len(clips or [0, 0, 0])} clips (largest error {worst:.1e})")
    return worst


def check_detect_contacts(fn, clips: list[Motion] | None = None) -> float:
    """Exercise 2: fn(positions (T, J, 3), skeleton, fps) -> (T, 2) bool.  Returns the agreement with the
    generator's ground-truth stance (a fraction)."""
    agree = []
    for m in clips or exercise_clips():
        P = m.positions()
        got = np.asarray(fn(P, m.skeleton, m.fps))
        ref = detect_contacts(P, m.skeleton, m.fps)
        assert got.shape == ref.shape, f"{m.action}: expected shape {ref.shape}, got {got.shape}"
        assert got.dtype == bool, f"contacts must be bool, got {got.dtype}"
        n_bad = int((got != ref).sum())
        assert n_bad == 0, (f"{m.action}: {n_bad} of {got.size} contact flags differ from the reference "
                            "(low = below 0.12 m ankle / 0.05 m toe; slow = below 0.3 m/s; either joint counts)")
        agree.append((got == m.meta["contacts"]).mean())
    print(f"check_detect_contacts passed; agreement with the generator's ground truth {np.mean(agree):.3f}")
    return float(np.mean(agree))


def _drag(positions: np.ndarray, fps: float, speed: float) -> np.ndarray:
    """The same positions with the whole body dragged along +X at `speed` m/s: (T, J, 3) -> (T, J, 3)."""
    out = positions.copy()
    out[..., 0] += speed * np.arange(len(positions))[:, None] / fps
    return out


def check_foot_skate(fn, clips: list[Motion] | None = None) -> float:
    """Exercise 3: fn(positions (T, J, 3), skeleton, fps) -> mean horizontal toe speed in contact, m/s.

    Compared with course_lib.evaluation.foot_skate on the clips and on the clips dragged at 0.5 m/s (a
    planted foot then skates at 0.5 m/s).  Returns the mean skate of the clips as generated, m/s."""
    clips = clips or exercise_clips()
    for m in clips:
        P = m.positions()
        for speed in (0.0, 0.5):
            Q = _drag(P, m.fps, speed)
            got, want = float(fn(Q, m.skeleton, m.fps)), foot_skate_at_floor(Q[None], fps=m.fps, skeleton=m.skeleton)
            assert np.isclose(got, want, rtol=1e-6, atol=1e-9), (
                f"{m.action}, body dragged at {speed} m/s: skate {got:.4f} m/s, want {want:.4f} -- the mean of the "
                "toes' horizontal (x, z) speed over frame pairs where the toe joint is below 0.05 m on both frames")
    skate = float(np.mean([fn(m.positions(), m.skeleton, m.fps) for m in clips]))
    print(f"check_foot_skate passed; the clips skate {100 * skate:.2f} cm/s")
    return skate


def check_cadence(fn, clips: list[Motion] | None = None) -> float:
    """Exercise 4: fn(contacts (T, 2) bool, fps) -> steps per minute, on the clips' ground-truth stance.
    Returns the turning walk's cadence (steps/min)."""
    clips = clips or exercise_clips()
    for m in clips:
        c = np.asarray(m.meta["contacts"], bool)
        got, want = float(fn(c, m.fps)), cadence(c, m.fps)
        assert np.isclose(got, want, rtol=1e-9), (
            f"{m.action}: {got:.2f} steps/min, want {want:.2f} -- count frames where a foot lands (contact now, "
            "none on the frame before) on both feet, divide by the clip's length in minutes")
    one = np.zeros((60, 2), bool)
    one[30:, 0] = True  # one left touch-down in 2 s at 30 fps: 30 steps/min
    assert np.isclose(float(fn(one, 30.0)), 30.0), f"one touch-down in 2 s is 30 steps/min, got {fn(one, 30.0)}"
    walk = float(fn(np.asarray(clips[0].meta["contacts"], bool), clips[0].fps))
    print(f"check_cadence passed; the turning walk takes {walk:.0f} steps/min")
    return walk
