"""Reference answers and self-checks for the exercises of notebooks/00c_measuring_motion.ipynb.

Students write their own version in the notebook; each ``check_*`` builds small inputs of known answer, runs the
student's code on them and compares it with the reference below, raising an AssertionError that says what is wrong.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from course_lib.motion import CONTACT_HEIGHT, Motion
from course_lib.skeleton import Skeleton

__all__ = ["check_fid_change", "check_noise_jitter", "check_skate_prediction", "check_skating_ratio", "dragged",
           "noise_jitter", "skating_ratio"]

TOES = ("LeftToeBase", "RightToeBase")


# ----------------------------------------------------------------------------- reference answers


def dragged(motions: list[Motion], speed: float, axis: int = 0) -> list[Motion]:
    """Each Motion with its root (so the whole body) carried along world axis ``axis`` at ``speed`` m/s: the
    limbs move exactly as before, every planted foot now slides at ``speed``."""
    out = []
    for m in motions:
        root = m.root_positions.copy()
        root[:, axis] += speed * np.arange(len(m)) / m.fps
        out.append(dataclasses.replace(m, root_positions=root))
    return out


def skating_ratio(positions: np.ndarray, fps: float, threshold: float = 0.5,
                  height: float = CONTACT_HEIGHT["ToeBase"]) -> float:
    """positions (N, T, 21, 3), world, m -> the share of contact pairs that slide: over both toes and every frame
    pair (t, t+1) with the toe below ``height`` above y = 0 on both frames, the fraction whose horizontal speed
    exceeds ``threshold`` m/s (0.0 when no toe touches the floor)."""
    sk = Skeleton.canonical()
    toes = np.asarray(positions, float)[..., [sk.index(n) for n in TOES], :]  # (N, T, 2, 3)
    low = toes[..., 1] < height
    both = low[:, 1:] & low[:, :-1]  # (N, T-1, 2)
    speed = np.linalg.norm(np.diff(toes[..., [0, 2]], axis=1), axis=-1) * fps  # (N, T-1, 2)
    return float((speed[both] > threshold).mean()) if both.any() else 0.0


def noise_jitter(sigma: float, fps: float) -> float:
    """The jitter (m/s^3) of white Gaussian position noise of sd ``sigma`` (m) per axis at ``fps``:
    the third difference e_{t+3} - 3 e_{t+2} + 3 e_{t+1} - e_t has sd sqrt(1 + 9 + 9 + 1) sigma per axis, and the
    mean length of a 3-D Gaussian vector of sd s per axis is s sqrt(8 / pi)."""
    return float(math.sqrt(20.0) * sigma * math.sqrt(8.0 / math.pi) * fps**3)


# ----------------------------------------------------------------------------- inputs of known answer


def _rest_on_floor(n: int = 2, T: int = 30) -> np.ndarray:
    """(n, T, 21, 3): the canonical rest pose standing still, its lowest joint on the floor."""
    import torch

    sk = Skeleton.canonical()
    identity = torch.zeros(1, sk.num_joints, 4, dtype=torch.float64)
    identity[..., 0] = 1.0
    rest = sk.fk(identity, torch.zeros(1, 3, dtype=torch.float64)).numpy()[0]
    rest = rest - [0.0, rest[:, 1].min(), 0.0]
    return np.repeat(rest[None, None], T, 1).repeat(n, 0).copy()


def _slide(pos: np.ndarray, speed: float, fps: float) -> np.ndarray:
    out = pos.copy()
    out[..., 0] += speed * np.arange(pos.shape[1])[None, :, None] / fps
    return out


def _clips(n_subjects: int = 2) -> list[Motion]:
    """A few real synthetic clips (walk, jog, jump, lift, both styles) at 30 fps, generated here."""
    from course_lib.evaluation.classifiers import ClassifierData

    data = ClassifierData()
    return data.motions(data.split()[1][:n_subjects], takes=1)


# ----------------------------------------------------------------------------- checks


def check_skate_prediction(predicted) -> None:
    """predicted: the foot skate (m/s) of real clips dragged along x at 0.3 m/s, checked against a run."""
    from course_lib.evaluation import foot_skate_at_floor

    assert isinstance(predicted, (int, float)) and not isinstance(predicted, bool) and math.isfinite(predicted), \
        f"give your prediction as one number in m/s, got {predicted!r}"
    clips = _clips(1)
    before, after = foot_skate_at_floor(clips), foot_skate_at_floor(dragged(clips, 0.3))
    assert abs(predicted - after) <= 0.05, (
        f"you predicted {predicted:.3f} m/s; the run gives {after:.3f} m/s (undragged: {before:.4f}). "
        + ("A planted toe was still; dragged, it moves at the drag's speed." if predicted < after
           else "Only the toes on the floor count, and each moves at the drag's speed, not faster."))
    print(f"the run: {before:.4f} m/s before, {after:.4f} m/s dragged at 0.3 m/s; you predicted {predicted:.3f}")


def check_skating_ratio(fn) -> None:
    """fn(positions (N, T, 21, 3), fps, threshold) -> float, on inputs of known answer."""
    fps, still = 30.0, _rest_on_floor()
    got = fn(still, fps, 0.5)
    assert abs(got) < 1e-12, f"a body standing still on the floor: no foot slides, expected 0, got {got}"
    fast = fn(_slide(still, 1.0, fps), fps, 0.5)
    assert abs(fast - 1.0) < 1e-12, (
        f"a body dragged at 1.0 m/s, toes on the floor: every contact pair slides faster than 0.5 m/s, "
        f"expected 1, got {fast}" + (" (speed is distance per frame times fps: did you forget the fps?)"
                                     if abs(fast) < 1e-12 else ""))
    slow = fn(_slide(still, 0.3, fps), fps, 0.5)
    assert abs(slow) < 1e-12, (f"dragged at 0.3 m/s, under the 0.5 m/s threshold: expected 0, got {slow}"
                               + (" (is the speed in m/s: metres per frame times fps?)" if slow > 0.5 else ""))
    up = _slide(still, 1.0, fps)
    up[..., 1] += 0.10
    lifted = fn(up, fps, 0.5)
    assert abs(lifted) < 1e-12, (f"toes 10 cm above the floor are not in contact: expected 0 (no contact pair), "
                                 f"got {lifted}; a toe counts only below {CONTACT_HEIGHT['ToeBase']} m on both frames")
    mixed = _slide(still, 1.0, fps)
    mixed[0, 10:, :, 1] += 0.10  # clip 0 lifts off at frame 10: pairs (9, 10) onward are not contacts
    vert = _slide(still, 0.0, fps)
    vert[1, :, :, 1] += 0.03 * (np.arange(30) % 2)[:, None]  # clip 1's feet bob 3 cm, still under 5 cm: no slide
    x = np.concatenate([mixed[:1], vert[1:]])
    want = skating_ratio(x, fps, 0.5)
    have = fn(x, fps, 0.5)
    assert abs(have - want) < 1e-9, (
        f"one clip slides for 10 frames and lifts off, the other bobs up and down without sliding: expected "
        f"{want:.4f}, got {have:.4f}. Count a pair only when the toe is low on both frames, and use the horizontal "
        "(x, z) speed only")


def check_noise_jitter(fn) -> None:
    """fn(sigma, fps) -> the jitter (m/s^3) of white noise; compared with the formula and with a simulation."""
    from course_lib.evaluation import jitter

    got = [fn(s, f) for s, f in ((0.01, 30.0), (0.001, 30.0), (0.01, 60.0))]
    assert all(isinstance(g, (int, float, np.floating)) and math.isfinite(g) for g in got), \
        f"return one finite number, got {got}"
    want = noise_jitter(0.01, 30.0)
    sim = jitter(np.random.default_rng(0).normal(0.0, 0.01, (4, 3000, 21, 3)), fps=30.0)
    r = got[0] / want
    hints = {math.sqrt(20): "the third difference adds four samples with weights 1, -3, 3, -1: its variance is 20 "
                            "sigma^2, not sigma^2",
             math.sqrt(8 / math.pi): "the mean length of a 3-D Gaussian vector is sigma sqrt(8/pi), not sigma",
             math.sqrt(20 * 8 / math.pi): "both factors are missing: sqrt(20) (the third difference) and sqrt(8/pi)",
             math.sqrt(3): "the mean length of a 3-D Gaussian vector is sigma sqrt(8/pi), not sigma sqrt(3)",
             30.0**3: "the jerk is the third difference times fps^3",
             30.0**2: "the jerk is the third difference times fps^3 (not fps^2)"}
    for factor, hint in hints.items():
        if abs(r * factor - 1) < 0.02:
            raise AssertionError(f"your value is {factor:.3g}x too small ({got[0]:.4g} vs a simulation's {sim:.4g}): "
                                 + hint)
    assert abs(r - 1) < 0.01, (f"sigma = 1 cm at 30 fps: you give {got[0]:.4g} m/s^3, a simulation of white noise "
                               f"gives {sim:.4g} (ratio {got[0] / sim:.3f})")
    assert abs(got[1] / got[0] - 0.1) < 1e-6, "the jitter of noise grows in proportion to sigma: 1 mm must give a " \
                                              "tenth of 1 cm's"
    assert abs(got[2] / got[0] - 8.0) < 1e-6, (f"at 60 fps the jitter must be 2^3 = 8 times 30 fps's, got "
                                               f"{got[2] / got[0]:.3g} times")


def check_fid_change(fn, reference: list[Motion], clips: list[Motion], classifier) -> None:
    """fn(clips) -> new Motions a person would see as changed, which FID scores at least 10x its floor while foot skate
    and jitter stay within 20 % of the original's."""
    from course_lib.evaluation import classifier_features, fid, foot_skate_at_floor, jitter

    before = [m.rotations.copy() for m in clips]
    changed = fn(clips)
    assert isinstance(changed, list) and changed and all(isinstance(m, Motion) for m in changed), \
        f"return a non-empty list of Motions, got {type(changed).__name__}"
    assert all(np.array_equal(m.rotations, b) for m, b in zip(clips, before, strict=True)), \
        "your change modified the input clips: return new Motions (dataclasses.replace, or m.copy())"
    ref = classifier_features(reference, classifier)
    floor = fid(ref, classifier_features(clips, classifier), classifier)
    value = fid(ref, classifier_features(changed, classifier), classifier)
    assert value >= 10 * floor, \
        f"FID {value:.1f} against a floor of {floor:.1f}: FID must see the change (10x the floor)"
    for name, measure in (("foot skate", foot_skate_at_floor), ("jitter", jitter)):
        a, b = measure(clips), measure(changed)
        tol = 0.2 * a + (0.005 if name == "foot skate" else 0.0)
        assert abs(b - a) <= tol, (f"{name} moved from {a:.4g} to {b:.4g}: this change is seen by {name} too; "
                                   "find one that only the classifier sees")
    print(f"FID {value:.0f} against a floor of {floor:.1f}; foot skate and jitter within 20 %")
