"""MoGlow: Henter, Alexanderson and Beskow 2019, "MoGlow: probabilistic and controllable motion synthesis
using normalising flows", sec. 3.3 (Glow's step of flow) and sec. 4 (the autoregressive model).

Taught in notebooks/06_moglow.ipynb; trained by ``python -m course_lib.reproduce moglow``.

A motion is poses x_{1:T} (N, T, D) and controls c_{1:T} (N, T, C).  The first tau poses are given
(the paper excludes the initial distribution from every probability, sec. 4.1); each later pose has
its own latent z_t (D), and

    h_t  = g(x_{t-tau:t-1}, c_{t-tau:t}, h_{t-1})                    eq. (17), an LSTM (state-space model)
    h_t  = g(x_{t-tau:t-1}, c_{t-tau:t})                             the Markov variant, eq. (12): an MLP
    z_t  = f(x_t; h_t),  f = K steps of flow, z_t ~ N(0, I)          eq. (16), one level, no squeeze/split
    log p(x_{tau+1:T} | x_{1:tau}, c) = sum_t log N(z_t; 0, I) + log|det dz_t / dx_t|     eq. (5)

One step of flow, written data -> latent (Glow's "inference" direction, Fig. 1):

    actnorm     y = exp(s) * (x + b),  log|det| = sum(s)             sec. 3.3.1 (unnumbered)
    1x1 linear  y = W x,  W = P L (U + diag(sign * exp(log_s))),  log|det| = sum(log_s)   sec. 3.3.2
    coupling    (raw, t) = NN(x_a, h_t);  sigma = sigmoid(raw + 2)                         eq. (7), (18)
                y_a = x_a,  y_b = sigma * (x_b + t),  log|det| = sum(log sigma)           eq. (6)

The equations of our copy of the paper lost their symbols; (16)-(18) are written here as we read
sec. 4.2 and Fig. 2/3: the next-step distribution is a Glow conditioned on the tau previous poses and
the controls of the current and tau previous frames, through the LSTM's state.

``next_step = "gaussian"`` replaces the flow by a conditional diagonal Gaussian with the same
conditioning network, x_t ~ N(mu(h_t), diag sigma(h_t)^2): what the flow buys over it is measured in
lesson 06.  Generation (decode / sample / stream) inverts the flow one frame at a time.

Differs from the paper:
- one LSTM computes h_t and is shared by the K couplings, each coupling's NN a 2-hidden-layer MLP on
  (x_a, h_t); in the paper (and StyleGestures) every coupling has its own 2-layer LSTM of 512 units.
  Sharing makes the model K times cheaper on a CPU and gives the Gaussian baseline exactly the
  conditioning network of the flow.  ``coupling_net = "lstm"`` makes each coupling's NN an LSTM over
  the frames on (x_a, h_t), as the authors' code does: its state carries every earlier frame's x_a,
  which history dropout does not hide (lesson 06's study notes: at our training length it does not
  plant the feet either).
- `MoGlowConfig.cpu()` (the course's models): K = 8 steps (paper 16), 1 LSTM layer of 128 units
  (paper 2 x 512), coupling MLPs of 128 units.
- autoregressive dropout as StyleGestures does it: each of the tau history frames of each output
  frame is zeroed (the mean pose, in standardised units) with probability ``dropout``, without
  rescaling; the controls are never dropped.  Applied by `loss` in training mode only.
- outside training the history is multiplied by the keep probability 1 - dropout (the weight-scaling
  inference rule of dropout, Srivastava et al. 2014), so the conditioning network sees inputs of the
  size it was trained on; StyleGestures' generator feeds the full, unscaled history.  A model trained
  with dropout 0.95 almost never saw ten kept history frames (0.05^10), and on our held-out windows
  it is both less likely and slides its feet more when fed them unscaled (lesson 06's study notes).
  ``history_scale=False`` restores StyleGestures' rule.
- the coupling scale is sigmoid(raw + scale_shift) (Glow's code; the paper cites [36, App. D]).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import nn

__all__ = ["ActNorm", "AffineCoupling", "FlowStep", "GaussianStep", "InvertibleLinear", "Memory", "MoGlow",
           "MoGlowConfig", "MoGlowStream"]

LOG_2PI = math.log(2 * math.pi)
CONDITIONERS = ("lstm", "markov")
NEXT_STEPS = ("glow", "gaussian")
COUPLING_NETS = ("lstm", "mlp")


@dataclass
class MoGlowConfig:
    """MoGlow hyper-parameters; the defaults are the paper's autoregressive model (sec. 5.2)."""

    pose_dim: int  # D: pose values modelled per frame (63 joint coordinates, minus any fixed ones)
    control_dim: int  # C: control values per frame (forward, sideways, yaw-rate displacement)
    tau: int = 10  # history frames the next-step distribution conditions on (0.5 s at 20 fps)
    steps: int = 16  # K: steps of flow (one level, L = 1)
    hidden: int = 512  # units of each layer of the conditioning LSTM (or MLP, Markov variant)
    layers: int = 2  # layers of the conditioning LSTM / MLP
    coupling_hidden: int = 512  # units of each coupling's NN (LSTM state, or the MLP's two hidden layers)
    coupling_net: str = "mlp"  # each coupling's NN: "lstm" (the authors' code: recurrent over the frames) or "mlp"
    conditioner: str = "lstm"  # "lstm" (state-space model, eq. 17) or "markov" (feed-forward, eq. 12)
    next_step: str = "glow"  # "glow" (the flow) or "gaussian" (conditional diagonal Gaussian baseline)
    dropout: float = 0.95  # per-frame dropout rate of the autoregressive pose inputs (sec. 5.3)
    scale_shift: float = 2.0  # coupling scale sigmoid(raw + shift): ~0.88 at the zero initialisation
    history_scale: bool = True  # outside training, history x (1 - dropout): dropout's inference rule

    @classmethod
    def cpu(cls, pose_dim: int, control_dim: int, tau: int = 10, **overrides) -> MoGlowConfig:
        """The CPU preset: K 16 -> 8, LSTM 2 x 512 -> 1 x 128, couplings 512 -> 128 (minutes per model)."""
        return cls(pose_dim, control_dim, tau, **{"steps": 8, "hidden": 128, "layers": 1,
                                                  "coupling_hidden": 128, **overrides})

    def __post_init__(self):
        if min(self.pose_dim, self.control_dim, self.tau, self.steps, self.hidden, self.layers,
               self.coupling_hidden) < 1:
            raise ValueError(f"MoGlowConfig: sizes must be positive integers, got {self}")
        if self.pose_dim < 2:
            raise ValueError(f"MoGlowConfig: a coupling needs pose_dim >= 2, got {self.pose_dim}")
        if self.conditioner not in CONDITIONERS:
            raise ValueError(f"MoGlowConfig: conditioner must be one of {CONDITIONERS}, got {self.conditioner!r}")
        if self.coupling_net not in COUPLING_NETS:
            raise ValueError(f"MoGlowConfig: coupling_net must be one of {COUPLING_NETS}, got {self.coupling_net!r}")
        if self.coupling_net == "lstm" and self.conditioner == "markov":
            raise ValueError("MoGlowConfig: a Markov model (conditioner 'markov') has no memory; its couplings "
                             "must be feed-forward (coupling_net 'mlp')")
        if self.next_step not in NEXT_STEPS:
            raise ValueError(f"MoGlowConfig: next_step must be one of {NEXT_STEPS}, got {self.next_step!r}")
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"MoGlowConfig: dropout must be in [0, 1), got {self.dropout}")

    @property
    def condition_dim(self) -> int:
        """Inputs of the conditioning network per frame: tau poses + (tau + 1) controls."""
        return self.tau * self.pose_dim + (self.tau + 1) * self.control_dim


