"""Datasets: npz storage (exact, deterministic, atomic), subject splits, windows and normalisation."""

import hashlib
import os

import numpy as np
import pytest
import torch
from test_representations import random_motion, straight_walk

from course_lib import datasets as D
from course_lib import representations as R
from course_lib.skeleton import Skeleton


def clips(n=6, T=121, fps=60.0):
    out = []
    for i in range(n):
        m = random_motion(T=T + 10 * i, fps=fps, seed=i, skeleton=Skeleton.canonical().scaled(0.9 + 0.04 * i))
        m.subject, m.action, m.style = f"s{i % 3}", ("walk", "jump")[i % 2], ("A", "B", None)[i % 3]
        m.meta = {"i": i, "program": np.arange(3) * 0.5}
        out.append(m)
    return out


def sha(path):
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


def test_save_load_round_trip(tmp_path):
    ms = clips()
    path = D.save_motions(ms, tmp_path / "set.npz", meta={"generator": "test", "n": np.int64(6)})
    back = D.load_motions(path)
    assert len(back) == 6 and [len(m) for m in back] == [len(m) for m in ms]
    for a, b in zip(ms, back, strict=True):
        assert np.abs(a.positions() - b.positions()).max() < 1e-5  # rotations stored as float32
        assert (a.action, a.style, a.subject, a.fps) == (b.action, b.style, b.subject, b.fps)
        np.testing.assert_array_equal(a.skeleton.offsets, b.skeleton.offsets)
        for j, v in a.skeleton.end_sites.items():
            np.testing.assert_array_equal(v, b.skeleton.end_sites[j])
    assert back[1].meta == {"i": 1, "program": [0.0, 0.5, 1.0]}
    assert back[2].style is None
    assert D.read_file_meta(path) == {"generator": "test", "n": 6}


def test_same_motions_give_same_bytes_and_refuse_overwrite(tmp_path):
    ms = clips(3)
    a = D.save_motions(ms, tmp_path / "a.npz")
    b = D.save_motions(clips(3), tmp_path / "b.npz")
    assert sha(a) == sha(b)
    with pytest.raises(FileExistsError, match="overwrite=True"):
        D.save_motions(ms[:1], a)
    assert sha(a) == sha(b)  # untouched
    D.save_motions(ms[:1], a, overwrite=True)
    assert len(D.load_motions(a)) == 1


def test_interrupted_write_leaves_old_file_and_no_temp(tmp_path, monkeypatch):
    path = D.save_motions(clips(2), tmp_path / "set.npz")
    before = sha(path)
    calls = []

    def interrupted(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    real = np.lib.format.write_array
    monkeypatch.setattr(np.lib.format, "write_array", interrupted)
    with pytest.raises(KeyboardInterrupt):
        D.save_motions(clips(4), path, overwrite=True)
    assert sha(path) == before and os.listdir(tmp_path) == ["set.npz"]


def test_load_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="data_scripts"):
        D.load_motions(tmp_path / "missing.npz")
    D.write_npz({"schema_version": np.array(99)}, tmp_path / "old.npz")
    with pytest.raises(ValueError, match="schema version 99"):
        D.load_motions(tmp_path / "old.npz")
    D.write_npz({"x": np.zeros(3)}, tmp_path / "other.npz")
    with pytest.raises(ValueError, match="no schema_version"):
        D.load_motions(tmp_path / "other.npz")
    (tmp_path / "text.npz").write_text("not a zip")
    with pytest.raises(ValueError, match="not a .npz motion file .not a zip archive"):
        D.load_motions(tmp_path / "text.npz")
    with pytest.raises(ValueError, match="no motions"):
        D.save_motions([], tmp_path / "empty.npz")


def test_load_errors_name_the_path_and_the_problem(tmp_path):
    (tmp_path / "zero.npz").write_bytes(b"")
    with pytest.raises(ValueError, match=f"{tmp_path / 'zero.npz'} is empty \\(0 bytes\\)"):
        D.load_motions(tmp_path / "zero.npz")
    np.save(tmp_path / "array.npy", np.zeros(3))
    with pytest.raises(ValueError, match=f"{tmp_path / 'array.npy'} is not a readable .npz motion file: it holds "
                                         "a single .npy array"):
        D.load_motions(tmp_path / "array.npy")
    for name in ("locomotion", "actions_noisy"):
        with pytest.raises(ValueError, match="load_dataset: unknown mode 'fast'; choose one of ci, class, full"):
            D.load_dataset(name, mode="fast", data_dir=tmp_path)


