"""Hierarchical VRNN (Ghorbani et al. 2020), its loss pieces, baselines and lesson-05 evaluation helpers."""

import dataclasses
import math

import numpy as np
import pytest
import torch
from conftest import load_study

from course_lib.models.baselines import AttributeRnn, AttributeRnnConfig
from course_lib.models.hvrnn import (
    DaeConfig,
    DenoisingAutoencoder,
    HierarchicalVrnn,
    HvrnnConfig,
    cl_weight,
    diag_gaussian_kl,
    geodesic,
    impact_factors,
    kl_weight,
    normalize_pose,
    unit_norm_loss,
    word_drop_rate,
)
from course_lib.rotations import axis_angle_to_quat
from course_lib.skeleton import Skeleton

torch.set_num_threads(1)
TINY = dict(gru=16, mlp=16, d_w=8, d_z=4, d_a=4, enc_layers=1)


def tiny(**kw) -> HierarchicalVrnn:
    torch.manual_seed(0)
    return HierarchicalVrnn(HvrnnConfig(**{**TINY, **kw}))


def poses(n=4, t=12, seed=0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return normalize_pose(torch.randn(n, t, 90, generator=g)).float()


def batch(n=4, t=12):
    return {"x": poses(n, t), "action_id": torch.arange(n) % 4, "style_id": torch.arange(n) % 2}


# ----------------------------------------------------------------------------- formulas


def test_impact_factors_hand_computed_tree():
    # root -> A (bone 1) -> B (bone 2, end site 0.5);  root -> C (bone 3, no end site)
    skel = Skeleton(("root", "A", "B", "C"), (-1, 0, 1, 0),
                    np.array([[0, 0, 0], [0, 1, 0], [0, 2, 0], [3, 0, 0]], float), {2: np.array([0.0, 0.5, 0.0])})
    # alpha_B = 0.5, alpha_A = 0.5 + 2, alpha_C = 0, alpha_root = max(2.5 + 1, 0 + 3) = 3.5   (eq. 23)
    np.testing.assert_allclose(impact_factors(skel, normalize=False), [3.5, 2.5, 0.5, 0.0])
    np.testing.assert_allclose(impact_factors(skel), np.array([3.5, 2.5, 0.5, 0.0]) / 1.625)


def test_impact_factors_canonical_decrease_down_the_tree():
    skel = Skeleton.canonical()
    alpha = impact_factors(skel)
    assert alpha.mean() == pytest.approx(1.0)
    for j, p in enumerate(skel.parents):
        if p >= 0:
            assert alpha[j] < alpha[p], skel.names[j]
    # Hips: the longest path is Hips -> Spine -> Spine1 -> shoulder -> arm -> forearm -> hand -> end site
    raw = impact_factors(skel, normalize=False)
    assert raw[0] == pytest.approx(0.11 + 0.19 + math.hypot(0.035, 0.17) + 0.14 + 0.28 + 0.25 + 0.09)


def test_geodesic_distances_against_the_true_angle():
    axis = torch.tensor([[0.0, 1.0, 0.0]])
    for angle in (0.3, 1.2, 2.9):
        q = axis_angle_to_quat(axis, torch.tensor([angle]))
        qi = torch.tensor([[1.0, 0, 0, 0]])
        assert geodesic(qi, q, "d1").item() == pytest.approx(angle, abs=1e-5)
        assert geodesic(qi, -q, "d1").item() == pytest.approx(angle, abs=1e-5)  # double cover, eq. (17)
        assert geodesic(qi, q, "log").item() == pytest.approx(angle, abs=1e-4)  # eq. (21)
        assert geodesic(qi, q, "d2").item() == pytest.approx(1 - math.cos(angle / 2), abs=1e-6)  # eq. (18)


def test_diag_gaussian_kl_matches_torch_distributions():
    g = torch.Generator().manual_seed(1)
    mq, mp = torch.randn(5, 3, generator=g), torch.randn(5, 3, generator=g)
    sq, sp = torch.rand(5, 3, generator=g) + 0.2, torch.rand(5, 3, generator=g) + 0.2
    ref = torch.distributions.kl_divergence(torch.distributions.Normal(mq, sq), torch.distributions.Normal(mp, sp))
    torch.testing.assert_close(diag_gaussian_kl(mq, sq, mp, sp), ref.sum(-1))


def test_schedules():
    assert [kl_weight(s, 10, 20) for s in (0, 9, 10, 20, 30, 100)] == [0, 0, 0, 0.5, 1.0, 1.0]
    assert [cl_weight(s, 10, 20, 0.1) for s in (0, 10, 20, 30, 99)] == pytest.approx([0, 0, 0.05, 0.1, 0.1])
    assert word_drop_rate(250, 500, 0.3) == pytest.approx(0.15)
    assert word_drop_rate(10_000, 500, 0.3) == pytest.approx(0.3)


def test_unit_norm_loss():
    q = torch.tensor([[[2.0, 0, 0, 0], [0.0, 1, 0, 0]]])  # |q|^2 = 4 and 1
    assert unit_norm_loss(q).item() == pytest.approx(3.0)  # eq. (26)


# ----------------------------------------------------------------------------- the model


@pytest.mark.parametrize("hierarchical", [True, False])
def test_shapes_of_every_piece(hierarchical):
    m = tiny(hierarchical=hierarchical)
    x = poses()
    y = m.to_model(x)
    w = m.words(y)
    L = 3 if hierarchical else 1
    assert w.shape == (4, 12 // L, 8 if hierarchical else 90)
    assert m.poses(w).shape == (4, 12, 90)
    a, combo = m.attributes(torch.tensor([0, 1, 2, 3]), torch.tensor([0, 1, 0, 1]))
    assert a.shape == (4, 4) and combo.tolist() == [0, 3, 4, 7]
    h = m.initial_state(combo)
    assert h.shape == (4, 32)
    w_out, fw, fz, mu_q, sd_q, mu_p, sd_p = m.cell_forward(w[:, 0], a, h)
    assert w_out.shape == w[:, 0].shape and fw.shape == fz.shape == (4, 8)
    assert mu_q.shape == sd_q.shape == mu_p.shape == sd_p.shape == (4, 4) and (sd_q > 0).all()
    assert m.transition(fw, fz, h).shape == (4, 32)
    out = m.reconstruct(x, a.new_tensor([0, 1, 2, 3]).long(), torch.tensor([0, 1, 0, 1]))
    assert out["x_hat"].shape == (4, 12, 90) and out["mu_q"].shape == (4, 12 // L, 4)
    assert m.sample(torch.tensor([0, 3]), torch.tensor([1, 0]), 10).shape == (2, 10, 90)


def _classifiers():
    from course_lib.evaluation.classifiers import ClassifierConfig, MotionClassifier

    torch.manual_seed(0)
    return [MotionClassifier(ClassifierConfig(hidden=8, kernel=3)),
            MotionClassifier(ClassifierConfig(task="style", classes=("A", "B"), hidden=8, kernel=3))]


def test_algorithm1_loss_finite_and_gradients_reach_every_parameter():
    m = tiny(kl_warmup=0, kl_anneal=1, cl_start=0, cl_ramp=1, drop_ramp=1, drop_max=0.5)
    m.set_classifiers(_classifiers())
    m.step.fill_(5)  # past every warm-up: lambda_KL = 1, lambda_CL = final
    m.train()
    out = m.loss(batch())
    assert torch.isfinite(out["loss"]) and out["lambda_kl"] == 1.0 and out["lambda_cl"] == pytest.approx(0.1)
    assert out["cl"] > 0 and out["kl"] > 0
    out["loss"].backward()
    missing = [n for n, p in m.named_parameters() if p.grad is None or not p.grad.abs().sum() > 0]
    assert not missing, missing
    assert int(m.step) == 6  # the schedules' step counter advanced
    assert all(p.grad is None for clf in m.classifiers for p in clf.parameters())  # classifiers stay frozen


def test_nl_ablation_has_unit_alphas_and_proposed_does_not():
    assert torch.equal(tiny(use_alpha=False).alpha, torch.ones(21))
    assert tiny().alpha[0] > 1.5 and tiny().alpha.mean().item() == pytest.approx(1.0)


def test_scheduled_word_dropping_rate():
    m = tiny(drop_ramp=10, drop_max=0.5)
    m.train()
    m.step.fill_(10)  # rate = 0.5
    w, w_out = torch.randn(4000, 8), torch.randn(4000, 8)
    fw = m.f_w(w)
    fed = m._exposure(w, w_out, fw)
    dropped = (fed - fw).abs().sum(-1) > 0
    assert dropped.float().mean().item() == pytest.approx(0.5, abs=0.03)
    torch.testing.assert_close(fed[dropped], m.f_w(w_out)[dropped])
    m.eval()
    assert torch.equal(m._exposure(w, w_out, fw), fw)  # no dropping at evaluation


def test_unit_norm_output_and_seeded_sampling():
    m = tiny()
    a, s = torch.tensor([0, 1, 2, 3]), torch.tensor([0, 0, 1, 1])
    x1 = m.sample(a, s, 9, generator=torch.Generator().manual_seed(3))
    x2 = m.sample(a, s, 9, generator=torch.Generator().manual_seed(3))
    x3 = m.sample(a, s, 9, generator=torch.Generator().manual_seed(4))
    assert torch.equal(x1, x2) and not torch.allclose(x1, x3)
    norms = x1[..., :84].unflatten(-1, (21, 4)).norm(dim=-1)
    torch.testing.assert_close(norms, torch.ones_like(norms))


@pytest.mark.parametrize("kind", ["erd", "quaternet"])
def test_attribute_rnn_baselines(kind):
    torch.manual_seed(0)
    m = AttributeRnn(AttributeRnnConfig(kind=kind, hidden=16, encoder=16, sample_ramp=1))
    m.train()
    out = m.loss(batch())
    assert torch.isfinite(out["loss"])
    out["loss"].backward()
    assert m.h0_mu.grad.abs().sum() > 0 and m.f_c.weight.grad.abs().sum() > 0
    g = lambda: torch.Generator().manual_seed(7)  # noqa: E731
    x1 = m.sample(torch.tensor([2, 3]), torch.tensor([0, 1]), 6, generator=g())
    assert x1.shape == (2, 6, 90) and torch.equal(x1, m.sample(torch.tensor([2, 3]), torch.tensor([0, 1]), 6,
                                                                 generator=g()))
    torch.testing.assert_close(x1[..., :84].unflatten(-1, (21, 4)).norm(dim=-1), torch.ones(2, 6, 21))


def test_clear_errors_on_bad_input():
    m = tiny()
    with pytest.raises(ValueError, match=r"\(N, T, 90\)"):
        m.loss({"x": torch.zeros(2, 12, 89), "action_id": torch.zeros(2), "style_id": torch.zeros(2)})
    x = poses(2)
    x[0, 3, 5] = float("nan")
    with pytest.raises(ValueError, match="NaN"):
        m.loss({"x": x, "action_id": torch.zeros(2), "style_id": torch.zeros(2)})
    with pytest.raises(ValueError, match="multiple of the word length"):
        m.reconstruct(poses(2, 10), torch.zeros(2), torch.zeros(2))
    with pytest.raises(ValueError, match="action ids"):
        m.sample(torch.tensor([4]), torch.tensor([0]), 6)
    with pytest.raises(ValueError, match="distance"):
        HvrnnConfig(distance="l2")
    with pytest.raises(ValueError, match="NaN"):
        DenoisingAutoencoder(DaeConfig(channels=8))(torch.full((1, 4, 90), float("nan")))


def test_checkpoint_round_trip(tmp_path):
    from course_lib.training import load_checkpoint, save_checkpoint

    m = tiny(hierarchical=False)
    m.set_stats(poses(8) * 3 + 1)
    save_checkpoint(m, m.config, tmp_path / "h.pt", command="pytest")
    back = load_checkpoint(tmp_path / "h.pt", HierarchicalVrnn, HvrnnConfig)
    assert back.config == m.config and torch.equal(back.root_std, m.root_std)
    a, s = torch.tensor([1, 2]), torch.tensor([1, 0])
    torch.testing.assert_close(back.sample(a, s, 6, generator=torch.Generator().manual_seed(0)),
                               m.sample(a, s, 6, generator=torch.Generator().manual_seed(0)))


def test_denoising_autoencoder_learns_and_keeps_unit_quaternions():
    torch.manual_seed(0)
    dae = DenoisingAutoencoder(DaeConfig(channels=16))
    g = torch.Generator().manual_seed(0)
    t = torch.linspace(0, 1, 16)[None, :, None]
    x = normalize_pose(torch.randn(8, 1, 90, generator=g) + torch.sin(3 * t + torch.randn(8, 1, 90, generator=g)))
    dae.set_stats(x)
    first = dae.loss(x, generator=torch.Generator().manual_seed(0))["loss"].item()
    assert first == pytest.approx(0.1 * 0.5**2, rel=0.3)  # the residual net starts near identity: the noise left
    opt = torch.optim.Adam(dae.parameters(), 3e-3)
    for _ in range(100):
        opt.zero_grad()
        dae.loss(x)["loss"].backward()
        opt.step()
    assert dae.loss(x, generator=torch.Generator().manual_seed(0))["loss"].item() < 0.97 * first
    y = dae(x)
    torch.testing.assert_close(y[..., :84].unflatten(-1, (21, 4)).norm(dim=-1), torch.ones(8, 16, 21))


# ----------------------------------------------------------------------------- lesson-05 evaluation helpers


def test_padding_collapse_metric_and_attribute_grid():
    from course_lib.experiments.hvrnn import attribute_grid, collapsed_fraction, last_second_activity, to_sequence
    from course_lib.motion import Motion

    skel = Skeleton.canonical()
    T = 45
    still = Motion(np.tile([1.0, 0, 0, 0], (T, 21, 1)), np.tile([0, 0.96, 0], (T, 1)).astype(float), skel, 30.0)
    t = np.arange(T) / 30.0
    rot = axis_angle_to_quat(torch.tensor([[1.0, 0, 0]]).expand(T, 3), torch.from_numpy(np.sin(4 * t))).numpy()
    moving = Motion(still.rotations.copy(), still.root_positions.copy(), skel, 30.0)
    moving.rotations[:, 1] = rot  # the left hip swings
    seq = to_sequence(still, 60)
    assert seq.shape == (60, 90) and np.allclose(seq[45:], seq[44])  # padded by holding the last frame
    speed, var = last_second_activity([still, moving])
    assert speed[0] == pytest.approx(0, abs=1e-9) and speed[1] > 0.1 and var[1] > var[0]
    assert collapsed_fraction([still, moving, still], (0.05, 1e-4)) == pytest.approx(2 / 3)
    a, s = attribute_grid(3)
    assert len(a) == 24 and torch.bincount(a).tolist() == [6] * 4 and torch.bincount(s).tolist() == [12] * 2


def test_reproduce_registers_hvrnn():
    from course_lib.reproduce import EXPERIMENTS

    assert "hvrnn" in EXPERIMENTS


def test_nc_forked_from_the_proposed_run_equals_nc_trained_from_scratch():
    """NC is the Proposed recipe with lambda_CL = 0, and lambda_CL is 0 until cl_start: the reproduction
    continues NC from the Proposed run's state at cl_start; that must be exact."""
    from course_lib.experiments import hvrnn as H

    torch.set_num_threads(1)
    specs = H.model_specs(scale=0.04)
    data = H.load_data("ci")
    classifiers = H.train_loss_classifiers(data["train"], 3)
    proposed = specs["hvrnn_proposed"]
    # the shipped NC trains STEPS at its own schedules; the Proposed model longer: no fork between them
    assert not H.forkable(specs) or H.PROPOSED_STEPS == H.STEPS
    nc = dataclasses.replace(specs["hvrnn_nc"], config=dataclasses.replace(proposed.config, lambda_cl=0.0),
                             steps=proposed.steps, batch=proposed.batch,
                             lr_end=proposed.lr_end)  # NC on the Proposed model's recipe, its falling rate too
    assert H.forkable({"hvrnn_proposed": proposed, "hvrnn_nc": nc})
    _, hist = H.train_model(proposed, data["train"], classifiers, keep_at=proposed.config.cl_start)
    forked, rest = H.continue_training(nc, hist.kept, data["train"])
    scratch, _ = H.train_model(nc, data["train"], classifiers)
    assert rest.num_steps == nc.steps - proposed.config.cl_start > 0
    for (name, a), b in zip(forked.state_dict().items(), scratch.state_dict().values(), strict=True):
        torch.testing.assert_close(a, b, rtol=0, atol=0, msg=name)


def test_fixed_dofs_of_the_data_are_set_in_every_generator_output():
    from course_lib.datasets import FixedDofs
    from course_lib.experiments import hvrnn as H

    data = H.load_data("ci")
    fixed = FixedDofs.detect(data["train"]["x"])
    assert len(fixed) == 28  # knees', elbows', toes' off-axis components; shoulders and hands
    for model in (HierarchicalVrnn(HvrnnConfig.cpu()), AttributeRnn(AttributeRnnConfig.cpu(kind="erd"))):
        model.set_stats(data["train"]["x"])
        x = H.generate(model, 1, 12, seed=0)["x"]  # untrained: every output channel moves
        const = torch.from_numpy(fixed.values[fixed.mask]).float().expand(8, 12, -1)
        torch.testing.assert_close(x[..., fixed.mask], const, rtol=0, atol=1e-6)  # (renormalised quaternions)
        assert x[..., ~fixed.mask].std(1).mean() > 0


def test_recipe_sweep_tool_runs_one_variant(tmp_path):
    """study hvrnn_sweep (the seed spread of the four Motion-Cell models): a few steps, every number."""
    import json

    sweep = load_study("hvrnn_sweep")
    out = tmp_path / "results.json"
    assert sweep.main(["--out", str(out), "--only", "nl_1200", "--smoke"]) == 0
    res = json.loads(out.read_text())["results"]["nl_1200"]
    assert res["base"] == "hvrnn_nl" and res["steps"] == 4
    assert res["reconstruction_FID"] >= 0 and res["FID"] >= 0 and 1 <= res["IS"] <= 8 and 0 <= res["C2ST"] <= 1
    with pytest.raises(SystemExit):  # refuses to overwrite a results file
        sweep.main(["--out", str(out), "--only", "nl_1200", "--smoke"])
    with pytest.raises(SystemExit):  # --merge needs a file to add to
        sweep.main(["--out", str(tmp_path / "none.json"), "--only", "nl_1200", "--smoke", "--merge"])
    assert sweep.main(["--out", str(out), "--only", "proposed_1200_seed2", "--smoke", "--merge"]) == 0
    merged = json.loads(out.read_text())
    assert merged["results"]["nl_1200"] == res  # kept
    assert merged["results"]["proposed_1200_seed2"]["seed"] == 2
    script = "studies/05_hierarchical_vrnn/hvrnn_sweep.py"
    command = f"python {script} --out {out} --only proposed_1200_seed2 --smoke --merge"
    assert merged["added_by"] == {"proposed_1200_seed2": command}


def test_retargeted_root_plants_a_short_legged_walk_on_the_canonical_legs():
    """Known answer: a walk by a subject whose bones are 0.9 x the canonical ones, encoded and played on the
    canonical skeleton (as every lesson-05 sample is), slides its planted feet and sinks into the floor; with
    the root's velocities and height retargeted (`retarget_root`) it skates as little as on its own skeleton."""
    from course_lib.evaluation import foot_skate_at_floor
    from course_lib.experiments.hvrnn import FPS, foot_quality, retarget_root, to_motions, to_sequence
    from course_lib.representations import encode_quaternion_root
    from course_lib.synthetic import generate_action, make_subject

    sub = make_subject(0, seed=0)
    big = dataclasses.replace(sub, scale=np.full_like(sub.scale, 0.9))
    walk = generate_action(big, "walk", duration=3.0, seed=0).resample(FPS)
    canon = Skeleton.canonical()
    f = encode_quaternion_root(walk)
    g = retarget_root(f, walk.skeleton)
    ratio = canon.leg_length() / walk.skeleton.leg_length()
    assert np.allclose(g[:, -6:-3], f[:, -6:-3] * ratio) and np.array_equal(g[:, :-6], f[:, :-6])
    assert np.array_equal(g[:, -3:], f[:, -3:])  # yaw rate, pitch, roll are angles: unchanged
    one = {"action_id": torch.tensor([0]), "style_id": torch.tensor([0]), "subject": ["s00"]}
    plain = to_motions({"x": torch.from_numpy(f[None]).float(), **one})
    fixed = to_motions({"x": torch.from_numpy(to_sequence(walk, 90)[None]), **one})
    own = foot_skate_at_floor([walk], fps=FPS)
    assert foot_skate_at_floor(plain, fps=FPS) > own + 0.05  # short legs' stride and hip height on longer legs
    assert foot_quality(plain)["penetration"] > 0.02
    assert foot_quality(fixed)["foot_skate"] < own + 0.02 and foot_quality(fixed)["penetration"] < 1e-3


def test_lr_factor_is_constant_then_a_cosine_down_to_lr_end():
    """Known answers: lr_end 1 keeps Adam's rate (the paper); lr_end 0.1 keeps it for the first half, is halfway
    down (0.55) at three quarters and 0.1 at the last step."""
    from course_lib.experiments.hvrnn import ModelSpec, lr_factor

    const = ModelSpec("m", "M", object, None, steps=101)
    assert all(lr_factor(const, k) == 1.0 for k in range(101))
    decay = dataclasses.replace(const, lr_end=0.1)
    assert [lr_factor(decay, k) for k in (0, 49, 50)] == [1.0, 1.0, 1.0]
    assert lr_factor(decay, 75) == pytest.approx(0.55)
    assert lr_factor(decay, 100) == pytest.approx(0.1)


def test_held_frames_counts_the_padding_of_short_clips():
    """Known answers: a clip 30 frames short of the sequence ends in 30 copies of its last frame; a clip that fills
    it, or whose last two frames differ, has none; a frame equal to the last one earlier on does not count."""
    from course_lib.experiments.hvrnn import held_frames

    rng = np.random.default_rng(0)
    full = rng.normal(size=(90, 4))
    short = np.concatenate((full[:60], np.repeat(full[59:60], 30, 0)))
    early = full.copy()
    early[10] = early[-1]
    assert held_frames(np.stack([short, full, early])).tolist() == [30, 0, 0]


def test_to_sequence_pads_a_short_clip_by_holding_or_by_looping():
    """Known answers on a 40-frame clip in a 90-frame sequence: "hold" repeats frame 39 fifty times (held_frames
    50); "loop" plays frames 0-39 again, then 0-9, so nothing is held; a full clip is the same either way; an
    unknown pad is refused."""
    from course_lib.experiments.hvrnn import held_frames, to_sequence
    from course_lib.synthetic import generate_action, make_subject

    clip = generate_action(make_subject(0, seed=0), "walk", duration=4.0, seed=0).resample(30.0)
    short = clip[:40]
    hold, loop = to_sequence(short, 90, pad="hold"), to_sequence(short, 90, pad="loop")
    assert np.array_equal(hold[:40], loop[:40]) and held_frames(hold[None]).tolist() == [50]
    assert np.array_equal(loop[40:80], loop[:40]) and np.array_equal(loop[80:], loop[:10])
    assert held_frames(loop[None]).tolist() == [0]
    assert np.array_equal(to_sequence(clip, 90, pad="hold"), to_sequence(clip, 90, pad="loop"))
    with pytest.raises(ValueError, match="pad"):
        to_sequence(short, 90, pad="zeros")
