"""Known answers of the motion measures lesson 03 moved into course_lib.evaluation: foot skate on walking
clips (planted feet ~0, a sliding body its speed), the lower toe's height, contact agreement, joint speed and
the freezing threshold."""

from __future__ import annotations

import numpy as np
import pytest

from course_lib.datasets import generate_locomotion_set
from course_lib.evaluation import contact_agreement, foot_skate, freeze_floor, joint_speed, lower_toe
from course_lib.evaluation.contacts import skate_sources
from course_lib.motion import Motion
from course_lib.skeleton import Skeleton

SKEL = Skeleton.canonical()
FPS = 30.0


@pytest.fixture(scope="module")
def walks() -> list[Motion]:
    return generate_locomotion_set(3, seed=5, fps=FPS, duration=4.0, n_subjects=3)


def rest(T: int = 10, height: float = 0.96, velocity=(0.0, 0.0, 0.0)) -> Motion:
    rot = np.zeros((T, SKEL.num_joints, 4))
    rot[..., 0] = 1.0
    root = np.array([0.0, height, 0.0]) + np.arange(T)[:, None] / FPS * np.asarray(velocity)
    return Motion(rot, root, SKEL, FPS)


def slid(m: Motion, velocity) -> Motion:
    """The same clip with the whole body dragged at a constant floor velocity (m/s): planted feet now slide."""
    root = m.root_positions + np.arange(len(m))[:, None] / m.fps * np.asarray(velocity)
    return Motion(m.rotations, root, m.skeleton, m.fps)


def test_planted_walking_feet_barely_skate_and_dragged_ones_skate_at_the_drag_speed(walks):
    planted = foot_skate(walks)
    assert planted < 0.02  # the generator's IK keeps stance feet in place
    dragged = foot_skate([slid(m, (0.0, 0.0, 0.5)) for m in walks])
    assert 0.4 < dragged < 0.6  # a stance foot dragged at 0.5 m/s: ~0.5 (stance toes already moved a little)
    assert dragged > 20 * planted
    # a lateral drag counts the same (horizontal speed)
    np.testing.assert_allclose(foot_skate([slid(m, (0.5, 0.0, 0.0)) for m in walks]), dragged, rtol=0.05)


def test_lower_toe_is_the_lower_toes_height():
    toe = rest().positions()[:, [SKEL.index("LeftToeBase"), SKEL.index("RightToeBase")], 1].min(-1)
    np.testing.assert_allclose(lower_toe(rest().positions(), SKEL), toe)
    np.testing.assert_allclose(lower_toe(rest(height=1.06).positions(), SKEL), toe + 0.1, atol=1e-12)
    pos = rest().positions().copy()
    pos[3, SKEL.index("RightToeBase"), 1] = -0.05  # one toe through the floor on frame 3
    assert lower_toe(pos, SKEL)[3] == -0.05 and lower_toe(pos[None], SKEL).shape == (1, 10)
    with pytest.raises(ValueError, match="positions must be"):
        lower_toe(np.zeros((10, 5, 3)), SKEL)


def test_contact_agreement_known_answers(walks):
    own = np.stack([m.contacts() for m in walks]).astype(float)  # (N, T, 2)
    assert contact_agreement(walks, own) == 1.0
    assert contact_agreement(walks, 1.0 - own) == 0.0
    coin = np.random.default_rng(0).random(own.shape)
    assert abs(contact_agreement(walks, coin) - 0.5) < 0.05  # labels that ignore the pose: chance
    with pytest.raises(ValueError, match="bits must be"):
        contact_agreement(walks, own[:, :, :1])


def test_joint_speed_counts_every_joint_and_the_root():
    pos = np.zeros((5, 2, 3))
    pos[:, 1, 0] = np.arange(5) * 0.1  # joint 1 moves 0.1 m per frame, joint 0 stands
    np.testing.assert_allclose(joint_speed(pos, FPS), 0.1 * FPS / 2)
    np.testing.assert_allclose(joint_speed(rest(velocity=(0.0, 0.0, 1.5)).positions(), FPS), 1.5)  # whole body
    with pytest.raises(ValueError, match="T >= 2"):
        joint_speed(pos[:1], FPS)