def test_split_by_subject():
    ms = []
    for s in range(20):
        for k in range(3):
            m = random_motion(T=4, seed=k)
            m.subject = f"s{s:02d}"
            ms.append(m)
    train, val, test = D.split_by_subject(ms, (0.7, 0.15, 0.15), seed=1)
    subj = [{m.subject for m in part} for part in (train, val, test)]
    assert [len(s) for s in subj] == [14, 3, 3] and len(train) + len(val) + len(test) == 60
    assert not (subj[0] & subj[1] or subj[0] & subj[2] or subj[1] & subj[2])
    again = D.split_by_subject(ms, (0.7, 0.15, 0.15), seed=1)
    assert [{m.subject for m in p} for p in again] == subj
    other = D.split_by_subject(ms, (0.7, 0.15, 0.15), seed=2)
    assert [{m.subject for m in p} for p in other] != subj
    tr, va, te = D.split_by_subject(ms, (0.8, 0.2, 0.0), test_subjects=["s00", "s05"], seed=0)
    assert {m.subject for m in te} == {"s00", "s05"} and len({m.subject for m in va}) == 4
    with pytest.raises(ValueError, match="unknown test subjects"):
        D.split_by_subject(ms, test_subjects=["nobody"])
    ms[0].subject = None
    with pytest.raises(ValueError, match="subject label"):
        D.split_by_subject(ms)


