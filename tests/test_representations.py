"""Representations: exact round trips, known answers, invariances, clear errors."""

import numpy as np
import pytest
import torch

from course_lib import representations as R
from course_lib.motion import Motion
from course_lib.rotations import axis_angle_to_quat, euler_to_quat, expmap_to_quat, quat_mul, quat_rotate
from course_lib.skeleton import Skeleton


def random_motion(T=481, fps=120.0, seed=0, skeleton=None) -> Motion:
    """A smooth random motion: every joint's expmap and the root's yaw/pitch/roll and path follow
    piecewise-linear random keys; the heading turns up to several full turns."""
    rng = np.random.default_rng(seed)
    sk = skeleton or Skeleton.canonical()
    J = sk.num_joints
    t, tk = np.linspace(0, 1, T), np.linspace(0, 1, 6)
    keys = rng.normal(0, 0.5, (6, J, 3))
    ex = np.stack([np.interp(t, tk, k) for k in keys.reshape(6, -1).T], -1).reshape(T, J, 3)
    rot = expmap_to_quat(torch.from_numpy(ex)).numpy()
    ypr = np.stack([np.interp(t, tk, rng.uniform(-1, 1, 6) * s) for s in (8.0, 0.4, 0.3)], -1)
    rot[:, 0] = euler_to_quat(torch.from_numpy(ypr), "YXZ").numpy()
    root = np.stack([np.interp(t, tk, rng.normal(0, 3, 6)), 0.9 + 0.05 * np.sin(9 * t),
                     np.interp(t, tk, rng.normal(0, 3, 6))], -1)
    return Motion(rot, root, sk, fps, action="random", subject=f"s{seed}")


def straight_walk(direction_deg=90.0, speed=1.5, heading_deg=90.0, fps=120.0, T=481) -> Motion:
    """Rest pose, root gliding at `speed` along the floor direction `direction_deg` (0 = +Z, 90 = +X),
    facing heading_deg."""
    sk = Skeleton.canonical()
    a = np.radians(direction_deg)
    t = np.arange(T) / fps
    root = np.stack((speed * t * np.sin(a), np.full(T, 0.96), speed * t * np.cos(a)), -1)
    rot = np.zeros((T, sk.num_joints, 4))
    rot[..., 0] = 1.0
    rot[:, 0] = axis_angle_to_quat(torch.tensor([0.0, 1.0, 0.0]), torch.tensor(np.radians(heading_deg))).numpy()
    return Motion(rot, root, sk, fps)


def rotated_about_y(m: Motion, angle: float, shift=(0.0, 0.0)) -> Motion:
    """The same motion turned by `angle` about the world Y axis and shifted on the floor."""
    y = torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64)
    qy = axis_angle_to_quat(y, torch.tensor(angle, dtype=torch.float64))
    rot = m.rotations.copy()
    rot[:, 0] = quat_mul(qy, torch.from_numpy(rot[:, 0])).numpy()
    root = quat_rotate(qy.expand(len(m), 4), torch.from_numpy(m.root_positions)).numpy()
    root += np.array([shift[0], 0.0, shift[1]])
    return Motion(rot, root, m.skeleton, m.fps)


@pytest.mark.parametrize("name", R.REPRESENTATIONS)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_round_trip_random_motion(name, seed):
    skel = Skeleton.canonical().scaled(1.0 + 0.1 * seed)
    m = random_motion(seed=seed, skeleton=skel, fps=(120.0, 60.0, 30.0)[seed])
    f = R.encode(m, name)
    assert f.shape == (len(m), R.feature_dim(name)) and f.dtype == np.float64
    p = R.decode_to_positions(f, name, m.skeleton, m.fps, R.root_start(m))
    assert np.abs(p - m.positions()).max() < 1e-8
    p32 = R.decode_to_positions(f.astype(np.float32), name, m.skeleton, m.fps, R.root_start(m))
    assert np.abs(p32 - m.positions()).max() < 1e-4


@pytest.mark.parametrize("name", ["state_features", "quaternion_root"])
def test_decoded_rotations_equal_originals(name):
    m = random_motion(seed=3)
    out = R.decode(R.encode(m, name), name, m.skeleton, m.fps, R.root_start(m))
    dots = np.abs((out.rotations * m.rotations).sum(-1))  # |q . q'| = 1 for the same rotation
    assert np.abs(dots - 1).max() < 1e-10
    assert np.abs(out.root_positions - m.root_positions).max() < 1e-9


def test_control_integrates_back_to_root_path_in_float32():
    m = random_motion(seed=4)  # 4 s at 120 fps, metres of travel and several turns
    f = R.encode_positions_control(m).astype(np.float32)
    p = R.decode_positions(f, m.fps, start=R.root_start(m))
    err = np.linalg.norm(p[:, 0, [0, 2]] - m.root_positions[:, [0, 2]], axis=-1)
    assert err[-1] < 0.01 and err.max() < 0.01
    assert np.linalg.norm(m.root_positions[-1, [0, 2]] - m.root_positions[0, [0, 2]]) > 0.5  # it did travel


