"""VAE-LSTM (Habibie et al. 2017): shapes, the modified LSTM written out, loss formulas, Algorithm 1."""

import math

import pytest
import torch
from conftest import load_study
from torch.nn import functional as F

from course_lib.models.vae import gaussian_kl
from course_lib.models.vae_lstm import ModifiedLstmCell, VaeLstm, VaeLstmConfig, conv_encoder


def tiny(**kw) -> VaeLstmConfig:
    if not kw.get("generation_weight", 1.0):  # the preset's heading term rides on Algorithm 1's ELBO
        kw.setdefault("heading_weight", 0.0)
    return VaeLstmConfig.cpu(**{"enc_channels": 8, "latent_dim": 8, "control_channels": 8, "control_hidden": 8,
                                "dec_channels": 8, "kernel": 5, "input_dropout": 0.0, **kw})


def test_paper_config_shapes_and_size():
    """The paper's sizes: 240 frames -> 60 pooled steps, 128-d latent, canvas (128, 60), output 66."""
    torch.manual_seed(0)
    m = VaeLstm(VaeLstmConfig()).eval()
    x = torch.randn(2, 240, 66)
    mu, logvar = m.encode(x)
    assert mu.shape == logvar.shape == (2, 60, 128)
    h_c = m.encode_control(x[..., 63:])
    assert h_c.shape == (2, 60, 128)
    canvas = m.run_decoder(h_c, mu)
    assert canvas.shape == (2, 128, 60)
    assert m.decode(canvas).shape == (2, 240, 66)
    # conv weights as in sec. 4.2: (63, 25) * 64, (64, 25) * 256, (3, 25) * 64, (64, 25) * 128
    assert tuple(m.inference[0].weight.shape) == (64, 63, 25)
    assert tuple(m.inference[3].weight.shape) == (256, 64, 25)
    assert tuple(m.control_encoder[3].weight.shape) == (128, 64, 25)
    assert tuple(m.decoder[4].weight.shape) == (66, 128, 25)


def test_cpu_preset_checkpoint_small():
    n = sum(p.numel() for p in VaeLstm(VaeLstmConfig.cpu()).parameters())
    assert n * 4 < 5e6  # float32 bytes: the checkpoint stays under 5 MB


def test_encoder_is_eq6():
    """CNN_enc(X) = Psi(alpha(Psi(alpha(X W0 + b0)) W1 + b1)), written out with F.conv1d."""
    torch.manual_seed(1)
    enc = conv_encoder(3, 4, 6, 5, 2)
    x = torch.randn(2, 3, 16)
    w0, b0, w1, b1 = enc[0].weight, enc[0].bias, enc[3].weight, enc[3].bias
    ref = F.max_pool1d(F.elu(F.conv1d(F.max_pool1d(F.elu(F.conv1d(x, w0, b0, padding=2)), 2), w1, b1, padding=2)), 2)
    torch.testing.assert_close(enc(x), ref)
    assert ref.shape == (2, 6, 4)


def test_modified_lstm_written_out():
    """Eq. (7)-(9) by hand, training and test branch, equal the module."""
    torch.manual_seed(2)
    cell = ModifiedLstmCell(6, 4)
    c_prev, h, z = torch.randn(3, 6), torch.randn(3, 4), torch.randn(3, 6)
    lin = lambda layer, v: v @ layer.weight.T + (layer.bias if layer.bias is not None else 0)  # noqa: E731
    i = 1 / (1 + torch.exp(-(lin(cell.W_ic, c_prev) + lin(cell.W_ih, h))))
    f = 1 / (1 + torch.exp(-(lin(cell.W_fc, c_prev) + lin(cell.W_fh, h))))
    elu = lambda a: torch.where(a > 0, a, torch.exp(a) - 1)  # noqa: E731
    train = elu(f * (z @ cell.W_c.weight.T) + i * (h @ cell.W_h.weight.T))
    test = elu(f * (c_prev @ cell.W_c.weight.T) + i * (h @ cell.W_h.weight.T))
    torch.testing.assert_close(cell(c_prev, h, z), train)
    torch.testing.assert_close(cell(c_prev, h), test)
    assert not torch.allclose(train, test)
    assert not hasattr(cell, "W_o")  # no output gate


