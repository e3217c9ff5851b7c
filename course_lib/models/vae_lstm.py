"""VAE-LSTM: the recurrent variational autoencoder of Habibie et al. 2017 (BMVC), sec. 3-4.

Taught in notebooks/02_vae_lstm.ipynb; trained by ``python -m course_lib.reproduce vae_lstm``.

A clip X_{1:T} (T = 240 frames at 60 fps, ``positions_control`` features: 63 joint positions in
the floor frame + 3 control values, normalised) is modelled as

    h^c_{1:T'} = CNN^enc_c(C_{1:T})                      control encoder (sec. 3.2), T' = T / 4
    e_{1:T'}   = CNN^enc_x(X_{1:T})                      inference network's features, eq. (6)
    mu, log sigma^2 = W_q e_t + b_q                      a linear posterior head on the pooled features
    z_t        = sigma_t * eps + mu_t                    eq. (3), one latent per pooled step
    c(t)       = RNN^dec(z_t or c(t-1), h^c_t)           modified LSTM, eq. (7)-(9)
    m_c        = [c(1) || ... || c(T')]                  motion canvas (units x T')
    X_hat      = CNN^dec(m_c)                            upsampling + conv back to T frames
    loss       = sum_t KL(q(z_t|X) || N(0, I)) - log N(X | X_hat, obs_std^2 I) + l1 sum|W|   eq. (4)-(5)

At test time (Algorithm 1) only z_1 is drawn -- from the prior N(0, I), or from the posterior
of the first 4 frames -- and the cell state is carried on by c(t) = alpha(f * W_c c(t-1) + i * W_h h^c_t).

The paper's loss trains only the first branch of eq. (9): the recursion W_c c(t-1) that Algorithm 1
runs is never trained.  ``generation_weight`` > 0
adds the ELBO of Algorithm 1's own generative path -- z_1 from the posterior of the first 4 frames,
every later cell state by the recursion -- to the paper's loss; ``kl_warmup_steps`` (KL annealing)
and ``free_bits`` are the usual collapse remedies of lesson 01, measured in lesson 02 as well.

Differs from the paper:
- the posterior head: eq. (6)'s ELU and max-pool act on the encoder's features, and a linear layer
  (2U -> 2U) reads mu and log sigma^2 from them.  The paper does not say where mu and sigma come from;
  taking them from the ELU + max-pool output itself would force every mu > -1 and every sigma > 0.61,
  a region the symmetric prior N(0, I) samples but training never uses.
- pooling: the paper says "pooling window and stride of size 1" but also 240 -> 60 steps with two
  pooling layers, which needs window = stride = 2; we use 2.
- the likelihood's standard deviation is not given in the paper; ``obs_std`` (normalised units)
  is a hyper-parameter.  The loss is summed over frames, features and steps and averaged over
  the clips of a batch (per-clip ELBO); the l1 term is added once per batch.
- the paper's dropout rate is not given; ``input_dropout`` = 0.1 on poses and controls.
- the activation alpha of eq. (9) is ELU as everywhere else in the paper.
- the paper does not say how z_1 is read from 4 initial frames; we run the inference network on
  the 4 frames padded to T by repeating the 4th (the paper pads clips with their first/last pose)
  and take the first pooled step's posterior mean.
- ``generation_weight`` > 0 adds Algorithm 1's ELBO to eq. (5), see above (the CPU preset: 1); the paper
  trains the first branch of eq. (9) only (``generation_weight`` = 0).
- ``heading_weight`` (a term on Algorithm 1's running yaw-rate error, ``heading_loss``) is ours; the CPU preset sets
  it to 100 (the path integrated from the model's own control drifts with its heading, which the per-frame
  likelihood hardly charges).  ``control_obs_std`` (a narrower likelihood on the 3 control channels) is ours too,
  off in the preset.
- ``VaeLstmConfig.cpu()`` shrinks the widths (listed there) so a model trains in minutes on a
  2-core CPU and its checkpoint stays under 5 MB; the paper trains 5000 epochs, we train minutes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import nn
from torch.nn import functional as F

from course_lib.models.vae import gaussian_kl, linear_beta

__all__ = ["ModifiedLstmCell", "VaeLstm", "VaeLstmConfig", "conv_encoder"]

LOG_2PI = math.log(2 * math.pi)


@dataclass
class VaeLstmConfig:
    """VAE-LSTM hyper-parameters; the defaults are the paper's (sec. 4.2)."""

    pose_dim: int = 63  # 21 joint positions x 3 (positions_control without the control)
    control_dim: int = 3  # forward velocity, sideways velocity, yaw rate
    enc_channels: int = 64  # first conv of the inference network: (63, 25) * 64
    latent_dim: int = 128  # z per pooled step; the inference net's last conv has 2 * 128 = 256 channels
    control_channels: int = 64  # first conv of the control encoder: (3, 25) * 64
    control_hidden: int = 128  # h^c: second conv of the control encoder (64, 25) * 128
    dec_channels: int = 128  # CNN_dec: (128, 25) * 128 then (128, 25) * 66
    kernel: int = 25  # temporal kernel of every conv (~0.4 s at 60 fps)
    pool: int = 2  # max-pool window = stride; two pools: 240 -> 60 steps (see "differs")
    input_dropout: float = 0.1  # dropout on joint positions and controls (rate not given in the paper)
    obs_std: float = 0.2  # std of the Gaussian likelihood p(X|z), normalised units (not given in the paper)
    control_obs_std: float | None = None  # the likelihood's std on the 3 control channels (None: obs_std)
    heading_weight: float = 0.0  # weight of Algorithm 1's heading term (`VaeLstm.heading_loss`; 0 = off, ours)
    l1: float = 0.1  # l1 weight regularisation (sec. 4.2)
    lr: float = 5e-4  # Adam learning rate (sec. 4.2); our short CPU runs use 1e-3 (experiments.vae_lstm)
    clip_length: int = 240  # frames per training clip (4 s at 60 fps)
    init_frames: int = 4  # frames that determine the first pooled step (pool ** 2)
    generation_weight: float = 0.0  # weight of Algorithm 1's ELBO added to eq. (5) (0 = the paper's loss)
    kl_warmup_steps: int = 0  # KL annealing: the KL weight grows linearly 0 -> 1 over these steps (0 = off)
    free_bits: float = 0.0  # nats per latent dim and pooled step that the KL does not charge (0 = off)
    z1_canvas: bool = False  # every canvas column also carries z_1 (m_c(t) = [c(t) || z_1]; ours, off: the paper's)

    @property
    def units(self) -> int:
        """LSTM units = latent size: the cell state is set to W_c z_t during training (eq. 9)."""
        return self.latent_dim

    @property
    def dim(self) -> int:
        return self.pose_dim + self.control_dim

    @classmethod
    def cpu(cls, **overrides) -> VaeLstmConfig:
        """The CPU preset: widths 64->32 (enc), 128->64 (latent/LSTM), 64->32 and 128->64 (control),
        128->64 (decoder), l1 0.1 -> 1e-4 (with our per-clip sums 0.1 dominates the loss at this size),
        generation_weight 0 -> 1 (Algorithm 1's path trained too), heading_weight 0 -> 100 (a term on
        Algorithm 1's heading drift, ours)."""
        return cls(**{"enc_channels": 32, "latent_dim": 64, "control_channels": 32, "control_hidden": 64,
                      "dec_channels": 64, "l1": 1e-4, "generation_weight": 1.0, "heading_weight": 100.0,
                      **overrides})

    def __post_init__(self):
        sizes = (self.pose_dim, self.control_dim, self.enc_channels, self.latent_dim, self.control_channels,
                 self.control_hidden, self.dec_channels, self.kernel, self.pool)
        if min(sizes) < 1:
            raise ValueError(f"VaeLstmConfig: sizes must be positive, got {self}")
        if self.kernel % 2 == 0:
            raise ValueError(f"VaeLstmConfig: kernel must be odd (same-length convs), got {self.kernel}")
        if self.clip_length % (self.pool ** 2):
            raise ValueError(f"VaeLstmConfig: clip_length {self.clip_length} must be divisible by pool^2")
        if self.control_obs_std is not None and self.control_obs_std <= 0:
            raise ValueError(f"VaeLstmConfig: control_obs_std must be > 0 or None, got {self.control_obs_std}")
        if self.obs_std <= 0 or self.l1 < 0 or not 0 <= self.input_dropout < 1:
            raise ValueError(f"VaeLstmConfig: need obs_std > 0, l1 >= 0, 0 <= input_dropout < 1: {self}")
        if self.heading_weight < 0 or (self.heading_weight and not self.generation_weight):
            raise ValueError(f"VaeLstmConfig: heading_weight must be >= 0 and needs generation_weight > 0: {self}")
        if self.generation_weight < 0 or self.kl_warmup_steps < 0 or self.free_bits < 0:
            raise ValueError(f"VaeLstmConfig: generation_weight, kl_warmup_steps, free_bits must be >= 0: {self}")