def test_walking_along_x_facing_x():
    m = straight_walk(direction_deg=90, heading_deg=90)
    assert R.root_start(m)[2] == pytest.approx(np.pi / 2)
    pc = R.encode_positions_control(m)
    np.testing.assert_allclose(pc[:, -3:], np.tile([1.5, 0.0, 0.0], (len(m), 1)), atol=1e-9)
    names = R.feature_names("positions_control")
    left_hip = pc[0, names.index("LeftUpLeg_x"):names.index("LeftUpLeg_x") + 3]
    np.testing.assert_allclose(left_hip, [0.09, 0.96 - 0.055, 0.0], atol=1e-12)  # left is local +X
    np.testing.assert_allclose(pc[0, :3], [0.0, 0.96, 0.0], atol=1e-12)  # root above the floor frame's origin
    sf = R.encode_state_features(m)
    np.testing.assert_allclose(sf[:, :6], np.tile([0.0, 1.5 / 120, 0.0, 0.96, 0.0, 0.0], (len(m), 1)), atol=1e-9)
    qr = R.encode_quaternion_root(m)
    np.testing.assert_allclose(qr[:, -6:], np.tile([1.5, 0.0, 0.96, 0.0, 0.0, 0.0], (len(m), 1)), atol=1e-9)
    np.testing.assert_allclose(qr[:, :4], np.tile([1.0, 0, 0, 0], (len(m), 1)), atol=1e-12)  # heading removed


def test_sidestep_left_and_backwards():
    side = R.encode_positions_control(straight_walk(direction_deg=90, heading_deg=0, speed=0.8))
    np.testing.assert_allclose(side[:, -3:], np.tile([0.0, 0.8, 0.0], (len(side), 1)), atol=1e-9)
    back = R.encode_positions_control(straight_walk(direction_deg=180, heading_deg=0, speed=1.0))
    np.testing.assert_allclose(back[:, -3:], np.tile([-1.0, 0.0, 0.0], (len(back), 1)), atol=1e-9)


def test_turning_on_the_spot_and_tilt():
    fps, T, omega = 60.0, 241, 1.2  # rad/s, 4.8 rad in total: crosses +-pi
    yaw = omega * np.arange(T) / fps
    ypr = np.column_stack((yaw, np.full(T, 0.3), np.full(T, -0.2)))
    m = straight_walk(speed=0.0, fps=fps, T=T)
    rot = m.rotations.copy()
    rot[:, 0] = euler_to_quat(torch.from_numpy(ypr), "YXZ").numpy()
    m = Motion(rot, m.root_positions, m.skeleton, fps)
    qr = R.encode_quaternion_root(m)
    np.testing.assert_allclose(qr[:, -3:], np.tile([omega, 0.3, -0.2], (T, 1)), atol=1e-9)
    sf = R.encode_state_features(m)
    np.testing.assert_allclose(sf[:, 2], omega / fps, atol=1e-12)
    pc = R.encode_positions_control(m)
    np.testing.assert_allclose(pc[:, -1], omega, atol=1e-9)


@pytest.mark.parametrize("name", R.REPRESENTATIONS)
def test_invariant_to_floor_rotation_and_translation(name):
    """Wang sec. 4.1.1: the features do not depend on where the character is or which way it faces."""
    m = random_motion(seed=5, T=121)
    f0 = R.encode(m, name)
    f1 = R.encode(rotated_about_y(m, 2.5, shift=(3.0, -7.0)), name)
    np.testing.assert_allclose(f1, f0, atol=1e-9)


def test_contact_bits_and_quaternion_continuity():
    m = straight_walk(speed=0.0, T=30)
    sf = R.encode_state_features(m)
    assert (sf[:, -2:] == 1).all()  # standing still at rest height
    lifted = Motion(m.rotations, m.root_positions + [0, 0.5, 0], m.skeleton, m.fps)
    assert (R.encode_state_features(lifted)[:, -2:] == 0).all()
    q = R.encode_quaternion_root(random_motion(seed=6))[:, :-6].reshape(-1, 21, 4)
    assert ((q[1:] * q[:-1]).sum(-1) >= 0).all() and (q[0, :, 0] >= 0).all()


def test_feature_names_and_dims():
    for name, d in zip(R.REPRESENTATIONS, (66, 68, 90), strict=True):
        assert R.feature_dim(name) == d == len(R.feature_names(name)) == R.DIMS[name]
    assert R.feature_names("state_features")[:3] == ["dx", "dz", "dyaw"]
    assert R.feature_names("state_features")[6] == "LeftUpLeg_rx"
    assert R.feature_names("quaternion_root")[-6:] == list(R.QUAT_ROOT_NAMES)