@pytest.mark.parametrize("name", R.REPRESENTATIONS)
def test_windows_decode_back_to_the_clip(name):
    ms = clips(4)
    ds = D.WindowDataset(ms, name, length=40, stride=25)
    assert len(ds) == sum((len(m) - 40) // 25 + 1 for m in ms)
    item = ds[5]
    assert item["x"].shape == (40, R.feature_dim(name)) and item["x"].dtype == torch.float32
    m = ds.clips[item["clip"]][item["start"]:item["start"] + 40]
    assert item["subject"] == m.subject and ds.actions[item["action_id"]] == m.action
    raw = ds.denormalize(item["x"].double()).numpy()
    p = R.decode_to_positions(raw, name, m.skeleton, m.fps, R.root_start(m))
    assert np.abs(p - m.positions()).max() < 1e-4  # float32 storage, window-local root integration


def test_normalisation_from_training_split_only(tmp_path):
    ms = clips(6)
    train = D.WindowDataset(ms[:4], "quaternion_root", length=30, stride=30)
    val = D.WindowDataset(ms[4:], "quaternion_root", length=30, stride=30, stats=train.stats)
    np.testing.assert_array_equal(val.stats[0], train.stats[0])
    own_mean, _ = D.compute_stats([R.encode(m, "quaternion_root") for m in ms[4:]])
    assert np.abs(own_mean - val.stats[0]).max() > 0.1  # val's own statistics would differ
    allx = np.concatenate([f for f in train.features])
    varying = train.stats[1] > D.STD_FLOOR
    np.testing.assert_allclose(allx[:, varying].mean(0), 0, atol=1e-4)
    np.testing.assert_allclose(allx[:, varying].std(0), 1, atol=1e-3)
    x = torch.randn(2, 30, 90, dtype=torch.float64)
    torch.testing.assert_close(train.normalize(train.denormalize(x)), x)
    # constant features: their std is floored, not 0
    const = D.WindowDataset(ms[:2], "positions_control", length=30)
    names = const.feature_names
    assert const.stats[1][names.index("Hips_x")] == D.STD_FLOOR
    path = train.save_stats(D.stats_path(tmp_path / "set.npz", "quaternion_root", 60.0))
    assert path.name == "set.stats.quaternion_root.60fps.npz"
    mean, std = D.load_stats(path, "quaternion_root")
    np.testing.assert_array_equal(mean, train.stats[0])
    with pytest.raises(ValueError, match="not 'state_features'"):
        D.load_stats(path, "state_features")
    with pytest.raises(ValueError, match=r"\(\.\.\., 90\)"):
        train.normalize(np.zeros((3, 66)))


def test_mirror_and_fps_options():
    ms = clips(2, T=121, fps=60.0)
    ds = D.WindowDataset(ms, "positions_control", length=20, stride=20, fps=30.0, mirror=True)
    assert [len(c) for c in ds.clips] == [61, 66, 61, 66] and ds.clips[2].meta.get("mirrored")
    assert len(ds) == 2 * (3 + 3)
    # the mirror image has the same forward speed and the opposite yaw rate
    f, g = R.encode_positions_control(ds.clips[0]), R.encode_positions_control(ds.clips[2])
    np.testing.assert_allclose(g[:, -3], f[:, -3], atol=1e-9)
    np.testing.assert_allclose(g[:, -1], -f[:, -1], atol=1e-9)
    rev = D.WindowDataset(ms[:1], "positions_control", length=20, stride=20, reverse=True)
    assert len(rev.clips) == 2 and rev.clips[1].meta["time_reversed"]
    np.testing.assert_allclose(rev.clips[1].positions(), rev.clips[0].positions()[::-1], atol=1e-12)
    back = D.time_reversed(straight_walk(direction_deg=90, heading_deg=90, speed=1.5))
    np.testing.assert_allclose(R.encode_positions_control(back)[:, -3:], [[-1.5, 0, 0]] * len(back), atol=1e-9)
    with pytest.raises(ValueError, match="no clip has 500 frames"):
        D.WindowDataset(ms, "positions_control", length=500)
    with pytest.raises(ValueError, match="unknown representation"):
        D.WindowDataset(ms, "euler", length=5)


def test_load_dataset_prefers_the_file(tmp_path):
    ms = clips(2)
    D.save_motions(ms, tmp_path / "actions.npz")
    back = D.load_dataset("actions", mode="class", data_dir=tmp_path)
    assert [len(m) for m in back] == [len(m) for m in ms]
    half = D.load_dataset("actions", mode="class", data_dir=tmp_path, fps=ms[0].fps / 2)
    assert half[0].fps == ms[0].fps / 2 and len(half[0]) == (len(ms[0]) + 1) // 2
    # CI mode never reads data/: its numbers must not depend on what `make data` left there
    assert len(D.load_dataset("actions", mode="ci", data_dir=tmp_path)) == 4 * len(D.ACTIONS) * len(D.STYLES)
    with pytest.raises(ValueError, match="unknown dataset"):
        D.load_dataset("mocap", data_dir=tmp_path)


def test_load_dataset_generates_a_small_seeded_set(tmp_path):
    ms = D.load_dataset("locomotion", mode="ci", data_dir=tmp_path)  # no file there: generated in memory
    assert len(ms) == D.GENERATED_SIZES["locomotion"]["ci"] == 24
    assert len({m.subject for m in ms}) == 8 and all(m.fps == 60 and len(m) == 241 for m in ms)
    again = D.generate_locomotion_set(2, seed=0, n_subjects=8)
    np.testing.assert_array_equal(again[1].rotations, ms[1].rotations)  # seeded per clip
    back = D.load_motions(D.save_motions(ms[:3], tmp_path / "x.npz"))  # per-frame meta arrays survive
    np.testing.assert_array_equal(back[2].meta["contacts"], ms[2].meta["contacts"])
    assert back[2].meta["speed"].dtype == np.float64 and back[2].meta["speed"].shape == (241,)
    assert back[2].meta["program"]["gaits"] == list(ms[2].meta["program"].gaits)


def test_per_frame_meta_of_some_clips_is_stored_as_arrays(tmp_path):
    ms = clips(3)
    ms[0].meta["object"] = np.arange(len(ms[0]) * 3, dtype=float).reshape(-1, 3)
    ms[2].meta["object"] = -np.ones((len(ms[2]), 3))
    ms[1].meta["flags"] = np.zeros(len(ms[1]), bool)
    path = D.save_motions(ms, tmp_path / "x.npz")
    import zipfile

    names = zipfile.ZipFile(path).namelist()
    assert "frame_meta__object.npy" in names and "frame_meta__flags.npy" in names
    back = D.load_motions(path)
    np.testing.assert_array_equal(back[0].meta["object"], ms[0].meta["object"])
    np.testing.assert_array_equal(back[2].meta["object"], ms[2].meta["object"])
    assert "object" not in back[1].meta and back[1].meta["flags"].dtype == bool and "flags" not in back[0].meta
