"""Contact handling (course_lib/models/contact_cleanup.py): the predicted contacts enforced on the root."""

import numpy as np
import pytest
import torch

from course_lib.datasets import generate_locomotion_set
from course_lib.evaluation import foot_skate
from course_lib.models.contact_cleanup import TOE_FLOOR, enforce_contacts, leg_columns, plant_feet, toe_floor_height
from course_lib.models.refiner import local_positions
from course_lib.representations import decode_state_features, encode_state_features, root_start


@pytest.fixture(scope="module")
def clip():
    return generate_locomotion_set(2, seed=5, fps=30.0, duration=3.0, n_subjects=2)[0]


def decoded(features, clip):
    return decode_state_features(features, clip.skeleton, clip.fps, root_start(clip))


def test_mocap_is_left_almost_unchanged(clip):
    f = encode_state_features(clip)
    g = enforce_contacts(f, clip.skeleton)
    assert np.array_equal(g[:, 2:3], f[:, 2:3]) and np.array_equal(g[:, 4:], f[:, 4:])  # yaw, tilt, angles, bits
    assert np.abs(g[:, 3] - f[:, 3]).max() < 0.003  # the data's planted toes are within 3 mm of TOE_FLOOR
    assert np.abs(decoded(g, clip).positions() - clip.positions()).max() < 0.01


def test_sliding_sunken_motion_is_repaired(clip):
    f = encode_state_features(clip)
    bad = f.copy()
    rng = np.random.default_rng(0)
    bad[1:, 0:2] += rng.normal(0, 0.01, (len(f) - 1, 2))  # the root slides: ~0.4 m/s of noise at 30 fps
    bad[:, 3] -= 0.08  # and sinks 8 cm: the feet go into the floor
    g = enforce_contacts(bad, clip.skeleton)
    assert foot_skate([decoded(bad, clip)]) > 0.2
    fixed = decoded(g, clip)
    assert foot_skate([fixed]) < 0.05
    pos, bits, toes = fixed.positions(), g[:, -2:] > 0.5, list(clip.skeleton.feet[1::2])
    lowest_flagged = np.where(bits, pos[:, toes, 1], np.inf).min(1)
    flagged = bits.any(1)
    assert np.allclose(lowest_flagged[flagged], TOE_FLOOR, atol=1e-6)  # point-plane: stance toe on the floor
    for side, toe in enumerate(toes):  # adjacent: a stance toe kept in contact does not move
        # the lower toe on both frames; a tie (both planted on the floor, equal to rounding) can go either way
        lower = pos[:, toe, 1] < pos[:, toes[1 - side], 1] - 1e-9
        still = bits[1:, side] & bits[:-1, side] & lower[1:] & lower[:-1]
        assert still.any()
        step = np.linalg.norm(np.diff(pos[:, toe][:, [0, 2]], axis=0), axis=-1)
        assert step[still].max() < 1e-6


def test_torch_batches_and_bad_input(clip):
    f = torch.from_numpy(np.stack([encode_state_features(clip)] * 2)).float()
    g = enforce_contacts(f, clip.skeleton)
    assert torch.is_tensor(g) and g.dtype == torch.float32 and g.shape == f.shape
    assert torch.allclose(g[0], g[1])
    with pytest.raises(ValueError, match="state features for 21 joints"):
        enforce_contacts(f[..., :-1], clip.skeleton)
    nan = f.clone()
    nan[0, 3, 7] = float("nan")
    with pytest.raises(ValueError, match="NaN"):
        enforce_contacts(nan, clip.skeleton)
    with pytest.raises(ValueError, match="smooth must be an odd int"):
        enforce_contacts(f, clip.skeleton, smooth=2)
    smoothed = enforce_contacts(f, clip.skeleton, smooth=5)
    assert torch.equal(smoothed[..., 4:], f[..., 4:])  # only the root's floor steps and height move
    with pytest.raises(ValueError, match="T >= 2"):
        enforce_contacts(f[:, :1], clip.skeleton)


def test_toe_floor_height_matches_the_constant(clip):
    assert toe_floor_height([clip]) == pytest.approx(TOE_FLOOR, abs=0.002)
    with pytest.raises(ValueError, match="no foot contact"):
        toe_floor_height([])