def test_decoder_train_vs_test_branch():
    """Training uses every z_t; Algorithm 1 uses z_1 then c(t-1): they agree on step 1 only."""
    torch.manual_seed(3)
    m = VaeLstm(tiny()).eval()
    h_c, z = torch.randn(2, 5, 8), torch.randn(2, 5, 8)
    train = m.run_decoder(h_c, z)
    test = m.run_decoder(h_c, z[:, 0])
    torch.testing.assert_close(train[..., 0], test[..., 0])
    assert (train[..., 1:] - test[..., 1:]).abs().max() > 1e-3
    # test branch by hand: c(t) = cell(c(t-1), h_t)
    c = m.cell(torch.zeros(2, 8), h_c[:, 0], z[:, 0])
    for t in range(1, 5):
        c = m.cell(c, h_c[:, t])
    torch.testing.assert_close(test[..., -1], c)


def test_loss_terms_match_formulas():
    """nll = -log N(x | x_hat, s^2) summed, kl = sum_t KL (eq. 4), checked with torch.distributions."""
    torch.manual_seed(4)
    m = VaeLstm(tiny(l1=0.5, generation_weight=0.0)).eval()
    x = torch.randn(3, 16, 66)
    eps = torch.randn(3, 4, 8)
    torch.manual_seed(5)
    out = m.loss(x)
    torch.manual_seed(5)
    fwd = m(x)
    s = m.config.obs_std
    nll = -torch.distributions.Normal(fwd["x_hat"], s).log_prob(x).sum() / 3
    q = torch.distributions.Normal(fwd["mu"], torch.exp(0.5 * fwd["logvar"]))
    kl = torch.distributions.kl_divergence(q, torch.distributions.Normal(0.0, 1.0)).sum() / 3
    torch.testing.assert_close(out["nll"], nll.detach(), rtol=1e-4, atol=1e-3)
    torch.testing.assert_close(out["kl"], kl.detach(), rtol=1e-4, atol=1e-3)
    torch.testing.assert_close(out["loss"], (nll + kl + 0.5 * m.l1_penalty()).detach(), rtol=1e-4, atol=1e-3)
    assert m(x, eps=eps)["z"].shape == (3, 4, 8)
    assert math.isfinite(float(out["loss"].detach()))


def test_generation_elbo_is_algorithm1_trained():
    """generation_weight adds -log p(X | Algorithm 1 from z_1 ~ q(z_1 | X_1:4)) + KL(z_1) to the paper's loss."""
    torch.manual_seed(9)
    m = VaeLstm(tiny(generation_weight=0.5, l1=0.0, heading_weight=0.0)).eval()  # the heading term: its own test
    x = torch.randn(3, 16, 66)
    torch.manual_seed(1)
    out = m.loss(x)
    torch.manual_seed(1)
    fwd = m(x)
    paper = m.nll(x, fwd["x_hat"]) + gaussian_kl(fwd["mu"], fwd["logvar"]).sum() / 3
    mu1, logvar1 = m.initial_posterior(x[:, :4], 16)
    z1 = mu1 + torch.exp(0.5 * logvar1) * torch.randn_like(mu1)
    x_gen = m.generate(x[..., 63:], z1)  # Algorithm 1 with this z_1
    gen = -torch.distributions.Normal(x_gen, m.config.obs_std).log_prob(x).sum() / 3
    gen_kl = torch.distributions.kl_divergence(torch.distributions.Normal(mu1, torch.exp(0.5 * logvar1)),
                                               torch.distributions.Normal(0.0, 1.0)).sum() / 3
    torch.testing.assert_close(out["gen_nll"], gen, rtol=1e-4, atol=1e-3)
    torch.testing.assert_close(out["gen_kl"], gen_kl, rtol=1e-4, atol=1e-4)
    torch.testing.assert_close(out["loss"], (paper + 0.5 * (gen + gen_kl)).detach(), rtol=1e-4, atol=1e-3)
    assert out["kl_per_dim"].shape == (8,)
    torch.testing.assert_close(out["kl_per_dim"].sum() * 4, out["kl"], rtol=1e-5, atol=1e-5)  # 4 steps


