"""The canonical skeleton, forward kinematics and the Motion container (float64)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from course_lib.motion import Motion, foot_contacts
from course_lib.rotations import axis_angle_to_quat, quat_identity, quat_mul, quat_normalize, quat_rotate
from course_lib.skeleton import CANONICAL_JOINTS, Skeleton, forward_kinematics


@pytest.fixture(scope="module")
def sk() -> Skeleton:
    return Skeleton.canonical()


def random_quats(shape: tuple[int, ...], seed: int = 0, spread: float = 1.0) -> np.ndarray:
    """(*shape, 4) random unit quaternions; spread < 1 keeps them near the identity."""
    q = np.random.default_rng(seed).normal(size=(*shape, 4)) * np.array([1.0, spread, spread, spread])
    q[..., 0] = np.abs(q[..., 0]) + (1 - spread) * 3
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def random_motion(sk: Skeleton, T: int = 121, fps: float = 120.0, seed: int = 0) -> Motion:
    """A smooth random clip: slowly varying joint rotations and a walking root."""
    t = np.arange(T)[:, None, None] / fps
    rng = np.random.default_rng(seed)
    axes = rng.normal(size=(1, sk.num_joints, 3))
    angle = 0.4 * np.sin(2 * np.pi * 1.3 * t[..., 0] + rng.uniform(0, 6, size=(1, sk.num_joints)))
    rot = axis_angle_to_quat(torch.from_numpy(np.broadcast_to(axes, (T, sk.num_joints, 3)).copy()),
                             torch.from_numpy(angle)).numpy()
    root = np.stack([0.3 * np.sin(t[:, 0, 0]), 0.96 + 0.02 * np.cos(9 * t[:, 0, 0]), 1.2 * t[:, 0, 0]], -1)
    return Motion(rot, root, sk, fps, action="walk", subject="s1")


# ---------------------------------------------------------------- canonical skeleton


def test_canonical_skeleton_facts(sk):
    assert sk.num_joints == 21 and sk.names == CANONICAL_JOINTS and sk.names[0] == "Hips"
    assert sk.parents[0] == -1 and all(0 <= p < j for j, p in enumerate(sk.parents) if j)
    assert sk.names[sk.parents[sk.index("LeftHand")]] == "LeftForeArm"
    assert sk.names[sk.parents[sk.index("Head")]] == "Neck"
    assert sorted(sk.names[j] for j in sk.end_effectors) == ["Head", "LeftHand", "LeftToeBase",
                                                              "RightHand", "RightToeBase"]
    assert [sk.names[j] for j in sk.feet] == ["LeftFoot", "LeftToeBase", "RightFoot", "RightToeBase"]
    with pytest.raises(KeyError, match="Tail"):
        sk.index("Tail")


def test_mirror_map_is_an_involution_swapping_sides(sk):
    m = sk.mirror_map
    assert all(m[m[j]] == j for j in range(sk.num_joints))
    for j, name in enumerate(sk.names):
        other = sk.names[m[j]]
        if name.startswith("Left"):
            assert other == "Right" + name[4:]
        elif name.startswith("Right"):
            assert other == "Left" + name[5:]
        else:
            assert m[j] == j
    # the rest pose is left/right symmetric: mirrored offsets are the offsets reflected in x
    np.testing.assert_allclose(sk.offsets[list(m)] * [-1, 1, 1], sk.offsets, atol=0)


def test_bone_lengths(sk):
    L = dict(zip(sk.names, sk.bone_lengths(), strict=True))
    assert L["Hips"] == 0.0
    assert L["LeftLeg"] == pytest.approx(0.415) and L["LeftFoot"] == pytest.approx(0.41)
    assert L["LeftForeArm"] == pytest.approx(0.28) and L["LeftHand"] == pytest.approx(0.25)
    for j, k in enumerate(sk.mirror_map):
        assert sk.bone_lengths()[j] == pytest.approx(sk.bone_lengths()[k])
    np.testing.assert_allclose(sk.scaled(1.1).bone_lengths(), 1.1 * sk.bone_lengths())
    assert sk.scaled(1.1).end_sites[sk.index("Head")] == pytest.approx(1.1 * sk.end_sites[sk.index("Head")])


def test_skeleton_rejects_bad_definitions():
    with pytest.raises(ValueError, match="offsets must be"):
        Skeleton(("a", "b"), (-1, 0), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="parent before its child"):
        Skeleton(("a", "b", "c"), (-1, 2, 0), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="NaN"):
        Skeleton(("a", "b"), (-1, 0), np.array([[0, 0, 0], [np.nan, 0, 0]]))


# ---------------------------------------------------------------- forward kinematics


def test_rest_pose_heights(sk):
    q = quat_identity((sk.num_joints,), torch.float64)
    pos, glob = forward_kinematics(q, torch.tensor([0.0, 0.96, 0.0], dtype=torch.float64),
                                   torch.from_numpy(sk.offsets), sk.parents)
    y = dict(zip(sk.names, pos[:, 1].tolist(), strict=True))
    assert y["Hips"] == pytest.approx(0.96, abs=1e-12)
    assert y["LeftToeBase"] == pytest.approx(0.025, abs=1e-12) and y["RightToeBase"] == pytest.approx(0.025, abs=1e-12)
    assert y["LeftFoot"] == pytest.approx(0.08, abs=1e-12)
    assert y["Head"] == pytest.approx(0.96 + 0.11 + 0.19 + 0.21 + 0.10, abs=1e-12)
    assert pos[sk.index("LeftHand"), 0] > 0.6 > -0.6 > pos[sk.index("RightHand"), 0]  # T-pose, left is +x
    torch.testing.assert_close(glob, q)


def test_fk_known_rotation(sk):
    """Hips turned 90 degrees about +y: the left hip (+x) moves to -z."""
    q = quat_identity((sk.num_joints,), torch.float64)
    up = torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64)
    q[0] = axis_angle_to_quat(up, torch.tensor(np.pi / 2, dtype=torch.float64))
    pos, _ = forward_kinematics(q, torch.zeros(3, dtype=torch.float64), torch.from_numpy(sk.offsets), sk.parents)
    np.testing.assert_allclose(pos[sk.index("LeftUpLeg")].numpy(), [0.0, -0.055, -0.09], atol=1e-12)


def test_fk_preserves_bone_lengths_under_random_rotations(sk):
    q = torch.from_numpy(random_quats((4, 50, sk.num_joints), seed=1))
    root = torch.from_numpy(np.random.default_rng(2).normal(size=(4, 50, 3)))
    pos, glob = forward_kinematics(q, root, torch.from_numpy(sk.offsets), sk.parents)
    parents = list(sk.parents[1:])
    lengths = torch.linalg.vector_norm(pos[..., 1:, :] - pos[..., parents, :], dim=-1)
    np.testing.assert_allclose(lengths.numpy(), np.broadcast_to(sk.bone_lengths()[1:], lengths.shape), atol=1e-9)
    np.testing.assert_allclose(torch.linalg.vector_norm(glob, dim=-1).numpy(), 1.0, atol=1e-9)
    torch.testing.assert_close(pos[..., 0, :], root)


def test_fk_per_frame_offsets_and_single_pose(sk):
    """(..., J, 3) offsets (per-subject scaling) and a bare (J, 4) pose give the same as the batched call."""
    q = torch.from_numpy(random_quats((sk.num_joints,), seed=3)).expand(3, -1, -1)  # one pose, three sizes
    root = torch.zeros(3, 3, dtype=torch.float64)
    off = torch.from_numpy(np.stack([sk.offsets * s for s in (0.9, 1.0, 1.1)]))
    pos, _ = forward_kinematics(q, root, off, sk.parents)
    for i in range(3):
        single, _ = forward_kinematics(q[i], root[i], off[i], sk.parents)
        torch.testing.assert_close(pos[i], single)
    torch.testing.assert_close(pos[2], pos[1] * 1.1)


def _fk_joint_by_joint(q, root, offsets, parents):
    """The plain definition, one joint after another: x_j = x_p + R_p o_j, R_j = R_p r_j."""
    glob, pos = [q[..., 0, :]], [root]
    for j in range(1, len(parents)):
        p = parents[j]
        pos.append(pos[p] + quat_rotate(glob[p], offsets[..., j, :]))
        glob.append(quat_mul(glob[p], q[..., j, :]))
    return torch.stack(pos, -2), torch.stack(glob, -2)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fk_on_random_trees_equals_joint_by_joint_definition(sk, seed):
    """The depth-level batching of forward_kinematics is exact on any tree, not only the canonical one."""
    rng = np.random.default_rng(seed)
    J = int(rng.integers(2, 40))
    parents = [-1] + [int(rng.integers(0, j)) for j in range(1, J)]
    q = torch.from_numpy(random_quats((3, 4, J), seed=seed))
    root, off = (torch.from_numpy(rng.normal(size=s)) for s in ((3, 4, 3), (J, 3)))
    for offsets in (off, off.expand(3, 4, J, 3)):
        pos, glob = forward_kinematics(q, root, offsets, parents)
        ref_pos, ref_glob = _fk_joint_by_joint(q, root, offsets, parents)
        torch.testing.assert_close(pos, ref_pos, atol=1e-12, rtol=0)
        torch.testing.assert_close(glob, ref_glob, atol=1e-12, rtol=0)


def test_fk_rejects_wrong_shapes(sk):
    off = torch.from_numpy(sk.offsets)
    with pytest.raises(ValueError, match=r"rotations must be \(\.\.\., 21, 4\)"):
        forward_kinematics(torch.zeros(5, 20, 4), torch.zeros(5, 3), off, sk.parents)
    with pytest.raises(ValueError, match="root_positions must be"):
        forward_kinematics(torch.zeros(5, 21, 4), torch.zeros(4, 3), off, sk.parents)
    with pytest.raises(ValueError, match="offsets must be"):
        forward_kinematics(torch.zeros(5, 21, 4), torch.zeros(5, 3), off[:20], sk.parents)


# ---------------------------------------------------------------- Motion


def test_mirror_twice_is_identity_and_reflects_positions(sk):
    m = random_motion(sk)
    mm = m.mirror()
    np.testing.assert_allclose(mm.mirror().rotations, m.rotations, atol=1e-12)
    np.testing.assert_allclose(mm.mirror().root_positions, m.root_positions, atol=0)
    expected = m.positions()[:, list(sk.mirror_map)] * np.array([-1.0, 1.0, 1.0])
    np.testing.assert_allclose(mm.positions(), expected, atol=1e-9)
    assert mm.meta["mirrored"] and not m.meta


def test_leg_length_and_retarget_undo_a_uniform_scaling(sk):
    assert sk.leg_length() == pytest.approx(0.96 - 0.025, abs=1e-12)  # hips above the toe joints at rest
    assert sk.scaled(1.1).leg_length() == pytest.approx(1.1 * 0.935, abs=1e-12)
    m = random_motion(sk)
    big = Motion(m.rotations, m.root_positions * 1.1, sk.scaled(1.1), m.fps, subject="tall")  # the same motion, 1.1x
    back = big.retarget(sk)
    np.testing.assert_allclose(back.positions(), m.positions(), atol=1e-9)
    assert back.meta["root_scale"] == pytest.approx(1 / 1.1) and back.meta["retargeted_from"] == "tall"
    np.testing.assert_allclose(big.root_positions, m.root_positions * 1.1)  # the input is untouched
    with pytest.raises(ValueError, match="same joints"):
        m.retarget(Skeleton(sk.names[:-1], sk.parents[:-1], sk.offsets[:-1]))


def test_trusted_contacts_drops_a_bit_whose_toe_is_in_the_air():
    from course_lib.motion import STANCE_MAX_ABOVE, trusted_contacts

    bits = np.array([[True, True], [True, False], [True, True], [False, True]])
    heights = np.array([[0.02, 0.02 + STANCE_MAX_ABOVE], [0.30, 0.02], [0.02, 0.08], [0.02, 0.2]])
    want = np.array([[True, True], [False, False], [True, False], [False, False]])  # 5 cm up: kept; 28, 6, 18: not
    np.testing.assert_array_equal(trusted_contacts(bits, heights), want)
    got = trusted_contacts(torch.from_numpy(bits), torch.from_numpy(heights))
    assert torch.is_tensor(got) and (got.numpy() == want).all()
    assert trusted_contacts(bits, heights, max_above=1.0).tolist() == bits.tolist()


def test_resample_half_rate_keeps_every_second_frame(sk):
    m = random_motion(sk, T=121, fps=120)
    h = m.resample(60)
    assert len(h) == 61 and h.fps == 60 and h.duration == pytest.approx(m.duration)
    np.testing.assert_allclose(h.rotations, m.rotations[::2], atol=1e-12)
    np.testing.assert_allclose(h.root_positions, m.root_positions[::2], atol=1e-12)
    assert h.action == "walk" and h.subject == "s1"


def test_resample_chain_durations(sk):
    m = random_motion(sk, T=241, fps=120)  # 2 s
    m30 = m.resample(30)
    assert len(m30) == 61 and m30.duration == pytest.approx(2.0)
    np.testing.assert_allclose(m30.positions(), m.positions()[::4], atol=1e-9)
    m20 = m30.resample(20)
    assert len(m20) == 41 and m20.duration == pytest.approx(2.0)
    back = m30.resample(120)
    assert len(back) == 241 and back.duration == pytest.approx(2.0)
    # upsampling interpolates: in-between frames lie within a few mm of the original smooth motion
    assert np.abs(back.positions() - m.positions()).max() < 0.01
    with pytest.raises(ValueError, match="fps must be positive"):
        m.resample(0)


def test_slicing(sk):
    m = random_motion(sk, T=100)
    part = m[10:30]
    assert len(part) == 20 and part.fps == m.fps and part.skeleton is m.skeleton
    np.testing.assert_allclose(part.positions(), m.positions()[10:30], atol=1e-12)
    assert len(m[5]) == 1 and len(m[-1]) == 1 and len(m[::2]) == 50
    np.testing.assert_allclose(m[-1].root_positions[0], m.root_positions[-1])
    part.meta["x"] = 1
    assert "x" not in m.meta


def test_contacts_on_a_constructed_case(sk):
    """Standing still: both feet down; left hip flexed 90 degrees: only the right foot down;
    the whole body gliding at 1 m/s: no contact (too fast)."""
    T, J = 30, sk.num_joints
    rest = np.tile(np.array([1.0, 0, 0, 0]), (T, J, 1))
    root = np.tile([0.0, 0.96, 0.0], (T, 1))
    assert Motion(rest, root, sk, 30.0).contacts().all()

    lifted = rest.copy()
    lifted[:, sk.index("LeftUpLeg")] = [np.cos(-np.pi / 4), np.sin(-np.pi / 4), 0, 0]  # -90 deg about x: leg forward
    pos = Motion(lifted, root, sk, 30.0).positions()
    assert pos[0, sk.index("LeftFoot"), 1] == pytest.approx(0.905, abs=1e-9)  # at hip height
    c = Motion(lifted, root, sk, 30.0).contacts()
    assert not c[:, 0].any() and c[:, 1].all()

    glide = root + np.arange(T)[:, None] / 30.0 * np.array([1.0, 0, 0])
    assert not Motion(rest, glide, sk, 30.0).contacts().any()
    assert foot_contacts(Motion(rest, glide, sk, 30.0).positions(), sk, 30.0, speed=1.5).all()  # a laxer threshold
    # foot_contacts on batched positions agrees with the per-clip result
    both = np.stack([Motion(rest, root, sk, 30.0).positions(), pos])
    np.testing.assert_array_equal(foot_contacts(both, sk, 30.0)[1], c)


def test_motion_rejects_bad_input(sk):
    q = random_quats((10, sk.num_joints))
    root = np.zeros((10, 3))
    with pytest.raises(ValueError, match=r"rotations must be \(T, 21, 4\)"):
        Motion(q[:, :20], root, sk, 30)
    with pytest.raises(ValueError, match=r"root_positions must be \(10, 3\)"):
        Motion(q, root[:9], sk, 30)
    bad = q.copy()
    bad[3, 4, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        Motion(bad, root, sk, 30)
    with pytest.raises(ValueError, match="unit quaternions"):
        Motion(q * 1.5, root, sk, 30)
    with pytest.raises(ValueError, match="fps must be positive"):
        Motion(q, root, sk, 0)


def test_positions_match_fk_and_float64(sk):
    m = random_motion(sk, T=20)
    pos = m.positions()
    assert pos.shape == (20, 21, 3) and pos.dtype == np.float64
    q = quat_normalize(torch.from_numpy(m.rotations))
    ref, glob = forward_kinematics(q, torch.from_numpy(m.root_positions), torch.from_numpy(sk.offsets), sk.parents)
    np.testing.assert_allclose(pos, ref.numpy(), atol=1e-12)
    np.testing.assert_allclose(m.global_rotations(), glob.numpy(), atol=1e-12)


def test_fk_refuses_invalid_rotations_and_takes_numpy():
    sk = Skeleton.canonical()
    q = np.tile([1.0, 0.0, 0.0, 0.0], (3, sk.num_joints, 1))
    root, off = np.zeros((3, 3)), sk.offsets
    pos, _ = forward_kinematics(q, root, off, sk.parents)  # numpy in, tensors out
    assert isinstance(pos, torch.Tensor)
    torch.testing.assert_close(pos, forward_kinematics(torch.from_numpy(q), torch.from_numpy(root),
                                                       torch.from_numpy(off), sk.parents)[0])
    thigh = np.linalg.norm(pos[0, 2].numpy() - pos[0, 1].numpy())
    assert thigh == pytest.approx(0.415)
    for bad, words in ((2 * q, "norm 2;"), (0 * q, "norm 0"), (np.where(q == 1, np.nan, q), "norm nan")):
        with pytest.raises(ValueError, match=f"forward_kinematics rotations: the quaternion at index .* {words}"):
            forward_kinematics(bad, root, off, sk.parents)
    with pytest.raises(ValueError, match="norm 2"):
        sk.fk(2 * q, root)


def test_chain_subset_keeps_each_joints_ancestors_and_fk_of_it_matches(sk):
    """The toes' chains are 9 joints of the 21 (root, both legs); FK over the subset gives the full FK's toe
    positions; a joint that is not there raises."""
    from course_lib.skeleton import chain_subset

    toes = (sk.index("LeftToeBase"), sk.index("RightToeBase"))
    idx, parents = chain_subset(sk.parents, toes)
    assert idx == (0, 1, 2, 3, 4, 5, 6, 7, 8) and parents == (-1, 0, 1, 2, 3, 0, 5, 6, 7)
    assert chain_subset(sk.parents, (0,)) == ((0,), (-1,))
    g = torch.Generator().manual_seed(0)
    q = quat_normalize(torch.randn(4, sk.num_joints, 4, generator=g, dtype=torch.float64))
    root = torch.randn(4, 3, generator=g, dtype=torch.float64)
    off = torch.as_tensor(sk.offsets)
    full = forward_kinematics(q, root, off, sk.parents)[0][:, list(toes)]
    sub = forward_kinematics(q[:, list(idx)], root, off[list(idx)], parents)[0][:, [idx.index(j) for j in toes]]
    assert torch.allclose(sub, full, atol=1e-12) and full.abs().max() > 0.1
    with pytest.raises(ValueError, match="joint 21"):
        chain_subset(sk.parents, (21,))
