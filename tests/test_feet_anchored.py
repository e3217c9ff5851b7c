"""representations.anchor_on_feet / unanchor_feet (lesson 03's RNN features): exact round trips on each clip's
own skeleton, known answers (a planted toe has zero slip, a dragged body slips at the drag speed, the lower
toe's height does not depend on the subject's size)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from course_lib.datasets import generate_locomotion_set
from course_lib.motion import Motion
from course_lib.representations import anchor_on_feet, encode_state_features, unanchor_feet
from course_lib.skeleton import Skeleton

SK = Skeleton.canonical()


@pytest.fixture(scope="module")
def walks() -> list[Motion]:
    return generate_locomotion_set(4, seed=5, fps=30.0, duration=3.0, n_subjects=4)


def feats(m: Motion) -> torch.Tensor:
    return torch.from_numpy(encode_state_features(m))


def test_round_trip_on_each_clips_own_skeleton(walks):
    f = torch.stack([feats(m) for m in walks])  # (N, T, 68)
    off = torch.from_numpy(np.stack([m.skeleton.offsets for m in walks]))  # (N, J, 3)
    a = anchor_on_feet(f, SK, off)
    assert (unanchor_feet(a, SK, off) - f).abs().max() < 1e-12
    for i, m in enumerate(walks):  # batched = one at a time on the clip's skeleton
        assert (anchor_on_feet(f[i], m.skeleton) - a[i]).abs().max() < 1e-12
    assert torch.equal(a[..., 2:3], f[..., 2:3]) and torch.equal(a[..., 4:], f[..., 4:])  # only dx, dz, height change


def test_planted_toe_has_no_slip_and_a_dragged_body_slips_at_the_drag_speed(walks):
    m = walks[0]
    a = anchor_on_feet(feats(m), m.skeleton)
    d_speed = float(feats(m)[1:, :2].norm(dim=-1).mean() * m.fps)
    slip = a[1:, :2].norm(dim=-1) * m.fps  # (T-1,) m/s
    assert d_speed > 0.5 and float(slip.median()) < 0.02  # the root moves, the anchor toe mostly does not
    root = m.root_positions + np.arange(len(m))[:, None] / m.fps * np.array([0.0, 0.0, 0.4])  # dragged at 0.4 m/s
    dragged = Motion(m.rotations, root, m.skeleton, m.fps)
    slip_d = anchor_on_feet(feats(dragged), m.skeleton)[1:, :2].norm(dim=-1) * m.fps
    assert abs(float(slip_d.median()) - 0.4) < 0.05


def test_toe_height_is_the_lower_toes_height_for_any_subject(walks):
    for m in walks:
        a = anchor_on_feet(feats(m), m.skeleton)
        toes = m.positions()[:, [m.skeleton.index("LeftToeBase"), m.skeleton.index("RightToeBase")], 1].min(-1)
        np.testing.assert_allclose(a[:, 3].numpy(), toes, atol=1e-9)
    # the same features decoded on a 10 % larger skeleton: the toe height is kept, the root rises
    m = walks[0]
    a = anchor_on_feet(feats(m), m.skeleton)
    big = unanchor_feet(a, m.skeleton, torch.from_numpy(1.1 * m.skeleton.offsets))
    rise = big[:, 3] - feats(m)[:, 3]
    assert float(rise.min()) > 0.05  # the root sits higher: the feet stay on the floor
    with pytest.raises(ValueError, match="state features"):
        anchor_on_feet(torch.zeros(5, 67), SK)


def test_soft_anchor_round_trip_hard_limit_and_drag(walks):
    """tau > 0 weights both toes by height: exact round trip, the hard anchor as tau -> 0, and a body dragged at
    0.4 m/s slips by exactly 0.4 m/s more than the undragged one (every toe's own slip grows by the drag, and the
    weights sum to one)."""
    f = torch.stack([feats(m) for m in walks])
    off = torch.from_numpy(np.stack([m.skeleton.offsets for m in walks]))
    for tau in (0.01, 0.03):
        a = anchor_on_feet(f, SK, off, tau)
        assert (unanchor_feet(a, SK, off, tau) - f).abs().max() < 1e-12
        assert torch.equal(a[..., 2:3], f[..., 2:3]) and torch.equal(a[..., 4:], f[..., 4:])
    assert (anchor_on_feet(f, SK, off, 1e-6) - anchor_on_feet(f, SK, off)).abs().max() < 1e-5
    m = walks[0]
    drag = np.arange(len(m))[:, None] / m.fps * np.array([0.0, 0.0, 0.4])
    dragged = Motion(m.rotations, m.root_positions + drag, m.skeleton, m.fps)
    s0, s1 = (anchor_on_feet(feats(x), m.skeleton, tau=0.02)[1:, :2] for x in (m, dragged))
    # the drag is along world z; the slip is in frame t-1's floor frame: compare lengths of the difference
    np.testing.assert_allclose(((s1 - s0).norm(dim=-1) * m.fps).numpy(), 0.4, atol=1e-9)
    for bad in (-0.01, float("nan")):
        with pytest.raises(ValueError, match="tau"):
            anchor_on_feet(feats(m), m.skeleton, tau=bad)