def test_kl_annealing_and_free_bits():
    """KL weight 0 -> 1 over kl_warmup_steps of training; free bits charge max(lambda, KL) per step and dim."""
    torch.manual_seed(10)
    m = VaeLstm(tiny(generation_weight=0.0, l1=0.0, kl_warmup_steps=4))
    x = torch.randn(2, 16, 66)
    betas = [m.loss(x)["beta"] for _ in range(6)]
    assert betas == [0.0, 0.25, 0.5, 0.75, 1.0, 1.0]
    m.eval()
    assert m.loss(x)["beta"] == 1.0 and int(m.num_updates) == 6  # evaluation does not advance the schedule
    fb = VaeLstm(tiny(generation_weight=0.0, free_bits=2.0))
    kl = torch.tensor([[[0.5, 3.0]], [[1.5, 1.0]]])  # (N=2, T'=1, D=2): batch means 1.0 and 2.0
    assert float(fb.kl_penalty(kl)) == 4.0  # max(2, 1) + max(2, 2)
    assert float(m.kl_penalty(kl)) == 3.0  # no free bits: the sum per clip
    with pytest.raises(ValueError, match="free_bits"):
        VaeLstmConfig(free_bits=-1.0)


def test_loss_decreases_on_small_batch():
    torch.manual_seed(6)
    m = VaeLstm(tiny())
    x = torch.randn(4, 32, 66) * 0.5 + torch.linspace(-1, 1, 32)[None, :, None]
    opt = torch.optim.Adam(m.parameters(), 3e-3)
    first = None
    for _ in range(60):
        out = m.loss(x)
        opt.zero_grad()
        out["loss"].backward()
        opt.step()
        first = first if first is not None else float(out["mse"])
    assert float(out["mse"]) < 0.5 * first


def test_algorithm1_and_initial_frames():
    torch.manual_seed(7)
    m = VaeLstm(tiny()).eval()
    control = torch.randn(2, 32, 3)
    a = m.generate(control, generator=torch.Generator().manual_seed(0))
    b = m.generate(control, generator=torch.Generator().manual_seed(0))
    c = m.generate(control, generator=torch.Generator().manual_seed(1))
    assert a.shape == (2, 32, 66)
    torch.testing.assert_close(a, b)  # seeded
    assert (a - c).abs().max() > 0  # the prior sample matters
    x = torch.randn(2, 32, 66)
    z1 = m.posterior_z1(x[:, :4], 32)
    torch.testing.assert_close(m.predict(x[:, :4], control), m.generate(control, z1))
    # z_1 only depends on the first 4 frames
    y = x.clone()
    y[:, 4:] += 5.0
    torch.testing.assert_close(m.posterior_z1(y[:, :4], 32), z1)


def test_bad_inputs_raise():
    m = VaeLstm(tiny())
    with pytest.raises(ValueError, match="66"):
        m.encode(torch.randn(2, 32, 65))
    with pytest.raises(ValueError, match="multiple of 4"):
        m.encode(torch.randn(2, 30, 66))
    with pytest.raises(ValueError, match="NaN"):
        m.loss(torch.full((1, 32, 66), float("nan")))
    with pytest.raises(ValueError, match="z1"):
        m.generate(torch.randn(2, 32, 3), z1=torch.randn(2, 5))
    with pytest.raises(ValueError, match="kernel"):
        VaeLstmConfig(kernel=4)


def test_evaluation_decoding_round_trip():
    """The reproduction's decoding of normalised test features gives back the clip's world positions,
    so Tables 1-2 measure the models and not the bookkeeping; a predictor that copies the truth scores 0."""
    import numpy as np

    from course_lib.datasets import WindowDataset
    from course_lib.evaluation import prediction_error
    from course_lib.experiments.vae_lstm import DataSpec, generate_clips, test_batch, to_world, with_control

    clips = generate_clips(DataSpec(n_clips=1), progress=False)
    ds = WindowDataset(clips, "positions_control", length=240, fps=60)
    x, starts = test_batch(ds)
    world = to_world(x, ds, starts)
    np.testing.assert_allclose(world[0], clips[0][:240].positions(), atol=2e-3)
    assert max(prediction_error(world, world, [70, 210]).values()) == 0.0
    shifted = with_control(x + 1.0, x[..., -3:])
    torch.testing.assert_close(shifted[..., -3:], x[..., -3:])
    assert prediction_error(to_world(shifted, ds, starts), world, [70])[70] > 1e-3


