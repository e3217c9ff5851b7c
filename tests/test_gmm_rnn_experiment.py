"""Lesson-03 experiment plumbing (course_lib/experiments/gmm_rnn.py) on a few small clips: windows,
continuations, the Fig. 12 stand-in rows (GAN2 + contacts), and the long-generation checks."""

import numpy as np
import pytest
import torch
from conftest import load_study

from course_lib.datasets import WindowDataset, generate_locomotion_set
from course_lib.experiments import gmm_rnn as X
from course_lib.models.gmm_rnn import GmmRnn, GmmRnnConfig
from course_lib.models.refiner import Refiner, RefinerConfig


@pytest.fixture(scope="module")
def setup():
    torch.manual_seed(0)
    clips = generate_locomotion_set(8, seed=3, fps=30.0, duration=3.0, n_subjects=4)
    ds = WindowDataset(clips[:6], "state_features", length=50, stride=10)
    model = GmmRnn(GmmRnnConfig.cpu(fc_width=16, lstm_width=16, out_width=16), stats=ds.stats).eval()
    refiners = {name: Refiner(RefinerConfig.cpu(fc_width=8, lstm_width=8, contacts=name == "GAN2"),
                              stats=ds.stats).eval() for name in ("GAN1", "GAN2")}
    spec = X.Lesson03Spec(eval_seconds=2.0, n_random=4, random_seconds=3.0)
    return clips, ds, model, refiners, spec


def test_window_sampler_shapes_and_seed():
    feats = [np.arange(40.0).reshape(20, 2), np.zeros((5, 2))]
    a = X.window_sampler(feats, 6, 3, torch.Generator().manual_seed(1))()
    b = X.window_sampler(feats, 6, 3, torch.Generator().manual_seed(1))()
    assert a.shape == (3, 6, 2) and torch.equal(a, b)
    assert (torch.diff(a[..., 0], dim=1) == 2).all()  # consecutive frames of the long sequence only
    with pytest.raises(ValueError, match="no sequence has 30 frames"):
        X.window_sampler(feats, 30, 3, torch.Generator())


def test_quality_table_rows(setup):
    clips, ds, model, refiners, spec = setup
    rows = X.quality_table(model, refiners, clips, ds.stats, spec, seed=0)
    assert list(rows) == list(X.ROWS)
    for name, r in rows.items():
        extra = {"contact_agreement"} if name != "Mocap" else set()
        keys = {"foot_skate", "jitter", "penetration", "fid", "is", "c2st", "c2st_low", "c2st_high"}
        assert set(r) == keys | extra, name
        assert 0.0 <= r.get("contact_agreement", 0.5) <= 1.0
        assert all(np.isfinite(v) for v in r.values()), name
        assert 0.0 <= r["c2st_low"] <= r["c2st"] <= r["c2st_high"] <= 1.0 and 1.0 <= r["is"] <= 4.0 + 1e-9
    assert rows["Mocap"]["foot_skate"] < 0.05  # the generator's planted feet barely move
    assert rows["Mocap"]["penetration"] < 0.005  # and stay on the floor
    # an untrained RNN skates; enforcing its predicted contacts removes some of GAN2's skate
    assert rows["GAN2 + contacts"]["foot_skate"] < rows["GAN2"]["foot_skate"]


def test_continuations_start_from_the_clips(setup):
    clips, ds, model, refiners, spec = setup
    sets = X.continuations(model, refiners, clips[:3], ds.stats, spec, seed=0)
    assert {k: tuple(v.shape) for k, v in sets.items()} == {k: (3, 60, 68) for k in ("RNN", "GAN1", "GAN2")}
    motions = X.to_motions(sets["RNN"], ds.stats, clips[:3], spec.fps)
    for m, c in zip(motions, clips[:3], strict=True):
        assert np.allclose(m.positions()[:2], c.positions()[:2], atol=1e-4)  # the two given frames


def test_long_generation_report(setup):
    clips, ds, model, refiners, spec = setup
    out = X.long_generation(model, refiners["GAN2"], clips[0], ds.stats, spec, clips, seed=0)
    assert out["frames"] == 90 and out["freeze_floor"] > 0
    lo, hi = out["data_root_height"]
    assert 0.5 < lo < hi < 1.3
    for name in ("RNN", "GAN2"):
        r = out[name]
        assert r["nan_motions"] == 0 and r["apd_m"] > 0 and 0 <= r["frozen"] <= 4
        assert 0 <= r["in_range_motions"] <= r["in_range_first_10s"] <= 4


