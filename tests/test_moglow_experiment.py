"""Lesson 06's experiment (course_lib/experiments/moglow.py): data, measures with known answers, registry."""

import dataclasses

import numpy as np
import pytest
import torch

from course_lib.experiments import moglow as E

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def data():
    return E.load_data("ci")


def test_data_is_sec_5_1(data):
    assert data.train["poses"].shape[1:] == (E.WINDOW, 61) and data.train["controls"].shape[-1] == 3
    assert data.fixed.sum() == 2 and data.pose_dim == 61  # the Hips' floor-frame x and z are not modelled
    # mirrored + time-reversed: 4x the training clips; standardised with the training split's stats
    assert len(data.train["poses"]) % 4 == 0
    assert data.train["poses"].mean().abs() < 0.05 and abs(data.train["poses"].std() - 1) < 0.05


def test_features_back_to_the_clips_positions(data):
    from course_lib.representations import root_start

    m = data.test_clips[0]
    pos = data.positions(data.test["poses"][:1], data.test["controls"][:1], [root_start(m)])[0]
    np.testing.assert_allclose(pos, m.positions()[: E.WINDOW], atol=1e-4)


def test_one_body_puts_every_clip_on_the_canonical_skeleton(data):
    from course_lib.representations import root_start
    from course_lib.skeleton import Skeleton

    one = E.load_data("ci", one_body=True)
    canonical = Skeleton.canonical()
    assert all(np.allclose(m.skeleton.offsets, canonical.offsets) for m in one.test_clips)
    assert not all(np.allclose(m.skeleton.offsets, canonical.offsets) for m in data.test_clips)  # bodies kept
    m = one.test_clips[0]  # the features still decode to the (retargeted) clip's own positions
    pos = one.positions(one.test["poses"][:1], one.test["controls"][:1], [root_start(m)])[0]
    np.testing.assert_allclose(pos, m.positions()[: E.WINDOW], atol=1e-4)


def test_stride_frequency_known_answer():
    t = np.arange(200) / E.FPS
    local = np.zeros((2, 200, 21, 3))
    from course_lib.skeleton import Skeleton

    sk = Skeleton.canonical()
    for i, f in enumerate((0.9, 1.4)):
        local[i, :, sk.index("LeftFoot"), 2] = 0.3 * np.sin(2 * np.pi * f * t)
        local[i, :, sk.index("RightFoot"), 2] = -0.3 * np.sin(2 * np.pi * f * t)
    np.testing.assert_allclose(E.stride_frequency(local), [0.9, 1.4], atol=0.01)


def test_data_cadence_estimator_agrees_with_the_generator():
    """On the data, the estimator's cadence is within 8 % of the generator's own (clip meta; 2.5 % on the full data)."""
    from types import SimpleNamespace

    from course_lib.datasets import load_dataset

    d = SimpleNamespace(test_clips=load_dataset("locomotion", mode="ci", fps=E.FPS))
    speed = float(np.median([np.mean(m.meta["speed"]) for m in d.test_clips if m.action == "walk"]))
    ref = E.data_gait(d, speed, tol=0.3)
    assert ref["clips"] >= 1 and ref["frames"] >= ref["clips"] * 1.5 * E.FPS  # runs of >= 1.5 s
    assert abs(ref["estimator_cadence"] / ref["cadence"] - 1) < 0.08  # 1.5-s runs: ~1.5 strides each
    assert abs(ref["stride_m"] - ref["speed"] / (ref["cadence"] / 2)) < 1e-9  # stride = v / stride frequency


def test_constant_control_and_foot_speed(data):
    c = E.constant_control(data, 2, 5, forward=1.2)
    raw = c.double().numpy() * data.stats[1][63:] + data.stats[0][63:]
    np.testing.assert_allclose(raw[..., 0], 1.2, atol=1e-5)
    np.testing.assert_allclose(raw[..., 1:], 0.0, atol=1e-5)
    still = np.zeros((1, 10, 21, 3))
    assert E.foot_speed(still) == 0.0
    moving = still.copy()
    moving[..., 2] = np.arange(10)[None, :, None] * 0.1  # every joint 0.1 m forward per frame
    assert abs(E.foot_speed(moving) - 0.1 * E.FPS) < 1e-9