def test_per_step_prior_uses_training_branch():
    """generate(per_step=True) == decoding prior draws z_t through the training branch of eq. (9)."""
    torch.manual_seed(8)
    m = VaeLstm(tiny()).eval()
    control = torch.randn(2, 32, 3)
    out = m.generate(control, generator=torch.Generator().manual_seed(0), per_step=True)
    z = torch.randn(2, 8, 8, generator=torch.Generator().manual_seed(0))
    torch.testing.assert_close(out, m.decode(m.run_decoder(m.encode_control(control), z)))
    with pytest.raises(ValueError, match="per_step"):
        m.generate(control, z1=torch.zeros(2, 8), per_step=True)



def test_predict_per_step_is_the_prior_samplers_draws_with_z1_from_the_initial_frames():
    """predict(per_step=True): z_1 the 4 frames' posterior mean, z_2.. the prior draws generate(per_step) makes."""
    torch.manual_seed(8)
    m = VaeLstm(tiny()).eval()
    x, control = torch.randn(2, 32, 66), torch.randn(2, 32, 3)
    out = m.predict(x[:, :4], control, per_step=True, generator=torch.Generator().manual_seed(0))
    z = torch.randn(2, 8, 8, generator=torch.Generator().manual_seed(0))
    z[:, 0] = m.posterior_z1(x[:, :4], 32)
    torch.testing.assert_close(out, m.decode(m.run_decoder(m.encode_control(control), z)))
    prior = m.generate(control, generator=torch.Generator().manual_seed(0), per_step=True)
    assert not torch.allclose(out[:, :4], prior[:, :4])  # the first pooled step differs: it reads the frames
    torch.testing.assert_close(m.predict(x[:, :4], control), m.generate(control, m.posterior_z1(x[:, :4], 32)))


def test_z1_canvas_puts_z1_beside_every_canvas_column_so_algorithm1_keeps_it():
    """z1_canvas: m_c(t) = [c(t) || z_1] in training (z_1 the first step's latent) and in Algorithm 1, so z_1 reaches
    the last frames, which the recursion alone forgets; off (the paper's), the canvas is the cell states alone."""
    torch.manual_seed(8)
    m = VaeLstm(tiny(z1_canvas=True)).eval()
    control = torch.randn(2, 32, 3)
    h_c, z = m.encode_control(control), torch.randn(2, 8, 8)
    canvas = m.run_decoder(h_c, z)
    assert canvas.shape == (2, 16, 8)
    torch.testing.assert_close(canvas[:, 8:], z[:, 0, :, None].expand(-1, -1, 8))
    a, b = m.generate(control, torch.randn(2, 8)), m.generate(control, torch.zeros(2, 8))
    assert (a[:, -8:] - b[:, -8:]).abs().max() > 1e-3
    assert VaeLstm(tiny()).run_decoder(h_c, z).shape == (2, 8, 8)


def test_latent_diagnostics_known_answers():
    """A model whose inference net outputs mu = 0, logvar = 0 has KL 0 in every dimension; with W_c = 0 neither
    z_t nor z_1 reaches the canvas, so zeroing z moves nothing; with W_c restored it does."""
    from course_lib.datasets import WindowDataset
    from course_lib.experiments.vae_lstm import DataSpec, generate_clips, latent_diagnostics

    ds = WindowDataset(generate_clips(DataSpec(n_clips=2), progress=False), "positions_control", length=240, fps=60)
    torch.manual_seed(11)
    m = VaeLstm(tiny()).eval()
    used = latent_diagnostics(m, ds)
    assert used["zero_z_training_branch_m"] > 1e-4 and used["zero_z1_algorithm1_m"] > 1e-5
    with torch.no_grad():
        m.posterior_head.weight.zero_()
        m.posterior_head.bias.zero_()  # mu = logvar = 0 from the linear head
        w_c = m.cell.W_c.weight.clone()
        m.cell.W_c.weight.zero_()
    cut = latent_diagnostics(m, ds)
    assert cut["kl_per_dim_min"] == cut["kl_per_dim_mean"] == 0.0 and cut["dims_above_0.05"] == 0
    assert cut["zero_z_training_branch_m"] == 0.0 and cut["zero_z1_algorithm1_m"] == 0.0
    with torch.no_grad():
        m.cell.W_c.weight.copy_(w_c)
    assert latent_diagnostics(m, ds)["zero_z1_algorithm1_m"] == 0.0  # mu_1 = 0 already: zeroing changes nothing


