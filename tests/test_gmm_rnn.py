"""GMM-RNN (Wang, Chai et al. 2021, sec. 4.1): shapes, eq. (6)-(8) vs. torch.distributions, training,
generation (sec. 4.1.4), gradient clipping by value, bad input."""

import math

import pytest
import torch
from torch import distributions as dist

from course_lib.models.gmm_rnn import GmmRnn, GmmRnnConfig, mixture_log_prob


def tiny(**kw) -> GmmRnnConfig:
    return GmmRnnConfig.cpu(**{"fc_width": 16, "lstm_width": 16, "out_width": 16, **kw})


def test_paper_config_shapes():
    """Fig. 3: widths 500, M = 5; the read-out has M (1 + 2 D) outputs (425 for the paper's D = 42)."""
    assert GmmRnn(GmmRnnConfig(dim=42, contact_dims=(40, 41))).out.out_features == 425
    torch.manual_seed(0)
    m = GmmRnn(tiny())
    params, (h, c) = m(torch.randn(3, 7, 68))
    assert params["logits"].shape == (3, 7, 5)
    assert params["mu"].shape == params["log_sigma"].shape == (3, 7, 5, 68)
    assert h.shape == c.shape == (2, 3, 16)
    assert (params["log_sigma"] >= math.log(0.01) - 1e-7).all()
    c = GmmRnnConfig.cpu()
    assert (c.fc_width, c.lstm_width, c.out_width, c.mixtures, c.noise_std, c.window, c.batch_size) == \
        (128, 128, 128, 5, 0.05, 50, 20)
    assert c.lr_factor(2) == pytest.approx(1e-3 * 0.95 ** 2 / c.lr)


def test_mixture_nll_matches_torch_distributions():
    """eq. (6)-(8) written out equals MixtureSameFamily(Categorical, Independent(Normal)) within 1e-5."""
    g = torch.Generator().manual_seed(1)
    logits, mu = torch.randn(4, 6, 5, generator=g), torch.randn(4, 6, 5, 9, generator=g)
    log_sigma, x = 0.5 * torch.randn(4, 6, 5, 9, generator=g), torch.randn(4, 6, 9, generator=g)
    ref = dist.MixtureSameFamily(dist.Categorical(logits=logits),
                                 dist.Independent(dist.Normal(mu, log_sigma.exp()), 1)).log_prob(x)
    ours = mixture_log_prob(x, logits, mu, log_sigma)
    assert ours.shape == (4, 6)
    assert torch.allclose(ours, ref, atol=1e-5, rtol=0)
    # and the model's loss is the mean of -log p over frames (no noise in eval mode)
    torch.manual_seed(0)
    m = GmmRnn(tiny(dim=9, contact_dims=(7, 8))).eval()
    xs = torch.randn(2, 5, 9, generator=g)
    params, _ = m(xs[:, :-1])
    mix = dist.MixtureSameFamily(dist.Categorical(logits=params["logits"]),
                                 dist.Independent(dist.Normal(params["mu"], params["log_sigma"].exp()), 1))
    assert m.loss(xs)["nll"].item() == pytest.approx(-mix.log_prob(xs[:, 1:]).mean().item(), abs=1e-5)


def test_nll_decreases_when_fitted():
    """100 RMSProp steps on one small batch of smooth sequences: the NLL falls by a lot."""
    torch.manual_seed(0)
    t = torch.linspace(0, 6, 20)
    x = torch.stack([torch.sin(t + p)[:, None] * torch.linspace(0.5, 1.5, 6) for p in (0.0, 1.0, 2.0, 3.0)])
    m = GmmRnn(tiny(dim=6, contact_dims=()))
    opt = torch.optim.RMSprop(m.parameters(), lr=3e-3)
    first = m.loss(x)["nll"].item()
    for _ in range(100):
        opt.zero_grad()
        m.loss(x)["loss"].backward()
        opt.step()
    m.eval()
    last = m.loss(x)["nll"].item()
    assert last < first - 3.0, (first, last)


def test_gradients_clipped_by_value():
    """The hooks of sec. 4.1.2 clip every gradient entry to [-c, c]; without them some exceed c."""
    torch.manual_seed(0)
    x = 30 * torch.randn(2, 6, 68)
    grads = {}
    for c in (None, 0.01):
        torch.manual_seed(0)
        m = GmmRnn(tiny(grad_clip_value=c)).eval()
        m.loss(x)["loss"].backward()
        grads[c] = max(p.grad.abs().max().item() for p in m.parameters())
    assert grads[None] > 0.01
    assert grads[0.01] == pytest.approx(0.01)