def test_registered_in_reproduce():
    from course_lib.reproduce import EXPERIMENTS

    assert "moglow" in EXPERIMENTS
    train, evaluate = EXPERIMENTS["moglow"]
    assert train.__name__ == "train_moglow" and evaluate.__name__ == "eval_moglow"


def test_steady_runs_known_answer():
    v = np.array([0.0, 1.0, 1.1, 0.9, 1.0, 3.0, 1.0, 1.0, 0.0, 1.05, 1.0, 1.0, 1.1])
    runs = E.steady_runs(v, 1.0, 0.15, 3)
    assert [(r.start, r.stop) for r in runs] == [(1, 5), (9, 13)]  # the 2-frame run is too short
    assert E.steady_runs(v, 5.0, 0.15, 1) == []


def test_stepping_speed_sees_steps_not_per_frame_noise():
    """Known answers: a foot that moves steadily keeps its speed at every lag; i.i.d. per-frame noise of 2 cm
    scores ~0.8 m/s frame to frame but ~5x less at STEP_LAG; standing still scores 0 at any lag."""
    rng = np.random.default_rng(0)
    T = 400
    still = np.zeros((4, T, 21, 3))
    assert E.foot_speed(still, E.STEP_LAG) == 0.0
    stepping = still.copy()
    stepping[..., 2] = 0.25 * np.sin(2 * np.pi * 0.9 * np.arange(T) / E.FPS)[None, :, None]  # a 0.9-Hz stride
    noisy = still + rng.normal(0, 0.02, still.shape)
    v_step = (E.foot_speed(stepping), E.foot_speed(stepping, E.STEP_LAG))
    v_noise = (E.foot_speed(noisy), E.foot_speed(noisy, E.STEP_LAG))
    assert v_step[1] > 0.75 * v_step[0]  # stepping: the 0.25-s lag keeps most of the speed
    expected = np.sqrt(np.pi / 2) * np.sqrt(2) * 0.02 * E.FPS  # mean of a Rayleigh of sd sqrt(2) * 0.02, x fps
    assert abs(v_noise[0] - expected) < 0.03 and abs(v_noise[1] - expected / E.STEP_LAG) < 0.01
    with pytest.raises(ValueError, match="lag"):
        E.foot_speed(still, T)


