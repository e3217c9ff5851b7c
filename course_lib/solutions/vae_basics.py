"""Reference answers and self-checks for the exercises of notebooks/01_vae_basics.ipynb.

Students write their own version in the notebook; each ``check_*`` runs it on fixed inputs and
compares it with the reference here, raising an AssertionError that says what is wrong.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from course_lib.models.vae import PoseVae, VaeConfig
from course_lib.training import fit, seed_everything

__all__ = ["beta_sweep", "check_beta_sweep", "check_elbo", "check_iwae", "check_kl", "check_reparameterise",
           "elbo_per_pose", "exercise_poses", "iwae_bound", "kl_closed_form", "reparameterise"]


# ----------------------------------------------------------------------------- reference answers


def kl_closed_form(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """KL(N(mu, diag e^logvar) || N(0, I)) summed over dims.  (N, D) -> (N,)."""
    return 0.5 * (mu**2 + logvar.exp() - logvar - 1).sum(-1)


def reparameterise(mu: torch.Tensor, logvar: torch.Tensor, eps: torch.Tensor) -> torch.Tensor:
    """z = sigma * eps + mu with sigma = exp(logvar / 2)   -- Habibie eq. (3).  (N, D) -> (N, D)."""
    return torch.exp(0.5 * logvar) * eps + mu


def elbo_per_pose(model: PoseVae, x: torch.Tensor, eps: torch.Tensor) -> torch.Tensor:
    """One-sample ELBO of each pose, log p(x|z) - KL(q(z|x) || p(z))   -- Habibie eq. (2).  (N, D) -> (N,)."""
    mu, logvar = model.encode(x)
    z = reparameterise(mu, logvar, eps)
    s = model.config.obs_std
    log_px = -0.5 * (((x - model.decode(z)) / s) ** 2 + 2 * math.log(s) + math.log(2 * math.pi)).sum(-1)
    return log_px - kl_closed_form(mu, logvar)


def iwae_bound(model: PoseVae, x: torch.Tensor, eps: torch.Tensor) -> torch.Tensor:
    """Importance-weighted bound (Burda et al. 2016) with K samples: eps (K, N, z_dim), x (N, D) -> (N,).

    log (1/K) sum_k p(x, z_k) / q(z_k | x),  z_k = mu + sigma eps_k; K = 1 is a one-sample ELBO, and the
    bound rises towards log p(x) as K grows.  In log space: logsumexp over k minus log K.
    """
    mu, logvar = model.encode(x)
    z = mu + torch.exp(0.5 * logvar) * eps  # (K, N, z_dim)
    s = model.config.obs_std
    x_hat = model.decode(z.flatten(0, 1)).unflatten(0, z.shape[:2])  # (K, N, D)
    log_px = -0.5 * (((x - x_hat) / s) ** 2 + 2 * math.log(s) + math.log(2 * math.pi)).sum(-1)
    log_pz = -0.5 * (z**2 + math.log(2 * math.pi)).sum(-1)
    log_qz = -0.5 * (eps**2 + logvar + math.log(2 * math.pi)).sum(-1)
    return torch.logsumexp(log_px + log_pz - log_qz, 0) - math.log(eps.shape[0])


def exercise_poses(n_clips: int = 24, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """A small seeded pose set for the exercises: normalised poses (N, 63) of training and held-out subjects.

    Poses are `positions_control` without the control (63 joint coordinates in the floor frame), minus the
    training mean, divided by one global scale (the training poses' RMS deviation), as in the lesson.
    """
    from course_lib.datasets import generate_locomotion_set, split_by_subject
    from course_lib.representations import encode

    clips = generate_locomotion_set(n_clips, seed=seed, fps=30.0, n_subjects=6)
    train, _, test = split_by_subject(clips, fractions=(0.75, 0.0, 0.25), seed=seed)
    poses = [np.concatenate([encode(m, "positions_control")[:, :63] for m in part]) for part in (train, test)]
    mean = poses[0].mean(0)
    scale = np.sqrt(((poses[0] - mean) ** 2).mean())
    return tuple(torch.tensor((p - mean) / scale, dtype=torch.float32) for p in poses)


def _minibatches(x: torch.Tensor, size: int, seed: int):
    """A callable returning random rows of x (N, D) -> (size, D), seeded."""
    g = torch.Generator().manual_seed(seed)
    return lambda: x[torch.randint(0, len(x), (size,), generator=g)]


def beta_sweep(x_train: torch.Tensor, x_test: torch.Tensor, betas, *, steps: int, seed: int = 0,
               z_dim: int = 2, obs_std: float = 0.1, hidden: int = 64) -> list[dict]:
    """For each beta, train a pose VAE (seeded) and return its test {'beta', 'kl', 'recon'} (nats per pose)."""
    results = []
    for beta in betas:
        seed_everything(seed)
        model = PoseVae(VaeConfig.cpu(x_dim=x_train.shape[1], z_dim=z_dim, obs_std=obs_std, hidden=hidden, beta=beta))
        fit(model, _minibatches(x_train, 128, seed), steps=steps, lr=3e-3, progress=False)
        model.eval()
        with torch.no_grad():
            out = model.loss(x_test, generator=torch.Generator().manual_seed(seed))
        results.append({"beta": float(beta), "kl": out["kl"].item(), "recon": out["recon"].item()})
    return results


# ----------------------------------------------------------------------------- self-checks


def _inputs(n=6, d=3, seed=0, dtype=torch.float64):
    g = torch.Generator().manual_seed(seed)
    return (torch.randn(n, d, generator=g, dtype=dtype), torch.randn(n, d, generator=g, dtype=dtype),
            torch.randn(n, d, generator=g, dtype=dtype))


def check_kl(fn) -> None:
    """Exercise 1: fn(mu, logvar) -> (N,) closed-form KL to N(0, I)."""
    mu, logvar, _ = _inputs()
    got, ref = fn(mu, logvar), kl_closed_form(mu, logvar)
    assert got.shape == ref.shape, f"KL should be {tuple(ref.shape)}, one value per row; got {tuple(got.shape)}"
    if not torch.allclose(got, ref, atol=1e-8):
        ratio = (got / ref).median().item()
        hint = ("your KL is 2x the reference: did you drop the 1/2?" if abs(ratio - 2) < 1e-6 else
                "your KL is minus the reference: D_KL = E_q[log q - log p], not log p - log q" if abs(ratio + 1) < 1e-6
                else "is sigma^2 exp(logvar), and did you sum over the latent dimensions?")
        raise AssertionError(f"KL values differ from the reference: {got.tolist()} vs {ref.tolist()}; {hint}")
    assert torch.allclose(fn(torch.zeros(2, 3), torch.zeros(2, 3)), torch.zeros(2)), \
        "KL(N(0,I)||N(0,I)) must be 0: check the constant -1 per dimension"
    print(f"check_kl passed: KL = {[round(v, 4) for v in got.tolist()]}")


def check_reparameterise(fn) -> None:
    """Exercise 2: fn(mu, logvar, eps) -> z, differentiable in mu and logvar."""
    mu, logvar, eps = _inputs(seed=1)
    mu.requires_grad_(True)
    logvar.requires_grad_(True)
    z = fn(mu, logvar, eps)
    ref = reparameterise(mu, logvar, eps)
    assert z.shape == ref.shape, f"z should have shape {tuple(ref.shape)}, got {tuple(z.shape)}"
    assert torch.allclose(z, ref, atol=1e-8), "z differs from sigma * eps + mu (is sigma exp(logvar / 2)?)"
    z.sum().backward()
    assert mu.grad is not None and logvar.grad is not None, "gradients must flow to mu and logvar"
    assert torch.allclose(logvar.grad, 0.5 * torch.exp(0.5 * logvar.detach()) * eps), "wrong gradient wrt logvar"
    print("check_reparameterise passed: values and gradients match eq. (3)")


def check_elbo(fn, model: PoseVae, x: torch.Tensor) -> None:
    """Exercise 3: fn(model, x, eps) -> (N,) one-sample ELBO per pose."""
    eps = torch.randn(len(x), model.config.z_dim, generator=torch.Generator().manual_seed(2), dtype=x.dtype)
    with torch.no_grad():
        got, ref = fn(model, x, eps), elbo_per_pose(model, x, eps)
        loss = model.loss(x, eps=eps)
    assert got.shape == ref.shape, f"ELBO should have shape {tuple(ref.shape)}, got {tuple(got.shape)}"
    assert torch.allclose(got, ref, rtol=1e-5, atol=1e-3), f"ELBO differs: mean {got.mean():.3f} vs {ref.mean():.3f}"
    assert torch.allclose(got.mean(), loss["elbo"], rtol=1e-5, atol=1e-3), "mean ELBO differs from model.loss"
    print(f"check_elbo passed: mean ELBO = {got.mean().item():.2f} nats per pose")


def check_iwae(fn, model: PoseVae, x: torch.Tensor, k: int = 32) -> float:
    """Exercise 3: fn(model, x (N, D), eps (K, N, z_dim)) -> (N,) importance-weighted bound.  Returns the mean
    gain of K samples over one sample, nats per pose."""
    g = torch.Generator().manual_seed(3)
    eps = torch.randn(k, len(x), model.config.z_dim, generator=g, dtype=x.dtype)
    with torch.no_grad():
        got, ref = fn(model, x, eps), iwae_bound(model, x, eps)
        one = fn(model, x, eps[:1])
        one_ref = iwae_bound(model, x, eps[:1])
    assert got.shape == ref.shape, \
        f"the bound should have shape {tuple(ref.shape)} (one value per pose), got {tuple(got.shape)}"
    assert torch.allclose(one, one_ref, rtol=1e-5, atol=1e-3), \
        f"K = 1 differs: mean {one.mean():.3f} vs {one_ref.mean():.3f} (log p(x|z) + log p(z) - log q(z|x))"
    assert torch.allclose(got, ref, rtol=1e-5, atol=1e-3), \
        f"K = {k} differs: mean {got.mean():.3f} vs {ref.mean():.3f} (logsumexp over the samples, minus log K)"
    gain = float((got - one).mean())
    print(f"check_iwae passed: K = {k} raises the bound by {gain:.2f} nats per pose over K = 1")
    return gain


def check_beta_sweep(results: list[dict], x_train, x_test, *, steps: int, seed: int = 0, rel_tol: float = 0.05,
                     **kwargs) -> None:
    """Exercise 4: results of a beta sweep (list of {'beta', 'kl', 'recon'}, increasing beta).

    Every beta is re-run with the reference ``beta_sweep`` (kwargs go to it); each KL and reconstruction
    NLL must agree within ``rel_tol`` (5 %: the recipe is given, so only the order of floating-point sums
    may differ).
    """
    betas = [r["beta"] for r in results]
    assert betas == sorted(betas) and len(betas) >= 3, "sweep at least 3 betas, in increasing order"
    kls = [r["kl"] for r in results]
    assert all(a > b for a, b in zip(kls, kls[1:], strict=False)), f"KL should fall as beta grows, got {kls}"
    refs = beta_sweep(x_train, x_test, betas, steps=steps, seed=seed, **kwargs)
    for mine, ref in zip(results, refs, strict=True):
        for key in ("kl", "recon"):
            assert math.isclose(mine[key], ref[key], rel_tol=rel_tol), (
                f"beta={mine['beta']}: your {key} {mine[key]:.3f} differs from the reference {ref[key]:.3f} by more "
                f"than {rel_tol:.0%}: same recipe (hidden 64, obs_std 0.1, batch 128, lr 3e-3, seeds 0)?")
    print(f"check_beta_sweep passed: KL falls {kls[0]:.2f} -> {kls[-1]:.2f} nats as beta goes "
          f"{betas[0]} -> {betas[-1]}; every beta within {rel_tol:.0%} of the reference")