def test_a_flagged_foot_in_the_air_is_not_the_stance_foot(clip):
    """max_above: a contact bit on a toe far above the other toe contradicts the pose and is ignored."""
    f = encode_state_features(clip)
    toes = local_positions(torch.from_numpy(f), clip.skeleton)[:, list(clip.skeleton.feet[1::2]), 1].numpy()
    t = int(np.argmax(np.abs(toes[:, 0] - toes[:, 1])))  # the frame where one toe is highest above the other
    high = int(np.argmax(toes[t]))
    assert toes[t, high] - toes[t, 1 - high] > 0.05
    bad = f.copy()
    bad[t, 66 + high], bad[t, 66 + 1 - high] = 1.0, 0.0  # only the foot in the air is flagged
    trusted = enforce_contacts(bad, clip.skeleton, max_above=None)
    gated = enforce_contacts(bad, clip.skeleton)
    assert trusted[t, 3] < f[t, 3] - 0.04  # trusting the bit pulls the body down to put that toe on the floor
    assert abs(gated[t, 3] - f[t, 3]) < 0.01  # the gate keeps the height (interpolated from the neighbours)


LEG_COLUMNS = [0, 1, 3, 6, 7, 8, 9, 12, 13, 14, 18, 19, 20, 21, 24, 25, 26]  # root step, height, hip/knee/ankle


def flagged_toe_steps(features, clip):
    """World (x, z) step (m) of each toe between frames where it is flagged on both, as plant_feet pins them."""
    pos, toes = decoded(features, clip).positions(), list(clip.skeleton.feet[1::2])
    y = pos[:, toes, 1]
    bits = (features[:, -2:] > 0.5) & (y <= y.min(1, keepdims=True) + 0.05)
    pinned = bits[1:] & bits[:-1]
    step = np.linalg.norm(np.diff(pos[:, toes][..., [0, 2]], axis=0), axis=-1)
    return step[pinned]


def test_plant_feet_leaves_mocap_and_pins_both_feet_of_a_sliding_motion(clip):
    f = encode_state_features(clip)
    g = plant_feet(f[None], clip.skeleton, LEG_COLUMNS)[0]
    pose = lambda x: local_positions(torch.from_numpy(x), clip.skeleton).numpy()  # noqa: E731
    assert np.abs(pose(g) - pose(f)).max() < 0.03  # mocap's pose moves under 3 cm (flagged toes to TOE_FLOOR) ...
    assert np.abs(decoded(g, clip).positions() - clip.positions()).max() < 0.05  # ... nor its path (3 s)
    bad = f.copy()
    rng = np.random.default_rng(1)
    bad[:, [6, 9, 18, 21]] += rng.normal(0, 0.03, (len(f), 4))  # hips and knees shake: the stance toes slide
    before = flagged_toe_steps(bad, clip)
    fixed = plant_feet(bad[None], clip.skeleton, LEG_COLUMNS)[0]
    after = flagged_toe_steps(fixed, clip)
    assert before.mean() * clip.fps > 0.3 and after.mean() < 0.15 * before.mean()
    untouched = [c for c in range(68) if c not in LEG_COLUMNS]
    assert np.array_equal(fixed[:, untouched], bad[:, untouched])  # heading, arms, tilt and bits as given
    with pytest.raises(ValueError, match="pose columns"):
        plant_feet(bad[None], clip.skeleton, [2])  # the heading is not a pose column
    with pytest.raises(ValueError, match=r"\(N, T >= 2, D\)"):
        plant_feet(bad, clip.skeleton, LEG_COLUMNS)


def test_leg_columns_are_the_hip_knee_and_ankle_angles(clip):
    sk = clip.skeleton  # canonical order: LeftUpLeg 1, LeftLeg 2, LeftFoot 3, RightUpLeg 5, RightLeg 6, RightFoot 7
    assert leg_columns(sk) == [6, 7, 8, 9, 10, 11, 12, 13, 14, 18, 19, 20, 21, 22, 23, 24, 25, 26]
    fixed = np.zeros(68, bool)
    fixed[[10, 11, 22, 23]] = True  # the knees' off-axis components, fixed in the course's data
    assert leg_columns(sk, fixed) == LEG_COLUMNS[3:]  # the contact handling's columns without the root's
    with pytest.raises(ValueError, match="one bool per state feature"):
        leg_columns(sk, np.zeros(60, bool))