def test_body_size_and_matched_control_pairs_known_answers():
    """body_size is the skeleton's bone lengths summed; a test set that is the training set has matched-control
    pairs 0 cm apart, and the same clips on a body 1.1x larger are apart by 10% of the joints' mean distance from
    the root's floor point (the one-body data of lesson 02 removes exactly this)."""
    import numpy as np

    from course_lib.datasets import WindowDataset
    from course_lib.experiments.vae_lstm import (
        DataSpec,
        _scaled_pose_error,
        body_size,
        generate_clips,
        matched_control_pairs,
    )
    from course_lib.motion import Motion

    clips = generate_clips(DataSpec(n_clips=2), progress=False)
    pos = np.stack([m[:240].positions() for m in clips])
    np.testing.assert_allclose(body_size(pos), [m.skeleton.bone_lengths()[1:].sum() for m in clips], rtol=1e-9)
    kw = dict(representation="positions_control", length=240, fps=60)
    ds = WindowDataset(clips, **kw)
    same = matched_control_pairs(ds, WindowDataset(clips, **kw, stats=ds.stats))
    assert same["nearest_cm"] < 1e-6 and same["best10_ctrl_rms_sd"] < 1e-6 and same["random_cm"] > 5
    big = [Motion(m.rotations, m.root_positions * 1.1, m.skeleton.scaled(1.1), m.fps) for m in clips]
    # the control scales with the body too (velocities 1.1x), so match on the original clips' controls
    scaled = WindowDataset(big, **kw, stats=ds.stats)
    for i in range(len(scaled.features)):
        scaled.features[i][..., -3:] = ds.features[i][..., -3:]
    pairs = matched_control_pairs(ds, scaled)
    big_pos = np.stack([m[:240].positions() for m in big])
    ones, undo = np.ones(2), body_size(pos) / body_size(big_pos)
    assert _scaled_pose_error(big_pos, pos, ones)[210] > 1e-3 > 1e-12 > _scaled_pose_error(big_pos, pos, undo)[210]
    root_rel = pos - pos[:, :, :1] * np.array([1.0, 0.0, 1.0])
    assert pairs["nearest_cm"] == pytest.approx(10 * np.linalg.norm(root_rel, axis=-1).mean(), rel=0.05)


def test_must_show_checks_read_the_right_numbers():
    """The course's targets on a crafted results dict: each flips when its number crosses its bound."""
    from course_lib.experiments.vae_lstm import BASELINES, FRAMES, must_show

    row = lambda v: {str(f): v for f in FRAMES}  # noqa: E731
    t1 = {**{b: row(1.0) for b in BASELINES}, "VAE-LSTM": row(0.1), "VAE-LSTM (prior sample)": row(0.12)}
    t2 = {**{b: row(0.02) for b in BASELINES}, "VAE-LSTM": row(0.01), "VAE-LSTM (prior sample)": row(0.012)}
    div = {"sampler": "per_step", "data_matched_control_apd_m": 0.015,
           "algorithm1": {"apd_m": 0.001, "path_error_m": 0.3}, "per_step": {"apd_m": 0.015, "path_error_m": 0.1}}
    res = {"table1": t1, "table2": t2, "prior_diversity": div, "latent": {"zero_z_change_m": 0.01}}
    assert all(h for _, _, h in must_show(res).values())
    t1["VAE-LSTM (prior sample)"] = dict(t1["VAE-LSTM"])  # identical rows, as a collapsed model's
    div["per_step"]["apd_m"] = 0.03  # 2x the data's spread, and zeroing z now moves less than half of it
    t2["VAE-LSTM"]["210"] = 0.03  # above the baselines and not flat
    failed = {k for k, (_, _, h) in must_show(res).items() if not h}
    assert failed == {"T1: 4-frame and prior rows differ (min relative difference over frames)",
                      "prior samples: APD / the data's matched-control spread, at most",
                      "zeroing z changes the output (m), at least half the APD",
                      "T2: VAE-LSTM (4 frames) / best baseline (max over frames)",
                      "T2: VAE-LSTM flat, frame 210 / frame 70"}
    div["sampler"] = "algorithm1"  # the other sampler's numbers are read when it is the lesson's
    failed = {k for k, (_, _, h) in must_show(res).items() if not h}
    assert {"prior samples: APD / the data's matched-control spread, at least",
            "prior samples: path error of the model's own control (m)"} <= failed


