"""GMM-RNN: the contact-aware generative RNN of Wang, Chai et al. 2021 (IEEE TVCG 27(1)), sec. 4.1 and 4.3.

Taught in notebooks/03_gmm_rnn_refiner.ipynb.

A motion is a sequence of ``state_features`` x_t (representations.py, eq. 3: dx, dz, dyaw in the
previous frame's floor frame, root height, pitch, roll, 20 x 3 expmap joint angles, 2 contact bits;
68 values, normalised by the dataset's mean/std).  The network of Fig. 3 predicts the next frame's
distribution:

    h_t          = LSTM2(LSTM1(relu(FC2(relu(FC1(x_t))))))         Fig. 3, eq. (5)
    w, mu, sigma = transform(FC_out(relu(FC3(h_t))))               eq. (7): softmax weights, exp std
    p(x_{t+1})   = sum_i w_i N(x_{t+1} | mu_i, diag(sigma_i^2))     eq. (6), M = 5
    E            = -log p(x_{t+1} | x_t, h_t, C_t)                  eq. (8), computed with logsumexp

Training (sec. 4.1.2-4.1.3): teacher forcing on 50-frame windows at 30 fps, i.i.d. Gaussian input noise
(sd 0.05), RMSProp at lr 1e-3 x 0.95 per epoch, batch 20, every gradient entry clipped to [-5, 5].
Generation (sec. 4.1.4): run the two initial frames through the network, then sample the mixture
each step and feed the sample back; `sample_step` carries the LSTM state, so generation can go on
for as long as wanted.  Decode with ``representations.decode_state_features`` (eq. 4).

Differs from the paper (the defaults are the paper's unless a line says otherwise):
- sigma = exp(max(sigma_hat, log(min_std))), min_std = 0.01 normalised units (the paper: no floor): the
  contact bits take two values only, so without a floor the NLL of eq. (8) is unbounded below.
- FC1-FC3 use ReLU (the paper gives no activation); FC3 is followed by a linear read-out to the M + 2 M D
  mixture parameters (Fig. 3's "Output(425)" = 5 + 2 * 5 * 42).
- the gradient clip of sec. 4.1.2 is a hook on each parameter (``grad_clip_value``), so the course's ``fit``
  (which only clips by norm) runs with ``grad_clip=None``.
- a sample's contact bits are thresholded at 0.5 in raw units before being fed back, so they stay binary as in
  the data (``contact_mode="clamp"`` clamps to [0, 1], ``"none"`` keeps the raw sample).
- ``GmmRnnConfig.cpu()``: widths 500 -> 128 (lesson 03 trains at 256) and residual means, to train in minutes
  on a CPU; the paper pre-trains on CMU and fine-tunes (sec. 4.1.3), we train once on the course data.
- ``residual=True``: mu_i = x_t + mu_hat_i, except in ``absolute_dims``.  Lesson 03 keeps dyaw and the joint
  angles residual and the slip, toe height, pitch and roll absolute: absolute angles, predicted afresh each
  frame, made the feet skate.
- ``features="feet_anchored"`` (lesson 03's): the root's floor step read as the anchor toe's slip and the root
  height as the lower toe's height (representations.anchor_on_feet), so a planted foot stays planted whatever
  pose is predicted.  The model keeps the normalisation of the features it reads (``feature_mean``,
  ``feature_std`` buffers, saved with the weights).
- ``fixed_dims``: columns the training data never vary (the knees' and elbows' off-axis angles, ...) are left out
  of eq. (8) and copied from x_t when sampling: at the sigma floor they dominated the NLL, which then said little
  about the pose.
- ``bernoulli_contacts``: the contact bits get their own Bernoulli head (two log-odds beside the mixture)
  instead of Gaussians with a sigma floor; samples are 0/1.
- ``self_feed=(k, m)`` (optional fine-tuning): inputs alternate k true frames and m of the model's own
  predictions, so that it learns to return from its own errors (acLSTM, Zhou et al. 2018).
- at sampling: ``bias`` (Graves 2013; 0 is the paper's sampling) sharpens the weights and narrows the sigmas;
  ``noise_scale`` scales each column's draw around the chosen mean (lesson 03: 0.3 on the joint angles);
  ``limits`` clamp each sampled column to a stored [low, high], a joint limit such as a rig has (lesson 03: the
  training data's range, `set_limits`), so that residual angles cannot drift until the pose folds.
studies/03_gmm_rnn_refiner/README.md measures lesson 03's choices (anchored features, residual means, input noise,
angle noise scale, widths, joint limits).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from course_lib.models.lstm_step import lstm_step

__all__ = ["GmmRnn", "GmmRnnConfig", "mixture_log_prob"]

LOG_2PI = math.log(2 * math.pi)
CONTACT_MODES = ("threshold", "clamp", "none")


@dataclass
class GmmRnnConfig:
    """GMM-RNN hyper-parameters; the defaults are the paper's (Fig. 3, sec. 4.1.2-4.1.3)."""

    dim: int = 68  # state features of eq. (3) + 2 contact bits (sec. 4.3), 21 joints
    fc_width: int = 500  # FC1, FC2 (Fig. 3)
    lstm_width: int = 500  # LSTM1, LSTM2 (Fig. 3)
    out_width: int = 500  # FC3 (Fig. 3)
    mixtures: int = 5  # M (sec. 4.1.2)
    min_std: float = 0.01  # floor on sigma, normalised units (see "differs")
    noise_std: float = 0.05  # Gaussian input noise during training (sec. 4.1.3)
    grad_clip_value: float | None = 5.0  # every gradient entry clipped to [-5, 5] (sec. 4.1.2)
    lr: float = 1e-3  # RMSProp learning rate (sec. 4.1.3)
    lr_decay: float = 0.95  # multiplied after every epoch (sec. 4.1.3)
    window: int = 50  # frames per training window (sec. 4.1.3)
    fps: float = 30.0  # training data downsampled to 30 fps (sec. 4.1.3)
    batch_size: int = 20  # sec. 4.1.3
    contact_dims: tuple[int, ...] = (66, 67)  # columns of the contact bits (last two of state_features)
    residual: bool = False  # mu_i = x_t + mu_hat_i instead of mu_hat_i (see "differs"); the paper: False
    self_feed: tuple[int, int] | None = None  # (k, m): k true frames then m own samples as inputs, repeated
    absolute_dims: tuple[int, ...] = ()  # with residual=True: columns whose means stay absolute, mu_i = mu_hat_i
    features: str = "state_features"  # what x is: "state_features" (eq. 3) or "feet_anchored" (lesson 03's)
    anchor_tau: float = 0.0  # feet_anchored: 0 the lower toe, > 0 (m) both toes weighted (anchor_on_feet's tau)
    anchor_rule: str = "lower"  # feet_anchored: "lower" toe, or "contact" (the bits; the root in flight)
    fixed_dims: tuple[int, ...] = ()  # columns the data never vary: not modelled, copied from x_t (see "differs")
    bernoulli_contacts: bool = False  # contact bits from a Bernoulli head, not from the Gaussians (see "differs")

    @property
    def gaussian_dims(self) -> tuple[int, ...]:
        """The columns the Gaussian mixture models: all but the fixed ones (and the bits with a Bernoulli head)."""
        skip = set(self.fixed_dims) | (set(self.contact_dims) if self.bernoulli_contacts else set())
        return tuple(c for c in range(self.dim) if c not in skip)

    @classmethod
    def cpu(cls, **overrides) -> GmmRnnConfig:
        """The CPU preset: fc_width, lstm_width, out_width 500 -> 128 and residual means (else as the paper)."""
        return cls(**{"fc_width": 128, "lstm_width": 128, "out_width": 128, "residual": True, **overrides})

    def lr_factor(self, epoch: int) -> float:
        """The paper's schedule for ``fit(lr_schedule=...)``: lr = 1e-3 x 0.95^epoch."""
        return self.lr_decay ** epoch

    def __post_init__(self):
        if min(self.dim, self.fc_width, self.lstm_width, self.out_width, self.mixtures, self.window) < 1:
            raise ValueError(f"GmmRnnConfig: sizes must be positive, got {self}")
        if self.min_std <= 0 or self.noise_std < 0:
            raise ValueError(f"GmmRnnConfig: need min_std > 0 and noise_std >= 0, got {self}")
        if self.grad_clip_value is not None and self.grad_clip_value <= 0:
            raise ValueError(f"GmmRnnConfig: grad_clip_value must be > 0 or None, got {self.grad_clip_value}")
        self.contact_dims = tuple(int(c) for c in self.contact_dims)
        self.absolute_dims = tuple(int(c) for c in self.absolute_dims)
        if any(not 0 <= c < self.dim for c in self.absolute_dims):
            raise ValueError(f"GmmRnnConfig: absolute_dims {self.absolute_dims} outside 0..{self.dim - 1}")
        if any(not 0 <= c < self.dim for c in self.contact_dims):
            raise ValueError(f"GmmRnnConfig: contact_dims {self.contact_dims} outside 0..{self.dim - 1}")
        if self.features not in ("state_features", "feet_anchored"):
            raise ValueError(f"GmmRnnConfig: features must be 'state_features' or 'feet_anchored', got "
                             f"{self.features!r}")
        if not (np.isfinite(self.anchor_tau) and self.anchor_tau >= 0) or (self.anchor_tau and
                                                                            self.features != "feet_anchored"):
            raise ValueError(f"GmmRnnConfig: anchor_tau must be >= 0 (m), and > 0 only with feet_anchored: {self}")
        if self.anchor_rule not in ("lower", "contact") or (self.anchor_rule != "lower" and (
                self.anchor_tau or self.features != "feet_anchored")):
            raise ValueError(f"GmmRnnConfig: anchor_rule must be 'lower' or 'contact' ('contact' only with "
                             f"feet_anchored and tau 0): {self}")
        self.fixed_dims = tuple(int(c) for c in self.fixed_dims)
        if any(not 0 <= c < self.dim for c in self.fixed_dims) or set(self.fixed_dims) & set(self.contact_dims):
            raise ValueError(f"GmmRnnConfig: fixed_dims {self.fixed_dims} must lie in 0..{self.dim - 1}, off the "
                             f"contact bits")
        if self.self_feed is not None:
            self.self_feed = tuple(int(v) for v in self.self_feed)
            if len(self.self_feed) != 2 or min(self.self_feed) < 1:
                raise ValueError(f"GmmRnnConfig: self_feed must be (true frames >= 1, own frames >= 1), got "
                                 f"{self.self_feed}")


