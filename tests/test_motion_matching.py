"""course_lib.models.motion_matching: the feature vector, the search and the playback on known answers."""

from __future__ import annotations

import numpy as np
import pytest

from course_lib.models.motion_matching import MotionMatching, MotionMatchingConfig, future_path


@pytest.fixture(scope="module")
def clips():
    from course_lib.experiments import vae_lstm as lesson02

    data = lesson02.DataSpec()
    train, test = lesson02.datasets(data, lesson02.load_clips(data, progress=False))
    return train.clips, test.clips[:3]


@pytest.fixture(scope="module")
def mm(clips):
    return MotionMatching(clips[0])


def test_future_path_of_a_straight_walk_and_a_turn():
    walk = np.tile([1.5, 0.0, 0.0], (40, 1))  # 1.5 m/s forward
    path = future_path(walk, 30.0)
    assert np.allclose(path[:, :2], [[0, 0.5], [0, 1.0], [0, 1.5]])  # (x, z) 1/3, 2/3, 1 s ahead
    assert np.allclose(path[:, 2:], [[0, 1]] * 3)  # still facing +Z
    turn = np.tile([0.0, 0.0, np.pi / 2], (40, 1))  # turning on the spot at 90 degrees/s
    assert np.allclose(future_path(turn, 30.0)[-1, 2:], [1, 0], atol=1e-9)  # after 1 s facing +X (left)


def test_features_are_27_and_a_database_frame_finds_itself(mm):
    assert mm.tree.data.shape[1] == 27 and len(mm.where) == mm.tree.n
    for row in (0, 1234, len(mm.where) - 1):
        c, t = mm.where[row]
        q = mm.features(mm.frames[c], t)
        assert np.allclose(q, mm.tree.data[row]) and mm.search(q)[0] == row


def test_replay_of_a_database_clip_is_exact(mm):
    """Started inside a database clip and asked for its own control, motion matching plays that clip on:
    the replay is the clip itself, frame for frame (no jump, no blend)."""
    f = mm.frames[5]
    out = mm.generate(f[:20], 40, control=f[20:, -3:])
    assert np.abs(out - f[20:60]).max() < 1e-9


def test_controlled_playback_follows_the_request_and_stays_continuous(mm, clips):
    from course_lib.representations import decode_positions, encode_positions_control, root_start

    m = clips[1][0].resample(30.0)
    f = encode_positions_control(m)
    new = mm.generate(f[:15], 100, control=f[15:, -3:])
    pos = decode_positions(np.concatenate((f[14:15], new)), 30.0, root_start(m[14:15]))
    truth = m.positions()[14:115]
    path = np.linalg.norm(pos[:, 0, [0, 2]] - truth[:, 0, [0, 2]], axis=-1).mean()
    assert path < 0.6, path  # the training split follows a held-out clip's path to within tens of cm
    step = np.linalg.norm(np.diff(pos, axis=0), axis=-1).max()
    fastest = np.linalg.norm(np.diff(truth, axis=0), axis=-1).max()
    assert step < 1.25 * fastest, (step, fastest)  # inertialisation: no joint pops faster than the mocap moves
    free = [mm.generate(f[:15], 60, None, np.random.default_rng(s)) for s in (0, 1)]
    assert np.abs(free[0] - free[1]).max() > 1e-3  # free generation: seeds choose among the k nearest


def test_config_checks_and_search_cost(clips):
    with pytest.raises(ValueError, match="no clips"):
        MotionMatching([])
    mm = MotionMatching(clips[0][:5], MotionMatchingConfig(search_every=1))
    with pytest.raises(ValueError, match=r"\(T, 3\)"):
        mm.generate(mm.frames[0][:5], 10, control=mm.frames[0])
    mm.generate(mm.frames[0][:5], 30, control=mm.frames[0][5:, -3:])
    assert mm.searches == 30 and mm.frames_made == 30 and mm.search_seconds > 0