def test_posterior_head_is_linear_on_the_pooled_features():
    """mu, log sigma^2 = W_q e_t + b_q on eq. (6)'s features e_t: they take any sign (no ELU floor at -1)."""
    torch.manual_seed(3)
    m = VaeLstm(tiny()).eval()
    x = torch.randn(2, 32, 66)
    e = m.inference(x[..., :63].transpose(1, 2)).transpose(1, 2)
    mu, logvar = m.encode(x)
    ref = F.linear(e, m.posterior_head.weight, m.posterior_head.bias)
    torch.testing.assert_close(torch.cat((mu, logvar), -1), ref)
    with torch.no_grad():
        m.posterior_head.bias.fill_(-3.0)
    mu, logvar = m.encode(x)
    assert mu.min() < -1 and logvar.min() < 2 * torch.log(torch.tensor(0.61))


def test_table1_uses_the_models_own_root_and_samplers():
    """Table 1's VAE-LSTM rows keep the model's decoded control (its own root), Table 2's carry the given control;
    the prior row is the lesson's sampler, and the 4-frame row the same sampler with z_1 from the 4 frames and
    the prior row's draws after it; zeroing z is what sample_prior(zero=True) decodes."""
    from course_lib.experiments import vae_lstm as R

    torch.manual_seed(4)
    m = VaeLstm(tiny(latent_dim=8)).eval()
    x = torch.randn(3, 32, 66)
    preds = R.lesson02_predictions({"vae_lstm": m}, x, seed=0)
    assert R.SAMPLER == "per_step"  # the lesson's sampler; Algorithm 1 is the other
    own = m.predict(x[:, :4], x[..., -3:], per_step=True, generator=torch.Generator().manual_seed(0))
    torch.testing.assert_close(preds["table1"]["VAE-LSTM"], own)
    other = "algorithm1"
    torch.testing.assert_close(preds["table1"]["VAE-LSTM (4 frames, Algorithm 1)"], m.predict(x[:, :4], x[..., -3:]))
    torch.testing.assert_close(preds["table2"]["VAE-LSTM"][..., -3:], x[..., -3:])
    assert not torch.allclose(own[..., -3:], x[..., -3:])
    ours = R.sample_prior(m, x[..., -3:], R.SAMPLER, torch.Generator().manual_seed(0))
    torch.testing.assert_close(preds["table1"]["VAE-LSTM (prior sample)"], ours)
    assert f"VAE-LSTM (prior, {R.SAMPLERS[other]})" in preds["table1"]
    h_c = m.encode_control(x[..., -3:])
    zero = m.decode(m.run_decoder(h_c, torch.zeros(3, 8, 8)))
    torch.testing.assert_close(R.sample_prior(m, x[..., -3:], "per_step", zero=True), zero)
    with pytest.raises(ValueError, match="sampler"):
        R.sample_prior(m, x[..., -3:], "every_step")


def test_reproduce_registers_vae_lstm_and_the_corpus_keeps_its_names():
    """reproduce.py is the registry + CLI and holds no lesson's names; the shared clips live in corpus.py, and
    lesson 02's notebook still finds them on its experiment module."""
    from course_lib import corpus, reproduce
    from course_lib.experiments import vae_lstm

    train_fn, eval_fn = reproduce.EXPERIMENTS["vae_lstm"]
    assert (train_fn, eval_fn) == (vae_lstm.train_vae_lstm, vae_lstm.eval_vae_lstm)
    assert issubclass(vae_lstm.DataSpec, corpus.DataSpec) and vae_lstm.load_clips is corpus.load_clips
    assert vae_lstm.DataSpec().one_body and not corpus.DataSpec().one_body  # lesson 02's data: one body
    assert vae_lstm.generate_clips is corpus.generate_clips
    for name in ("DataSpec", "load_clips", "lesson02_tables", "rounded"):
        assert not hasattr(reproduce, name), name