def test_generate_shapes_reproducible_and_contacts_binary():
    torch.manual_seed(0)
    m = GmmRnn(tiny()).eval()
    x0 = torch.randn(3, 2, 68)
    mean, std = torch.zeros(68), torch.ones(68)
    mean[66:], std[66:] = 0.4, 0.5
    a = m.generate(x0, 30, generator=torch.Generator().manual_seed(5), stats=(mean, std))
    b = m.generate(x0, 30, generator=torch.Generator().manual_seed(5), stats=(mean, std))
    c = m.generate(x0, 30, generator=torch.Generator().manual_seed(6), stats=(mean, std))
    assert a.shape == (3, 32, 68) and torch.isfinite(a).all()
    assert torch.equal(a, b) and not torch.equal(a, c)
    assert torch.equal(a[:, :2], x0)
    raw = a[:, 2:, 66:] * 0.5 + 0.4  # contact bits back in raw units: exactly 0 or 1
    assert ((raw - 0).abs() < 1e-6).logical_or((raw - 1).abs() < 1e-6).all()
    clamped = m.generate(x0, 10, generator=torch.Generator().manual_seed(5), contact_mode="clamp")
    assert clamped[:, 2:, 66:].min() >= 0 and clamped[:, 2:, 66:].max() <= 1


def test_sample_step_continues_generate():
    """generate = read x_0, then sample_step from x_1 with the carried state (infinite generation)."""
    torch.manual_seed(0)
    m = GmmRnn(tiny()).eval()
    x0 = torch.randn(2, 2, 68)
    full = m.generate(x0, 4, generator=torch.Generator().manual_seed(3), contact_mode="none")
    g = torch.Generator().manual_seed(3)
    _, state = m(x0[:, :1])
    x_t, frames = x0[:, 1], []
    for _ in range(4):
        x_t, state = m.sample_step(x_t, state, g, contact_mode="none")
        frames.append(x_t)
    assert torch.allclose(full[:, 2:], torch.stack(frames, 1))


def test_bad_input_errors():
    m = GmmRnn(tiny())
    with pytest.raises(ValueError, match=r"\(N, T >= 1, 68\)"):
        m(torch.randn(2, 5, 67))
    with pytest.raises(ValueError, match="NaN"):
        m.loss(torch.full((2, 5, 68), float("nan")))
    with pytest.raises(ValueError, match="T >= 2"):
        m.loss(torch.randn(2, 1, 68))
    with pytest.raises(ValueError, match="two initial frames"):
        m.generate(torch.randn(2, 3, 68), 5)
    with pytest.raises(ValueError, match="steps"):
        m.generate(torch.randn(2, 2, 68), -1)
    with pytest.raises(ValueError, match="contact mode"):
        m.generate(torch.randn(2, 2, 68), 1, contact_mode="round")
    with pytest.raises(ValueError, match="contact_dims"):
        GmmRnnConfig(dim=10)
    with pytest.raises(ValueError, match="anchor_tau"):
        GmmRnnConfig(anchor_tau=0.02)  # a soft anchor needs feet-anchored features
    with pytest.raises(ValueError, match="anchor_tau"):
        GmmRnnConfig(features="feet_anchored", anchor_tau=-0.01)


def test_residual_means_start_from_the_input():
    """residual=True (the CPU preset): mu_i = x_t + mu_hat_i, so a zero read-out predicts "no change"."""
    m = GmmRnn(tiny(residual=True))
    with torch.no_grad():
        m.out.weight.zero_()
        m.out.bias.zero_()
    x = torch.randn(2, 5, 68)
    params, _ = m(x)
    assert torch.equal(params["mu"], x.unsqueeze(-2).expand(-1, -1, 5, -1))
    assert not GmmRnnConfig().residual and GmmRnnConfig.cpu().residual  # the paper's output is not residual