# ----------------------------------------------------------------------------- building blocks


def conv_encoder(in_dim: int, hidden: int, out_dim: int, kernel: int, pool: int) -> nn.Sequential:
    """CNN^enc of eq. (6): Psi(alpha(Psi(alpha(X * W_0 + b_0)) * W_1 + b_1)).

    Input (N, in_dim, T) -> (N, out_dim, T / pool^2); alpha = ELU, Psi = max-pool.
    """
    pad = kernel // 2
    return nn.Sequential(nn.Conv1d(in_dim, hidden, kernel, padding=pad), nn.ELU(), nn.MaxPool1d(pool),
                         nn.Conv1d(hidden, out_dim, kernel, padding=pad), nn.ELU(), nn.MaxPool1d(pool))


def conv_decoder(units: int, hidden: int, out_dim: int, kernel: int, pool: int) -> nn.Sequential:
    """CNN^dec (sec. 3.3): upsampling + conv, twice.  (N, units, T') -> (N, out_dim, T' * pool^2)."""
    pad = kernel // 2
    return nn.Sequential(nn.Upsample(scale_factor=pool, mode="linear", align_corners=False),
                         nn.Conv1d(units, hidden, kernel, padding=pad), nn.ELU(),
                         nn.Upsample(scale_factor=pool, mode="linear", align_corners=False),
                         nn.Conv1d(hidden, out_dim, kernel, padding=pad))


