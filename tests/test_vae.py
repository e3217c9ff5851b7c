"""Tests of course_lib.models.vae: KL formulas, ELBO terms, schedules, free bits, CVAE, training."""

import math

import pytest
import torch

from course_lib.models.vae import PoseVae, VaeConfig, cyclical_beta, gaussian_kl, gaussian_nll, linear_beta, mc_kl
from course_lib.training import fit, seed_everything


def test_gaussian_kl_matches_torch_distributions():
    g = torch.Generator().manual_seed(0)
    mu, logvar = torch.randn(2, 7, 4, generator=g, dtype=torch.float64)
    q = torch.distributions.Normal(mu, (0.5 * logvar).exp())
    p = torch.distributions.Normal(torch.zeros_like(mu), torch.ones_like(mu))
    assert torch.allclose(gaussian_kl(mu, logvar), torch.distributions.kl_divergence(q, p), atol=1e-12)
    assert torch.all(gaussian_kl(torch.zeros(3), torch.zeros(3)) == 0)


def test_mc_kl_converges_to_closed_form():
    g = torch.Generator().manual_seed(1)
    mu, logvar = torch.randn(2, 3, 2, generator=g, dtype=torch.float64)
    est = mc_kl(mu, logvar, n_samples=200_000, generator=g)
    assert torch.allclose(est, gaussian_kl(mu, logvar).sum(-1), atol=0.03)
    with pytest.raises(ValueError, match="n_samples"):
        mc_kl(mu, logvar, eps=torch.zeros(5, 3, 3))


def test_gaussian_nll_matches_torch_distributions():
    x, x_hat = torch.randn(5, 6, dtype=torch.float64), torch.randn(5, 6, dtype=torch.float64)
    ref = -torch.distributions.Normal(x_hat, 0.3).log_prob(x).sum(-1)
    assert torch.allclose(gaussian_nll(x, x_hat, 0.3), ref, atol=1e-12)


def test_loss_terms_are_the_elbo_with_injected_eps():
    torch.manual_seed(0)
    model = PoseVae(VaeConfig.cpu(x_dim=10, z_dim=3, hidden=16)).double()
    x, eps = torch.randn(8, 10, dtype=torch.float64), torch.randn(8, 3, dtype=torch.float64)
    out = model.loss(x, eps=eps)
    mu, logvar = model.encode(x)
    z = mu + (0.5 * logvar).exp() * eps
    recon = -torch.distributions.Normal(model.decode(z), 0.1).log_prob(x).sum(-1).mean()
    kl = gaussian_kl(mu, logvar).sum(-1).mean()
    assert torch.allclose(out["recon"], recon) and torch.allclose(out["kl"], kl)
    assert torch.allclose(out["elbo"], -(recon + kl)) and torch.allclose(out["loss"], recon + kl)
    assert out["kl_per_dim"].shape == (3,) and torch.allclose(out["kl_per_dim"].sum(), kl)
    assert torch.equal(model.loss(x, eps=eps)["loss"], model.loss(x, eps=eps)["loss"])  # deterministic given eps


def test_schedules_and_free_bits():
    assert linear_beta(0, 100) == 0 and linear_beta(50, 100) == 0.5 and linear_beta(500, 100, 2.0) == 2.0
    assert cyclical_beta(0, 100) == 0 and cyclical_beta(25, 100) == 0.5 and cyclical_beta(75, 100) == 1.0
    assert cyclical_beta(125, 100) == 0.5
    model = PoseVae(VaeConfig.cpu(x_dim=4, z_dim=2, hidden=8, kl_schedule="linear", kl_warmup_steps=10))
    betas = [model.loss(torch.randn(4, 4))["beta"] for _ in range(12)]
    assert betas[0] == 0 and betas[5] == pytest.approx(0.5) and betas[11] == 1.0
    model.eval()
    assert model.loss(torch.randn(4, 4))["beta"] == 1.0 and int(model.num_updates) == 12  # eval does not advance
    fb = PoseVae(VaeConfig.cpu(x_dim=4, z_dim=2, hidden=8, free_bits=5.0))
    out = fb.loss(torch.randn(4, 4), eps=torch.zeros(4, 2))
    assert torch.allclose(out["loss"], out["recon"] + 10.0)  # both dims are below 5 nats: penalty is 2 * 5


