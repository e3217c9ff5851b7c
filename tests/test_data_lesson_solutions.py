"""The reference answers of lesson 00b's exercises (course_lib/solutions/data_lesson.py) against the library."""

from __future__ import annotations

import numpy as np
import pytest

from course_lib.motion import foot_contacts
from course_lib.representations import encode, integrate_root, root_deltas, root_yaw_pitch_roll
from course_lib.solutions import data_lesson as S


@pytest.fixture(scope="module")
def clips():
    return S.exercise_clips(fps=30.0)


def test_control_from_root_equals_the_positions_control_columns(clips):
    for m in clips:
        yaw = root_yaw_pitch_roll(m)[:, 0]
        got = S.control_from_root(m.root_positions[:, [0, 2]], yaw, m.fps)
        np.testing.assert_allclose(got, encode(m, "positions_control")[:, -3:], atol=1e-9)


def test_control_from_root_knows_the_answer_of_a_circle():
    # walking a circle of radius 2 m at 1.5 m/s, facing along the path: forward 1.5, sideways 0, yaw rate 0.75
    fps, T = 60.0, 200
    w = 1.5 / 2.0
    yaw = w * np.arange(T) / fps
    xz = 2.0 * np.stack([1 - np.cos(yaw), np.sin(yaw)], -1)  # starts at 0 heading +Z, turns left (+X)
    got = S.control_from_root(xz, yaw, fps)
    chord = 2 * 2.0 * np.sin(w / fps / 2) * fps  # the frame-to-frame chord, not the arc
    np.testing.assert_allclose(got[:, 0], chord * np.cos(w / fps / 2), rtol=1e-9)
    np.testing.assert_allclose(got[:, 1], chord * np.sin(w / fps / 2), rtol=1e-9)  # chord leans to the left
    np.testing.assert_allclose(got[:, 2], w, rtol=1e-9)
    d, dyaw = root_deltas(xz, yaw)  # and it inverts with the library's integrator (Wang eq. 4)
    back, _ = integrate_root(got[:, [1, 0]] / fps, got[:, 2] / fps, (0.0, 0.0, 0.0))
    np.testing.assert_allclose(back, xz, atol=1e-9)
    np.testing.assert_allclose(d * fps, got[:, [1, 0]], atol=1e-9)


def test_control_from_root_rejects_bad_shapes():
    with pytest.raises(ValueError, match="root_xz must be"):
        S.control_from_root(np.zeros((5, 3)), np.zeros(5), 30.0)


def test_detect_contacts_equals_the_library_and_mostly_the_ground_truth(clips):
    for m in clips:
        P = m.positions()
        got = S.detect_contacts(P, m.skeleton, m.fps)
        np.testing.assert_array_equal(got, foot_contacts(P, m.skeleton, m.fps))
        assert (got == m.meta["contacts"]).mean() > 0.85, m.action


def test_detect_contacts_rejects_wrong_joint_count(clips):
    with pytest.raises(ValueError, match="positions must be"):
        S.detect_contacts(clips[0].positions()[:, :20], clips[0].skeleton, 30.0)


def test_checks_pass_the_reference_and_fail_wrong_answers(clips):
    assert S.check_control_from_root(S.control_from_root, clips) < 1e-9
    assert S.check_detect_contacts(S.detect_contacts, clips) > 0.85

    def world_velocity(xz, yaw, fps):  # forgets to rotate into the floor frame
        v = np.diff(xz, axis=0, prepend=xz[:1]) * fps
        w = np.diff(yaw, prepend=yaw[:1]) * fps  # right, frame 0 aside
        return np.stack([v[:, 1], v[:, 0], w], -1)

    with pytest.raises(AssertionError, match="velocities off"):
        S.check_control_from_root(world_velocity, clips)

    def height_only(P, skeleton, fps):  # ignores the speed test
        return np.stack([P[:, skeleton.index(s + "ToeBase"), 1] < 0.05 for s in ("Left", "Right")], -1)

    with pytest.raises(AssertionError, match="contact flags differ"):
        S.check_detect_contacts(height_only, clips)


def test_cadence_knows_the_answer_and_the_checks_reject_mistakes(clips):
    c = np.zeros((90, 2), bool)
    c[10:40, 0], c[25:60, 1], c[70:, 0] = True, True, True  # three touch-downs in 3 s at 30 fps: 60 steps/min
    assert S.cadence(c, 30.0) == pytest.approx(60.0)
    assert S.check_cadence(S.cadence, clips) == pytest.approx(S.cadence(np.asarray(clips[0].meta["contacts"]), 30.0))
    with pytest.raises(AssertionError, match="steps/min"):  # counts lift-offs too
        S.check_cadence(lambda c, fps: 60.0 * (c[1:] != c[:-1]).sum() / (len(c) / fps), clips)

    from course_lib.evaluation import foot_skate_at_floor

    assert S.check_foot_skate(lambda P, sk, fps: foot_skate_at_floor(P[None], fps=fps, skeleton=sk), clips) < 0.03

    def ankle_skate(P, sk, fps):  # the ankles instead of the toe joints
        return foot_skate_at_floor(P[None], fps=fps, skeleton=sk, joints=("LeftFoot", "RightFoot"), height=0.12)

    with pytest.raises(AssertionError, match="skate"):
        S.check_foot_skate(ankle_skate, clips)