# ----------------------------------------------------------------------------- the three sub-steps
# Every flow layer maps data -> latent with forward(x, h) -> (y, log_det) and back with inverse(y, h);
# x, y: (..., D); h: (..., H) conditioning (ignored by actnorm and the 1x1 map); log_det: (...).


class ActNorm(nn.Module):
    """y = exp(s) * (x + b) per feature, initialised from the first batch to zero mean, unit variance."""

    def __init__(self, dim: int):
        super().__init__()
        self.bias = nn.Parameter(torch.zeros(dim))  # b
        self.log_scale = nn.Parameter(torch.zeros(dim))  # s
        self.register_buffer("initialized", torch.tensor(False))

    @torch.no_grad()
    def initialize(self, x: torch.Tensor) -> None:
        """x: (..., D) the first batch's inputs -> b = -mean, s = -log std (data-dependent init, sec. 3.3.1)."""
        flat = x.reshape(-1, x.shape[-1])
        self.bias.copy_(-flat.mean(0))
        self.log_scale.copy_(-torch.log(flat.std(0) + 1e-6))
        self.initialized.fill_(True)

    def forward(self, x: torch.Tensor, h: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        if self.training and not bool(self.initialized):
            self.initialize(x)
        y = (x + self.bias) * torch.exp(self.log_scale)  # y = exp(s) (x + b)
        return y, self.log_scale.sum().expand(x.shape[:-1])  # log|det| = sum_i s_i, per frame

    def inverse(self, y: torch.Tensor, h: torch.Tensor | None = None) -> torch.Tensor:
        return y * torch.exp(-self.log_scale) - self.bias


class InvertibleLinear(nn.Module):
    """y = W x with W = P L (U + diag(sign * exp(log_s))): P a fixed permutation, L unit lower-triangular,
    U strictly upper-triangular (Glow's LU-decomposed 1x1 convolution), initialised to a random rotation."""

    def __init__(self, dim: int, generator: torch.Generator | None = None):
        super().__init__()
        w0 = torch.linalg.qr(torch.randn(dim, dim, generator=generator, dtype=torch.float64))[0]
        P, L, U = torch.linalg.lu(w0)
        diag = torch.diagonal(U)
        self.register_buffer("P", P.float())
        self.register_buffer("sign_s", torch.sign(diag).float())
        self.register_buffer("lower_mask", torch.tril(torch.ones(dim, dim), -1))
        self.lower = nn.Parameter(L.float())
        self.upper = nn.Parameter(torch.triu(U, 1).float())
        self.log_s = nn.Parameter(torch.log(diag.abs()).float())

    def weight(self) -> torch.Tensor:
        """-> W (D, D)."""
        eye = torch.eye(len(self.log_s), dtype=self.log_s.dtype, device=self.log_s.device)
        L = self.lower * self.lower_mask + eye
        U = self.upper * self.lower_mask.T + torch.diag(self.sign_s * torch.exp(self.log_s))
        return self.P @ L @ U

    def forward(self, x: torch.Tensor, h: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        y = x @ self.weight().T  # (..., D)
        return y, self.log_s.sum().expand(x.shape[:-1])  # log|det W| = sum log|s_i| (det P = +-1, det L = 1)

    def inverse(self, y: torch.Tensor, h: torch.Tensor | None = None, weight_inv: torch.Tensor | None = None):
        """weight_inv: W^-1 computed once (`torch.linalg.inv(self.weight())`) when inverting many frames."""
        w_inv = torch.linalg.inv(self.weight()) if weight_inv is None else weight_inv
        return y @ w_inv.T


def _mlp(inputs: int, hidden: int, outputs: int) -> nn.Sequential:
    """Two hidden ReLU layers; the output layer starts at zero, so the layer starts near the identity."""
    net = nn.Sequential(nn.Linear(inputs, hidden), nn.ReLU(), nn.Linear(hidden, hidden), nn.ReLU(),
                        nn.Linear(hidden, outputs))
    nn.init.zeros_(net[-1].weight)
    nn.init.zeros_(net[-1].bias)
    return net


class Memory:
    """The running state of one recurrent coupling across calls (generation frame by frame): ``value`` is the
    LSTM's (h, c), None before the first frame.  A coupling given no Memory starts from zero state."""

    def __init__(self):
        self.value = None


class AffineCoupling(nn.Module):
    """y_a = x_a, y_b = sigmoid(raw + shift) * (x_b + t) with (raw, t) = NN(x_a, h)   -- eq. (6), (7), (18).

    x_a: the first D // 2 features, x_b the other D - D // 2.  ``recurrent``: the NN is an LSTM over the frames
    (then x (N, T, D), h (N, T, H)) with a zero-initialised linear output, as the authors' code builds it: its
    state carries every earlier frame's x_a, a memory of the poses that history dropout does not reach."""

    def __init__(self, dim: int, cond_dim: int, hidden: int, scale_shift: float = 2.0, recurrent: bool = False):
        super().__init__()
        self.split, self.scale_shift, self.recurrent = dim // 2, scale_shift, recurrent
        outputs = 2 * (dim - self.split)
        if recurrent:
            self.lstm = nn.LSTM(self.split + cond_dim, hidden, batch_first=True)
            self.out = nn.Linear(hidden, outputs)
            nn.init.zeros_(self.out.weight)
            nn.init.zeros_(self.out.bias)
        else:
            self.net = _mlp(self.split + cond_dim, hidden, outputs)

    def scale_and_shift(self, x_a: torch.Tensor, h: torch.Tensor,
                        memory: Memory | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """-> log sigma, t: (..., D - D // 2) each; a recurrent coupling reads and updates `memory`."""
        inputs = torch.cat((x_a, h), -1)
        if self.recurrent:
            hidden, state = self.lstm(inputs, None if memory is None else memory.value)
            if memory is not None:
                memory.value = state
            raw, t = self.out(hidden).chunk(2, -1)
        else:
            raw, t = self.net(inputs).chunk(2, -1)
        return nn.functional.logsigmoid(raw + self.scale_shift), t  # sigma in (0, 1): the stable scale

    def forward(self, x: torch.Tensor, h: torch.Tensor, memory: Memory | None = None):
        x_a, x_b = x[..., :self.split], x[..., self.split:]
        log_sigma, t = self.scale_and_shift(x_a, h, memory)
        y_b = torch.exp(log_sigma) * (x_b + t)  # eq. (6)
        return torch.cat((x_a, y_b), -1), log_sigma.sum(-1)

    def inverse(self, y: torch.Tensor, h: torch.Tensor, memory: Memory | None = None) -> torch.Tensor:
        y_a, y_b = y[..., :self.split], y[..., self.split:]
        log_sigma, t = self.scale_and_shift(y_a, h, memory)  # y_a = x_a: the same NN input as the forward pass
        return torch.cat((y_a, y_b * torch.exp(-log_sigma) - t), -1)


class FlowStep(nn.Module):
    """One Glow step of flow (Fig. 1): actnorm -> invertible 1x1 linear -> affine coupling."""

    def __init__(self, dim: int, cond_dim: int, hidden: int, scale_shift: float = 2.0,
                 generator: torch.Generator | None = None, recurrent: bool = False):
        super().__init__()
        self.actnorm = ActNorm(dim)
        self.linear = InvertibleLinear(dim, generator)
        self.coupling = AffineCoupling(dim, cond_dim, hidden, scale_shift, recurrent)

    def forward(self, x: torch.Tensor, h: torch.Tensor, memory: Memory | None = None):
        """x (..., D), h (..., H) -> y (..., D), log|det dy/dx| (...)."""
        y, ld1 = self.actnorm(x)
        y, ld2 = self.linear(y)
        y, ld3 = self.coupling(y, h, memory)
        return y, ld1 + ld2 + ld3

    def inverse(self, y: torch.Tensor, h: torch.Tensor, weight_inv: torch.Tensor | None = None,
                memory: Memory | None = None) -> torch.Tensor:
        x = self.coupling.inverse(y, h, memory)
        x = self.linear.inverse(x, weight_inv=weight_inv)
        return self.actnorm.inverse(x)


class GaussianStep(nn.Module):
    """The baseline: z = (x - mu(h)) / sigma(h), i.e. x ~ N(mu(h), diag sigma(h)^2); log|det| = -sum log sigma."""

    def __init__(self, dim: int, cond_dim: int, hidden: int):
        super().__init__()
        self.net = _mlp(cond_dim, hidden, 2 * dim)  # starts at mu = 0, sigma = 1

    def forward(self, x: torch.Tensor, h: torch.Tensor, memory=None) -> tuple[torch.Tensor, torch.Tensor]:
        mu, log_sigma = self.net(h).chunk(2, -1)
        return (x - mu) * torch.exp(-log_sigma), -log_sigma.sum(-1)

    def inverse(self, z: torch.Tensor, h: torch.Tensor, weight_inv=None, memory=None) -> torch.Tensor:
        mu, log_sigma = self.net(h).chunk(2, -1)
        return z * torch.exp(log_sigma) + mu


# ----------------------------------------------------------------------------- the model


class MoGlow(nn.Module):
    """The autoregressive MoGlow of sec. 4.2 (or its Markov / Gaussian variants, see MoGlowConfig)."""

    def __init__(self, config: MoGlowConfig):
        super().__init__()
        self.config = c = config
        if c.conditioner == "lstm":
            self.lstm = nn.LSTM(c.condition_dim, c.hidden, c.layers, batch_first=True)
        else:
            layers = [nn.Linear(c.condition_dim, c.hidden), nn.ReLU()]
            for _ in range(c.layers - 1):
                layers += [nn.Linear(c.hidden, c.hidden), nn.ReLU()]
            self.mlp = nn.Sequential(*layers)
        if c.next_step == "glow":
            self.flow = nn.ModuleList(FlowStep(c.pose_dim, c.hidden, c.coupling_hidden, c.scale_shift,
                                               recurrent=c.coupling_net == "lstm") for _ in range(c.steps))
        else:
            self.flow = nn.ModuleList([GaussianStep(c.pose_dim, c.hidden, c.coupling_hidden)])

    # --- shapes and the conditioning network -------------------------------------------------------

    def _check(self, poses: torch.Tensor, controls: torch.Tensor, min_frames: int) -> None:
        c = self.config
        if poses.ndim != 3 or poses.shape[-1] != c.pose_dim:
            raise ValueError(f"MoGlow: poses must be (N, T, {c.pose_dim}), got {tuple(poses.shape)}")
        if controls.ndim != 3 or controls.shape[-1] != c.control_dim or controls.shape[0] != poses.shape[0]:
            raise ValueError(f"MoGlow: controls must be (N, T, {c.control_dim}) with N = {poses.shape[0]}, "
                             f"got {tuple(controls.shape)}")
        if poses.shape[1] < min_frames:
            raise ValueError(f"MoGlow: need at least {min_frames} frames (tau = {c.tau}), got {poses.shape[1]}")

    def condition_inputs(self, poses: torch.Tensor, controls: torch.Tensor, dropout: float = 0.0,
                         generator: torch.Generator | None = None) -> torch.Tensor:
        """poses (N, T, D), controls (N, T, C) -> (N, T - tau, tau * D + (tau + 1) * C): for frame t the
        poses x_{t-tau:t-1} (each frame zeroed with probability `dropout`, sec. 5.3; with dropout = 0, i.e.
        outside training, times `history_scale()`) and controls c_{t-tau:t}."""
        tau, T = self.config.tau, poses.shape[1]
        hist = poses.unfold(1, tau, 1)[:, : T - tau].transpose(-1, -2)  # (N, T', tau, D)
        if dropout > 0:
            keep = torch.rand(hist.shape[:-1] + (1,), generator=generator, device=poses.device) >= dropout
            hist = hist * keep  # no rescaling: a dropped frame reads as the mean pose
        else:
            hist = hist * self.history_scale()  # E[keep * x] = (1 - dropout) x: the training inputs' mean
        ctrl = controls.unfold(1, tau + 1, 1).transpose(-1, -2)  # (N, T', tau + 1, C)
        return torch.cat((hist.flatten(2), ctrl.flatten(2)), -1)

    def history_scale(self) -> float:
        """The factor on the history outside training: 1 - dropout (dropout's inference rule), or 1."""
        return 1.0 - self.config.dropout if self.config.history_scale else 1.0

    def condition(self, inputs: torch.Tensor, state=None):
        """inputs (N, T', I) -> h (N, T', H) and the LSTM state (None for the Markov variant)  -- eq. (17)."""
        if self.config.conditioner == "lstm":
            return self.lstm(inputs, state)
        return self.mlp(inputs), None

    # --- the flow, data <-> latent, for conditioned frames ----------------------------------------

    def flow_forward(self, x: torch.Tensor, h: torch.Tensor, memory: list | None = None):
        """x (N, T', D), h (N, T', H) -> z (N, T', D), log|det dz/dx| (N, T'); memory: `new_memory()`'s
        states of the recurrent couplings, read and updated (None: they start from zero)."""
        memory = memory or [None] * len(self.flow)
        log_det = torch.zeros(x.shape[:-1], dtype=x.dtype, device=x.device)
        for layer, mem in zip(self.flow, memory, strict=True):
            x, ld = layer(x, h, mem)
            log_det = log_det + ld
        return x, log_det

    def flow_inverse(self, z: torch.Tensor, h: torch.Tensor, weight_invs=None, memory: list | None = None):
        """z (N, T', D), h (N, T', H) -> x (N, T', D); weight_invs: the 1x1 maps' inverses
        (`weight_inverses`); memory: as `flow_forward`."""
        weight_invs = weight_invs or [None] * len(self.flow)
        memory = memory or [None] * len(self.flow)
        for layer, w_inv, mem in zip(reversed(self.flow), reversed(weight_invs), reversed(memory), strict=True):
            z = layer.inverse(z, h, weight_inv=w_inv, memory=mem)
        return z

    def new_memory(self) -> list[Memory]:
        """Fresh running states for the couplings, one per step of flow (for generation frame by frame)."""
        return [Memory() for _ in self.flow]

    def weight_inverses(self) -> list[torch.Tensor | None]:
        """The inverse of each step's 1x1 map, computed once per generated sequence."""
        return [torch.linalg.inv(layer.linear.weight()) if isinstance(layer, FlowStep) else None
                for layer in self.flow]

    # --- the public API ----------------------------------------------------------------------------

    def _encode(self, poses, controls, dropout: float = 0.0, generator=None):
        self._check(poses, controls, self.config.tau + 1)
        h, _ = self.condition(self.condition_inputs(poses, controls, dropout, generator))  # (N, T', H)
        z, log_det = self.flow_forward(poses[:, self.config.tau:], h)  # (N, T', D), (N, T')
        return z, log_det

    def encode(self, poses: torch.Tensor, controls: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """poses (N, T, D), controls (N, T, C) -> z (N, T - tau, D), log_det (N,) = log|det dz / dposes[:, tau:]|."""
        z, log_det = self._encode(poses, controls)
        return z, log_det.sum(-1)

    def log_prob(self, poses: torch.Tensor, controls: torch.Tensor) -> torch.Tensor:
        """-> (N,) log p(x_{tau+1:T} | x_{1:tau}, c_{1:T}) in nats, by the change of variables (eq. 5)."""
        z, log_det = self.encode(poses, controls)
        return (-0.5 * (z ** 2 + LOG_2PI)).sum((-1, -2)) + log_det

    def loss(self, batch: dict) -> dict:
        """batch {"poses": (N, T, D), "controls": (N, T, C)} -> {"loss": NLL per frame (nats), "nll_frame",
        "log_det_frame"}; in training mode with the autoregressive dropout of sec. 5.3."""
        poses, controls = batch["poses"], batch["controls"]
        z, log_det = self._encode(poses, controls, self.config.dropout if self.training else 0.0)
        log_p = (-0.5 * (z ** 2 + LOG_2PI)).sum(-1) + log_det  # (N, T') log p(x_t | h_t)
        nll = -log_p.mean()
        return {"loss": nll, "nll_frame": nll.detach(), "log_det_frame": log_det.mean().detach()}

    @torch.no_grad()
    def decode(self, z: torch.Tensor, initial_poses: torch.Tensor, controls: torch.Tensor) -> torch.Tensor:
        """z (N, T - tau, D), initial_poses (N, tau, D), controls (N, T, C) -> poses (N, T, D), the exact
        inverse of `encode`: frame by frame, each new pose feeding the next frame's history."""
        return self._decode(z, initial_poses, controls)

    def _decode(self, z, initial_poses, controls, history_fn=None) -> torch.Tensor:
        c = self.config
        N, Tz = z.shape[0], z.shape[1]
        self._check(initial_poses, controls[:, : c.tau], c.tau)
        if z.ndim != 3 or z.shape[-1] != c.pose_dim or controls.shape[1] != c.tau + Tz or controls.shape[0] != N:
            raise ValueError(f"MoGlow.decode: z (N, T - tau, {c.pose_dim}) and controls (N, T, {c.control_dim}) "
                             f"must agree, got {tuple(z.shape)} and {tuple(controls.shape)}")
        stream = self.stream(initial_poses, controls[:, : c.tau], history_fn)
        frames = [stream.step(controls[:, c.tau + t], z=z[:, t]) for t in range(Tz)]
        return torch.cat((initial_poses, torch.stack(frames, 1)), 1)

    @torch.no_grad()
    def sample(self, controls: torch.Tensor, initial_poses: torch.Tensor, temperature: float = 1.0,
               generator: torch.Generator | None = None, history_fn=None) -> torch.Tensor:
        """controls (N, T, C) (the first tau those of initial_poses (N, tau, D)) -> poses (N, T, D), with
        z_t ~ N(0, temperature^2 I).  history_fn: see `MoGlowStream` (an experiment's hook, None in use)."""
        if temperature < 0:
            raise ValueError(f"MoGlow.sample: temperature must be >= 0, got {temperature}")
        c = self.config
        N, T = controls.shape[0], controls.shape[1] - c.tau
        z = temperature * torch.randn(N, max(T, 0), c.pose_dim, generator=generator, dtype=initial_poses.dtype)
        return self._decode(z, initial_poses, controls, history_fn)

    def stream(self, initial_poses: torch.Tensor, initial_controls: torch.Tensor,
               history_fn=None) -> MoGlowStream:
        """A generator that makes one frame per `step(control)` call (real-time control, sec. 4.2)."""
        return MoGlowStream(self, initial_poses, initial_controls, history_fn)


class MoGlowStream:
    """Streaming generation: holds the last tau poses and controls and the LSTM state.

    initial_poses (N, tau, D), initial_controls (N, tau, C); ``step(control (N, C)) -> pose (N, D)``.
    history_fn: pose (N, D) -> (N, D), applied to each generated pose before it enters the history
    (e.g. a clamp to the data's range); the pose returned by `step` is the unaltered one."""

    def __init__(self, model: MoGlow, initial_poses: torch.Tensor, initial_controls: torch.Tensor,
                 history_fn=None):
        c = model.config
        model._check(initial_poses, initial_controls, c.tau)
        if initial_poses.shape[1] != c.tau or initial_controls.shape[1] != c.tau:
            raise ValueError(f"MoGlowStream: need exactly tau = {c.tau} initial frames, got "
                             f"{initial_poses.shape[1]} poses and {initial_controls.shape[1]} controls")
        self.model, self.state, self.history_fn = model, None, history_fn
        self.poses, self.controls = initial_poses.clone(), initial_controls.clone()  # (N, tau, D), (N, tau, C)
        self.weight_invs, self.memory = model.weight_inverses(), model.new_memory()

    @torch.no_grad()
    def step(self, control: torch.Tensor, z: torch.Tensor | None = None, temperature: float = 1.0,
             generator: torch.Generator | None = None) -> torch.Tensor:
        """control (N, C) c_t -> pose x_t (N, D) = f^-1(z_t; h_t), z_t given or ~ N(0, temperature^2 I)."""
        N, D = self.poses.shape[0], self.poses.shape[-1]
        if control.shape != (N, self.controls.shape[-1]):
            raise ValueError(f"MoGlowStream.step: control must be ({N}, {self.controls.shape[-1]}), "
                             f"got {tuple(control.shape)}")
        ctrl = torch.cat((self.controls, control[:, None]), 1)  # (N, tau + 1, C): c_{t-tau:t}
        hist = self.poses.flatten(1) * self.model.history_scale()  # as condition_inputs outside training
        inputs = torch.cat((hist, ctrl.flatten(1)), -1)[:, None]  # (N, 1, I)
        h, self.state = self.model.condition(inputs, self.state)  # (N, 1, H)
        if z is None:
            z = temperature * torch.randn(N, D, generator=generator, dtype=self.poses.dtype)
        x = self.model.flow_inverse(z[:, None], h, self.weight_invs, self.memory)[:, 0]  # (N, D)
        kept = x if self.history_fn is None else self.history_fn(x)  # what the next frames condition on
        self.poses = torch.cat((self.poses[:, 1:], kept[:, None]), 1)
        self.controls = ctrl[:, 1:]
        return x
