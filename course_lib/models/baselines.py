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

Lesson 05 (notebooks/05_hierarchical_vrnn.ipynb, Ghorbani et al. 2020 sec. 5.1) adds `AttributeRnn`:
an ERD and a QuaterNet-style GRU (Pavllo et al. 2019) that generate ``quaternion_root`` poses from
the attributes (action, style) alone, the learned Gaussian initial state of each attribute
combination being their only source of randomness; trained with the proposed model's geodesic
loss (Ghorbani eq. 17, all alpha_k = 1) and unit-norm constraint (eq. 26).  Differs: 1000 units ->
128 (``AttributeRnnConfig.cpu()``); QuaterNet's loss is on FK positions and it predicts rotations
residually, here the geodesic angle loss on absolute rotations; its teacher forcing is replaced by
scheduled sampling growing to ``sample_max``.

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

import math
from dataclasses import dataclass

import torch
from torch import nn
from torch.nn import functional as F

from course_lib.models.hvrnn import (
    NUM_ROOT,
    PoseCoding,
    check_poses,
    mlp,
    normalize_pose,
    reconstruction_loss,
    unit_norm_loss,
)
from course_lib.models.vae import linear_beta

__all__ = ["AttributeRnn", "AttributeRnnConfig", "CRbm", "CRbmConfig", "Erd", "ErdConfig", "Lstm3lr",
           "Lstm3lrConfig", "rollout"]


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



# ----------------------------------------------------------------------------- lesson 05: attribute-driven RNNs


@dataclass
class AttributeRnnConfig:
    """ERD / QuaterNet-style GRU generating ``quaternion_root`` poses from attributes (Ghorbani et al. 2020,
    sec. 5.1): the learned Gaussian initial state of each (action, style) is the only randomness."""

    kind: str = "quaternet"  # "quaternet": 2 GRU layers (Pavllo et al. 2019) | "erd": FC encoder, 2 LSTMs, FC decoder
    num_joints: int = 21  # pose = 4 J + 6 features
    n_actions: int = 4
    n_styles: int = 2
    d_a: int = 8  # attribute features fed every frame
    hidden: int = 1000  # recurrent width (QuaterNet: 1000; ERD: 1000)
    encoder: int = 500  # ERD's FC encoder / decoder width
    distance: str = "d1"  # geodesic of the reconstruction, as the proposed model (Ghorbani eq. 17)
    rec_weight: float = 10.0  # as HvrnnConfig.rec_weight
    root_weight: float = 1.0  # weight of the root features' squared error (standardised)
    input_noise: float = 0.05  # ERD: std of Gaussian noise on the inputs (Fragkiadaki's curriculum, fixed)
    sample_max: float = 0.3  # QuaterNet: final probability of feeding back its own prediction (scheduled sampling)
    sample_ramp: int = 2000  # steps from 0 to sample_max
    lambda_ang: float = 0.1  # unit-norm constraint (Ghorbani eq. 26), as the proposed model

    @classmethod
    def cpu(cls, **overrides) -> AttributeRnnConfig:
        """recurrent 1000 -> 128, ERD encoder/decoder 500 -> 128."""
        return cls(**{"hidden": 128, "encoder": 128, **overrides})

    def __post_init__(self):
        if self.kind not in ("quaternet", "erd"):
            raise ValueError(f"kind must be 'quaternet' or 'erd', got {self.kind!r}")

    @property
    def pose_dim(self) -> int:
        return 4 * self.num_joints + NUM_ROOT


