"""Autoregressive baselines of Habibie et al. 2017, Tables 1-2: ERD, LSTM-3LR and a conditional RBM.

Taught in notebooks/02_vae_lstm.ipynb.  All three model one frame of ``positions_control``
features (63 pose + 3 control, normalised) given the past, so they predict pose *and* control
jointly.  ``predict(x_init, horizon, control=None)`` rolls them out from initial frames; with
``control`` (the ground truth, Table 2) the control dimensions are overwritten by it every frame.

- ERD (Fragkiadaki et al. 2015): FC encoder -> 2-layer LSTM -> FC decoder, next-frame regression.
- LSTM-3LR (Fragkiadaki et al. 2015): 3 stacked LSTMs + a linear read-out.
- cRBM (Taylor, Hinton & Roweis 2006): Gaussian visible units v_t (unit variance), binary hidden
  units h_t; the previous ``order`` frames p_t shift both biases (autoregressive and dynamic
  biases): a_t = a + A p_t, b_t = b + B p_t.  Trained with contrastive divergence CD-k (Taylor's
  CD-1; the paper's table also lists CD-15) by minimising F(v_data) - F(v_k), whose gradient is the
  CD update, with F(v) = |v - a_t|^2 / 2 - sum_j softplus(b_t + W^T v)_j the free energy.

Differs from the papers:
- sizes shrunk for a 2-core CPU: ERD encoder 500-500 -> 128, LSTMs 1000 -> 128, decoder 100 -> 128;
  LSTM-3LR 3 x 1000 -> 3 x 128; cRBM 150 hidden units -> 128 (``*.cpu()`` presets; the defaults
  are the papers' sizes).
- training on 120-frame sub-windows with Gaussian input noise (Fragkiadaki's noise curriculum,
  reduced to a fixed std) and MSE; Fragkiadaki train on Euler angles, here on joint positions.
- the cRBM's order is 4 frames (60 fps; Taylor: 3 frames at 30 fps ~ 6 at 60 fps) so that it can
  start from the 4 initial frames of Table 2; generation uses ``gibbs_steps`` alternating Gibbs
  steps started from the previous frame and returns the mean visible of the last step.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn
from torch.nn import functional as F

__all__ = ["CRbm", "CRbmConfig", "Erd", "ErdConfig", "Lstm3lr", "Lstm3lrConfig", "rollout"]


def _check_seq(x: torch.Tensor, dim: int, name: str) -> None:
    if x.ndim != 3 or x.shape[-1] != dim:
        raise ValueError(f"{name} must be (N, T, {dim}), got {tuple(x.shape)}")
    if not torch.isfinite(x).all():
        raise ValueError(f"{name} contains NaN or inf")


def _windows(x: torch.Tensor, length: int, generator: torch.Generator | None = None) -> torch.Tensor:
    """x: (N, T, D) -> a random sub-window (N, length, D) per clip (whole clip if shorter)."""
    if x.shape[1] <= length:
        return x
    starts = torch.randint(0, x.shape[1] - length + 1, (x.shape[0],), generator=generator)
    idx = starts[:, None] + torch.arange(length)
    return x[torch.arange(x.shape[0])[:, None], idx]


def rollout(step_fn, x_init: torch.Tensor, horizon: int, control: torch.Tensor | None, control_dim: int):
    """Autoregressive generation shared by the baselines.

    step_fn(frame (N, D), state) -> (next frame (N, D), state); x_init: (N, n, D) initial frames,
    horizon: frames to add; control: (N, n + horizon, control_dim) ground truth or None
    -> (N, n + horizon, D), the initial frames first.
    """
    N, n, D = x_init.shape
    if control is not None and (control.shape[:2] != (N, n + horizon) or control.shape[-1] != control_dim):
        raise ValueError(f"control must be ({N}, {n + horizon}, {control_dim}), got {tuple(control.shape)}")
    frames, state, prev = [x_init[:, t] for t in range(n)], None, None
    for t in range(n):  # warm up on the initial frames
        prev, state = step_fn(x_init[:, t], state)
    for t in range(n, n + horizon):
        nxt = prev
        if control is not None:  # Table 2: the ground-truth control replaces the predicted one
            nxt = torch.cat((nxt[:, :-control_dim], control[:, t]), -1)
        frames.append(nxt)
        prev, state = step_fn(nxt, state)
    return torch.stack(frames, 1)


# ----------------------------------------------------------------------------- ERD and LSTM-3LR


@dataclass
class ErdConfig:
    """ERD (Fragkiadaki et al. 2015); defaults are the paper's sizes, ``cpu()`` ours."""

    dim: int = 66  # features per frame: 63 pose + 3 control
    control_dim: int = 3
    encoder: int = 500  # two FC layers of this width
    lstm: int = 1000  # two LSTM layers of this width
    decoder: int = 100  # FC layers before the linear output
    input_noise: float = 0.05  # std of Gaussian noise on the inputs while training (normalised units)
    window: int = 120  # training sub-window, frames
    lr: float = 1e-3

    @classmethod
    def cpu(cls, **overrides) -> ErdConfig:
        """encoder 500 -> 128, LSTM 1000 -> 128, decoder 100 -> 128."""
        return cls(**{"encoder": 128, "lstm": 128, "decoder": 128, **overrides})


