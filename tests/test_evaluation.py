"""Known-answer tests of course_lib.evaluation's metrics, distribution maths and tables.

Clips are built from the canonical skeleton's rest pose moved by hand, so every
expected value is computed on paper.  Classifier-based tests (FID ladder, IS,
accuracies) are in tests/test_classifiers.py.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import torch

from course_lib.evaluation import (
    apd,
    bone_length_violation,
    c2st,
    facing_yaw,
    foot_skate,
    foot_skate_at_floor,
    frechet_distance,
    ground_penetration,
    heading_error,
    inception_score,
    jitter,
    npss,
    path_distance,
    pose_error,
    prediction_error,
    root_jerk_split,
    speed_error,
    table,
    wilson_interval,
)
from course_lib.motion import CONTACT_HEIGHT, Motion
from course_lib.rotations import axis_angle_to_quat
from course_lib.skeleton import Skeleton

SKEL = Skeleton.canonical()
FPS = 30.0


def rest_clip(T: int = 31, velocity=(0.0, 0.0, 0.0), yaw: float = 0.0, height: float = 0.96,
              skeleton: Skeleton = SKEL) -> np.ndarray:
    """(T, J, 3) rest pose turned by ``yaw`` about +Y, its root moving at ``velocity`` m/s."""
    q = axis_angle_to_quat(torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64), torch.tensor(yaw, dtype=torch.float64))
    rot = torch.zeros(T, skeleton.num_joints, 4, dtype=torch.float64)
    rot[..., 0] = 1.0
    rot[:, 0] = q
    t = np.arange(T)[:, None] / FPS
    root = np.array([0.0, height, 0.0]) + t * np.asarray(velocity)
    return skeleton.fk(rot, torch.from_numpy(root)).numpy()


def rest_motion(T: int = 31, velocity=(0.0, 0.0, 0.0), skeleton: Skeleton = SKEL) -> Motion:
    rot = np.zeros((T, skeleton.num_joints, 4))
    rot[..., 0] = 1.0
    root = np.array([0.0, 0.96, 0.0]) + np.arange(T)[:, None] / FPS * np.asarray(velocity)
    return Motion(rot, root, skeleton, FPS)


# ----------------------------------------------------------------------------- prediction / pose error


def test_prediction_error_is_mean_squared_joint_distance():
    target = np.stack([rest_clip(), rest_clip(velocity=(0.5, 0, 0))])
    pred = target + np.array([0.1, 0.0, 0.0])  # every joint 10 cm off -> 0.01 m^2
    err = prediction_error(pred, target, frames=[0, 10, 30])
    assert list(err) == [0, 10, 30]
    np.testing.assert_allclose(list(err.values()), 0.01, rtol=1e-12)
    pred2 = target.copy()
    pred2[:, :, 12, 1] += 0.21  # only the head, 21 cm: 0.21^2 / 21 joints
    np.testing.assert_allclose(prediction_error(pred2, target)[5], 0.21**2 / 21, rtol=1e-12)


def test_pose_error_ignores_root_translation_and_yaw_but_not_pose():
    target = rest_clip(velocity=(0.3, 0, 1.0))[None]
    moved = rest_clip(velocity=(-1.0, 0, 0.2), yaw=1.2)[None] + np.array([2.0, 0.0, -3.0])
    assert prediction_error(moved, target)[20] > 1.0
    assert max(pose_error(moved, target).values()) < 1e-20
    bent = moved.copy()
    bent[:, :, 16] += np.array([0.0, 0.3, 0.0])  # raise the left hand 30 cm (vertical: unaffected by yaw)
    np.testing.assert_allclose(pose_error(bent, target)[7], 0.09 / 21, rtol=1e-9)


def test_facing_yaw_convention():
    assert abs(facing_yaw(rest_clip(yaw=0.0))[0, 0]) < 1e-12
    np.testing.assert_allclose(facing_yaw(rest_clip(yaw=np.pi / 2))[0, 3], np.pi / 2, atol=1e-12)  # faces +X


# ----------------------------------------------------------------------------- physics


def test_foot_skate_at_floor_known_speeds():
    assert foot_skate_at_floor(rest_clip(), fps=FPS) == 0.0  # standing still
    np.testing.assert_allclose(foot_skate_at_floor(rest_clip(velocity=(0.1, 0, 0)), fps=FPS), 0.10, rtol=1e-9)
    np.testing.assert_allclose(foot_skate_at_floor([rest_motion(velocity=(0, 0, 0.25))]), 0.25, rtol=1e-9)
    assert foot_skate_at_floor(rest_clip(velocity=(1.0, 0, 0), height=1.2), fps=FPS) == 0.0  # flying: no contact
    # the threshold is motion.CONTACT_HEIGHT: toes just above it do not count
    lifted = rest_clip(velocity=(1.0, 0, 0), height=0.96 + CONTACT_HEIGHT["ToeBase"])
    assert foot_skate_at_floor(lifted, fps=FPS) == 0.0
    on_a_step = rest_clip(velocity=(0.1, 0, 0), height=0.96 + 0.2)  # toes 0.225 m up: a floor at y = 0.2
    assert foot_skate_at_floor(on_a_step, fps=FPS) == 0.0
    np.testing.assert_allclose(foot_skate_at_floor(on_a_step, fps=FPS, floor=0.2), 0.10, rtol=1e-9)


def test_foot_skate_holds_on_real_mocap_at_any_rate():
    """The default call on the real CMU walk (its floor offset and tilted): near the floor, the same at 30, 60
    and 120 fps; the whole body dragged at 0.3 m/s scores about the drag; a floor moved 10 cm changes nothing.
    The rule for a known floor at y = 0 scores the same clip far higher (its stance toes sit below y = 0 and
    its swing toes pass under 5 cm)."""
    from course_lib.bvh import CMU_SCALE, cmu_sample_path, map_to_canonical, read_bvh

    walk = map_to_canonical(read_bvh(cmu_sample_path(), scale=CMU_SCALE))[1:]  # frame 0 is a glitch (lesson 00b)
    skate = foot_skate([walk])
    assert 0.0 < skate <= 0.10
    rates = [foot_skate([walk.resample(f)]) for f in (30.0, 60.0, 120.0)]
    assert max(rates) - min(rates) < 0.1 * skate
    root = walk.root_positions.copy()
    dragged, lowered = root.copy(), root.copy()
    dragged[:, 0] += 0.3 * np.arange(len(walk)) / walk.fps
    lowered[:, 1] -= 0.10
    as_motion = lambda r: Motion(walk.rotations, r, walk.skeleton, fps=walk.fps)  # noqa: E731
    assert foot_skate([as_motion(dragged)]) == pytest.approx(0.3, abs=0.03)
    assert foot_skate([as_motion(lowered)]) == pytest.approx(skate, rel=1e-9)
    assert foot_skate_at_floor([walk]) > 2 * skate


def test_foot_skate_counts_a_toe_only_when_it_stays_low_for_the_interval():
    clip = rest_clip(velocity=(0.2, 0, 0))  # toes on the floor, gliding at 0.2 m/s
    assert foot_skate(clip, fps=FPS) == pytest.approx(0.2, rel=1e-9)
    swing = clip.copy()
    swing[::3, :, 1] += 0.3  # every third frame the whole body is 30 cm up: no 0.1-s interval stays low
    assert foot_skate(swing, fps=FPS) == 0.0
    assert foot_skate(swing, fps=FPS, interval=None) == pytest.approx(0.2, rel=1e-9)  # frame to frame it counts
    with pytest.raises(ValueError, match="floor must be 'auto' or a height"):
        foot_skate(clip, fps=FPS, floor="lowest")
    with pytest.raises(ValueError, match="interval must be a positive number"):
        foot_skate(clip, fps=FPS, interval=0.0)


def test_ground_penetration_and_jitter():
    assert ground_penetration(rest_clip()) == 0.0
    np.testing.assert_allclose(ground_penetration(rest_clip(height=0.96 - 0.1)), 0.1 - 0.025, atol=1e-9)
    assert jitter(rest_clip(velocity=(1.0, 0, 0.5)), fps=FPS) < 1e-6  # constant velocity: no jerk
    t = np.arange(40) / FPS
    clip = np.repeat(rest_clip(T=40)[:1], 40, axis=0)
    clip[..., 0] += (0.5 * t**3)[:, None]  # x = a t^3 -> jerk 6a = 3 m/s^3 for every joint
    np.testing.assert_allclose(jitter(clip, fps=FPS), 3.0, rtol=1e-6)


def test_root_jerk_split_by_change_of_support():
    """A root moving at constant velocity has no jerk; a 1-cm jump of the root on the frame the lower toe changes
    shows near the change only, the same jump 10 frames away only elsewhere."""
    T, lt, rt = 40, SKEL.index("LeftToeBase"), SKEL.index("RightToeBase")
    clip = rest_clip(T=T, velocity=(1.0, 0, 0.5))
    clip[:20, lt, 1] -= 0.01  # the left toe is lower until frame 19, the right from frame 20: one change, at 20
    clip[20:, rt, 1] -= 0.01
    calm = root_jerk_split(clip, fps=FPS)
    assert calm["all"] < 1e-6 and calm["near_change"] < 1e-6 and calm["elsewhere"] < 1e-6
    jump = clip.copy()
    jump[20:, 0, 0] += 0.01  # the root steps 1 cm sideways at the change
    at = root_jerk_split(jump, fps=FPS, window=2)
    assert at["near_change"] > 100 and at["elsewhere"] < 1e-6 and at["near_share"] == pytest.approx(1.0)
    # the third difference of a unit step is (1, -2, 1) around it: 4 x 0.01 m x fps^3 over the 37 jerk samples
    np.testing.assert_allclose(at["all"], 4 * 0.01 * FPS**3 / (T - 3), rtol=1e-9)
    away = clip.copy()
    away[30:, 0, 0] += 0.01
    far = root_jerk_split(away, fps=FPS, window=2)
    assert far["near_change"] < 1e-6 and far["elsewhere"] > 0 and far["near_share"] < 1e-9
    np.testing.assert_allclose(far["all"], at["all"], rtol=1e-9)  # the same jerk, somewhere else
    # the window's edge: a jerk sample k (frames k..k+3) is near when frame k+1 or k+2 is within 2 frames of the
    # change at 20. A step at frame s gives samples s-3..s-1 (1, 2, 1); at s = 24 only sample 21 (frames 22 and 23)
    # touches frame 22, so a quarter of the jerk is near; at s = 25 none is
    for s, share in ((24, 0.25), (25, 0.0)):
        edge = clip.copy()
        edge[s:, 0, 0] += 0.01
        assert root_jerk_split(edge, fps=FPS, window=2)["near_share"] == pytest.approx(share, abs=1e-9)
    short = root_jerk_split(clip[:4], fps=FPS, window=2)  # fewer frames than the window's width
    assert short["all"] < 1e-6
    with pytest.raises(ValueError, match="window"):
        root_jerk_split(clip, fps=FPS, window=-1)


def test_bone_length_violation():
    assert bone_length_violation(rest_clip(velocity=(1, 0, 0), yaw=0.7)) < 1e-12
    big = SKEL.scaled(1.1)
    np.testing.assert_allclose(bone_length_violation(rest_clip(skeleton=big)), 0.1, rtol=1e-9)
    assert bone_length_violation([rest_motion(skeleton=big)]) < 1e-12  # a Motion brings its own skeleton
    stretched = rest_clip()
    stretched[5:, 16] += np.array([0.05, 0.0, 0.0])  # left hand 5 cm further from the 0.25 m forearm
    np.testing.assert_allclose(bone_length_violation(stretched), 0.05 / 0.25, rtol=1e-9)


# ----------------------------------------------------------------------------- control following


def test_speed_heading_and_path():
    walk = rest_clip(velocity=(0.6, 0, 0.8))[None]  # 1 m/s
    np.testing.assert_allclose(speed_error(walk, 1.0, fps=FPS), 0.0, atol=1e-9)
    np.testing.assert_allclose(speed_error(walk, np.full((1, 31), 1.5), fps=FPS), 0.5, atol=1e-9)
    turned = rest_clip(yaw=np.pi - 0.1)[None]
    np.testing.assert_allclose(heading_error(turned, np.pi - 0.1), 0.0, atol=1e-9)
    np.testing.assert_allclose(heading_error(turned, -np.pi + 0.1), 0.2, atol=1e-9)  # wraps around
    along_x = rest_clip(velocity=(1.0, 0, 0))[None]
    assert path_distance(along_x, [[-1, 0], [0.5, 0], [5, 0]]) < 1e-12
    np.testing.assert_allclose(path_distance(along_x, [[-1, 0, 1.0], [5, 3, 1.0]]), 1.0, atol=1e-12)
    np.testing.assert_allclose(path_distance(along_x[:, :1], [[3.0, 4.0]]), 5.0, atol=1e-12)  # one point


# ----------------------------------------------------------------------------- diversity, spectra


def test_apd():
    x = rest_clip(velocity=(1, 0, 0))
    assert apd(np.stack([x, x, x])) == 0.0
    np.testing.assert_allclose(apd(np.stack([x, x + np.array([0, 0, 0.5])])), 0.5, rtol=1e-12)
    three = np.stack([x, x + np.array([0.3, 0, 0]), x + np.array([0, 0, 0.4])])  # pair distances 0.3, 0.4, 0.5
    np.testing.assert_allclose(apd(three), 0.4, rtol=1e-12)
    np.testing.assert_allclose(apd(np.stack([three, np.stack([x, x, x])])), 0.2, rtol=1e-12)  # (N, S, ...)


def test_npss():
    t = np.arange(64) / FPS
    slow = np.sin(2 * np.pi * 1.0 * t)[None, :, None]
    fast = np.sin(2 * np.pi * 5.0 * t)[None, :, None]
    assert npss(slow, slow) == 0.0
    assert npss(3 * slow, slow) < 1e-12  # power spectra are normalised: amplitude does not matter
    assert npss(fast, slow) > 5.0  # energy moved ~ (5 - 1) Hz / (FPS / 64) bins ~ 8.5 bins
    assert npss(fast, slow) > npss(np.sin(2 * np.pi * 2.0 * t)[None, :, None], slow)


# ----------------------------------------------------------------------------- distributions


def test_frechet_distance_against_scipy_sqrtm():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(5, 5)), rng.normal(size=(5, 5))
    s1, s2 = a @ a.T + 0.1 * np.eye(5), b @ b.T + 0.1 * np.eye(5)
    mu1, mu2 = rng.normal(size=5), rng.normal(size=5)
    ref = ((mu1 - mu2) ** 2).sum() + np.trace(s1 + s2 - 2 * scipy.linalg.sqrtm(s1 @ s2).real)
    np.testing.assert_allclose(frechet_distance(mu1, s1, mu2, s2), ref, rtol=1e-8)
    # N(0, I) vs N(m, 4I) in 3-D: |m|^2 + 3 (1 + 4 - 2 * 2)
    np.testing.assert_allclose(frechet_distance(np.zeros(3), np.eye(3), np.ones(3), 4 * np.eye(3)), 6.0, atol=1e-12)


def test_inception_score_from_probabilities():
    confident = np.eye(4)[np.arange(40) % 4]
    np.testing.assert_allclose(inception_score(confident), 4.0, rtol=1e-6)
    np.testing.assert_allclose(inception_score(np.tile([0.7, 0.1, 0.1, 0.1], (10, 1))), 1.0, rtol=1e-12)
    with pytest.raises(ValueError, match="probabilities"):
        inception_score(np.full((5, 4), 0.5))


def test_c2st_on_gaussians():
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(200, 8)), rng.normal(size=(200, 8))
    same = c2st(a, b, seed=0)
    assert same["ci_low"] <= 0.5 <= same["ci_high"] and same["n"] == 400
    shifted = c2st(a, b + 2.0, seed=0)  # one direction: Phi(sqrt(8)) ~ 0.998 is the best possible
    assert shifted["accuracy"] > 0.95 and shifted["ci_low"] > 0.9
    slight = c2st(a, b + 0.25, seed=0)["accuracy"]  # the best possible: Phi(0.25 sqrt(8) / 2) = 0.638
    assert 0.55 < slight < 0.72


def test_wilson_interval_known_values():
    low, high = wilson_interval(50, 100)  # textbook: 0.4038 .. 0.5962
    np.testing.assert_allclose([low, high], [0.4038, 0.5962], atol=1e-4)
    assert wilson_interval(0, 10)[0] == 0.0 and wilson_interval(10, 10)[1] == pytest.approx(1.0)
    with pytest.raises(ValueError, match="correct"):
        wilson_interval(11, 10)


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("metric", [
    lambda x: prediction_error(x, x), lambda x: pose_error(x, x), lambda x: foot_skate(x, fps=FPS),
    lambda x: ground_penetration(x), lambda x: jitter(x, fps=FPS), lambda x: bone_length_violation(x),
    lambda x: speed_error(x, 1.0, fps=FPS), lambda x: heading_error(x, 0.0), lambda x: path_distance(x, [[0, 0]]),
    lambda x: apd(np.stack([x[0], x[0]])),
])
def test_metrics_reject_bad_input(metric):
    good = rest_clip()[None]
    metric(good)  # accepted
    with pytest.raises(ValueError, match="joints"):
        metric(good[:, :, :20])
    nan = good.copy()
    nan[0, 3, 4, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        metric(nan)
    with pytest.raises(ValueError, match="shape"):
        metric(good[..., :2])


def test_paired_metrics_reject_mismatched_lengths():
    a, b = rest_clip(T=31)[None], rest_clip(T=30)[None]
    for metric in (prediction_error, pose_error, npss):
        with pytest.raises(ValueError, match="mismatched"):
            metric(a, b)
    with pytest.raises(ValueError, match="frames"):
        prediction_error(a, a, frames=[31])
    with pytest.raises(ValueError, match="fps"):
        foot_skate(a)
    with pytest.raises(ValueError, match="lengths"):
        apd([rest_motion(T=31), rest_motion(T=20)])
    with pytest.raises(ValueError, match="NaN"):
        npss(np.full((1, 8, 2), np.nan), np.ones((1, 8, 2)))
    with pytest.raises(ValueError, match="path"):
        path_distance(a, [1.0, 2.0])


# ----------------------------------------------------------------------------- tables


def test_table_sets_ours_beside_the_paper():
    t = table({"VAE-LSTM": {70: 0.0123456, 90: 0.02}}, paper={"VAE-LSTM": {70: 1.45, 90: 1.75}, "ERD": {70: 0.66}},
              columns=[70, 90], units="m^2", title="Prediction error")
    md = t.markdown()
    assert "| VAE-LSTM | ours | 0.01235 | 0.02 |" in md
    assert "| VAE-LSTM | paper | 1.45 | 1.75 |" in md
    assert "| ERD | paper | 0.66 | \u2014 |" in md
    assert "units: m^2" in md
    assert t._repr_html_() == t.html() and "<td style=\"text-align:right\">1.45</td>" in t.html()
    d = t.to_dict()
    assert d["rows"][1] == {"model": "VAE-LSTM", "source": "paper", "values": {70: 1.45, 90: 1.75}}
    with pytest.raises(TypeError, match="rows"):
        table([1, 2])
