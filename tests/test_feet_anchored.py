"""representations.anchor_on_feet / unanchor_feet (lesson 03's RNN features): exact round trips on each clip's
own skeleton, known answers (a planted toe has zero slip, a dragged body slips at the drag speed, the lower
toe's height does not depend on the subject's size)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from course_lib.datasets import generate_locomotion_set
from course_lib.motion import Motion
from course_lib.representations import anchor_on_feet, encode_state_features, root_start, unanchor_feet
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


def test_soft_anchor_round_trip_hard_limit_and_weights(walks):
    """tau > 0 weights both toes by height: exact round trip, the hard anchor as tau -> 0, and the slip and the toe
    height recomputed another way: from the joint positions, each toe's own floor-frame slip and height weighted by
    softmax(-height / tau) (frame t-1's heights for step t's slip, frame t's for the height)."""
    f = torch.stack([feats(m) for m in walks])
    off = torch.from_numpy(np.stack([m.skeleton.offsets for m in walks]))
    for tau in (0.01, 0.03):
        a = anchor_on_feet(f, SK, off, tau)
        assert (unanchor_feet(a, SK, off, tau) - f).abs().max() < 1e-12
        assert torch.equal(a[..., 2:3], f[..., 2:3]) and torch.equal(a[..., 4:], f[..., 4:])
    assert (anchor_on_feet(f, SK, off, 1e-6) - anchor_on_feet(f, SK, off)).abs().max() < 1e-5
    m, tau = walks[0], 0.02
    pos = m.positions()  # (T, J, 3) world
    toes = pos[:, [m.skeleton.index("LeftToeBase"), m.skeleton.index("RightToeBase")]]  # (T, 2, 3)
    dyaw = feats(m)[:, 2].numpy()  # yaw change per frame (frame 0 repeats frame 1's)
    heading = root_start(m)[2] + np.cumsum(np.r_[0.0, dyaw[1:]])  # each frame's floor-frame yaw
    c, s = np.cos(heading), np.sin(heading)
    h = toes[..., 1] - pos[:, None, 0, 1]  # toe height above the root
    w = np.exp(-h / tau) / np.exp(-h / tau).sum(-1, keepdims=True)  # (T, 2)
    a = anchor_on_feet(feats(m), m.skeleton, tau=tau).numpy()
    np.testing.assert_allclose(a[:, 3], pos[:, 0, 1] + (w * h).sum(-1), atol=1e-9)
    assert w.min() < 0.05 < 0.4 < w.max(axis=-1).min()  # some frames lean on one toe, none ignores both
    # each toe's world displacement from t-1 to t, in frame t-1's floor frame: its own slip
    dw = toes[1:, :, [0, 2]] - toes[:-1, :, [0, 2]]
    own = np.stack((c[:-1, None] * dw[..., 0] - s[:-1, None] * dw[..., 1],
                    s[:-1, None] * dw[..., 0] + c[:-1, None] * dw[..., 1]), -1)
    np.testing.assert_allclose(a[1:, :2], (w[:-1, :, None] * own).sum(1), atol=1e-9)
    for bad in (-0.01, float("nan")):
        with pytest.raises(ValueError, match="tau"):
            anchor_on_feet(feats(m), m.skeleton, tau=bad)


def test_contact_rule_follows_the_bits_and_the_root_in_a_flight(walks):
    """rule "contact": step t's anchor is the one foot in contact on frame t-1, the previous foot while both are
    (after a flight: the lower toe), the root while none is; checked against each toe's own floor-frame slip
    recomputed from the joint positions, and the root's own step d_t in a flight."""
    m = walks[1]
    f = feats(m).clone()
    T = len(f)
    pattern = [(1, 0), (1, 1), (0, 1), (1, 1), (0, 0), (0, 0), (1, 1), (1, 0)]  # frames 0..7, then repeated
    f[:, -2:] = torch.tensor([pattern[t % len(pattern)] for t in range(T)], dtype=f.dtype)
    a = anchor_on_feet(f, m.skeleton, rule="contact")
    assert (unanchor_feet(a, m.skeleton, rule="contact") - f).abs().max() < 1e-12
    assert torch.equal(a[:, 2:3], f[:, 2:3]) and torch.equal(a[:, 4:], f[:, 4:])
    pos = m.positions()
    toes = pos[:, [m.skeleton.index("LeftToeBase"), m.skeleton.index("RightToeBase")]]
    heading = root_start(m)[2] + np.cumsum(np.r_[0.0, f[1:, 2].numpy()])
    c, s = np.cos(heading), np.sin(heading)
    dw = toes[1:, :, [0, 2]] - toes[:-1, :, [0, 2]]
    own = np.stack((c[:-1, None] * dw[..., 0] - s[:-1, None] * dw[..., 1],
                    s[:-1, None] * dw[..., 0] + c[:-1, None] * dw[..., 1]), -1)  # (T-1, 2 toes, 2)
    lower = toes[:, :, 1].argmin(-1)
    expected = {0: 0, 1: 0, 2: 1, 3: 1, 4: "root", 5: "root", 6: "lower", 7: 0}  # step t+1 <- frame t's bits
    for t in range(1, T - 1):
        e = expected[t % len(pattern)]
        e = int(lower[t]) if e == "lower" else e
        want = f[t + 1, :2].numpy() if e == "root" else own[t, e]
        np.testing.assert_allclose(a[t + 1, :2].numpy(), want, atol=1e-9, err_msg=f"step {t + 1}")
    with pytest.raises(ValueError, match="rule"):
        anchor_on_feet(f, m.skeleton, tau=0.02, rule="contact")
    with pytest.raises(ValueError, match="rule"):
        anchor_on_feet(f, m.skeleton, rule="heel")