class _NextFrameModel(nn.Module):
    """Shared training/rollout of the recurrent next-frame regressors (ERD, LSTM-3LR)."""

    config: ErdConfig

    def core(self, x: torch.Tensor, state=None):
        raise NotImplementedError

    def forward(self, x: torch.Tensor, state=None):
        """x: (N, T, D) -> predicted next frames (N, T, D), LSTM state."""
        _check_seq(x, self.config.dim, "x")
        return self.core(x, state)

    def loss(self, batch) -> dict:
        """batch: (N, T, D) or {"x": ...} -> {"loss": next-frame MSE}."""
        x = _windows(batch["x"] if isinstance(batch, dict) else batch, self.config.window)
        noisy = x + self.config.input_noise * torch.randn_like(x)
        pred, _ = self(noisy[:, :-1])
        return {"loss": F.mse_loss(pred, x[:, 1:])}

    @torch.no_grad()
    def predict(self, x_init: torch.Tensor, horizon: int, control: torch.Tensor | None = None) -> torch.Tensor:
        """x_init (N, n, D), horizon -> (N, n + horizon, D); control (N, n + horizon, 3) clamps the control."""
        _check_seq(x_init, self.config.dim, "x_init")

        def step(frame, state):
            out, state = self.core(frame[:, None], state)
            return out[:, 0], state

        return rollout(step, x_init, horizon, control, self.config.control_dim)


class Erd(_NextFrameModel):
    """Encoder-Recurrent-Decoder: FC encoder, 2-layer LSTM, FC decoder; predicts x_{t+1} from x_{<=t}."""

    def __init__(self, config: ErdConfig | None = None):
        super().__init__()
        self.config = c = config or ErdConfig()
        self.encoder = nn.Sequential(nn.Linear(c.dim, c.encoder), nn.ReLU(), nn.Linear(c.encoder, c.encoder))
        self.lstm = nn.LSTM(c.encoder, c.lstm, num_layers=2, batch_first=True)
        self.decoder = nn.Sequential(nn.Linear(c.lstm, c.decoder), nn.ReLU(), nn.Linear(c.decoder, c.dim))

    def core(self, x, state=None):
        h, state = self.lstm(self.encoder(x), state)  # (N, T, lstm)
        return x + self.decoder(h), state  # residual: the decoder predicts the change of the frame


@dataclass
class Lstm3lrConfig:
    """LSTM-3LR (Fragkiadaki et al. 2015); defaults are the paper's sizes, ``cpu()`` ours."""

    dim: int = 66
    control_dim: int = 3
    lstm: int = 1000  # three LSTM layers of this width
    input_noise: float = 0.05
    window: int = 120
    lr: float = 1e-3

    @classmethod
    def cpu(cls, **overrides) -> Lstm3lrConfig:
        """LSTM 1000 -> 128 units per layer."""
        return cls(**{"lstm": 128, **overrides})


class Lstm3lr(_NextFrameModel):
    """Three stacked LSTM layers and a linear read-out; predicts x_{t+1} from x_{<=t}."""

    def __init__(self, config: Lstm3lrConfig | None = None):
        super().__init__()
        self.config = c = config or Lstm3lrConfig()
        self.lstm = nn.LSTM(c.dim, c.lstm, num_layers=3, batch_first=True)
        self.out = nn.Linear(c.lstm, c.dim)

    def core(self, x, state=None):
        h, state = self.lstm(x, state)  # (N, T, lstm)
        return x + self.out(h), state


# ----------------------------------------------------------------------------- conditional RBM


