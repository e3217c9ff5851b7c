"""Shipped action/style classifiers and the metrics built on them: FID, IS, foot skate.

Known answers on real synthetic clips (held-out subjects vs. other subjects):
FID(real, real) is small and grows monotonically as noise, mean-pose collapse,
time freezing and foot sliding are added; IS of real data is close to the
number of classes and of one repeated clip is ~1; foot skate of ground truth is
~0 and of feet dragged at 10 cm/s ~0.10 m/s.  The known answers of the feature space itself
(small turns vs. semantic changes, C2ST) are in test_known_answers.py.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from course_lib.evaluation import (
    ClassifierConfig,
    MotionClassifier,
    fid,
    foot_skate,
    inception_score,
    load_classifier,
)
from course_lib.evaluation.classifiers import ClassifierData, accuracy, checkpoint_path
from course_lib.representations import encode_quaternion_root
from course_lib.rotations import quat_slerp

DATA = ClassifierData()
N_QUAT = 84  # quaternion channels of quaternion_root (21 x 4); the last 6 are root features


@pytest.fixture(scope="module")
def action_clf() -> MotionClassifier:
    return load_classifier("action")


@pytest.fixture(scope="module")
def held_out():
    """One clip per (action, style) of the 4 held-out subjects: 32 clips at 30 fps."""
    return DATA.motions(DATA.split()[1])


@pytest.fixture(scope="module")
def other_real():
    """The same recipe on 4 training subjects the classifiers did not see (s06..s09)."""
    from course_lib.synthetic import make_subjects

    return DATA.motions(make_subjects(DATA.num_subjects, DATA.seed)[6:10])


def test_checkpoints_are_small_and_load_weights_only():
    for task in ("action", "style"):
        path = checkpoint_path(task)
        assert path.stat().st_size < 2_000_000
        payload = torch.load(path, map_location="cpu", weights_only=True)
        assert payload["config_class"] == "ClassifierConfig"
        assert load_classifier(task).config.task == task


def test_heldout_accuracy(held_out, action_clf):
    assert accuracy(action_clf, held_out) >= 0.95
    style = load_classifier("style")
    assert style.config.actions == ("walk", "jog", "jump", "lift")  # every action carries its style
    assert accuracy(style, held_out) >= 0.90


def test_classifier_shapes_and_any_length():
    clf = MotionClassifier(ClassifierConfig.for_task("style"))
    x = torch.randn(3, 47, 90)
    assert clf(x).shape == (3, 2) and clf.features(x).shape == (3, 64)
    with pytest.raises(ValueError, match="expected"):
        clf(torch.randn(3, 47, 63))


# ----------------------------------------------------------------------------- FID ladder


def windows(motions, length: int = 60) -> np.ndarray:
    """Motions -> (W, length, 90) every whole non-overlapping window of their quaternion_root features."""
    out = []
    for m in motions:
        f = encode_quaternion_root(m)
        n = len(f) // length
        start = (len(f) - n * length) // 2
        out += [f[start + i * length:start + (i + 1) * length] for i in range(n)]
    return np.stack(out).astype(np.float32)


def _noise(x, level, rng):
    return x + level * rng.standard_normal(x.shape).astype(np.float32)


def _collapse(x, level, rng):
    mean = x.mean(axis=(0, 1), keepdims=True)  # the data set's mean frame
    return (1 - level) * x + level * mean


def _freeze(x, level, rng):
    """Time frozen for the first `level` of each window: the first pose held (no root motion), then the motion."""
    T = x.shape[1]
    d = int(round(level * T))
    y = x[:, np.maximum(0, np.arange(T) - d)].copy()
    y[:, :d, [N_QUAT, N_QUAT + 1, N_QUAT + 3]] = 0.0  # forward, sideways velocity and yaw rate
    return y


def _drag(motions, level):
    """Foot sliding: leg rotations slerped by `level` towards their first-frame pose, the root path kept."""
    legs = list(range(1, 9))  # LeftUpLeg .. RightToeBase
    out = []
    for m in motions:
        q = torch.from_numpy(m.rotations.copy())
        still = q[:1, legs].expand_as(q[:, legs])
        q[:, legs] = quat_slerp(q[:, legs], still, torch.full(still.shape[:-1], float(level), dtype=q.dtype))
        out.append(replace(m, rotations=q.numpy()))
    return out


def _slide(motions, speed):
    """Drag the whole body (so both feet) along +X at `speed` m/s on top of the clip's own motion."""
    out = []
    for m in motions:
        t = np.arange(len(m))[:, None] / m.fps
        out.append(replace(m, root_positions=m.root_positions + t * np.array([speed, 0.0, 0.0])))
    return out