def test_clear_errors():
    sk = Skeleton.canonical()
    with pytest.raises(ValueError, match="unknown representation"):
        R.encode(random_motion(T=5), "euler")
    with pytest.raises(ValueError, match=r"\(T, 68\)"):
        R.decode_state_features(np.zeros((10, 67)), sk, 30.0)
    bad = np.zeros((10, 90))
    bad[3, 5] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        R.decode_quaternion_root(bad, sk, 30.0)
    with pytest.raises(ValueError, match="zero norm"):
        R.decode_quaternion_root(np.zeros((10, 90)), sk, 30.0)
    with pytest.raises(ValueError, match="3J"):
        R.decode_positions(np.zeros((10, 65)), 30.0)


@pytest.mark.parametrize("name", R.REPRESENTATIONS)
def test_round_trip_generated_and_real_motion(name, cmu_bvh_path):
    from course_lib.bvh import map_to_canonical, read_bvh
    from course_lib.synthetic import generate_locomotion, make_subject

    clips = [generate_locomotion(make_subject(i, seed=1), None, duration=4.0, fps=60, seed=i) for i in range(2)]
    clips.append(map_to_canonical(read_bvh(cmu_bvh_path))[:240])
    for m in clips:
        f = R.encode(m, name)
        p = R.decode_to_positions(f.astype(np.float32), name, m.skeleton, m.fps, R.root_start(m))
        assert np.abs(p - m.positions()).max() < 1e-4


def test_control_matches_the_generators_commands():
    """The control decoded from the body agrees, on average over a clip, with the velocity and heading
    rate the generator was driven by (they differ per frame by the pelvis' sway and twist)."""
    from course_lib.synthetic import generate_locomotion, make_subject

    for i in range(3):
        m = generate_locomotion(make_subject(i, seed=1), None, duration=4.0, fps=60, seed=i)
        c = R.encode_positions_control(m)[:, -3:].mean(0)  # (forward, sideways, yaw rate)
        v, w = m.meta["velocity"].mean(0), m.meta["heading_rate"].mean()  # v: (x left, z forward)
        np.testing.assert_allclose(c, [v[1], v[0], w], atol=0.1)


def test_contact_bits_agree_with_the_generators_stance():
    """state_features' contact bits (motion.foot_contacts thresholds) vs the generator's ground-truth stance."""
    from course_lib.synthetic import generate_locomotion, make_subject

    agree = []
    for i in range(3):
        m = generate_locomotion(make_subject(i, seed=2), None, duration=4.0, fps=60, seed=10 + i)
        bits = R.encode_state_features(m)[:, -2:]
        agree.append((bits == m.meta["contacts"]).mean())
    assert np.mean(agree) > 0.9


@pytest.mark.parametrize("seed", [0, 1])
def test_motion_from_positions_recovers_the_bones(seed):
    """FK(motion_from_positions(FK(m))) == FK(m) for a random motion (every bone direction and the root),
    and on a skeleton with other bone lengths each bone keeps its direction; bad input is a clear error."""
    m = random_motion(T=60, seed=seed)
    pos = m.positions()
    back = R.motion_from_positions(pos, m.skeleton, m.fps)
    np.testing.assert_allclose(back.positions(), pos, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(back.rotations, axis=-1), 1.0, atol=1e-12)
    longer = m.skeleton.scaled(1.2)
    moved = R.motion_from_positions(pos, longer, m.fps).positions()
    for j, p in enumerate(m.skeleton.parents[1:], 1):
        a, b = pos[:, j] - pos[:, p], moved[:, j] - moved[:, p]
        np.testing.assert_allclose(b, 1.2 * a, atol=1e-9)  # same direction, the new skeleton's length
    with pytest.raises(ValueError, match="positions"):
        R.motion_from_positions(pos[:, :20], m.skeleton, m.fps)


def test_local_positions_raise_on_nan_angles():
    """FK by rotation matrices would pass a NaN angle on as NaN positions: it is an error instead."""
    sk = Skeleton.canonical()
    feats = torch.zeros(1, 3, R.feature_dim("state_features", sk.num_joints), dtype=torch.float64)
    feats[0, 1, 7] = float("nan")
    with pytest.raises(ValueError, match="NaN"):
        R.local_positions(feats, sk)


def test_local_positions_of_some_joints_are_those_of_the_full_fk():
    """local_positions(joints=...) runs FK over those joints' chains only; the positions are the full FK's."""
    sk = Skeleton.canonical()
    g = torch.Generator().manual_seed(3)
    feats = torch.randn(2, 5, R.feature_dim("state_features", sk.num_joints), generator=g, dtype=torch.float64) * 0.3
    joints = (sk.index("RightToeBase"), sk.index("LeftHand"), 0)
    full = R.local_positions(feats, sk)
    some = R.local_positions(feats, sk, joints=joints)
    assert some.shape == (2, 5, 3, 3)
    torch.testing.assert_close(some, full[..., list(joints), :], atol=1e-12, rtol=0)
    scaled = torch.as_tensor(sk.offsets)[None].expand(2, -1, -1) * torch.tensor([1.0, 1.1])[:, None, None]
    torch.testing.assert_close(R.local_positions(feats, sk, scaled, joints),
                               R.local_positions(feats, sk, scaled)[..., list(joints), :], atol=1e-12, rtol=0)