def test_conditional_vae_and_errors():
    model = PoseVae(VaeConfig.cpu(x_dim=6, z_dim=2, hidden=8, n_labels=3))
    x, y = torch.randn(5, 6), torch.tensor([0, 1, 2, 1, 0])
    assert model.loss((x, y))["loss"].ndim == 0
    assert model.sample(4, label=2, generator=torch.Generator().manual_seed(0)).shape == (4, 6)
    with pytest.raises(ValueError, match="conditional"):
        model.loss(x)
    with pytest.raises(ValueError, match=r"\[0, 3\)"):
        model.loss((x, torch.tensor([0, 1, 2, 3, 0])))
    with pytest.raises(ValueError, match=r"\(N, 6\)"):
        model.encode(torch.randn(5, 7), y)
    with pytest.raises(ValueError, match="NaN"):
        model.encode(torch.full((5, 6), float("nan")), y)
    with pytest.raises(ValueError, match="kl_schedule"):
        VaeConfig(kl_schedule="exp")


def test_sample_is_reproducible_with_generator():
    model = PoseVae(VaeConfig.cpu(x_dim=6, hidden=8))
    a = model.sample(3, generator=torch.Generator().manual_seed(4))
    b = model.sample(3, generator=torch.Generator().manual_seed(4))
    assert torch.equal(a, b)


def _toy_poses(n=1024, seed=0):
    """Points on a noisy 2-D manifold embedded in 20-D (a stand-in for poses)."""
    g = torch.Generator().manual_seed(seed)
    t = torch.rand(n, 2, generator=g) * 2 * math.pi
    basis = torch.randn(4, 20, generator=g)
    feats = torch.stack([t[:, 0].sin(), t[:, 0].cos(), t[:, 1].sin(), 0.5 * t[:, 1].cos()], -1)
    return feats @ basis + 0.01 * torch.randn(n, 20, generator=g)


def test_training_improves_elbo_and_reconstruction():
    seed_everything(0)
    x = _toy_poses()
    model = PoseVae(VaeConfig.cpu(x_dim=20, z_dim=4, hidden=64, obs_std=0.1))
    g = torch.Generator().manual_seed(0)
    err0 = (model.reconstruct(x) - x).pow(2).mean().item()
    hist = fit(model, lambda: x[torch.randint(0, len(x), (128,), generator=g)], steps=400, steps_per_epoch=100,
               lr=3e-3, progress=False)
    err1 = (model.reconstruct(x) - x).pow(2).mean().item()
    assert hist.final("elbo", 20) > hist.step["elbo"][0] + 1000
    assert err1 < err0 / 10


def test_skip_noise_decoder_collapses_and_free_bits_keep_kl():
    seed_everything(0)
    x = _toy_poses(seed=1)
    g = torch.Generator().manual_seed(0)
    kls = {}
    for fb in (0.0, 1.0):
        seed_everything(0)
        model = PoseVae(VaeConfig.cpu(x_dim=20, z_dim=4, hidden=64, obs_std=0.5, skip_noise=0.05, free_bits=fb))
        h = fit(model, lambda: x[torch.randint(0, len(x), (128,), generator=g)], steps=600, lr=3e-3, progress=False)
        kls[fb] = h.final("kl", 50) / 4
    assert kls[0.0] < 0.05  # collapsed: z carries (almost) nothing
    assert kls[1.0] > 0.5  # free bits: about 1 nat per dim is used
    with pytest.raises(ValueError, match="noisy pose"):
        model.sample(2)