def test_train_rnn_runs_teacher_forcing_then_self_fed_stages(setup):
    _, ds, _, _, _ = setup
    spec = X.Lesson03Spec(finetune=((2, 3, 2), (1, 4, 2)))
    model, hist, ft = X.train_rnn(ds, spec, seed=0, steps=3, progress=False)
    assert hist.num_steps == 3 and ft.num_steps == 4 and not model.training
    assert model.config.self_feed == (1, 4) and model.config.residual
    assert all(np.isfinite(hist.step["loss"] + ft.step["loss"]))


def test_pool_and_gan_carry_each_clips_skeleton(setup):
    """The refiners' kinematics use the subject of each motion: the pool remembers each start clip's offsets,
    GAN2's D sees the contact bits, GAN1's does not."""
    clips, ds, model, _, _ = setup
    spec = X.Lesson03Spec(pool_sequences=4, pool_frames=20, refiner_window=16)
    pool = X.rnn_pool(model, ds, spec, seed=0)
    assert pool.features.shape == (4, 20, 68) and pool.offsets.shape == (4, 21, 3)
    subjects = np.unique(np.stack([m.skeleton.offsets for m in ds.clips]).round(6), axis=0)  # (S, J, 3)
    assert len(subjects) > 1  # several subjects, several skeletons
    gap = np.abs(pool.offsets.numpy()[:, None] - subjects[None]).max(axis=(2, 3)).min(1)  # to the nearest subject
    assert (gap < 1e-6).all()
    # each pooled motion starts with the two frames of a clip of that subject
    x0, off = X.window_sampler(ds.features, 2, 4, torch.Generator().manual_seed(0), X.clip_offsets(ds.clips))()
    assert torch.equal(pool.features[:, :2], x0) and torch.equal(pool.offsets, off)
    for contacts in (False, True):
        R, D, h = X.train_gan(pool, ds, spec, contacts=contacts, seed=0, iterations=2, progress=False)
        assert D.fc1.in_features == 30 + 2 * contacts and R.config.discriminator_contacts == contacts
        assert h.num_steps == 2 and np.isfinite(h.step["d_loss"]).all()


def test_feet_anchored_rnn_round_trip_and_one_step(setup):
    """The shipped RNN reads feet-anchored features on each clip's skeleton: to_rnn / from_rnn invert each
    other, generation starts from the given frames, one-step predictions keep frames 0-1 true."""
    clips, ds, _, _, _ = setup
    spec = X.Lesson03Spec(rnn_steps=3)
    model, _, _ = X.train_rnn(ds, spec, seed=0, progress=False)
    c = model.config
    assert c.features == "feet_anchored" and c.bernoulli_contacts and len(c.fixed_dims) > 10
    assert 66 not in c.gaussian_dims and not set(c.fixed_dims) & set(c.gaussian_dims)
    x = torch.from_numpy(np.stack([(X.encode_state_features(m)[:40] - ds.stats[0]) / ds.stats[1]
                                   for m in clips[6:]])).float()
    off = X.clip_offsets(clips[6:])
    y = X.to_rnn(x, ds.stats, model, off)
    assert (X.from_rnn(y, ds.stats, model, off) - x).abs().max() < 1e-4
    gen = X.generate(model, x[:, :2], 5, off, ds.stats, torch.Generator().manual_seed(0))
    assert gen.shape == (2, 7, 68) and torch.equal(gen[:, :2], x[:, :2])
    pred = X.one_step(model, [m[:40] for m in clips[6:]], ds.stats, mean=True)
    assert pred.shape == (2, 40, 68) and (pred[:, :2] - x[:, :2]).abs().max() < 1e-4


def test_skate_study_measures_one_model(setup):
    """study gmm_rnn_skate (what the recipe's residual means and feet-anchored features do): every number of one
    model."""
    study = load_study("gmm_rnn_skate")
    clips, ds, *_ = setup
    spec = X.Lesson03Spec(eval_seconds=2.0, n_random=4, random_seconds=3.0, rnn_steps=3, sample_angle_noise=0.3)
    model, _, _ = X.train_rnn(ds, spec, seed=0, progress=False)
    res = study.measure(model, clips[4:], ds.stats, spec)
    for k in ("one_step_sample_skate", "one_step_mean_skate", "free_skate", "free_jitter", "free_fid"):
        assert np.isfinite(res[k]) and res[k] >= 0, k
    assert res["long"]["nan_motions"] == 0 and 0 <= res["long"]["in_range_motions"] <= 4
    assert set(study.VARIANTS) == {"paper_features_absolute", "paper_features_residual", "anchored_absolute",
                                  "anchored_residual"}