def test_ten_bodies_study_runs(tmp_path):
    """study vae_lstm_ten_bodies: 30 clips on their own bodies, 3 steps, every part and the targets."""
    import json

    tool = load_study("vae_lstm_ten_bodies")
    out = tool.run(smoke=True, out_path=tmp_path / "r.json")
    rec = json.loads((tmp_path / "r.json").read_text())
    assert rec["command"] and rec["checks"] == out["checks"] and len(out["checks"]) == 10
    assert {"algorithm1", "per_step", "data_matched_control_apd_m"} <= set(out["prior_diversity"])


def test_z1_study_runs(tmp_path):
    """study vae_lstm_z1: 30 clips, 3 steps of one remedy; the pretrained row and the variant's are scored with
    both samplers as the lesson's, and with the lesson's own sampler the checks are must_show's."""
    import json

    from course_lib.experiments.vae_lstm import SAMPLER, must_show

    tool = load_study("vae_lstm_z1")
    out = tool.run(smoke=True, only=["free_bits"], out_path=tmp_path / "r.json")
    rec = json.loads((tmp_path / "r.json").read_text())
    assert rec["command"] and set(rec["rows"]) == {"pretrained", "free_bits"}
    for row in out["rows"].values():
        assert set(row["checks"]) == {"algorithm1", "per_step"} and len(row["checks"]["algorithm1"]) == 10
        own = must_show(row)  # on the rounded numbers the file keeps
        assert set(row["checks"][SAMPLER]) == set(own)
        for k, (v, b, _) in own.items():
            assert row["checks"][SAMPLER][k][:2] == pytest.approx([v, b], rel=1e-3, abs=1e-5), k
        assert row["targets_held"]["algorithm1"] == sum(c[2] for c in row["checks"]["algorithm1"].values())


def test_control_obs_std_narrows_the_control_channels_only():
    """control_obs_std: the last 3 features get their own likelihood std; the 63 pose features keep obs_std."""
    torch.manual_seed(6)
    m = VaeLstm(tiny(control_obs_std=0.05)).eval()
    x, x_hat = torch.randn(2, 16, 66), torch.randn(2, 16, 66)
    std = torch.full((66,), m.config.obs_std)
    std[63:] = 0.05
    expect = -torch.distributions.Normal(x_hat, std).log_prob(x).sum() / 2
    torch.testing.assert_close(m.nll(x, x_hat), expect, rtol=1e-5, atol=1e-3)
    same = VaeLstm(tiny()).eval()
    torch.testing.assert_close(same.nll(x, x_hat), -torch.distributions.Normal(x_hat, 0.2).log_prob(x).sum() / 2)
    with pytest.raises(ValueError, match="control_obs_std"):
        tiny(control_obs_std=0.0)