def test_exercise_checks_accept_the_reference_and_reject_mistakes():
    from course_lib.solutions import vae_basics as ans

    ans.check_kl(ans.kl_closed_form)
    with pytest.raises(AssertionError, match="KL values differ"):
        ans.check_kl(lambda mu, logvar: 0.5 * (mu**2 + logvar.exp() - logvar).sum(-1))  # forgot the -1
    with pytest.raises(AssertionError, match="did you drop the 1/2"):
        ans.check_kl(lambda mu, logvar: 2 * ans.kl_closed_form(mu, logvar))
    ans.check_reparameterise(ans.reparameterise)
    with pytest.raises(AssertionError, match="exp\\(logvar / 2\\)"):
        ans.check_reparameterise(lambda mu, logvar, eps: mu + logvar.exp() * eps)  # used the variance
    model = PoseVae(VaeConfig.cpu(x_dim=6, z_dim=2, hidden=8))
    x = torch.randn(10, 6)
    ans.check_elbo(ans.elbo_per_pose, model, x)
    with pytest.raises(AssertionError, match="ELBO differs"):
        ans.check_elbo(lambda m, x, eps: ans.elbo_per_pose(m, x, eps) + 0.5 * math.log(2 * math.pi), model, x)
    with pytest.raises(AssertionError, match="KL should fall"):
        ans.check_beta_sweep([{"beta": b, "kl": 1.0, "recon": 0.0} for b in (0.1, 1, 10)], x, x, steps=1)


def test_beta_sweep_reference_kl_falls_with_beta():
    from course_lib.solutions import vae_basics as ans

    x = _toy_poses(n=512)
    res = ans.beta_sweep(x[:400], x[400:], [0.3, 3.0], steps=150, hidden=32, obs_std=0.3)
    assert res[0]["kl"] > res[1]["kl"] + 0.5
    sweep = ans.beta_sweep(x[:400], x[400:], [0.3, 1.0, 3.0], steps=60, hidden=32, obs_std=0.3)
    ans.check_beta_sweep(sweep, x[:400], x[400:], steps=60, hidden=32, obs_std=0.3)
    off = [dict(r, recon=r["recon"] * 1.08) if r["beta"] == 3.0 else r for r in sweep]  # one beta 8 % off
    with pytest.raises(AssertionError, match="beta=3.0: your recon"):
        ans.check_beta_sweep(off, x[:400], x[400:], steps=60, hidden=32, obs_std=0.3)


def test_iwae_bound_rises_with_k_and_its_check_rejects_mistakes():
    from course_lib.solutions import vae_basics as ans

    torch.manual_seed(0)
    model = PoseVae(VaeConfig.cpu(x_dim=20, z_dim=2, hidden=16, obs_std=0.3))
    x = _toy_poses(n=64)
    eps = torch.randn(64, 64, 2, generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        b1, b64 = ans.iwae_bound(model, x, eps[:1]), ans.iwae_bound(model, x, eps)
        # K = 1 is the one-sample ELBO with the Monte-Carlo KL: log p(x|z) + log p(z) - log q(z|x)
        mu, logvar = model.encode(x)
        z = mu + (0.5 * logvar).exp() * eps[0]
        log_px = -gaussian_nll(x, model.decode(z), 0.3)
        log_pz = -0.5 * (z**2 + math.log(2 * math.pi)).sum(-1)
        log_qz = -0.5 * (eps[0] ** 2 + logvar + math.log(2 * math.pi)).sum(-1)
    torch.testing.assert_close(b1, log_px + log_pz - log_qz)
    assert (b64 - b1).mean() > 0  # Burda et al.: the bound tightens with K
    assert ans.check_iwae(ans.iwae_bound, model, x) > 0
    with pytest.raises(AssertionError, match="K = 32 differs"):  # mean of the weights' logs: the ELBO again
        ans.check_iwae(lambda m, x, e: torch.stack([ans.iwae_bound(m, x, e[k:k + 1]) for k in range(len(e))]).mean(0),
                       model, x)

