"""Lesson 01's pose data (course_lib.experiments.vae_basics): body scale, normalisation and its inverse."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from course_lib.experiments import vae_basics as V
from course_lib.representations import encode


@pytest.fixture(scope="module")
def data():
    return V.load_pose_data(8, 4, seed=0)


def test_body_scale_is_leg_length_over_the_canonical_one(data):
    from dataclasses import replace

    from course_lib.skeleton import Skeleton

    m = data.train_clips[0]
    assert V.body_scale(replace(m, skeleton=Skeleton.canonical())) == pytest.approx(1.0)
    assert V.body_scale(replace(m, skeleton=Skeleton.canonical().scaled(1.2))) == pytest.approx(1.2)


def test_split_by_subject_with_mirrored_training_clips(data):
    train_subjects = {m.subject for m in data.train_clips}
    assert not train_subjects & {m.subject for m in data.test_clips}  # held-out people
    assert len(data.train_clips) % 2 == 0  # each training clip and its mirror
    assert len(data.x_train) == len(data.s_train) == len(data.y_train) == sum(len(m) for m in data.train_clips)


def test_normalisation_is_one_global_scale_and_to_metres_inverts_it(data):
    x = data.x_train.double().numpy()
    assert np.abs(x.mean(0)).max() < 1e-5 and np.sqrt((x ** 2).mean()) == pytest.approx(1.0, abs=1e-5)
    assert 0.02 < data.std < 0.5 and data.x_train.dtype == torch.float32
    m = data.test_clips[0]
    want = encode(m, "positions_control")[:, :63].reshape(-1, 21, 3)  # metres of this subject
    got = data.to_metres(data.x_test[: len(m)], data.s_test[: len(m)])
    np.testing.assert_allclose(got, want, atol=1e-6)


class _Shift:
    def __init__(self, d):
        self.d = d

    def reconstruct(self, x, label=None):
        return x + self.d


def test_joint_error_cm_known_answers(data):
    assert data.joint_error_cm(_Shift(0.0), data.x_test, data.s_test) == 0.0
    one_cm_up = torch.zeros(63)
    one_cm_up[1::3] = 0.01 / data.std  # every joint 1 cm higher, in normalised units of a body-scale-1 subject
    err = data.joint_error_cm(_Shift(one_cm_up), data.x_test, data.s_test)
    assert err == pytest.approx(float(np.mean(data.s_test)), rel=1e-3)  # 1 cm times each subject's scale
