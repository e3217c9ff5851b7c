"""The prior of MAP motion control (Wang, Chai et al. 2021, sec. 5.2, eq. 15-16): the GMM-RNN of lesson 03
read as a density over raw ``state_features`` frames, with noise variables d on its inputs.

Taught in notebooks/04_map_control.ipynb.

    -log p(s, d | s_0) = sum_i -log p(s_i | s_0..s_{i-1}, d_0..d_{i-1})   -- eq. (15), each factor eq. (8)
                       + sum_i ||d_i||^2 / (2 sigma_noise^2)               -- eq. (16), sigma_noise = 0.05

The RNN reads s_{i-1} + d_{i-1} (d in the model's normalised units, as its training noise, sec. 4.1.3) and its
mixture scores s_i.  `RnnPrior` only uses the model's public interface (``forward``, ``log_prob``,
``sample_step``, its config's ``features``) and the lesson's normalisation statistics, so it keeps working when
lesson 03's model is retrained.

Differs from the paper:
- a model whose buffers hold no normalisation (checkpoints saved before them) is normalised with the
  lesson's stats file; columns the data never vary (std at the floor) are held at the data's constants.
- a model that reads feet-anchored features (``config.features == "feet_anchored"``) gets them through
  ``representations.anchor_on_feet``; every energy of this package stays in raw ``state_features``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from course_lib import representations
from course_lib.datasets import STD_FLOOR, load_stats
from course_lib.models.gmm_rnn import GmmRnn, GmmRnnConfig, mixture_log_prob
from course_lib.paths import CHECKPOINTS  # the pretrained ones (lesson 03 trains gmm_rnn.pt)
from course_lib.skeleton import Skeleton
from course_lib.training import load_checkpoint

__all__ = ["RnnPrior", "noise_energy", "expand_state", "SIGMA_NOISE"]

SIGMA_NOISE = 0.05  # eq. (16): "set to 0.05 by experiment"


def noise_energy(d: torch.Tensor, sigma_noise: float = SIGMA_NOISE) -> torch.Tensor:
    """-log P(d) of eq. (16) up to a constant: d (N, T, D) -> (N,) sum ||d_i||^2 / (2 sigma_noise^2)."""
    return (d ** 2).sum((-1, -2)) / (2 * sigma_noise ** 2)


def expand_state(state, n: int):
    """An LSTM state (h, C), each (layers, 1, H) -> (layers, n, H); None stays None."""
    if state is None or state[0].shape[1] == n:
        return state
    return tuple(s.expand(s.shape[0], n, s.shape[2]).contiguous() for s in state)


@dataclass
class RnnPrior:
    """The GMM-RNN ``model`` and the raw state-feature statistics (mean (D,), std (D,)) of its training data.

    Frames are raw state features (N, T, D) throughout.  ``state`` is the LSTM state after reading every
    frame before the last context frame, so that ``model(prev[:, -1:], state)`` predicts the next frame.
    """

    model: torch.nn.Module
    mean: np.ndarray
    std: np.ndarray
    min_std: float | None = None  # a floor on the mixture's sigmas in the energy (normalised units); None: the model's

    @classmethod
    def from_checkpoints(cls, checkpoints: Path | None = None) -> RnnPrior:
        """The pretrained GMM-RNN (checkpoints/gmm_rnn.pt, lesson 03's ``load_models_rnn``) and its stats."""
        checkpoints = Path(checkpoints or CHECKPOINTS)
        model = load_checkpoint(checkpoints / "gmm_rnn.pt", GmmRnn, GmmRnnConfig)
        model.eval()
        for p in model.parameters():
            p.requires_grad_(False)
        return cls(model, *load_stats(checkpoints / "gmm_rnn_stats.npz", "state_features"))

    def __post_init__(self):
        self.mean, self.std = np.asarray(self.mean, np.float64), np.asarray(self.std, np.float64)
        D = self.model.config.dim
        if self.mean.shape != (D,) or self.std.shape != (D,):
            raise ValueError(f"RnnPrior: stats must be (mean ({D},), std ({D},)), got {self.mean.shape}, "
                             f"{self.std.shape}")
        self.fixed = self.std <= STD_FLOOR  # (D,) columns the data never vary
        self.contact_cols = list(self.model.config.contact_dims)
        free = ~self.fixed
        free[self.contact_cols] = False
        self.free = free  # (D,) the columns an optimiser moves: not fixed, not the contact bits
        cfg = self.model.config
        # what the model reads and which columns it copies (older GmmRnn versions: state features, none)
        self.features = getattr(cfg, "features", "state_features")
        self.anchor_tau = getattr(cfg, "anchor_tau", 0.0)
        self.anchor_rule = getattr(cfg, "anchor_rule", "lower")
        self.fixed_dims = tuple(getattr(cfg, "fixed_dims", ()))
        buf_mean, buf_std = getattr(self.model, "feature_mean", None), getattr(self.model, "feature_std", None)
        identity = buf_mean is None or bool((buf_mean == 0).all() and (buf_std == 1).all())
        # the normalisation of the model's own features: its buffers, or the stats for an older checkpoint
        if identity and self.features == "state_features":
            self.model_norm = torch.from_numpy(self.mean), torch.from_numpy(self.std)
        else:
            self.model_norm = buf_mean.double(), buf_std.double()

    def log_prob(self, targets: torch.Tensor, params: dict) -> torch.Tensor:
        """log p(x_{t+1}) (...) of targets (..., D) under one step's params (eq. 6): the model's ``log_prob``,
        or the plain mixture of eq. (6) for a GmmRnn version without one."""
        if self.min_std is not None:  # a broader prior: sigma >= min_std (see denoise.py)
            params = dict(params, log_sigma=params["log_sigma"].clamp(min=float(np.log(self.min_std))))
        if hasattr(self.model, "log_prob"):
            return self.model.log_prob(targets, params)
        return mixture_log_prob(targets, params["logits"], params["mu"], params["log_sigma"])

    @property
    def dim(self) -> int:
        return self.model.config.dim

    def clean(self, raw: torch.Tensor) -> torch.Tensor:
        """(..., D) -> the same with the fixed columns at the data's constants."""
        out = raw.clone()
        out[..., self.fixed] = torch.as_tensor(self.mean[self.fixed], dtype=raw.dtype)
        return out

    def to_model(self, raw: torch.Tensor, skeleton: Skeleton) -> torch.Tensor:
        """Raw state features (N, T, D) -> the model's normalised input features (N, T, D), float32."""
        raw = raw.double()
        if self.features == "feet_anchored":
            raw = representations.anchor_on_feet(raw, skeleton, tau=self.anchor_tau, rule=self.anchor_rule)
        mean, std = self.model_norm
        return ((raw - mean) / std).float()

    def from_model(self, y: torch.Tensor, skeleton: Skeleton, with_toes: bool = False):
        """The inverse of `to_model`: (N, T, D) model features -> raw state features (float64); with_toes: also
        the toes relative to the root, (N, T, 2, 3) (`representations.toes_relative`), which un-anchoring
        feet-anchored features computes on the way (None for a model of plain state features)."""
        mean, std = self.model_norm
        raw = self.clean(y.double() * std + mean)  # the pose as decoded, before the root is rebuilt from it
        raw[..., self.contact_cols] = raw[..., self.contact_cols].round()  # 0/1 bits, not 2e-8 (float32)
        toes = None
        if self.features == "feet_anchored":
            toes = representations.toes_relative(raw, skeleton)
            raw = representations.unanchor_feet(raw, skeleton, tau=self.anchor_tau, rule=self.anchor_rule, toes=toes)
        return (raw, toes) if with_toes else raw

    def start_state(self, start: torch.Tensor, skeleton: Skeleton):
        """start (N, 2, D) raw: the two initial frames of sec. 4.1.4 -> the state after reading frame 0 (the
        zero-state start of lesson 03's ``generate``; `initial_state.estimate_initial_state` is eq. 26's)."""
        _, state = self.model(self.to_model(start, skeleton)[:, :1])
        return state

    def _inputs(self, prev: torch.Tensor, frames: torch.Tensor, skeleton: Skeleton):
        y = self.to_model(torch.cat((prev, frames), 1), skeleton)  # (N, P + T, D)
        P = prev.shape[1]
        return y[:, P - 1:-1], y[:, P:]  # inputs s_{i-1}, targets s_i

    def nll(self, prev: torch.Tensor, frames: torch.Tensor, state, skeleton: Skeleton,
            d: torch.Tensor | None = None) -> torch.Tensor:
        """Eq. (15): prev (N, P, D) known frames, frames (N, T, D) raw, d (N, T, D) input noise or None
        -> (N,) sum over the T frames of -log p(s_i | s_{<i}, d) (eq. 8)."""
        inputs, targets = self._inputs(prev, frames, skeleton)
        if d is not None:
            inputs = inputs + d.float()
        state = expand_state(state, len(frames))
        params, _ = self.model(inputs, state)
        return -self.log_prob(targets, params).sum(-1)

    @torch.no_grad()
    def predictions(self, prev: torch.Tensor, frames: torch.Tensor, state, skeleton: Skeleton) -> dict:
        """The mixture parameters of every frame given the frames before it, held fixed (no gradient):
        prev (N, P, D), frames (N, T, D) raw -> params with (N, T, ...) entries."""
        inputs, _ = self._inputs(prev, frames, skeleton)
        return self.model(inputs, expand_state(state, len(frames)))[0]

    def nll_given(self, prev: torch.Tensor, frames: torch.Tensor, params: dict, skeleton: Skeleton) -> torch.Tensor:
        """Eq. (15) with the mixtures fixed (`predictions`): -log p of each frame under its given mixture -> (N,)."""
        _, targets = self._inputs(prev, frames, skeleton)
        return -self.log_prob(targets, params).sum(-1)

    def advance(self, prev: torch.Tensor, frames: torch.Tensor, state, skeleton: Skeleton,
                d: torch.Tensor | None = None):
        """The state after reading prev[:, -1] and frames[:, :-1] (+ d): the state for prev = frames."""
        inputs, _ = self._inputs(prev, frames, skeleton)
        if d is not None:
            inputs = inputs + d.float()
        with torch.no_grad():
            _, state = self.model(inputs, state)  # reads s_{-1}, s_0 .. s_{T-2}
        return state

    @torch.no_grad()
    def sample(self, prev: torch.Tensor, state, steps: int, skeleton: Skeleton, generator=None,
               bias: float = 0.0) -> torch.Tensor:
        """Sec. 4.1.4 from prev (N, P, D) raw and state -> (N, steps, D) raw sampled frames."""
        y_prev = self.to_model(prev, skeleton)
        mean, std = self.model_norm
        x_t, frames = y_prev[:, -1], []
        for _ in range(int(steps)):
            x_t, state = self.model.sample_step(x_t, state, generator, stats=(mean.numpy(), std.numpy()),
                                                bias=bias)
            frames.append(x_t)
        y = torch.cat((y_prev, torch.stack(frames, 1)), 1)
        return self.from_model(y, skeleton)[:, prev.shape[1]:]