class ModifiedLstmCell(nn.Module):
    """The modified LSTM cell of eq. (7)-(9): no output gate, the cell state is the output.

    c_prev: (N, U) c(t-1), h_c: (N, H) control code h^c_t, z: (N, U) z_t or None -> c(t): (N, U).
    With z (training) the candidate is W_c z_t; without (test time) it is W_c c(t-1).
    """

    def __init__(self, units: int, control_hidden: int):
        super().__init__()
        self.W_ic, self.W_ih = nn.Linear(units, units), nn.Linear(control_hidden, units)
        self.W_fc, self.W_fh = nn.Linear(units, units), nn.Linear(control_hidden, units)
        self.W_c = nn.Linear(units, units, bias=False)
        self.W_h = nn.Linear(control_hidden, units, bias=False)

    def forward(self, c_prev: torch.Tensor, h_c: torch.Tensor, z: torch.Tensor | None = None) -> torch.Tensor:
        # i(t) = s((W_ic c_{t-1} + b_ic) + (W_ih h^c_t + b_ih))                      -- eq. (7)
        i = torch.sigmoid(self.W_ic(c_prev) + self.W_ih(h_c))
        # f(t) = s((W_fc c_{t-1} + b_fc) + (W_fh h^c_t + b_fh))                      -- eq. (8)
        f = torch.sigmoid(self.W_fc(c_prev) + self.W_fh(h_c))
        # c(t) = alpha(f * W_c z_t + i * W_h h^c_t)  (training)                      -- eq. (9)
        # c(t) = alpha(f * W_c c_{t-1} + i * W_h h^c_t)  (test time)
        source = z if z is not None else c_prev
        return F.elu(f * self.W_c(source) + i * self.W_h(h_c))


# ----------------------------------------------------------------------------- the model


