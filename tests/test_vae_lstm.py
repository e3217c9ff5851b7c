"""VAE-LSTM (Habibie et al. 2017): shapes, the modified LSTM written out, loss formulas, Algorithm 1."""

import math

import pytest
import torch
from torch.nn import functional as F

from course_lib.models.vae_lstm import ModifiedLstmCell, VaeLstm, VaeLstmConfig, conv_encoder


def tiny(**kw) -> VaeLstmConfig:
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
    m = VaeLstm(tiny(l1=0.5)).eval()
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
    from course_lib.reproduce import DataSpec, generate_clips, test_batch, to_world, with_control

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