def test_freeze_floor_is_a_tenth_of_the_least_varying_clip_and_flags_a_frozen_motion(walks):
    pos = np.zeros((9, 1, 3))
    pos[:, 0, 0] = np.cumsum([0.0] + [0.1, 0.3] * 4)  # speed alternates 3 and 9 m/s: variance 9
    a = Motion(np.tile([1.0, 0, 0, 0], (9, SKEL.num_joints, 1)), np.zeros((9, 3)), SKEL, FPS)
    np.testing.assert_allclose(joint_speed(pos, FPS).var(), 9.0)
    assert freeze_floor([a]) == 0.0  # a clip standing still: nothing can score below it
    floor = freeze_floor(walks)
    assert floor == pytest.approx(0.1 * min(joint_speed(m.positions(), FPS).var() for m in walks))
    frozen = walks[0].positions()[-1:].repeat(150, 0)  # the last pose held for 5 s
    frozen[:, :, 2] += np.arange(150)[:, None] * 1.2 / FPS  # ... and glided forward at 1.2 m/s
    assert joint_speed(frozen, FPS).var() < floor < joint_speed(walks[0].positions(), FPS).var()


def test_lesson_modules_keep_the_old_names():
    """Lesson 06 (moglow) imports freeze_floor and joint_speed from lesson 03's experiment."""
    from course_lib import evaluation
    from course_lib.experiments import gmm_rnn

    assert gmm_rnn.freeze_floor is evaluation.freeze_floor and gmm_rnn.joint_speed is evaluation.joint_speed


def test_skate_sources_split_flagged_from_unflagged_low_toes():
    """Left toe flagged and sliding at 0.3 m/s, right toe 2 cm up (under the 5-cm line), bit off, at 1.2 m/s:
    the flagged speed is 0.3, the unflagged 1.2, and 1.2 / 1.5 of the skate comes from the unflagged toe."""
    T = 10
    pos = np.zeros((1, T, SKEL.num_joints, 3))
    pos[..., 1] = 0.5  # every other joint well above the floor
    lt, rt = SKEL.index("LeftToeBase"), SKEL.index("RightToeBase")
    pos[0, :, lt] = np.stack([np.arange(T) * 0.3 / FPS, np.full(T, 0.02), np.zeros(T)], -1)
    pos[0, :, rt] = np.stack([np.zeros(T), np.full(T, 0.04), np.arange(T) * 1.2 / FPS], -1)
    bits = np.zeros((1, T, 2), bool)
    bits[..., 0] = True
    out = skate_sources(pos, bits, SKEL, FPS)
    assert out["flagged_speed"] == pytest.approx(0.3) and out["unflagged_low_speed"] == pytest.approx(1.2)
    assert out["flagged_fraction"] == pytest.approx(0.5) and out["unflagged_low_fraction"] == pytest.approx(0.5)
    assert out["skate_from_unflagged"] == pytest.approx(1.2 / 1.5)
    assert foot_skate(pos, fps=FPS) == pytest.approx(0.75)  # the plain measure: the mean of both
    bits[..., 1] = True  # now the right toe is flagged too (2 cm above the left: within 5 cm)
    assert skate_sources(pos, bits, SKEL, FPS)["unflagged_low_fraction"] == 0.0
    with pytest.raises(ValueError, match="bits must be"):
        skate_sources(pos, bits[:, :-1], SKEL, FPS)


def test_skate_sources_of_mocap_labels(walks):
    """Mocap with its own contact labels: flagged toes hardly move, and little skate comes from unflagged toes."""
    pos = np.stack([m.positions() for m in walks])
    out = skate_sources(pos, np.stack([m.contacts() for m in walks]), SKEL, FPS)
    assert out["flagged_speed"] < 0.02 and out["flagged_fraction"] > 0.3