class VaeLstm(nn.Module):
    """Habibie et al. 2017.  Features are normalised ``positions_control`` clips (N, T, 66)."""

    def __init__(self, config: VaeLstmConfig | None = None):
        super().__init__()
        self.config = c = config or VaeLstmConfig()
        self.dropout = nn.Dropout(c.input_dropout)
        self.inference = conv_encoder(c.pose_dim, c.enc_channels, 2 * c.latent_dim, c.kernel, c.pool)
        self.posterior_head = nn.Linear(2 * c.latent_dim, 2 * c.latent_dim)  # e_t -> (mu_t, log sigma_t^2)
        self.control_encoder = conv_encoder(c.control_dim, c.control_channels, c.control_hidden, c.kernel, c.pool)
        self.cell = ModifiedLstmCell(c.units, c.control_hidden)
        self.decoder = conv_decoder(c.units * (2 if c.z1_canvas else 1), c.dec_channels, c.dim, c.kernel, c.pool)
        # optimiser steps taken (drives the KL annealing); not saved: a schedule only matters in training
        self.register_buffer("num_updates", torch.zeros((), dtype=torch.long), persistent=False)

    # --- shapes ---------------------------------------------------------------------------

    def _check(self, x: torch.Tensor, dim: int, name: str) -> None:
        if x.ndim != 3 or x.shape[-1] != dim:
            raise ValueError(f"{name} must be (N, T, {dim}), got {tuple(x.shape)}")
        step = self.config.pool ** 2
        if x.shape[1] < step or x.shape[1] % step:
            raise ValueError(f"{name}: T = {x.shape[1]} frames must be a positive multiple of {step} (pool^2)")
        if not torch.isfinite(x).all():
            raise ValueError(f"{name} contains NaN or inf")

    # --- the pieces -----------------------------------------------------------------------

    def encode(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """x: (N, T, 66) -> posterior mu, logvar: (N, T', latent) with T' = T / pool^2 (eq. 6)."""
        self._check(x, self.config.dim, "x")
        pose = self.dropout(x[..., : self.config.pose_dim])
        e = self.inference(pose.transpose(1, 2)).transpose(1, 2)  # (N, T', 2 * latent) features, eq. (6)
        mu, logvar = self.posterior_head(e).chunk(2, dim=-1)  # linear: mu and log sigma^2 take any sign
        return mu, logvar.clamp(-12.0, 8.0)

    def encode_control(self, control: torch.Tensor) -> torch.Tensor:
        """control: (N, T, 3) -> h^c: (N, T', control_hidden)."""
        self._check(control, self.config.control_dim, "control")
        return self.control_encoder(self.dropout(control).transpose(1, 2)).transpose(1, 2)

    def run_decoder(self, h_c: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        """RNN^dec: h^c (N, T', H) and z (N, T', U) (training: every step) or (N, U) (test: z_1 only)
        -> motion canvas m_c: (N, U, T') of the cell states c(1..T') ((N, 2U, T') with z_1 beside each, z1_canvas)."""
        N, Tp, _ = h_c.shape
        c = h_c.new_zeros(N, self.config.units)  # c(0) = 0
        cells = []
        for t in range(Tp):
            if z.ndim == 3:
                c = self.cell(c, h_c[:, t], z[:, t])  # training: candidate from z_t
            elif t == 0:
                c = self.cell(c, h_c[:, 0], z)  # c(1) = RNN^dec(z_1, h^c_1)
            else:
                c = self.cell(c, h_c[:, t])  # c(t) = RNN^dec(c(t-1), h^c_t)
            cells.append(c)
        canvas = torch.stack(cells, dim=-1)  # m_c = [c(1) || ... || c(T')]
        if self.config.z1_canvas:  # each column also carries z_1, which the recursion alone forgets
            z1 = z[:, 0] if z.ndim == 3 else z
            canvas = torch.cat((canvas, z1[..., None].expand(-1, -1, Tp)), 1)
        return canvas

    def decode(self, canvas: torch.Tensor) -> torch.Tensor:
        """m_c: (N, U, T') -> X_hat: (N, T' pool^2, 66) (CNN^dec)."""
        return self.decoder(canvas).transpose(1, 2)

    # --- training -------------------------------------------------------------------------

    def forward(self, x: torch.Tensor, eps: torch.Tensor | None = None) -> dict:
        """x: (N, T, 66) -> {"x_hat": (N, T, 66), "mu", "logvar", "z": (N, T', U), "h_c": (N, T', H)}
        (the training branch of eq. 9)."""
        mu, logvar = self.encode(x)
        eps = torch.randn_like(mu) if eps is None else eps
        z = mu + torch.exp(0.5 * logvar) * eps  # eq. (3)
        h_c = self.encode_control(x[..., self.config.pose_dim:])
        return {"x_hat": self.decode(self.run_decoder(h_c, z)), "mu": mu, "logvar": logvar, "z": z, "h_c": h_c}

    def l1_penalty(self) -> torch.Tensor:
        """sum |W| over every weight matrix / kernel (biases excluded)."""
        return sum(p.abs().sum() for name, p in self.named_parameters() if p.ndim > 1)

    def nll(self, x: torch.Tensor, x_hat: torch.Tensor) -> torch.Tensor:
        """L_x = -log N(X | X_hat, diag(obs_std^2)): x, x_hat (N, T, 66) -> summed over frames and features,
        averaged over clips (scalar).  The 3 control channels use ``control_obs_std`` when it is set."""
        c = self.config
        std = x.new_full((x.shape[-1],), c.obs_std)
        if c.control_obs_std is not None:
            std[c.pose_dim:] = c.control_obs_std
        var = std ** 2
        return 0.5 * (((x - x_hat) ** 2) / var + torch.log(var) + LOG_2PI).sum() / x.shape[0]

    def heading_loss(self, x: torch.Tensor, x_hat: torch.Tensor) -> torch.Tensor:
        """The heading term: the yaw-rate output's error summed from the first frame (the heading error, up to the
        yaw rate's std and the frame rate), divided by the frames so far (the running mean error, sd units), as a
        Gaussian of std obs_std on every frame: x, x_hat (N, T, 66) -> summed over frames, averaged over clips.
        The per-frame likelihood charges a slow yaw-rate error little; the path integrates it (lesson 02, sec. 9)."""
        t = torch.arange(1, x.shape[1] + 1, dtype=x.dtype, device=x.device)
        running = torch.cumsum(x_hat[..., -1] - x[..., -1], dim=1) / t
        return 0.5 * (running ** 2).sum() / self.config.obs_std ** 2 / x.shape[0]

    def kl_weight(self) -> float:
        """The KL weight now: 1 (the ELBO), or linear from 0 over ``kl_warmup_steps`` (KL annealing)."""
        c = self.config
        return linear_beta(int(self.num_updates), c.kl_warmup_steps) if c.kl_warmup_steps else 1.0

    def kl_penalty(self, kl: torch.Tensor) -> torch.Tensor:
        """kl: (N, ..., D) per clip, step and dim -> the charged KL (scalar, per clip): with free bits
        each (step, dim)'s batch-mean KL below ``free_bits`` nats is free (Kingma et al. 2016)."""
        if not self.config.free_bits:
            return kl.sum() / kl.shape[0]
        return kl.mean(0).clamp(min=self.config.free_bits).sum()

    def generation_elbo(self, x: torch.Tensor, h_c: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Algorithm 1's path, trained: z_1 ~ q(z_1 | X_{1:4}) (reparameterised), c(t) = RNN^dec(c(t-1), h^c_t)
        -> (nll, kl per clip (N, U), x_hat (N, T, 66))."""
        mu1, logvar1 = self.initial_posterior(x[:, : self.config.init_frames], x.shape[1])
        z1 = mu1 + torch.exp(0.5 * logvar1) * torch.randn_like(mu1)  # eq. (3)
        x_gen = self.decode(self.run_decoder(h_c, z1))
        return self.nll(x, x_gen), gaussian_kl(mu1, logvar1), x_gen

    def loss(self, batch) -> dict:
        """batch: (N, T, 66) or {"x": ...} -> {"loss", "nll", "kl", "kl_per_dim" (U,), "l1", "mse", and with
        generation_weight > 0 "gen_nll", "gen_kl", "gen_mse"} (eq. 4-5 + l1 + Algorithm 1's ELBO)."""
        x = batch["x"] if isinstance(batch, dict) else batch
        c = self.config
        out = self(x)
        nll = self.nll(x, out["x_hat"])
        # L_z = sum_t KL(q(z_t | X) || N(0, I))                                     -- eq. (4)
        kl_all = gaussian_kl(out["mu"], out["logvar"])  # (N, T', U)
        kl = kl_all.sum() / x.shape[0]
        beta, l1 = self.kl_weight(), self.l1_penalty()
        loss = nll + beta * self.kl_penalty(kl_all) + c.l1 * l1  # eq. (5) + l1 regularisation (sec. 4.2)
        logs = {"nll": nll.detach(), "kl": kl.detach(), "kl_per_dim": kl_all.mean((0, 1)).detach(),
                "l1": l1.detach(), "mse": F.mse_loss(out["x_hat"], x).detach(), "beta": beta}
        if c.generation_weight:
            gen_nll, gen_kl, x_gen = self.generation_elbo(x, out["h_c"])
            loss = loss + c.generation_weight * (gen_nll + beta * self.kl_penalty(gen_kl))
            logs.update(gen_nll=gen_nll.detach(), gen_kl=(gen_kl.sum() / x.shape[0]).detach(),
                        gen_mse=F.mse_loss(x_gen, x).detach())
            if c.heading_weight:
                heading = self.heading_loss(x, x_gen)
                loss = loss + c.heading_weight * heading
                logs["heading"] = heading.detach()
        if self.training:
            self.num_updates += 1
        return {"loss": loss, **logs}

    # --- synthesis (Algorithm 1) -----------------------------------------------------------

    @torch.no_grad()
    def generate(self, control: torch.Tensor, z1: torch.Tensor | None = None,
                 generator: torch.Generator | None = None, per_step: bool = False) -> torch.Tensor:
        """Algorithm 1.  control: (N, T, 3) normalised C_{1:T}; z1: (N, U) or None (z_1 ~ N(0, I))
        -> X_hat: (N, T, 66).  Only z_1 is used; later cell states come from W_c c(t-1).

        per_step: instead draw z_t ~ N(0, I) for every pooled step and run the training branch of
        eq. (9) (the alternative the paper mentions in sec. 3.3); z1 must then be None."""
        h_c = self.encode_control(control)  # h^c_{1:T} = CNN^enc(C_{1:T})
        if per_step:
            if z1 is not None:
                raise ValueError("generate: per_step=True draws every z_t from the prior; pass z1=None")
            z = torch.randn(*h_c.shape[:2], self.config.units, generator=generator)  # z_t ~ N(0, I)
            return self.decode(self.run_decoder(h_c, z))
        if z1 is None:
            z1 = torch.randn(control.shape[0], self.config.units, generator=generator)  # z_1 ~ N(0, I)
        if z1.shape != (control.shape[0], self.config.units):
            raise ValueError(f"z1 must be ({control.shape[0]}, {self.config.units}), got {tuple(z1.shape)}")
        return self.decode(self.run_decoder(h_c, z1))  # X_hat = CNN^dec(m_c(T))

    def initial_posterior(self, x_init: torch.Tensor, length: int) -> tuple[torch.Tensor, torch.Tensor]:
        """x_init: (N, n, 66) first frames (n >= init_frames) -> mu, logvar (N, U) of z_1: the inference
        network on the frames padded to ``length`` with the last one, its first pooled step."""
        n = x_init.shape[1] if x_init.ndim == 3 else 0
        if n < self.config.init_frames:
            raise ValueError(f"x_init must be (N, >= {self.config.init_frames}, 66), got {tuple(x_init.shape)}")
        pad = x_init[:, -1:].expand(-1, length - n, -1)
        mu, logvar = self.encode(torch.cat((x_init, pad), 1))
        return mu[:, 0], logvar[:, 0]

    @torch.no_grad()
    def posterior_z1(self, x_init: torch.Tensor, length: int, sample: bool = False,
                     generator: torch.Generator | None = None) -> torch.Tensor:
        """x_init: (N, n, 66) first frames (n >= init_frames) -> z_1: (N, U), the posterior of the first
        pooled step (mean, or a sample if ``sample``), the clip padded to ``length`` with its last frame."""
        mu, logvar = self.initial_posterior(x_init, length)
        if not sample:
            return mu
        return mu + torch.exp(0.5 * logvar) * torch.randn(mu.shape, generator=generator)

    @torch.no_grad()
    def predict(self, x_init: torch.Tensor, control: torch.Tensor, per_step: bool = False,
                generator: torch.Generator | None = None) -> torch.Tensor:
        """Synthesis from initial frames: x_init (N, 4, 66), control (N, T, 3) -> (N, T, 66); z_1 is the
        posterior mean of the initial frames (Table 1, "VAE-LSTM, 4 initial frames").  Algorithm 1, or with
        ``per_step`` the z-every-step sampler with z_2, z_3, ... drawn from the prior: the same draws as
        ``generate(control, generator=g, per_step=True)`` for a generator in the same state, z_1 excepted."""
        z1 = self.posterior_z1(x_init[:, : self.config.init_frames], control.shape[1])
        if not per_step:
            return self.generate(control, z1)
        h_c = self.encode_control(control)
        z = torch.randn(*h_c.shape[:2], self.config.units, generator=generator)  # generate's per-step draws
        z[:, 0] = z1  # the first pooled step's latent from the 4 frames, the rest from the prior
        return self.decode(self.run_decoder(h_c, z))