def test_absolute_dims_keep_their_means_absolute():
    """absolute_dims: those columns predict mu_hat itself (root height, tilt, contacts in lesson 03)."""
    m = GmmRnn(tiny(residual=True, absolute_dims=(3, 66, 67)))
    with torch.no_grad():
        m.out.weight.zero_()
        m.out.bias.zero_()
    x = torch.randn(2, 5, 68)
    mu = m(x)[0]["mu"]  # (2, 5, M, 68)
    assert torch.equal(mu[..., [3, 66, 67]], torch.zeros(2, 5, 5, 3))
    keep = [i for i in range(68) if i not in (3, 66, 67)]
    assert torch.equal(mu[..., keep], x[..., keep].unsqueeze(-2).expand(-1, -1, 5, -1))
    with pytest.raises(ValueError, match="absolute_dims"):
        GmmRnnConfig(absolute_dims=(68,))


def test_sampling_bias_shrinks_the_spread():
    """Graves' bias b: sigma * exp(-b) and sharper weights; b = 0 is the paper's sampling."""
    m = GmmRnn(tiny())
    g = torch.Generator().manual_seed(0)
    params = {"logits": torch.tensor([[2.0, 0.0, 0.0, 0.0, 0.0]]).expand(4000, -1),
              "mu": torch.arange(5.0)[None, :, None].expand(4000, 5, 68) * 10,
              "log_sigma": torch.zeros(4000, 5, 68)}
    plain, biased = m.sample_mixture(params, g), m.sample_mixture(params, g, bias=2.0)
    # component 0 (mean 0) has weight e^2 / (e^2 + 4) = 0.649 at b = 0 and e^6 / (e^6 + 4) = 0.990 at b = 2
    assert (plain[:, 0].abs() < 5).float().mean() == pytest.approx(0.649, abs=0.03)
    assert (biased[:, 0].abs() < 5).float().mean() == pytest.approx(0.990, abs=0.01)
    near = biased[biased[:, 0].abs() < 5]
    assert near.std() == pytest.approx(math.exp(-2.0), rel=0.05)
    with pytest.raises(ValueError, match="bias"):
        m.sample_mixture(params, g, bias=-1.0)


def test_self_feed_uses_own_samples_only_in_training():
    """self_feed=(k, m): in training, steps k..k+m-1 of each cycle read the model's own samples."""
    torch.manual_seed(0)
    m = GmmRnn(tiny(self_feed=(2, 3), noise_std=0.0))
    x = torch.randn(3, 12, 68)
    m.eval()
    forced = m.loss(x)["nll"]
    m.train()
    torch.manual_seed(1)
    fed = m.loss(x)
    assert torch.isfinite(fed["loss"]) and not torch.allclose(fed["nll"], forced)
    fed["loss"].backward()
    assert all(p.grad is not None and torch.isfinite(p.grad).all() for p in m.parameters())
    # with the first k = 11 steps true, a 12-frame window (11 inputs) is plain teacher forcing
    m2 = GmmRnn(tiny(self_feed=(11, 1), noise_std=0.0))
    m2.load_state_dict(m.state_dict())
    m2.train()
    m.eval()
    assert torch.allclose(m2.loss(x)["nll"], m.loss(x)["nll"], atol=1e-5)
    with pytest.raises(ValueError, match="self_feed"):
        GmmRnnConfig(self_feed=(0, 3))


def test_fixed_columns_are_not_modelled_and_carry_over():
    """fixed_dims: the NLL ignores them (a constant column cannot buy likelihood at the sigma floor) and
    generation copies them from the input frame."""
    torch.manual_seed(0)
    m = GmmRnn(tiny(fixed_dims=(10, 11))).eval()
    x = torch.randn(2, 6, 68)
    y = x.clone()
    y[:, -1, 10:12] = 123.0  # whatever the fixed columns of a target hold does not change its likelihood
    assert torch.allclose(m.loss(x)["nll"], m.loss(y)["nll"])
    assert m.config.gaussian_dims == tuple(c for c in range(68) if c not in (10, 11))
    x0 = torch.randn(3, 2, 68)
    out = m.generate(x0, 4, generator=torch.Generator().manual_seed(0), contact_mode="none")
    assert torch.equal(out[:, 2:, 10:12], x0[:, 1:2, 10:12].expand(3, 4, 2))
    with pytest.raises(ValueError, match="fixed_dims"):
        GmmRnnConfig(fixed_dims=(66,))