LADDERS = {"noise": (_noise, (0.05, 0.1, 0.2, 0.4)), "mean-pose collapse": (_collapse, (0.25, 0.5, 0.75, 1.0)),
           "time freezing": (_freeze, (0.2, 0.4, 0.6, 0.8))}
DRAG_LEVELS = (0.25, 0.5, 0.75, 1.0)


@pytest.fixture(scope="module")
def ladder(held_out, other_real, action_clf):
    """{name: [FID at level 0 (real vs real), level 1, ...]} -- printed for the report."""
    real, test = windows(other_real), windows(held_out)
    base = fid(real, test, action_clf)
    rng = np.random.default_rng(0)
    out = {name: [base] + [fid(real, f(test, lv, rng), action_clf) for lv in levels]
           for name, (f, levels) in LADDERS.items()}
    out["foot sliding"] = [base] + [fid(real, windows(_drag(held_out, a)), action_clf) for a in DRAG_LEVELS]
    print(f"FID ladders ({len(real)} vs {len(test)} windows):",
          {k: [round(v, 1) for v in vals] for k, vals in out.items()})
    return out


@pytest.mark.parametrize("name", [*LADDERS, "foot sliding"])
def test_fid_grows_monotonically_with_damage(ladder, name):
    values = ladder[name]
    assert np.all(np.diff(values) > 0), f"{name}: FID {values} does not grow with the damage"
    assert values[-1] > 5 * values[0]  # the worst damage is far from real-vs-real


def test_fid_of_identical_sets_is_zero(held_out, action_clf):
    test = windows(held_out)
    assert fid(test, test, action_clf) == 0.0  # clipped round-off


def test_foot_sliding_ladder_is_real_foot_skate(held_out):
    skate = [foot_skate(held_out)] + [foot_skate(_drag(held_out, a)) for a in DRAG_LEVELS]
    print("foot skate along the sliding ladder (m/s):", [round(v, 3) for v in skate])
    assert np.all(np.diff(skate) > 0) and skate[1] > 0.1


# ----------------------------------------------------------------------------- IS, skate


def test_inception_score_real_vs_repeated(held_out, action_clf):
    real = inception_score(held_out, action_clf)
    repeated = inception_score([held_out[0]] * 16, action_clf)
    print(f"IS real {real:.3f}, one repeated clip {repeated:.3f}")
    assert 3.5 < real <= 4.0  # 4 balanced, confidently classified actions
    assert repeated < 1.01


def test_foot_skate_ground_truth_vs_dragged(held_out):
    truth = foot_skate(held_out)
    dragged = foot_skate(_slide(held_out, 0.10))
    print(f"foot skate: ground truth {truth:.4f} m/s, dragged 10 cm/s {dragged:.4f} m/s")
    assert truth < 0.03
    assert abs(dragged - 0.10) < 0.03


def test_distribution_metrics_reject_bad_input(action_clf):
    x = np.zeros((4, 30, 90), np.float32)
    with pytest.raises(ValueError, match="NaN"):
        fid(x, np.full_like(x, np.nan), action_clf)
    with pytest.raises(ValueError, match="90"):
        fid(x, x[..., :63], action_clf)
    with pytest.raises(ValueError, match="at least 2"):
        fid(np.zeros((1, 64)), np.zeros((5, 64)), action_clf)
    with pytest.raises(ValueError, match="NaN"):
        inception_score(np.full((4, 30, 90), np.nan, np.float32), action_clf)