class AttributeRnn(PoseCoding, nn.Module):
    """x_t = f(x_{t-1}, a, h_{t-1}) with h_0 ~ N(mu_c, sigma_c) learned per attribute combination.

    Raw ``quaternion_root`` poses (N, T, 4J + 6); x_0 is a zero "start" frame, so generation needs
    no seed frames.  ``loss`` is teacher-forced next-frame geodesic reconstruction (+ input noise for
    the ERD, scheduled sampling for the QuaterNet-style GRU); ``sample`` rolls out from h_0 and feeds
    back its own normalised output.
    """

    def __init__(self, config: AttributeRnnConfig | None = None):
        super().__init__()
        self.config = c = config or AttributeRnnConfig()
        D, H = c.pose_dim, c.hidden
        self.f_c = nn.Linear(c.n_actions + c.n_styles, c.d_a)
        if c.kind == "erd":
            self.encoder = mlp(D + c.d_a, c.encoder, 1, c.encoder)
            self.rnn = nn.LSTM(c.encoder, H, num_layers=2, batch_first=True)
            self.decoder = mlp(H, c.encoder, 1, D)
        else:
            self.rnn = nn.GRU(D + c.d_a, H, num_layers=2, batch_first=True)
            self.decoder = nn.Linear(H, D)
        n_state = (4 if c.kind == "erd" else 2) * H  # (h, c) of two LSTM layers, or h of two GRU layers
        self.h0_mu = nn.Parameter(torch.zeros(c.n_actions * c.n_styles, n_state))
        self.h0_logstd = nn.Parameter(torch.full((c.n_actions * c.n_styles, n_state), math.log(0.1)))
        self.register_pose_buffers(c.pose_dim)
        self.register_buffer("step", torch.zeros((), dtype=torch.long))

    def output_layer(self) -> tuple[nn.Linear, int]:
        """The decoder's last linear layer, one frame per step (used by `set_stats`)."""
        return (self.decoder[-1] if self.config.kind == "erd" else self.decoder), 1

    def _initial(self, combo: torch.Tensor, generator: torch.Generator | None = None):
        """h_0 ~ N(mu_c, diag sigma_c^2): (N,) -> the RNN's state ((2, N, H) GRU, or LSTM's (h, c))."""
        eps = torch.randn(len(combo), self.h0_mu.shape[1], generator=generator)
        s = self.h0_mu[combo] + self.h0_logstd[combo].exp() * eps
        layers = s.reshape(len(combo), -1, self.config.hidden).transpose(0, 1).contiguous()  # (2 or 4, N, H)
        return (layers[:2].contiguous(), layers[2:].contiguous()) if self.config.kind == "erd" else layers

    def _step(self, y_prev: torch.Tensor, a: torch.Tensor, state):
        """model-space frames (N, T, D), a (N, d_a) -> next frames (N, T, D) (quaternions raw), state."""
        inp = torch.cat((y_prev, a[:, None].expand(-1, y_prev.shape[1], -1)), -1)
        h, state = self.rnn(self.encoder(inp) if self.config.kind == "erd" else inp, state)
        return self.decoder(h), state

    def _teacher_forced(self, prev: torch.Tensor, a: torch.Tensor, state) -> torch.Tensor:
        """prev (N, T, D) inputs -> outputs (N, T, D): ERD with input noise, QuaterNet with scheduled sampling."""
        c = self.config
        if c.kind == "erd":
            return self._step(prev + c.input_noise * torch.randn_like(prev), a, state)[0]
        p = linear_beta(int(self.step), c.sample_ramp, c.sample_max)  # P(feed back its own prediction)
        outs, inp = [], prev[:, :1]
        for t in range(prev.shape[1]):
            out, state = self._step(inp, a, state)
            outs.append(out)
            if t + 1 < prev.shape[1]:
                own = torch.rand(len(prev), 1, 1) < p
                inp = torch.where(own, normalize_pose(out.detach(), c.num_joints), prev[:, t + 1:t + 2])
        return torch.cat(outs, 1)

    def loss(self, batch: dict) -> dict:
        """batch {"x": (N, T, D) raw, "action_id", "style_id"} -> {"loss", "rec", "rec_root", "ang"}."""
        c, J = self.config, self.config.num_joints
        x = batch["x"]
        check_poses(x, c.pose_dim)
        a, combo = self.attributes(batch["action_id"], batch["style_id"])
        y = self.to_model(x)
        prev = torch.cat((torch.zeros_like(y[:, :1]), y[:, :-1]), 1)  # x_0 = 0, then the data
        y_hat = self._teacher_forced(prev, a, self._initial(combo))
        q = x[..., :4 * J].unflatten(-1, (J, 4))
        q_hat = self.from_model(y_hat)[..., :4 * J].unflatten(-1, (J, 4))
        rec = reconstruction_loss(q, q_hat, torch.ones(J), c.distance).mean()
        rec_root = (y_hat[..., -NUM_ROOT:] - y[..., -NUM_ROOT:]).pow(2).sum(-1).mean()
        ang = unit_norm_loss(y_hat[..., :4 * J].unflatten(-1, (J, 4))).mean()
        if self.training:
            self.step += 1
        total = c.rec_weight * (rec + c.root_weight * rec_root) + c.lambda_ang * ang
        return {"loss": total, "rec": rec, "rec_root": rec_root, "ang": ang}

    @torch.no_grad()
    def sample(self, action, style, frames: int, generator: torch.Generator | None = None) -> torch.Tensor:
        """action (N,), style (N,) ids -> raw poses (N, frames, D); the only randomness is h_0."""
        if frames < 1:
            raise ValueError(f"frames must be >= 1, got {frames}")
        a, combo = self.attributes(action, style)
        state, inp, outs = self._initial(combo, generator), torch.zeros(len(a), 1, self.config.pose_dim), []
        for _ in range(frames):
            out, state = self._step(inp, a, state)
            inp = normalize_pose(out, self.config.num_joints)
            outs.append(inp)
        return self.from_model(torch.cat(outs, 1))
