"""experiments.gmm_rnn_jitter.toe_error_jerk: known answers (no error, a constant tilt, a tilt that flips sign
every frame) on synthetic clips on their own skeletons."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from course_lib.datasets import generate_locomotion_set
from course_lib.experiments.gmm_rnn_jitter import toe_error_jerk
from course_lib.representations import encode_state_features


@pytest.fixture(scope="module")
def clips():
    ms = generate_locomotion_set(3, seed=3, fps=30.0, duration=2.0, n_subjects=3)
    f = torch.from_numpy(np.stack([encode_state_features(m) for m in ms]))
    off = torch.from_numpy(np.stack([m.skeleton.offsets for m in ms]))
    return f, off


def test_no_error_and_the_root_columns_are_ignored(clips):
    f, off = clips
    other = f.clone()
    other[..., :4] += 0.3  # the root's step, yaw and height: not the pose
    r = toe_error_jerk(other, f, off, 30.0)
    assert r["mean_m"] == 0.0 and r["jerk"] == 0.0


def test_a_constant_tilt_errs_without_jerk_and_a_flipping_one_jerks_eight_times_its_size(clips):
    f, off = clips
    const = f.clone()
    const[..., 4] += 0.02  # the root pitched 0.02 rad more on every frame
    r = toe_error_jerk(const, f, off, 30.0)
    assert 0.005 < r["mean_m"] < 0.03  # about 0.02 rad x the 0.9 m from the root to the toes
    # a constant rotation moves the toes by a constant amount only while the pose stands still; the jerk left is
    # that of the pose's own motion x 0.02 rad, far below the flipping case below
    flip = f.clone()
    flip[..., 4] += 0.02 * (-1.0) ** torch.arange(f.shape[1])[None, :]  # +-0.02 rad, sign flipped every frame
    rf = toe_error_jerk(flip, f, off, 30.0)
    # e_t ~ (-1)^t a: the third difference is 8 a, so the jerk is about 8 x the mean error x fps^3
    assert rf["jerk"] == pytest.approx(8 * rf["mean_m"] * 30.0 ** 3, rel=0.05)
    assert r["jerk"] < 0.02 * rf["jerk"]
    with pytest.raises(ValueError, match="same"):
        toe_error_jerk(f[:, :3], f[:, :3], off, 30.0)