def test_path_error_sources_known_answers():
    """A stand-in model that copies the given control exactly has no path error; one whose yaw-rate output carries a
    bias strays, and making the yaw rate exact removes all of it while the other two channels' copies remove none."""
    from course_lib.datasets import WindowDataset
    from course_lib.experiments.vae_lstm import DataSpec, generate_clips, path_error_sources, test_batch

    ds = WindowDataset(generate_clips(DataSpec(n_clips=2), progress=False), "positions_control", length=240, fps=60)
    x, _ = test_batch(ds)

    class Copy:
        yaw_bias, frames = 0.0, slice(None)

        def generate(self, control, generator=None):
            i = next(k for k in range(len(x)) if torch.equal(x[k, :, -3:], control[0]))
            out = x[i:i + 1].expand(len(control), -1, -1).clone()
            out[:, self.frames, -1] += self.yaw_bias
            return out

    exact = path_error_sources(Copy(), ds, n_samples=2)
    assert exact["path_error_m"] < 1e-9 and max(exact["rms"].values()) == 0.0
    assert max(exact["rms_across_draws"].values()) == 0.0  # every draw the same
    biased = Copy()
    biased.yaw_bias = 0.5
    r = path_error_sources(biased, ds, n_samples=2)
    assert r["path_error_m"] > 0.05 and r["exact"]["yaw rate"] < 1e-9
    assert r["exact"]["forward velocity"] == pytest.approx(r["path_error_m"])
    assert r["bias"]["yaw rate"] == pytest.approx(0.5) and r["bias"]["forward velocity"] == 0.0
    # as integrate_root, frame t's heading sums the rates of frames 1..t: 0.5 sd of yaw rate turns the heading by
    # drift x t / 60 s by frame t, so drift x 239 / 60 at the last frame and drift x (60 s - 1) / 60 after s seconds,
    # and drift x 2 s on average over frames 1..239
    drift = math.degrees(0.5 * float(ds.stats[1][-1]))  # degrees per second
    assert r["final_heading_error_deg"] == pytest.approx(drift * 239 / 60, rel=1e-6)
    assert exact["final_heading_error_deg"] < 1e-9
    assert r["heading_error_deg_at"] == pytest.approx({str(s): drift * (60 * s - 1) / 60 for s in (1, 2, 3, 4)},
                                                      rel=1e-6)
    assert r["mean_heading_error_deg"] == pytest.approx(drift * 2.0, rel=1e-6)
    first = Copy()  # an error on frame 0 alone: integrate_root never applies frame 0's rate
    first.yaw_bias, first.frames = 0.5, slice(0, 1)
    f0 = path_error_sources(first, ds, n_samples=2)
    assert f0["final_heading_error_deg"] < 1e-9 and f0["mean_heading_error_deg"] < 1e-9 and f0["path_error_m"] < 1e-9


def test_load_clips_refuses_a_cache_of_another_spec(tmp_path):
    """The cache records the DataSpec that made it; another spec gets an error naming the difference, and the file
    is left as it was (a smaller cache must not silently stand in for the lesson's 400 clips)."""
    from course_lib.datasets import file_sha256, save_motions
    from course_lib.experiments.vae_lstm import DataSpec, load_clips

    path = tmp_path / "clips.npz"
    made = load_clips(DataSpec(n_clips=2), path, progress=False)
    assert len(load_clips(DataSpec(n_clips=2), path, progress=False)) == len(made) == 2
    before = file_sha256(path)
    with pytest.raises(ValueError, match=r"n_clips 2, asked 3.*delete the file"):
        load_clips(DataSpec(n_clips=3), path, progress=False)
    with pytest.raises(ValueError, match=r"seed 2017, asked 1"):
        load_clips(DataSpec(n_clips=2, seed=1), path, progress=False)
    assert file_sha256(path) == before
    old = tmp_path / "old.npz"  # a cache from before the spec was recorded: its clip count is checked
    save_motions(made, old)
    assert len(load_clips(DataSpec(n_clips=2), old, progress=False)) == 2
    with pytest.raises(ValueError, match=r"n_clips 2, asked 400"):
        load_clips(DataSpec(), old, progress=False)


def test_heading_loss_charges_a_slow_yaw_error_more_than_a_fast_one():
    """heading_loss: a constant yaw-rate error b (a heading drift) costs 0.5 T b^2 / obs_std^2 per clip; an error of
    the same size that alternates sign every frame (no drift) costs far less; the loss adds heading_weight times it."""
    m = VaeLstm(tiny(heading_weight=10.0)).eval()
    x = torch.zeros(2, 16, 66)
    slow, fast = x.clone(), x.clone()
    slow[..., -1] = 0.1
    fast[..., -1] = 0.1 * (-1.0) ** torch.arange(16)
    s2 = m.config.obs_std ** 2
    torch.testing.assert_close(m.heading_loss(x, slow), torch.tensor(0.5 * 16 * 0.01 / s2))
    assert float(m.heading_loss(x, fast)) < 0.25 * float(m.heading_loss(x, slow))
    batch = torch.randn(2, 16, 66)
    torch.manual_seed(3)
    out = m.loss(batch)
    assert "heading" in out and float(out["heading"]) > 0
    m.config.heading_weight = 0.0  # the same draws without the term: the loss falls by exactly 10 x heading
    torch.manual_seed(3)
    torch.testing.assert_close(out["loss"] - m.loss(batch)["loss"], 10.0 * out["heading"], rtol=1e-4, atol=1e-3)
    with pytest.raises(ValueError, match="heading_weight"):
        tiny(heading_weight=1.0, generation_weight=0.0)