def test_bernoulli_contacts_likelihood_and_samples():
    """bernoulli_contacts: the bits' log-likelihood is Bernoulli's (torch.distributions), samples are 0/1 in raw
    units written in the model's normalisation."""
    torch.manual_seed(0)
    mean, std = torch.zeros(68), torch.ones(68)
    mean[66:], std[66:] = 0.4, 0.5  # raw bit = x * 0.5 + 0.4
    m = GmmRnn(tiny(bernoulli_contacts=True), stats=(mean.numpy(), std.numpy())).eval()
    assert m.out.out_features == 5 * (1 + 2 * 68) + 2 and 66 not in m.config.gaussian_dims
    x = torch.randn(2, 5, 68)
    x[..., 66:] = (torch.randint(0, 2, (2, 5, 2)).float() - 0.4) / 0.5  # binary bits, normalised
    params, _ = m(x[:, :-1])
    cols = list(m.config.gaussian_dims)
    gauss = mixture_log_prob(x[:, 1:, cols], params["logits"], params["mu"][..., cols], params["log_sigma"][..., cols])
    bits = (x[:, 1:, 66:] * 0.5 + 0.4 > 0.5).float()
    bern = dist.Bernoulli(logits=params["contact_logits"]).log_prob(bits).sum(-1)
    torch.testing.assert_close(m.log_prob(x[:, 1:], params), gauss + bern)
    out = m.generate(x[:, :2], 6, generator=torch.Generator().manual_seed(1), contact_mode="none")
    raw = out[:, 2:, 66:] * 0.5 + 0.4
    assert torch.all((raw.abs() < 1e-6) | ((raw - 1).abs() < 1e-6))


def test_joint_limits_clamp_each_sampled_column_and_nothing_else():
    """limits: a column with low = high = c is sampled as c every frame, a column with a band stays inside it, the
    free (+-inf) columns draw exactly what they draw without limits (the same generator)."""
    torch.manual_seed(0)
    m = GmmRnn(tiny()).eval()
    x0 = torch.randn(3, 2, 68)
    low, high = torch.full((68,), -math.inf), torch.full((68,), math.inf)
    low[7], high[7] = 0.25, 0.25
    low[8], high[8] = -0.1, 0.1
    free = m.generate(x0, 12, generator=torch.Generator().manual_seed(2), contact_mode="none")
    held = m.generate(x0, 12, generator=torch.Generator().manual_seed(2), contact_mode="none", limits=(low, high))
    assert torch.equal(held[:, 2:, 7], torch.full((3, 12), 0.25))
    assert held[:, 2:, 8].abs().max() <= 0.1 and free[:, 2:, 8].abs().max() > 0.1  # the band binds
    assert torch.equal(held[:, 2, 9:], free[:, 2, 9:])  # first sampled frame: free columns untouched
    assert torch.equal(held[:, :2], x0)  # the given frames are not clamped


def test_stored_limits_round_trip_and_default_to_none(tmp_path):
    from course_lib.training import load_checkpoint, save_checkpoint

    m = GmmRnn(tiny())
    assert torch.isinf(m.limits()[0]).all() and (m.limits()[0] < 0).all() and (m.limits()[1] > 0).all()
    low, high = -torch.arange(68.0) - 1, torch.arange(68.0) + 1
    m.set_limits(low, high)
    save_checkpoint(m, m.config, tmp_path / "g.pt", command="pytest")
    back = load_checkpoint(tmp_path / "g.pt", GmmRnn, GmmRnnConfig)
    assert torch.equal(back.limits()[0], low) and torch.equal(back.limits()[1], high)
    old = {k: v for k, v in m.state_dict().items() if k not in ("feature_low", "feature_high")}
    fresh = GmmRnn(tiny())
    fresh.load_state_dict(old)  # a checkpoint saved before the limits existed: no limits
    assert torch.isinf(fresh.limits()[1]).all()


@pytest.mark.parametrize("limits, match", [
    ((torch.zeros(67), torch.ones(67)), r"two \(68,\) bounds"),
    ((torch.full((68,), math.nan), torch.ones(68)), "NaN"),
    ((torch.ones(68), torch.zeros(68)), "low > high in columns"),
    ((torch.zeros(68),), r"\(low, high\)"),
])
def test_bad_limits_are_named(limits, match):
    m = GmmRnn(tiny()).eval()
    with pytest.raises(ValueError, match=match):
        m.generate(torch.zeros(1, 2, 68), 2, limits=limits)
    with pytest.raises(ValueError, match=match):
        m.set_limits(*limits) if len(limits) == 2 else m.check_limits(limits)