def mixture_log_prob(x: torch.Tensor, logits: torch.Tensor, mu: torch.Tensor, log_sigma: torch.Tensor) -> torch.Tensor:
    """log p(x) of a diagonal Gaussian mixture, eq. (6)/(8), in log space.

    x: (..., D), logits: (..., M) w_hat, mu and log_sigma: (..., M, D) -> (...).
    """
    z = (x.unsqueeze(-2) - mu) * torch.exp(-log_sigma)  # (..., M, D)
    # log N(x | mu_i, sigma_i) = sum_j -0.5 z_j^2 - log sigma_ij - 0.5 log 2 pi
    log_n = (-0.5 * z ** 2 - log_sigma - 0.5 * LOG_2PI).sum(-1)  # (..., M)
    # log w_i = w_hat_i - logsumexp(w_hat): the softmax of eq. (7)
    log_w = torch.log_softmax(logits, dim=-1)
    return torch.logsumexp(log_w + log_n, dim=-1)  # log sum_i w_i N(x | mu_i, sigma_i)


class GmmRnn(nn.Module):
    """Fig. 3: FC1-FC2-LSTM1-LSTM2-FC3 + mixture read-out.  Features are normalised (N, T, dim)."""

    def __init__(self, config: GmmRnnConfig | None = None, stats=None):
        super().__init__()
        self.config = c = config or GmmRnnConfig()
        self.fc1, self.fc2 = nn.Linear(c.dim, c.fc_width), nn.Linear(c.fc_width, c.fc_width)
        self.lstm = nn.LSTM(c.fc_width, c.lstm_width, num_layers=2, batch_first=True)  # LSTM1, LSTM2
        self.fc3 = nn.Linear(c.lstm_width, c.out_width)
        n_bits = len(c.contact_dims) if c.bernoulli_contacts else 0
        self.out = nn.Linear(c.out_width, c.mixtures * (1 + 2 * c.dim) + n_bits)  # w_hat, mu_hat, sigma_hat[, bits]
        # the normalisation of the features the model reads, (mean (D,), std (D,)); saved with the weights
        mean, std = (np.zeros(c.dim), np.ones(c.dim)) if stats is None else stats
        self.register_buffer("feature_mean", torch.as_tensor(np.asarray(mean), dtype=torch.float32).reshape(c.dim))
        self.register_buffer("feature_std", torch.as_tensor(np.asarray(std), dtype=torch.float32).reshape(c.dim))
        # joint limits, normalised (see "differs"): +-inf (none) until set_limits; saved with the weights
        self.register_buffer("feature_low", torch.full((c.dim,), -math.inf))
        self.register_buffer("feature_high", torch.full((c.dim,), math.inf))
        if c.grad_clip_value is not None:
            for p in self.parameters():
                p.register_hook(_ClampGrad(c.grad_clip_value))

    def _load_from_state_dict(self, state_dict, prefix, *args, **kwargs):
        for key in ("feature_mean", "feature_std", "feature_low", "feature_high"):  # older checkpoints: no change
            state_dict.setdefault(prefix + key, getattr(self, key).clone())
        super()._load_from_state_dict(state_dict, prefix, *args, **kwargs)

    def _check(self, x: torch.Tensor, name: str, min_frames: int = 1) -> None:
        D = self.config.dim
        if not torch.is_tensor(x) or x.ndim != 3 or x.shape[-1] != D or x.shape[1] < min_frames:
            shape = tuple(x.shape) if torch.is_tensor(x) else type(x).__name__
            raise ValueError(f"{name} must be (N, T >= {min_frames}, {D}), got {shape}")
        if not torch.isfinite(x).all():
            raise ValueError(f"{name} contains NaN or inf")

    def forward(self, x: torch.Tensor, state=None) -> tuple[dict, tuple]:
        """x: (N, T, D) -> ({"logits": (N, T, M), "mu", "log_sigma": (N, T, M, D)[, "contact_logits": (N, T, 2)]},
        LSTM state (h, C)).

        Row t parameterises p(x_{t+1} | x_{<=t}); state carries (h_t, C_t) of both LSTMs, eq. (5).
        """
        self._check(x, "x")
        N, T, _ = x.shape
        M, D = self.config.mixtures, self.config.dim
        a = F.relu(self.fc2(F.relu(self.fc1(x))))  # (N, T, fc_width)
        if T == 1:  # one frame at a time (generation, control): the same LSTM written out, several times faster
            h, state = lstm_step(self.lstm, a[:, 0], state)
            h = h[:, None]
        else:
            h, state = self.lstm(a, state)  # (N, T, lstm_width)
        raw = self.out(F.relu(self.fc3(h)))  # (N, T, M (1 + 2 D))
        logits = raw[..., :M]  # w_hat
        mu = raw[..., M: M + M * D].reshape(N, T, M, D)  # mu = mu_hat                     -- eq. (7)
        if self.config.residual:
            mu = mu + (x * self._residual_mask(x)).unsqueeze(-2)  # mu_i = x_t + mu_hat_i: the change is predicted
        # sigma = exp(sigma_hat), floored at min_std (see "differs")                         -- eq. (7)
        log_sigma = raw[..., M + M * D: M + 2 * M * D].reshape(N, T, M, D).clamp(min=math.log(self.config.min_std))
        params = {"logits": logits, "mu": mu, "log_sigma": log_sigma}
        if self.config.bernoulli_contacts:
            params["contact_logits"] = raw[..., M + 2 * M * D:]  # (N, T, 2): log-odds of each foot's contact
        return params, state

    def log_prob(self, targets: torch.Tensor, params: dict) -> torch.Tensor:
        """log p(x_{t+1}) (...) of targets (..., D) under one step's params: the mixture of eq. (6) over
        config.gaussian_dims, plus the Bernoulli log-likelihood of the contact bits (raw > 0.5) with a
        Bernoulli head.  Fixed columns are not modelled."""
        cols = list(self.config.gaussian_dims)
        lp = mixture_log_prob(targets[..., cols], params["logits"], params["mu"][..., cols],
                              params["log_sigma"][..., cols])
        if self.config.bernoulli_contacts:
            bits = self._raw_bits(targets)
            lp = lp - F.binary_cross_entropy_with_logits(params["contact_logits"], bits, reduction="none").sum(-1)
        return lp

    def _raw_bits(self, x: torch.Tensor) -> torch.Tensor:
        """Normalised (..., D) -> the contact bits (..., 2) as 0/1 in raw units."""
        cols = list(self.config.contact_dims)
        return ((x[..., cols] * self.feature_std[cols] + self.feature_mean[cols]) > 0.5).to(x.dtype)

    def _residual_mask(self, x: torch.Tensor) -> torch.Tensor:
        """(D,) 1 for residual columns, 0 for ``absolute_dims`` (kept between calls: generation reads one frame at
        a time)."""
        key = (x.dtype, x.device, tuple(self.config.absolute_dims))
        cached = self.__dict__.get("_mask_cache")
        if cached is None or cached[0] != key:
            mask = torch.ones(self.config.dim, dtype=x.dtype, device=x.device)
            mask[list(self.config.absolute_dims)] = 0.0
            self.__dict__["_mask_cache"] = cached = (key, mask)
        return cached[1]

    def loss(self, batch, noise: torch.Tensor | None = None) -> dict:
        """batch: (N, T, D) or {"x": ...} normalised windows -> {"loss", "nll"}: eq. (8) per frame.

        Teacher forcing: inputs x_{1..T-1} plus N(0, noise_std^2) noise (training mode only, sec. 4.1.3;
        ``noise`` (N, T-1, D) overrides the draw), targets x_{2..T}.
        """
        x = batch["x"] if isinstance(batch, dict) else batch
        self._check(x, "batch", min_frames=2)
        inputs, targets = x[:, :-1], x[:, 1:]
        if noise is None and self.training and self.config.noise_std > 0:
            noise = torch.randn_like(inputs) * self.config.noise_std
        if noise is not None:
            inputs = inputs + noise
        if self.training and self.config.self_feed is not None:
            nll = -self._self_fed_log_prob(inputs, targets).mean()
        else:
            params, _ = self(inputs)
            nll = -self.log_prob(targets, params).mean()  # E = -log p(x_{t+1} | x_t, h_t, C_t)  -- eq. (8)
        return {"loss": nll, "nll": nll.detach()}

    def _self_fed_log_prob(self, inputs: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
        """(N, T-1, D) noisy true inputs and targets -> log p of every target (N, T-1), where in each cycle of
        k + m steps the first k read the true frame and the next m read the model's own (detached) prediction
        of the previous step, the mean of its most likely component (acLSTM, Zhou et al. 2018; not in Wang et
        al.).  Feeding random samples instead made a test model widen its components until generation blew up."""
        k, m = self.config.self_feed
        state, own, out = None, None, []
        for t in range(inputs.shape[1]):
            x_t = inputs[:, t] if t % (k + m) < k or own is None else own
            params, state = self(x_t[:, None], state)
            params = {key: v[:, 0] for key, v in params.items()}
            out.append(self.log_prob(targets[:, t], params))
            with torch.no_grad():  # the own prediction: the mean of the most likely component
                top = params["logits"].argmax(-1)
                own = params["mu"][torch.arange(len(top), device=top.device), top].detach()
        return torch.stack(out, dim=1)

    # --- generation (sec. 4.1.4) ----------------------------------------------------------

    def sample_mixture(self, params: dict, generator: torch.Generator | None = None, bias: float = 0.0,
                       noise_scale: torch.Tensor | None = None) -> torch.Tensor:
        """params of one step ("logits" (N, M), "mu"/"log_sigma" (N, M, D)) -> a sample (N, D):
        a component i ~ Categorical(w), then x ~ N(mu_i, diag(sigma_i^2)); with a Bernoulli head the contact bits
        are drawn from sigmoid((1 + b) log-odds) and written in normalised units.

        bias b >= 0 (Graves 2013, eq. 61-62; not in Wang et al.): w = softmax((1 + b) w_hat) and
        sigma = exp(sigma_hat - b), so rare broad components are picked less and samples stay closer to
        the means; b = 0 is the paper's sampling.  noise_scale (D,) (not in the paper) multiplies each column's
        draw around its mean: 0 takes the component's mean (no per-dimension noise), 1 samples."""
        if bias < 0:
            raise ValueError(f"sampling bias must be >= 0, got {bias}")
        w = torch.softmax((1.0 + bias) * params["logits"], dim=-1)  # eq. (7)
        i = torch.multinomial(w, 1, generator=generator)[:, 0]  # (N,)
        rows = torch.arange(len(i))
        mu, sigma = params["mu"][rows, i], (params["log_sigma"][rows, i] - bias).exp()  # (N, D)
        eps = torch.randn(mu.shape, generator=generator, dtype=mu.dtype)
        x = mu + sigma * (eps if noise_scale is None else eps * noise_scale.to(mu.dtype))
        if self.config.bernoulli_contacts:
            p = torch.sigmoid((1.0 + bias) * params["contact_logits"])  # (N, 2)
            bits = (torch.rand(p.shape, generator=generator, dtype=p.dtype) < p).to(x.dtype)
            cols = list(self.config.contact_dims)
            x[:, cols] = (bits - self.feature_mean[cols]) / self.feature_std[cols]
        return x

    def fix_contacts(self, x: torch.Tensor, stats=None, mode: str = "threshold") -> torch.Tensor:
        """x: (..., D) normalised sample -> the same with the contact bits made binary ("threshold" at 0.5),
        clamped to [0, 1] ("clamp") or left alone ("none"), in raw units: raw = x * std + mean with
        stats = (mean (D,), std (D,)); stats None means x is not normalised."""
        if mode not in CONTACT_MODES:
            raise ValueError(f"contact mode must be one of {CONTACT_MODES}, got {mode!r}")
        cols = list(self.config.contact_dims)
        if mode == "none" or not cols:
            return x
        mean, std = (torch.zeros(self.config.dim), torch.ones(self.config.dim)) if stats is None else \
            (torch.as_tensor(np.asarray(s), dtype=x.dtype) for s in stats)
        raw = x[..., cols] * std[cols] + mean[cols]
        raw = (raw > 0.5).to(x.dtype) if mode == "threshold" else raw.clamp(0.0, 1.0)
        out = x.clone()
        out[..., cols] = (raw - mean[cols]) / std[cols]
        return out

    @torch.no_grad()
    def sample_step(self, x_t: torch.Tensor, state=None, generator: torch.Generator | None = None,
                    stats=None, contact_mode: str = "threshold", bias: float = 0.0,
                    noise_scale: torch.Tensor | None = None, limits=None) -> tuple[torch.Tensor, tuple]:
        """One step of sec. 4.1.4: x_t (N, D), state (h_t, C_t) or None -> x_{t+1} (N, D), new state.
        limits: None or (low (D,), high (D,)) normalised bounds each sampled column is clamped to (+-inf: free)."""
        params, state = self(x_t[:, None], state)
        x_next = self.sample_mixture({k: v[:, -1] for k, v in params.items()}, generator, bias, noise_scale)
        if self.config.fixed_dims:  # not modelled: the data's constants carry over
            cols = list(self.config.fixed_dims)
            x_next[:, cols] = x_t[:, cols]
        if limits is not None:  # joint limits (see "differs")
            x_next = torch.clamp(x_next, *(torch.as_tensor(b, dtype=x_next.dtype) for b in limits))
        return self.fix_contacts(x_next, stats, contact_mode), state

    def set_limits(self, low, high) -> None:
        """Store joint limits with the model: low, high (D,) normalised bounds (+-inf: free); see `limits`."""
        self.check_limits((low, high))
        self.feature_low.copy_(torch.as_tensor(low, dtype=torch.float32))
        self.feature_high.copy_(torch.as_tensor(high, dtype=torch.float32))

    def limits(self) -> tuple[torch.Tensor, torch.Tensor]:
        """The stored joint limits (low (D,), high (D,)), normalised; +-inf where none were set."""
        return self.feature_low, self.feature_high

    def check_limits(self, limits) -> None:
        """limits: None or (low, high), each (D,) with low <= high and no NaN; otherwise ValueError naming it."""
        if limits is None:
            return
        if len(limits) != 2:
            raise ValueError(f"limits must be (low, high), got {len(limits)} items")
        low, high = (torch.as_tensor(b) for b in limits)
        D = self.config.dim
        if low.shape != (D,) or high.shape != (D,):
            raise ValueError(f"limits must be two ({D},) bounds, got {tuple(low.shape)} and {tuple(high.shape)}")
        if torch.isnan(low).any() or torch.isnan(high).any():
            raise ValueError("limits contain NaN")
        if (low > high).any():
            raise ValueError(f"limits: low > high in columns {torch.nonzero(low > high)[:, 0].tolist()}")

    @torch.no_grad()
    def generate(self, x0: torch.Tensor, steps: int, generator: torch.Generator | None = None,
                 stats=None, contact_mode: str = "threshold", bias: float = 0.0,
                 noise_scale: torch.Tensor | None = None, limits=None) -> torch.Tensor:
        """x0: (N, 2, D) two initial frames (normalised) -> (N, 2 + steps, D): x0 then ``steps`` sampled frames.

        The network reads x_0 and x_1, then each sample x_{t+1} is fed back (sec. 4.1.4).  stats: the
        dataset's (mean, std), used only to make the contact bits binary in raw units; noise_scale: see
        `sample_mixture`; limits: see `sample_step`.
        """
        self._check(x0, "x0")
        self.check_limits(limits)
        if x0.shape[1] != 2:
            raise ValueError(f"x0 must hold two initial frames (N, 2, {self.config.dim}), got {tuple(x0.shape)}")
        if int(steps) != steps or steps < 0:
            raise ValueError(f"steps must be a non-negative int, got {steps!r}")
        _, state = self(x0[:, :1])  # read x_0; x_1 is the first input of the loop
        frames, x_t = [x0[:, 0], x0[:, 1]], x0[:, 1]
        for _ in range(int(steps)):
            x_t, state = self.sample_step(x_t, state, generator, stats, contact_mode, bias, noise_scale, limits)
            frames.append(x_t)
        return torch.stack(frames, dim=1)


class _ClampGrad:
    """A parameter hook clipping every gradient entry to [-c, c] (sec. 4.1.2); a class, not a lambda,
    so models stay picklable and deep-copyable."""

    def __init__(self, c: float):
        self.c = float(c)

    def __call__(self, grad: torch.Tensor) -> torch.Tensor:
        return grad.clamp(-self.c, self.c)