def test_long_samples_counts_an_exploded_sample_and_scores_the_rest(data):
    class Replay:
        """Plays a held-out window's poses back on loop; sequence 0 blows up after 3 s."""

        def sample(self, controls, initial_poses, temperature=1.0, generator=None):
            T = controls.shape[1]
            loop = data.test["poses"][:1, E.TAU:].repeat(1, T // (E.WINDOW - E.TAU) + 1, 1)[:, :T]
            out = loop.expand(len(controls), -1, -1).clone()
            out[0, 60:] = float("nan")
            return out

    res = E.long_samples({"replay": Replay()}, data, seed=0, n=3, seconds=8.0)["models"]["replay"]
    assert res["exploded"] == 1 and res["n"] == 3 and not res["finite"]
    assert res["frozen"] == 0 and res["min_speed_var"] > 0  # mocap played back does not freeze


def test_long_program_pairs_each_clip_control_with_its_mocap(data):
    prog = E.long_program(data, seed=0, n=3, seconds=8.0)
    T = E.TAU + 160
    assert prog["controls"].shape == (3, T, 3) and prog["poses"].shape == (3, T, data.pose_dim)
    assert prog["seams"] == [E.TAU, E.TAU + 70, E.TAU + 140]
    x0, c0 = E.start_frames(data, 3, 0)
    torch.testing.assert_close(prog["poses"][:, :E.TAU], x0)
    torch.testing.assert_close(prog["controls"][:, :E.TAU], c0)
    for i in range(3):
        seg = prog["controls"][i, E.TAU + 70:E.TAU + 140]  # the second clip of sample i
        j = int(((data.test["controls"][:, E.TAU:] - seg).abs().amax((1, 2))).argmin())
        assert (data.test["controls"][j, E.TAU:] - seg).abs().max() == 0
        assert (data.test["poses"][j, E.TAU:] - prog["poses"][i, E.TAU + 70:E.TAU + 140]).abs().max() == 0


def test_exploded_counts_nan_and_values_beyond_blow_up():
    poses = torch.zeros(4, 5, 2)
    poses[1, 3, 0] = E.BLOW_UP + 0.1
    poses[2, 4, 1] = float("nan")
    poses[3, 2, 1] = -(E.BLOW_UP - 0.1)  # inside
    assert E.exploded(poses).tolist() == [False, True, True, False]


def test_lr_factor_is_constant_then_a_half_cosine_to_the_floor():
    assert E.lr_factor(0, 5000, None) == 1.0 and E.lr_factor(4999, 5000, None) == 1.0
    assert E.lr_factor(0, 5000, 0.6) == 1.0 and E.lr_factor(3000, 5000, 0.6) == 1.0  # constant until 60 %
    assert E.lr_factor(4999, 5000, 0.6, floor=0.01) == pytest.approx(0.01)  # the last step at the floor
    mid = E.lr_factor(3000 + 999.5, 5000, 0.6, floor=0.0)  # half-way through the decay: cos(pi / 2)
    assert mid == pytest.approx(0.5)
    values = [E.lr_factor(s, 5000, 0.6) for s in range(3000, 5000)]
    assert all(np.diff(values) <= 0)  # never rises


def test_train_model_sets_the_decayed_learning_rate(data):
    _, hist = E.train_model("moglow", data, steps=4, seed=0, decay_from=0.5)
    assert hist.lr[:3] == pytest.approx([E.LR, E.LR, E.LR * E.lr_factor(2, 4, 0.5)])
    assert hist.lr[-1] == pytest.approx(E.LR * E.LR_FLOOR)


def test_train_resumable_continued_from_its_state_file_is_the_same_run(data, tmp_path):
    whole, step = E.train_resumable("moglow", data, steps=6, state=tmp_path / "whole.pt", chunk=3)
    assert step == 6
    _, step = E.train_resumable("moglow", data, steps=6, state=tmp_path / "parts.pt", until=3, chunk=3)
    assert step == 3
    parts, step = E.train_resumable("moglow", data, steps=6, state=tmp_path / "parts.pt", chunk=3)  # a new sitting
    assert step == 6
    for (k, a), b in zip(whole.state_dict().items(), parts.state_dict().values(), strict=True):
        assert torch.equal(a, b), k
    saved = torch.load(tmp_path / "parts.pt", weights_only=True)
    assert saved["optimizer"]["param_groups"][0]["lr"] == pytest.approx(E.LR * E.lr_factor(6, 6))
    with pytest.raises(ValueError, match="holds the run"):  # another recipe's state is refused by name
        E.train_resumable("moglow", data, steps=12, state=tmp_path / "parts.pt", chunk=3)
    with pytest.raises(ValueError, match="holds the run"):  # so is another config's under the same name
        E.train_resumable("moglow_nodrop", data, steps=6, state=tmp_path / "parts.pt", chunk=3)
    with pytest.raises(ValueError, match="multiple of chunk"):
        E.train_resumable("moglow", data, steps=6, state=tmp_path / "new.pt", until=4, chunk=3)


def test_noisy_mocap_zero_noise_is_the_mocap_and_noise_shakes(data, monkeypatch):
    """Known answers of lesson 06's noise study: sd 0 scores the decoded mocap itself (its skate and jitter);
    i.i.d. frame noise raises the jitter several-fold and the skate, and so does the shaped noise of the same
    total variance; the held-out poses are not changed."""
    from course_lib.evaluation import foot_skate_at_floor, jitter
    from course_lib.representations import root_start

    # CI's tiny data holds out 3 windows: score 8 training windows, decoded on a held-out clip's skeleton
    data = dataclasses.replace(data, test={k: v[:8] for k, v in data.train.items()},
                               test_clips=[data.test_clips[0]] * 8)
    monkeypatch.setattr(E, "MIN_DISTRIBUTION_CLIPS", 8)
    before = data.test["poses"].clone()
    starts = [root_start(m) for m in data.test_clips]
    mocap = E.to_motions(data.positions(data.test["poses"], data.test["controls"], starts), data.test_clips)
    for shaped in (False, True):
        rows = E.noisy_mocap(data, (0.0, 0.3), seed=0, shaped=shaped)
        assert rows[0.0]["jitter"] == pytest.approx(jitter(mocap)) and rows[0.0]["foot_skate"] == pytest.approx(
            foot_skate_at_floor(mocap))
        assert rows[0.3]["jitter"] > 3 * rows[0.0]["jitter"] and rows[0.3]["foot_skate"] > 2 * rows[0.0]["foot_skate"]
    assert torch.equal(data.test["poses"], before)