@dataclass
class CRbmConfig:
    """Conditional RBM (Taylor et al. 2006); defaults are the paper's sizes, ``cpu()`` ours."""

    dim: int = 66
    control_dim: int = 3
    hidden: int = 150  # binary hidden units
    order: int = 4  # past frames conditioning the biases
    cd_k: int = 1  # Gibbs steps of contrastive divergence (CD-1; Table 1 also CD-15)
    gibbs_steps: int = 30  # alternating Gibbs steps per generated frame
    lr: float = 1e-3

    @classmethod
    def cpu(cls, **overrides) -> CRbmConfig:
        """hidden 150 -> 128."""
        return cls(**{"hidden": 128, **overrides})


class CRbm(nn.Module):
    """Gaussian-binary conditional RBM: p(v_t, h_t | p_t) with a_t = a + A p_t, b_t = b + B p_t."""

    def __init__(self, config: CRbmConfig | None = None):
        super().__init__()
        self.config = c = config or CRbmConfig()
        self.W = nn.Parameter(0.01 * torch.randn(c.dim, c.hidden))
        self.A = nn.Linear(c.order * c.dim, c.dim)  # autoregressive weights + visible bias a
        self.B = nn.Linear(c.order * c.dim, c.hidden)  # dynamic bias weights + hidden bias b
        nn.init.zeros_(self.A.weight)
        nn.init.zeros_(self.B.weight)

    def biases(self, past: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """past: (N, order * D) -> a_t (N, D), b_t (N, H)."""
        return self.A(past), self.B(past)

    def free_energy(self, v: torch.Tensor, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        """F(v) = |v - a|^2 / 2 - sum_j softplus(b + W^T v)_j.  v, a: (N, D), b: (N, H) -> (N,)."""
        return 0.5 * ((v - a) ** 2).sum(-1) - F.softplus(b + v @ self.W).sum(-1)

    def gibbs(self, v: torch.Tensor, a: torch.Tensor, b: torch.Tensor, k: int,
              generator: torch.Generator | None = None) -> torch.Tensor:
        """k alternating Gibbs steps from v -> the mean visible of the last step (N, D)."""
        for _ in range(k):
            p_h = torch.sigmoid(b + v @ self.W)  # p(h_j = 1 | v, past)
            h = torch.bernoulli(p_h, generator=generator)
            v = a + h @ self.W.T  # mean of p(v | h, past) = N(a + W h, I)
        return v

    def _pairs(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """x: (N, T, D) -> v (M, D), past (M, order * D) with M = N (T - order), past newest first."""
        n = self.config.order
        past = torch.cat([x[:, n - k - 1: x.shape[1] - k - 1] for k in range(n)], -1)  # (N, T-n, n D)
        return x[:, n:].reshape(-1, x.shape[-1]), past.reshape(-1, past.shape[-1])

    def loss(self, batch) -> dict:
        """batch: (N, T, D) or {"x": ...} -> {"loss": F(v_data) - F(v_k) (its gradient is CD-k), "recon"}."""
        x = batch["x"] if isinstance(batch, dict) else batch
        _check_seq(x, self.config.dim, "x")
        v, past = self._pairs(x)
        a, b = self.biases(past)
        with torch.no_grad():
            v_k = self.gibbs(v, a, b, self.config.cd_k)
        loss = (self.free_energy(v, a, b) - self.free_energy(v_k, a, b)).mean()
        return {"loss": loss, "recon": F.mse_loss(v_k, v).detach()}

    @torch.no_grad()
    def predict(self, x_init: torch.Tensor, horizon: int, control: torch.Tensor | None = None,
                generator: torch.Generator | None = None) -> torch.Tensor:
        """x_init (N, n >= order, D), horizon -> (N, n + horizon, D); control clamps the control dims."""
        _check_seq(x_init, self.config.dim, "x_init")
        n = self.config.order
        if x_init.shape[1] < n:
            raise ValueError(f"x_init needs >= order = {n} frames, got {x_init.shape[1]}")

        def step(frame, state):
            hist = frame[:, None] if state is None else torch.cat((state, frame[:, None]), 1)[:, -n:]
            if hist.shape[1] < n:
                return frame, hist
            a, b = self.biases(hist.flip(1).reshape(len(frame), -1))  # newest first
            return self.gibbs(frame, a, b, self.config.gibbs_steps, generator), hist

        return rollout(step, x_init, horizon, control, self.config.control_dim)
