"""Pose VAE and conditional pose VAE: the variational autoencoder of Habibie et al. 2017, sec. 3.1.

Taught in notebooks/01_vae_basics.ipynb (the JAX twin is ``course_lib/models/jax_vae.py``).

One pose x (the 63 joint positions of ``positions_control``, in the floor-projected root
frame, normalised per feature) is encoded to a diagonal Gaussian posterior
q(z|x) = N(mu(x), diag sigma^2(x)) with a unit Gaussian prior p(z) = N(0, I), and decoded
by p(x|z) = N(f(z), obs_std^2 I).  Training maximises the ELBO (eq. 1-2) with one
reparameterised sample z = sigma * eps + mu (eq. 3).

Differs from the paper:
- single poses and MLPs instead of sequences, 1-D convolutions and an LSTM (that is lesson 02);
- the likelihood's standard deviation ``obs_std`` is a fixed hyper-parameter (the paper leaves
  it implicit); it sets the trade-off between reconstruction and KL just like beta;
- beta, KL annealing (linear, cyclical: Fu et al. 2019) and free bits (Kingma et al. 2016)
  are added to show and cure posterior collapse; the paper uses plain beta = 1;
- ``skip_noise``: an optional decoder input, a noisy copy of x, that makes the decoder so
  strong that z becomes useless (the posterior-collapse demonstration); off by default.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import nn
from torch.nn import functional as F

__all__ = ["PoseVae", "VaeConfig", "cyclical_beta", "gaussian_kl", "gaussian_nll", "linear_beta", "mc_kl"]

LOG_2PI = math.log(2 * math.pi)


@dataclass
class VaeConfig:
    """Pose VAE hyper-parameters; ``VaeConfig.cpu()`` is the small preset the notebook trains live."""

    x_dim: int = 63  # pose features: 21 joints x 3 (positions_control without its 3 control values)
    z_dim: int = 2  # latent size; 2 lets us draw the latent space, 16 reconstructs better
    hidden: int = 256  # width of every hidden layer of encoder and decoder
    layers: int = 2  # hidden layers in the encoder and (separately) in the decoder
    n_labels: int = 0  # > 0: conditional VAE on a one-hot label (gait / action), fed to both nets
    obs_std: float = 0.1  # std of p(x|z) in normalised units; smaller = sharper reconstructions, more KL
    beta: float = 1.0  # weight of the KL term (1 = the ELBO of eq. 2; beta-VAE otherwise)
    kl_schedule: str = "constant"  # "constant" | "linear" (warm-up) | "cyclical" (Fu et al. 2019)
    kl_warmup_steps: int = 1000  # linear: steps from beta=0 to beta; cyclical: length of one cycle
    kl_cycle_ramp: float = 0.5  # cyclical: fraction of each cycle spent ramping up (rest at beta)
    free_bits: float = 0.0  # nats per latent dim that cost nothing (Kingma et al. 2016); 0 = off
    skip_noise: float = 0.0  # > 0: decoder also sees x + skip_noise * noise (collapse demo); 0 = off

    @classmethod
    def cpu(cls, **overrides) -> VaeConfig:
        """The small preset trained live in the notebook (a few seconds per 1000 steps on a laptop)."""
        return cls(**{"hidden": 128, "layers": 2, "z_dim": 2, **overrides})

    def __post_init__(self):
        if self.kl_schedule not in ("constant", "linear", "cyclical"):
            raise ValueError(f"kl_schedule must be constant|linear|cyclical, got {self.kl_schedule!r}")
        if self.x_dim < 1 or self.z_dim < 1 or self.hidden < 1 or self.layers < 1:
            raise ValueError(f"sizes must be positive: {self}")
        if self.obs_std <= 0:
            raise ValueError(f"obs_std must be > 0, got {self.obs_std}")


# ----------------------------------------------------------------------------- the formulas


def gaussian_kl(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """KL(N(mu, diag e^logvar) || N(0, I)) per dimension, in closed form.  mu, logvar: (..., D) -> (..., D).

    KL_d = 1/2 (mu_d^2 + sigma_d^2 - log sigma_d^2 - 1)      -- the KL term of Habibie eq. (2)
    """
    if mu.shape != logvar.shape:
        raise ValueError(f"mu {tuple(mu.shape)} and logvar {tuple(logvar.shape)} must have the same shape")
    return 0.5 * (mu.pow(2) + logvar.exp() - logvar - 1.0)


def mc_kl(mu: torch.Tensor, logvar: torch.Tensor, n_samples: int = 1, eps: torch.Tensor | None = None,
          generator: torch.Generator | None = None) -> torch.Tensor:
    """Monte-Carlo KL estimate, mean over samples of log q(z|x) - log p(z).  mu, logvar: (..., D) -> (...).

    eps: optional (n_samples, ..., D) standard normal noise (drawn from ``generator`` otherwise).
    """
    if eps is None:
        eps = torch.randn((n_samples, *mu.shape), generator=generator, dtype=mu.dtype)
    if eps.shape[1:] != mu.shape:
        raise ValueError(f"eps {tuple(eps.shape)} must be (n_samples, *{tuple(mu.shape)})")
    z = mu + (0.5 * logvar).exp() * eps  # eq. (3)
    log_q = -0.5 * (eps.pow(2) + logvar + LOG_2PI).sum(-1)  # log N(z; mu, sigma^2), (z-mu)/sigma = eps
    log_p = -0.5 * (z.pow(2) + LOG_2PI).sum(-1)
    return (log_q - log_p).mean(0)


def gaussian_nll(x: torch.Tensor, x_hat: torch.Tensor, std: float) -> torch.Tensor:
    """-log N(x; x_hat, std^2 I) summed over features.  x, x_hat: (N, D) -> (N,)."""
    return 0.5 * (((x - x_hat) / std).pow(2) + 2 * math.log(std) + LOG_2PI).sum(-1)


def linear_beta(step: int, warmup_steps: int, beta_max: float = 1.0) -> float:
    """KL warm-up (Bowman et al. 2016): beta grows linearly from 0 to beta_max in warmup_steps."""
    return beta_max * min(1.0, step / max(1, warmup_steps))


def cyclical_beta(step: int, cycle_steps: int, beta_max: float = 1.0, ramp: float = 0.5) -> float:
    """Cyclical annealing (Fu et al. 2019): each cycle ramps 0 -> beta_max over ``ramp`` of it, then holds."""
    phase = (step % max(1, cycle_steps)) / max(1, cycle_steps)
    return beta_max * min(1.0, phase / ramp)


def _mlp(d_in: int, hidden: int, layers: int, d_out: int) -> nn.Sequential:
    mods, d = [], d_in
    for _ in range(layers):
        mods += [nn.Linear(d, hidden), nn.SiLU()]
        d = hidden
    return nn.Sequential(*mods, nn.Linear(d, d_out))


# ----------------------------------------------------------------------------- the model


class PoseVae(nn.Module):
    """VAE on single poses; conditional (CVAE) when ``config.n_labels > 0``.

    Batches given to :meth:`loss` are ``x`` (N, x_dim) or ``(x, label)`` with label (N,) int64.
    """

    def __init__(self, config: VaeConfig):
        super().__init__()
        self.config = c = config
        skip = c.x_dim if c.skip_noise > 0 else 0
        self.encoder = _mlp(c.x_dim + c.n_labels, c.hidden, c.layers, 2 * c.z_dim)  # -> [mu, logvar]
        self.decoder = _mlp(c.z_dim + c.n_labels + skip, c.hidden, c.layers, c.x_dim)  # -> mean of p(x|z)
        self.register_buffer("num_updates", torch.zeros((), dtype=torch.long))  # drives the KL schedule

    # -- pieces ---------------------------------------------------------------------------------
    def _onehot(self, label, n: int) -> torch.Tensor | None:
        c = self.config
        if c.n_labels == 0:
            if label is not None:
                raise ValueError("this VAE is unconditional (n_labels=0) but a label was given")
            return None
        if label is None:
            raise ValueError(f"this is a conditional VAE (n_labels={c.n_labels}): pass label=")
        label = torch.as_tensor(label, dtype=torch.long).expand(n) if torch.as_tensor(label).ndim == 0 else label
        if label.shape != (n,) or label.min() < 0 or label.max() >= c.n_labels:
            raise ValueError(f"label must be (N={n},) ints in [0, {c.n_labels}), got {tuple(label.shape)}")
        return F.one_hot(label.long(), c.n_labels).to(self.encoder[0].weight.dtype)

    def _check_x(self, x: torch.Tensor) -> None:
        if x.ndim != 2 or x.shape[1] != self.config.x_dim:
            raise ValueError(f"x must be (N, {self.config.x_dim}) poses, got {tuple(x.shape)}")
        if not torch.isfinite(x).all():
            raise ValueError("x contains NaN or inf")

    def encode(self, x: torch.Tensor, label=None) -> tuple[torch.Tensor, torch.Tensor]:
        """x: (N, x_dim) -> mu, logvar: (N, z_dim), the parameters of q(z|x)."""
        self._check_x(x)
        y = self._onehot(label, len(x))
        h = self.encoder(x if y is None else torch.cat([x, y], -1))  # (N, 2 z_dim)
        mu, logvar = h.chunk(2, dim=-1)
        return mu, logvar

    @staticmethod
    def reparameterise(mu, logvar, eps=None, generator=None) -> torch.Tensor:
        """z = sigma * eps + mu, eps ~ N(0, I)   -- Habibie eq. (3).  (N, D) -> (N, D)."""
        if eps is None:
            eps = torch.randn(mu.shape, generator=generator, dtype=mu.dtype)
        if eps.shape != mu.shape:
            raise ValueError(f"eps must be {tuple(mu.shape)}, got {tuple(eps.shape)}")
        return (0.5 * logvar).exp() * eps + mu

    def decode(self, z: torch.Tensor, label=None, x_noisy: torch.Tensor | None = None) -> torch.Tensor:
        """z: (N, z_dim) -> mean of p(x|z): (N, x_dim).  x_noisy: (N, x_dim), only for skip_noise > 0."""
        if z.ndim != 2 or z.shape[1] != self.config.z_dim:
            raise ValueError(f"z must be (N, {self.config.z_dim}), got {tuple(z.shape)}")
        parts = [z]
        y = self._onehot(label, len(z))
        if y is not None:
            parts.append(y)
        if self.config.skip_noise > 0:
            if x_noisy is None:
                raise ValueError("skip_noise > 0: this decoder also needs x_noisy (a noisy copy of the pose)")
            parts.append(x_noisy)
        return self.decoder(torch.cat(parts, -1))

    def beta_now(self) -> float:
        """The KL weight at the current training step (constant, linear warm-up or cyclical)."""
        c, step = self.config, int(self.num_updates)
        if c.kl_schedule == "linear":
            return linear_beta(step, c.kl_warmup_steps, c.beta)
        if c.kl_schedule == "cyclical":
            return cyclical_beta(step, c.kl_warmup_steps, c.beta, c.kl_cycle_ramp)
        return c.beta

    # -- the objective ----------------------------------------------------------------------------
    def loss(self, batch, eps: torch.Tensor | None = None, generator: torch.Generator | None = None,
             skip_eps: torch.Tensor | None = None) -> dict:
        """Negative (beta-weighted, free-bits) ELBO of a batch, and its terms (all means over the batch).

        batch: x (N, x_dim) or (x, label).  eps: (N, z_dim) reparameterisation noise; skip_eps: (N, x_dim)
        noise of the decoder's noisy copy.  Returns loss, recon (NLL), kl, kl_per_dim (z_dim,), elbo, beta.
        """
        x, label = batch if isinstance(batch, (tuple, list)) else (batch, None)
        mu, logvar = self.encode(x, label)
        z = self.reparameterise(mu, logvar, eps, generator)  # eq. (3)
        x_noisy = None
        if self.config.skip_noise > 0:
            noise = skip_eps if skip_eps is not None else torch.randn(x.shape, generator=generator, dtype=x.dtype)
            x_noisy = x + self.config.skip_noise * noise
        x_hat = self.decode(z, label, x_noisy)
        recon = gaussian_nll(x, x_hat, self.config.obs_std).mean()  # -E_q[log p(x|z)], one sample (eq. 5)
        kl_per_dim = gaussian_kl(mu, logvar).mean(0)  # (z_dim,) closed form
        kl = kl_per_dim.sum()
        # free bits: dims with KL below lambda are not penalised (Kingma et al. 2016, eq. in sec. C.8)
        kl_penalty = kl_per_dim.clamp(min=self.config.free_bits).sum() if self.config.free_bits > 0 else kl
        beta = self.beta_now()
        if self.training:
            self.num_updates += 1
        return {"loss": recon + beta * kl_penalty, "recon": recon, "kl": kl, "kl_per_dim": kl_per_dim,
                "elbo": -(recon + kl), "beta": beta}  # eq. (2): ELBO = -KL + E_q[log p(x|z)]

    @torch.no_grad()
    def reconstruct(self, x: torch.Tensor, label=None) -> torch.Tensor:
        """Decode the posterior mean: x (N, x_dim) -> (N, x_dim).  (skip_noise models get x itself as copy.)"""
        mu, _ = self.encode(x, label)
        return self.decode(mu, label, x if self.config.skip_noise > 0 else None)

    @torch.no_grad()
    def sample(self, n: int, label=None, generator: torch.Generator | None = None,
               z: torch.Tensor | None = None) -> torch.Tensor:
        """n poses from the prior: z ~ N(0, I), x = f(z).  -> (n, x_dim) normalised features."""
        if self.config.skip_noise > 0:
            raise ValueError("a skip_noise decoder cannot sample from the prior alone (it needs a noisy pose)")
        if z is None:
            z = torch.randn((n, self.config.z_dim), generator=generator, dtype=self.encoder[0].weight.dtype)
        return self.decode(z, label)