def test_training_limits_bound_the_training_angles_only(setup):
    """Known answer: every training frame's joint angles (in the model's features) lie within the limits and each
    bound is reached by some frame; the root columns and the contact bits are free."""
    clips, ds, model, refiners, spec = setup
    low, high = X.training_limits(model, ds)
    feats, _ = X.rnn_features(ds, model.config.features)
    y = torch.from_numpy(np.concatenate(feats))
    angles = slice(6, 66)
    assert torch.isinf(low[:6]).all() and torch.isinf(high[66:]).all()
    assert (y[:, angles] >= low[angles] - 1e-5).all() and (y[:, angles] <= high[angles] + 1e-5).all()
    assert torch.allclose(y[:, angles].min(0).values, low[angles], atol=1e-5)
    assert torch.allclose(y[:, angles].max(0).values, high[angles], atol=1e-5)


def test_generation_with_stored_limits_stays_within_them(setup):
    clips, ds, model, refiners, spec = setup
    import copy
    limited = copy.deepcopy(model)
    limited.set_limits(*X.training_limits(limited, ds))
    x0 = torch.from_numpy(np.stack([f[:2] for f in ds.features[:3]])).float()
    off = X.clip_offsets(ds.clips[:3])
    out = X.generate(limited, x0, 20, off, ds.stats, torch.Generator().manual_seed(0), limits=True)
    y = X.to_rnn(out, ds.stats, limited, off)[:, 2:]
    low, high = limited.limits()
    assert (y[..., 6:66] >= low[6:66] - 1e-4).all() and (y[..., 6:66] <= high[6:66] + 1e-4).all()
    free = X.generate(limited, x0, 20, off, ds.stats, torch.Generator().manual_seed(0), limits=False)
    assert not torch.allclose(free, out)  # an untrained RNN leaves the training range; the limits bind


def test_column_groups_split_the_pose_columns_by_joint():
    """The clamp tests' groups: the root's 6 columns, the 8 leg joints' 24 angle columns and the 12 upper-body joints'
    36, disjoint, covering every column but the two contact bits."""
    from course_lib.representations import feature_names

    g = X.column_groups()
    names = feature_names("state_features")
    assert g["root"] == list(range(6)) and g["legs"] == list(range(6, 30)) and g["upper body"] == list(range(30, 66))
    assert all("Leg" in names[i] or "Foot" in names[i] or "Toe" in names[i] for i in g["legs"])
    assert sorted(g["root"] + g["legs"] + g["upper body"]) == list(range(len(names) - 2))


def test_store_limits_keeps_limits_equal_to_rounding(setup, tmp_path):
    """A refiner-only retrain on another CPU must not rewrite the RNN for limits that differ in the last bits: the
    first store writes them, a second finds them equal and keeps the file (same sha256), a real change rewrites."""
    import copy
    import json

    from course_lib.training import save_checkpoint

    clips, ds, model, refiners, spec = setup
    save_checkpoint(copy.deepcopy(model), model.config, tmp_path / "gmm_rnn.pt", command="test", metrics={})
    sha = lambda: json.loads((tmp_path / "MANIFEST.json").read_text())["gmm_rnn"]["sha256"]  # noqa: E731
    assert X.store_limits(ds, tmp_path) is True  # +-inf before: written
    first = sha()
    assert X.store_limits(ds, tmp_path) is False and sha() == first  # the same limits: kept
    stored = X.load_models_rnn(tmp_path)
    low, high = (b.clone() for b in stored.limits())
    stored.set_limits(low - 2e-7 * torch.isfinite(low), high)  # a last-bits difference: still kept
    save_checkpoint(stored, stored.config, tmp_path / "gmm_rnn.pt", command="test", metrics={}, overwrite=True)
    assert X.store_limits(ds, tmp_path) is False
    moved = X.load_models_rnn(tmp_path)
    moved.set_limits(low - 0.5 * torch.isfinite(low), high)  # a real change of the stored limits ...
    save_checkpoint(moved, moved.config, tmp_path / "gmm_rnn.pt", command="test", metrics={}, overwrite=True)
    assert X.store_limits(ds, tmp_path) is True and X.load_models_rnn(tmp_path).limits()[0].equal(low)  # ... undone
