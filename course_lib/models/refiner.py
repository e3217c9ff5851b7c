"""Adversarial refiner of Wang, Chai et al. 2021 (IEEE TVCG 27(1)), sec. 4.2-4.3.

Taught in notebooks/03_gmm_rnn_refiner.ipynb.

The GMM-RNN's motions x_RNN (``state_features``, normalised, see gmm_rnn.py) are refined by a
residual network R and judged by a discriminator D that sees end-effector positions and velocities:

    R_input = [x, p_end(x), v_end(x)]
    R(x)    = (W_r2 lstm(relu(W_r1 R_input + b_r1)) + b_r2) + x                 eq. (11), Fig. 4
    l(x)    = W_d2 bilstm(relu(W_d1 [p_end(x), v_end(x)] + b_d1)) + b_d2            eq. (12), Fig. 5
    D(x)    = sigmoid(l(x))   (eq. 12 as printed has no sigmoid; eq. 10 and 13 take log D)
    L_R     = -log D(R(x_RNN)) + lambda ||root(x) - root(R(x))||^2, lambda = 20  eq. (9), (13)
    L_D     = -log(1 - D(R(x_RNN))) - log D(x_real)                              eq. (10), see "differs"

p_end and v_end are computed in torch (forward kinematics of the decoded pose), so D's loss is
differentiable through to R's parameters.  Training (sec. 4.2.2): `AdversarialSchedule` (75
warm-up updates of each network, then 5 R updates per D update, R's count doubled when D's loss
< 0.01 and halved when > 1), `HistoryBuffer` (B = 320 refined motions; half of each D batch of
b = 32 comes from it; b / 2 of its entries are replaced after each D update), RMSProp at lr 0.002
(R) and 0.005 (D), decay 0.9.  Contact awareness (sec. 4.3): the contact bits are part of x, so R
reads and refines them; contact_cleanup.py enforces the predicted contacts on the output.

Differs from the paper (the defaults are the paper's unless a line says otherwise):
- end effectors are the skeleton's leaf joints (toes, hands, head: 5 for the canonical skeleton).
  p_end is taken in each frame's floor frame (the root's floor projection and heading, as the
  features themselves are translation and rotation invariant) and v_end is the displacement from
  frame t-1 to t in frame t-1's floor frame, times fps (m/s); frame 0 repeats frame 1.
- D's output: Fig. 5 has FC2(2) then a single output; we read one logit from the concatenated last
  forward and first backward hidden states of the BiLSTM (a 2-way softmax is a sigmoid of a
  difference).  Losses use log-sigmoid of the logit, never log(D + eps).
- R's last layer is initialised at 1% of PyTorch's default scale so that R starts near the identity
  (the paper does not say how R is initialised).
- ||root(x) - root(R(x))||^2 is summed over x, y, z and averaged over frames and motions; root()
  integrates eq. (4) from the origin for both motions.
- ``contacts=False`` (the paper's GAN1, no contact awareness) hides the contact bits from R's input
  and passes them through unchanged.
- the buffer stores D's view of the refined motions (p_end, v_end and the bits D sees), detached, so D's
  half-batch from the buffer carries no gradient to R.
- ``RefinerConfig.cpu()`` shrinks the widths: R 500 -> 128 (FC1), 1000 -> 128 (LSTM); D 500 -> 64, to train
  on a CPU.
- D's loss is eq. (10) halved, (softplus(-l_real) + softplus(l_fake)) / 2: the mean cross-entropy of its
  two-way softmax, the "discriminator's softmax loss" the balance rule of sec. 4.2.2 reads.  Its chance level
  is ln 2 = 0.69, below the halving threshold 1; with the sum (chance 2 ln 2 = 1.39) a D at chance would halve
  R's update count every round.  RMSProp makes the factor 1/2 irrelevant to D's updates.
- each motion's own skeleton: R and D compute p_end and v_end with the rest offsets of the subject the
  motion belongs to (``offsets=`` (N, J, 3); the canonical skeleton when None), as the evaluation decodes
  every clip on its own skeleton.
- ``pose_lam`` > 0 (not in eq. 13; default 0): SimGAN's self-regularisation on the pose too, pose_lam times the
  mean squared change (R(x) - x)^2 of every refined column but the contact bits, in sd units.  Eq. 13 keeps only
  the root near x; without the term R changed the spine, shoulders and arms, which alone raised the FID
  many times over.
- ``leg_pose_lam`` > 0 (not in eq. 13; default 0): the same term once more on the hip, knee and ankle angles
  alone (``contact_cleanup.leg_columns``): with pose_lam alone R's leg change raised GAN1's FID above the RNN's.
  Lesson 03's weights (10 and 30) and what they change: studies/03_gmm_rnn_refiner/README.md.
- ``discriminator_joints="all"`` (not in eq. 12): D sees the floor-frame positions and velocities of every joint,
  not only the end effectors (R's input is unchanged).
- ``discriminator_contacts=True`` (not in eq. 12, off in the paper's config, on for our GAN2): D also sees
  the two contact bits, thresholded at 0.5 with a straight-through gradient (D sees 0/1 for real and
  refined motions alike, R gets the gradient of the soft bit), so R learns bits that match its feet.
- `AdversarialSchedule` can apply the balance rule to the mean of the last few D losses (``smooth``) and caps R's
  update count (``max_r_updates``); lesson 03 sets its own band and cap (experiments.gmm_rnn.Lesson03Spec).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from course_lib.history import History
from course_lib.models.contact_cleanup import leg_columns
from course_lib.representations import _check_state_tensor, _turn, local_positions, root_trajectory
from course_lib.skeleton import Skeleton

__all__ = ["AdversarialSchedule", "Discriminator", "HistoryBuffer", "Refiner", "RefinerConfig",
           "discriminator_loss", "end_effector_features", "local_positions",
           "pose_regularisation", "refiner_adversarial_loss", "refiner_loss", "root_regularisation", "root_trajectory",
           "train_refiner"]


@dataclass
class RefinerConfig:
    """Refiner R and discriminator D hyper-parameters; the defaults are the paper's (Fig. 4-5, sec. 4.2.2)."""

    dim: int = 68  # state features incl. the 2 contact bits (sec. 4.3), 21 joints
    num_end_effectors: int = 5  # leaf joints of the canonical skeleton: toes, head, hands
    fc_width: int = 500  # R's FC1 (Fig. 4)
    lstm_width: int = 1000  # R's LSTM (Fig. 4)
    d_fc_width: int = 500  # D's FC1 (Fig. 5)
    d_lstm_width: int = 500  # D's BiLSTM, per direction (Fig. 5)
    contacts: bool = True  # GAN2 (contact-aware, sec. 4.3); False = GAN1
    discriminator_contacts: bool = False  # D also sees the contact bits (not in eq. 12, see "differs")
    discriminator_joints: str = "end_effectors"  # whose positions and velocities D sees: eq. 12's, or "all" joints
    contact_dims: tuple[int, ...] = (66, 67)  # columns of the contact bits
    lam: float = 20.0  # lambda of the root self-regularisation, eq. (13)
    pose_lam: float = 0.0  # weight of the pose self-regularisation (SimGAN's; not in eq. 13, see "differs")
    leg_pose_lam: float = 0.0  # extra weight of that term on the hip, knee and ankle angles alone (see "differs")
    fps: float = 30.0  # frame rate of the features (for v_end in m/s)
    lr_refiner: float = 0.002  # RMSProp (sec. 4.2.2)
    lr_discriminator: float = 0.005  # RMSProp (sec. 4.2.2)
    rmsprop_decay: float = 0.9  # RMSProp's alpha (sec. 4.2.2)
    buffer_size: int = 320  # B (sec. 4.2.2)
    d_batch: int = 32  # b: half current refined motions, half from the buffer
    warmup: int = 75  # updates of each network before the 5:1 schedule
    r_per_d: int = 5  # refiner updates per discriminator update
    d_loss_low: float = 0.01  # D loss below: R's update count doubled
    d_loss_high: float = 1.0  # D loss above: R's update count halved
    residual_init_scale: float = 0.01  # R's last layer starts at 1% of the default init (see "differs")

    @classmethod
    def cpu(cls, **overrides) -> RefinerConfig:
        """The CPU preset: fc_width 500 -> 128, lstm_width 1000 -> 128, d_fc_width and d_lstm_width 500 -> 64."""
        return cls(**{"fc_width": 128, "lstm_width": 128, "d_fc_width": 64, "d_lstm_width": 64, **overrides})

    def __post_init__(self):
        sizes = (self.dim, self.num_end_effectors, self.fc_width, self.lstm_width, self.d_fc_width,
                 self.d_lstm_width, self.buffer_size, self.d_batch, self.r_per_d)
        if min(sizes) < 1 or self.warmup < 0:
            raise ValueError(f"RefinerConfig: sizes must be positive, got {self}")
        if self.d_batch % 2 or self.d_batch // 2 > self.buffer_size:
            raise ValueError(f"RefinerConfig: d_batch must be even and d_batch / 2 <= buffer_size, got {self}")
        self.contact_dims = tuple(int(c) for c in self.contact_dims)
        if any(not 0 <= c < self.dim for c in self.contact_dims):
            raise ValueError(f"RefinerConfig: contact_dims {self.contact_dims} outside 0..{self.dim - 1}")
        if not 0 < self.d_loss_low < self.d_loss_high:
            raise ValueError(f"RefinerConfig: need 0 < d_loss_low < d_loss_high, got {self}")
        for name in ("pose_lam", "leg_pose_lam"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise ValueError(f"RefinerConfig: {name} must be finite and >= 0, got {getattr(self, name)}")
        if self.discriminator_joints not in ("end_effectors", "all"):
            raise ValueError(f"RefinerConfig: discriminator_joints must be 'end_effectors' or 'all', got "
                             f"{self.discriminator_joints!r}")
        if self.discriminator_contacts and not self.contacts:
            raise ValueError("RefinerConfig: discriminator_contacts needs contacts=True (GAN1 cannot change the bits)")

    @property
    def refined_dims(self) -> tuple[int, ...]:
        """The feature columns R reads and changes (all, or all but the contact bits for GAN1)."""
        return tuple(range(self.dim)) if self.contacts else \
            tuple(c for c in range(self.dim) if c not in self.contact_dims)

    @property
    def pose_dims(self) -> tuple[int, ...]:
        """The columns the pose self-regularisation keeps near x: every refined column but the contact bits."""
        return tuple(c for c in self.refined_dims if c not in self.contact_dims)

    @property
    def num_joints(self) -> int:
        """Joints of the skeleton the features describe: dim = 6 + 3 (J - 1) + 2."""
        return (self.dim - 8) // 3 + 1

    @property
    def d_joints(self) -> int:
        """How many joints D sees: the end effectors (eq. 12) or all of them."""
        return self.num_end_effectors if self.discriminator_joints == "end_effectors" else self.num_joints

    @property
    def d_input_dim(self) -> int:
        """Width of D's per-frame input: positions and velocities (3 each per joint D sees) and the contact bits
        if D sees them."""
        return 6 * self.d_joints + (len(self.contact_dims) if self.discriminator_contacts else 0)


# ----------------------------------------------------------------------------- kinematics in torch


def end_effector_features(features: torch.Tensor, skeleton: Skeleton, fps: float,
                          offsets: torch.Tensor | None = None, joints=None) -> tuple[torch.Tensor, torch.Tensor]:
    """Raw state features (..., T, D) -> p_end, v_end: (..., T, 3E) each (E = leaf joints, or the joint indices
    ``joints``).

    p_end: positions in the frame's floor frame; v_end: (p_t - p_{t-1}) expressed in frame t-1's
    floor frame, times fps: R_y(dyaw_t) p^local_t + (dx_t, 0, dz_t) - p^local_{t-1}.
    """
    joints = list(skeleton.end_effectors) if joints is None else [int(j) for j in joints]
    pos = local_positions(features, skeleton, offsets)[..., joints, :]  # (..., T, E, 3)
    T = pos.shape[-3]
    if T < 2:
        raise ValueError(f"end_effector_features needs T >= 2 frames for velocities, got {T}")
    d, dyaw = features[..., 1:, None, 0:2], features[..., 1:, None, 2]
    moved_xz = _turn(pos[..., 1:, :, [0, 2]], dyaw) + d  # frame t's points in frame t-1's floor frame
    moved = torch.stack((moved_xz[..., 0], pos[..., 1:, :, 1], moved_xz[..., 1]), -1)
    v = (moved - pos[..., :-1, :, :]) * fps  # (..., T-1, E, 3)
    v = torch.cat((v[..., :1, :, :], v), -3)  # frame 0 repeats frame 1
    return pos.flatten(-2), v.flatten(-2)


# ----------------------------------------------------------------------------- networks


class Refiner(nn.Module):
    """R of eq. (11), Fig. 4: normalised features x (N, T, D) -> refined x (N, T, D) (residual).

    skeleton: joint tree and default rest offsets for p_end/v_end (canonical by default); every call takes
    ``offsets`` (N, J, 3), each motion's own rest offsets.  stats: the dataset's (mean (D,), std (D,)), kept
    as buffers (saved with the weights) to undo the normalisation before the kinematics.
    """

    def __init__(self, config: RefinerConfig | None = None, skeleton: Skeleton | None = None, stats=None):
        super().__init__()
        self.config = c = config or RefinerConfig()
        self.skeleton = skeleton or Skeleton.canonical()
        if len(self.skeleton.end_effectors) != c.num_end_effectors:
            raise ValueError(f"skeleton has {len(self.skeleton.end_effectors)} end effectors, config says "
                             f"{c.num_end_effectors}")
        mean, std = (np.zeros(c.dim), np.ones(c.dim)) if stats is None else stats
        self.register_buffer("mean", torch.as_tensor(np.asarray(mean), dtype=torch.float32).reshape(c.dim))
        self.register_buffer("std", torch.as_tensor(np.asarray(std), dtype=torch.float32).reshape(c.dim))
        self.register_buffer("offsets", torch.as_tensor(self.skeleton.offsets, dtype=torch.float32))
        self.register_buffer("cols", torch.tensor(c.refined_dims, dtype=torch.long))
        r_in = len(c.refined_dims) + 6 * c.num_end_effectors
        self.fc1 = nn.Linear(r_in, c.fc_width)
        self.lstm = nn.LSTM(c.fc_width, c.lstm_width, batch_first=True)
        self.fc2 = nn.Linear(c.lstm_width, len(c.refined_dims))
        with torch.no_grad():
            self.fc2.weight.mul_(c.residual_init_scale)
            self.fc2.bias.zero_()

    def raw(self, x: torch.Tensor) -> torch.Tensor:
        """Normalised (..., D) -> raw units (x * std + mean)."""
        return x * self.std + self.mean

    def _offsets(self, x: torch.Tensor, offsets) -> torch.Tensor:
        """None -> the refiner's skeleton's (J, 3); else each motion's (N, J, 3), checked against x (N, T, D)."""
        if offsets is None:
            return self.offsets
        off = torch.as_tensor(offsets, dtype=self.offsets.dtype, device=x.device)
        if off.shape != (x.shape[0],) + tuple(self.offsets.shape):
            raise ValueError(f"offsets must be (N={x.shape[0]}, {self.offsets.shape[0]}, 3), one skeleton per "
                             f"motion, got {tuple(off.shape)}")
        return off

    def end_effectors(self, x: torch.Tensor, offsets=None) -> tuple[torch.Tensor, torch.Tensor]:
        """Normalised x (N, T, D), offsets (N, J, 3) or None -> p_end(x), v_end(x): (N, T, 3E) each, m and m/s."""
        return end_effector_features(self.raw(x), self.skeleton, self.config.fps, self._offsets(x, offsets))

    def discriminator_input(self, x: torch.Tensor, offsets=None) -> torch.Tensor:
        """Normalised x (N, T, D) -> D's input (N, T, config.d_input_dim): [p_end, v_end] (eq. 12), plus the
        contact bits thresholded at 0.5 with a straight-through gradient if D sees them (see "differs")."""
        if self.config.discriminator_joints == "all":
            parts = list(end_effector_features(self.raw(x), self.skeleton, self.config.fps, self._offsets(x, offsets),
                                               joints=range(self.skeleton.num_joints)))
        else:
            parts = list(self.end_effectors(x, offsets))
        if self.config.discriminator_contacts:
            cols = list(self.config.contact_dims)
            soft = self.raw(x)[..., cols]  # (N, T, 2) raw bits
            # 0/1 forward; backward the gradient of the soft bit clipped to [0, 1], so R cannot push a raw bit
            # without bound (an unclipped gradient lets it)
            clipped = soft.clamp(0.0, 1.0)
            parts.append((soft > 0.5).to(soft.dtype) + clipped - clipped.detach())
        return torch.cat(parts, -1)

    def forward(self, x: torch.Tensor, offsets=None) -> torch.Tensor:
        """x: (N, T, D) normalised x_RNN, offsets (N, J, 3) each motion's rest offsets or None -> R(x): (N, T, D)."""
        _check_state_tensor(x, self.skeleton, "x")
        if x.ndim != 3:
            raise ValueError(f"x must be (N, T, {self.config.dim}), got {tuple(x.shape)}")
        p_end, v_end = self.end_effectors(x, offsets)  # (N, T, 3E) each
        r_input = torch.cat((x.index_select(-1, self.cols), p_end, v_end), -1)  # R_input, eq. (11)
        h, _ = self.lstm(F.relu(self.fc1(r_input)))  # (N, T, lstm_width)
        delta = self.fc2(h)  # W_r2 lstm(relu(W_r1 R_input + b_r1)) + b_r2
        # R(x) = delta + x, only on the refined columns (all of them when contact-aware)  -- eq. (11)
        return x + torch.zeros_like(x).index_add(-1, self.cols, delta)


class Discriminator(nn.Module):
    """D of eq. (12), Fig. 5: [p_end, v_end(, contact bits)] (N, T, config.d_input_dim) -> probability of being
    real (N,).  The parts may be given separately: D(p_end, v_end) or D(d_input)."""

    def __init__(self, config: RefinerConfig | None = None):
        super().__init__()
        self.config = c = config or RefinerConfig()
        self.fc1 = nn.Linear(c.d_input_dim, c.d_fc_width)
        self.bilstm = nn.LSTM(c.d_fc_width, c.d_lstm_width, batch_first=True, bidirectional=True)
        self.fc2 = nn.Linear(2 * c.d_lstm_width, 1)

    def logits(self, *parts: torch.Tensor) -> torch.Tensor:
        """D's input (N, T, d_input_dim), or its parts p_end, v_end (N, T, 3E) [, bits] -> logit of D (N,)."""
        F_in = self.config.d_input_dim
        if not parts or any(p.ndim != 3 or p.shape[:2] != parts[0].shape[:2] for p in parts) or \
                sum(p.shape[-1] for p in parts) != F_in:
            raise ValueError(f"D's input must be (N, T, {F_in}) (p_end, v_end{', contact bits' if F_in % 3 else ''}), "
                             f"got {[tuple(p.shape) for p in parts]}")
        d_input = torch.cat(parts, -1)  # eq. (12)
        h, _ = self.bilstm(F.relu(self.fc1(d_input)))  # (N, T, 2 H)
        H = self.config.d_lstm_width
        last = torch.cat((h[:, -1, :H], h[:, 0, H:]), -1)  # forward pass's end, backward pass's end
        return self.fc2(last)[:, 0]  # W_d2 bilstm(...) + b_d2

    def forward(self, *parts: torch.Tensor) -> torch.Tensor:
        """D's input or its parts (see `logits`) -> D(x): (N,) in (0, 1)."""
        return torch.sigmoid(self.logits(*parts))


# ----------------------------------------------------------------------------- losses


def refiner_adversarial_loss(d_fake_logits: torch.Tensor) -> torch.Tensor:
    """(N,) logits of D(R(x_RNN)) -> -log D(R(x_RNN)), mean over motions   -- eq. (9)."""
    return F.softplus(-d_fake_logits).mean()  # -log sigmoid(l) = softplus(-l)


def discriminator_loss(d_real_logits: torch.Tensor, d_fake_logits: torch.Tensor) -> torch.Tensor:
    """(-log(1 - D(R(x_RNN))) - log D(x_real)) / 2, each term averaged over its motions   -- eq. (10) halved:
    the mean cross-entropy of D's softmax, chance level ln 2 (see "differs")."""
    return 0.5 * (F.softplus(d_fake_logits).mean() + F.softplus(-d_real_logits).mean())  # -log(1 - s(l)) = softplus(l)


def root_regularisation(x_raw: torch.Tensor, refined_raw: torch.Tensor) -> torch.Tensor:
    """Raw features (N, T, D) of x and R(x) -> ||root(x) - root(R(x))||^2 (sum over xyz, mean over N, T)."""
    return ((root_trajectory(x_raw)[0] - root_trajectory(refined_raw)[0]) ** 2).sum(-1).mean()


def pose_regularisation(x: torch.Tensor, refined: torch.Tensor, cols) -> torch.Tensor:
    """Normalised features (N, T, D) of x and R(x), the pose columns -> mean over N, T and the columns of
    (R(x) - x)^2: SimGAN's self-regularisation (Shrivastava et al. 2017) on the pose, in sd units."""
    cols = torch.as_tensor(list(cols), dtype=torch.long, device=x.device)
    return (refined.index_select(-1, cols) - x.index_select(-1, cols)).pow(2).mean()


def refiner_loss(d_fake_logits: torch.Tensor, x_raw: torch.Tensor, refined_raw: torch.Tensor,
                 lam: float = 20.0) -> dict:
    """E = -log D(R(x)) + lambda ||root(x) - root(R(x))||^2   -- eq. (13) -> {"loss", "adversarial", "root"}."""
    adv, reg = refiner_adversarial_loss(d_fake_logits), root_regularisation(x_raw, refined_raw)
    return {"loss": adv + lam * reg, "adversarial": adv.detach(), "root": reg.detach()}


# ----------------------------------------------------------------------------- training recipe (sec. 4.2.2)


class HistoryBuffer:
    """B refined motions from earlier refiners (sec. 4.2.2, after Shrivastava et al. 2017).

    fill(B samples) at the start; each D update takes b/2 current samples + b/2 from the buffer
    (`discriminator_batch`), then `replace` overwrites b/2 random entries with the current ones.
    """

    def __init__(self, capacity: int = 320, generator: torch.Generator | None = None):
        if capacity < 1:
            raise ValueError(f"HistoryBuffer: capacity must be >= 1, got {capacity}")
        self.capacity, self.generator, self.data = int(capacity), generator, None

    def __len__(self) -> int:
        return 0 if self.data is None else len(self.data)

    def fill(self, samples: torch.Tensor) -> None:
        """samples: (B, ...) -> the buffer's initial content (detached copies)."""
        if len(samples) != self.capacity:
            raise ValueError(f"HistoryBuffer.fill needs exactly {self.capacity} samples, got {len(samples)}")
        self.data = samples.detach().clone()

    def _need(self, n: int, what: str) -> None:
        if self.data is None:
            raise RuntimeError("HistoryBuffer is empty: call fill(samples) first")
        if not 0 <= n <= self.capacity:
            raise ValueError(f"HistoryBuffer.{what}: n = {n} not in 0..{self.capacity}")

    def sample(self, n: int) -> torch.Tensor:
        """n distinct random entries (n, ...)."""
        self._need(n, "sample")
        return self.data[torch.randperm(self.capacity, generator=self.generator)[:n]]

    def replace(self, new: torch.Tensor) -> torch.Tensor:
        """Overwrite len(new) distinct random entries with new (detached); returns their indices."""
        self._need(len(new), "replace")
        if new.shape[1:] != self.data.shape[1:]:
            raise ValueError(f"HistoryBuffer.replace: samples {tuple(new.shape[1:])} != stored "
                             f"{tuple(self.data.shape[1:])}")
        idx = torch.randperm(self.capacity, generator=self.generator)[: len(new)]
        self.data[idx] = new.detach().to(self.data.dtype)
        return idx

    def discriminator_batch(self, current: torch.Tensor) -> torch.Tensor:
        """current: (b/2, ...) refined now -> (b, ...): current then b/2 from the buffer."""
        return torch.cat((current, self.sample(len(current)).to(current.dtype)))


class AdversarialSchedule:
    """How many R and D updates each round gets (sec. 4.2.2).

    Round 0 is the warm-up: (warmup, warmup) updates.  Every later round: (r_updates, 1); after each
    D update `record(d_loss)` doubles r_updates if d_loss < low and halves it (at least 1) if > high.
    smooth > 1 applies the rule to the mean of the last ``smooth`` D losses instead (not in the paper: with
    the loss of single batches, rare spikes above ``high`` ratchet r down to 1 for good).
    """

    def __init__(self, warmup: int = 75, r_per_d: int = 5, low: float = 0.01, high: float = 1.0,
                 max_r_updates: int = 640, smooth: int = 1):
        if warmup < 0 or r_per_d < 1 or not 0 < low < high or max_r_updates < r_per_d or smooth < 1:
            raise ValueError(f"AdversarialSchedule: bad settings warmup={warmup}, r_per_d={r_per_d}, "
                             f"low={low}, high={high}, max_r_updates={max_r_updates}, smooth={smooth}")
        self.warmup, self.low, self.high, self.max_r_updates = warmup, low, high, max_r_updates
        self.smooth, self._recent = int(smooth), []  # the rule reads the mean of the last `smooth` D losses
        self.r_updates, self.round = r_per_d, 0
        self.history: list[int] = []  # r_updates of every round after the warm-up, for plots

    @classmethod
    def from_config(cls, config: RefinerConfig) -> AdversarialSchedule:
        return cls(config.warmup, config.r_per_d, config.d_loss_low, config.d_loss_high)

    def next_round(self) -> tuple[int, int]:
        """-> (refiner updates, discriminator updates) of the next round."""
        self.round += 1
        if self.round == 1 and self.warmup > 0:
            return self.warmup, self.warmup
        self.history.append(self.r_updates)
        return self.r_updates, 1

    def record(self, d_loss: float) -> int:
        """D's loss after its update -> R's update count for the next round."""
        if not math.isfinite(d_loss):
            raise FloatingPointError(f"discriminator loss is {d_loss}")
        self._recent = (self._recent + [float(d_loss)])[-self.smooth:]
        d_loss = sum(self._recent) / len(self._recent)  # smooth = 1: the paper's rule on each batch
        if d_loss < self.low:  # D too strong: train R more
            self.r_updates = min(2 * self.r_updates, self.max_r_updates)
        elif d_loss > self.high:  # D too weak: train R less
            self.r_updates = max(self.r_updates // 2, 1)
        return self.r_updates


# ----------------------------------------------------------------------------- adversarial training loop (sec. 4.2.2)


def _draw(sample, name: str, dim: int, min_n: int) -> tuple[torch.Tensor, torch.Tensor | None]:
    """Call a batch-making callable -> (x (N, T, dim) finite float tensor with N >= min_n, offsets (N, J, 3) or
    None); the callable returns x or (x, offsets), each motion's rest offsets (else a clear error)."""
    out = sample()
    x, off = out if isinstance(out, (tuple, list)) else (out, None)
    x = torch.as_tensor(x, dtype=torch.float32)
    if x.ndim != 3 or x.shape[-1] != dim or len(x) < min_n:
        raise ValueError(f"{name}() must return (N >= {min_n}, T, {dim}) normalised features, got {tuple(x.shape)}")
    if not torch.isfinite(x).all():
        raise ValueError(f"{name}() returned NaN or inf")
    if off is not None:
        off = torch.as_tensor(off, dtype=torch.float32)
        if off.ndim != 3 or len(off) != len(x) or off.shape[-1] != 3:
            raise ValueError(f"{name}() offsets must be (N={len(x)}, J, 3), got {tuple(off.shape)}")
    return x, off


def _take(off: torch.Tensor | None, n: int) -> torch.Tensor | None:
    return None if off is None else off[:n]


def _d_accuracy(real_logits: torch.Tensor, fake_logits: torch.Tensor) -> tuple[float, float]:
    """(N,), (M,) logits -> fraction of real motions called real, fraction of refined ones called fake."""
    return float((real_logits > 0).float().mean()), float((fake_logits < 0).float().mean())


def _refiner_step(refiner, discriminator, opt_r, batch, lam: float, adversarial: bool) -> dict:
    """One R update on batch = (x (N, T, D), offsets): eq. (13) if adversarial, else only
    lambda ||root(x) - root(R(x))||^2; both plus config.pose_lam times the pose self-regularisation."""
    x, off = batch
    refined = refiner(x, off)
    if adversarial:
        logits = discriminator.logits(refiner.discriminator_input(refined, off))
        terms = refiner_loss(logits, refiner.raw(x), refiner.raw(refined), lam)
    else:  # warm-up: the self-regularisation term of eq. (13) alone (SimGAN's refiner pre-training)
        reg = root_regularisation(refiner.raw(x), refiner.raw(refined))
        terms = {"loss": lam * reg, "adversarial": torch.tensor(float("nan")), "root": reg.detach()}
    pose = pose_regularisation(x, refined, refiner.config.pose_dims)
    terms["pose"] = pose.detach()
    if refiner.config.pose_lam > 0:
        terms["loss"] = terms["loss"] + refiner.config.pose_lam * pose
    if refiner.config.leg_pose_lam > 0:
        legs = pose_regularisation(x, refined, leg_columns(refiner.skeleton))
        terms["legs"] = legs.detach()
        terms["loss"] = terms["loss"] + refiner.config.leg_pose_lam * legs
    if not torch.isfinite(terms["loss"]):
        raise FloatingPointError(f"refiner loss is {float(terms['loss'])}")
    opt_r.zero_grad(set_to_none=True)
    terms["loss"].backward()
    opt_r.step()
    return {k: float(v.detach()) for k, v in terms.items()}


def _discriminator_step(refiner, discriminator, opt_d, buffer: HistoryBuffer, batch, real, half: int) -> dict:
    """One D update (eq. 10): real (x, offsets) vs b/2 refined now + b/2 from the buffer; then refresh the buffer.
    The buffer holds D's view of the refined motions (`Refiner.discriminator_input`), fixed once refined."""
    (x, off), (x_real, off_real) = batch, real
    with torch.no_grad():
        current = refiner.discriminator_input(refiner(x[:half], _take(off, half)), _take(off, half))  # no grad to R
        fake = buffer.discriminator_batch(current)  # (b, T, F)
        real_in = refiner.discriminator_input(x_real, off_real)
    l_real, l_fake = discriminator.logits(real_in), discriminator.logits(fake)
    loss = discriminator_loss(l_real, l_fake)
    if not torch.isfinite(loss):
        raise FloatingPointError(f"discriminator loss is {float(loss)}")
    opt_d.zero_grad(set_to_none=True)
    loss.backward()
    opt_d.step()
    buffer.replace(current)  # b/2 random entries <- the newest refined motions (sec. 4.2.2)
    acc_real, acc_fake = _d_accuracy(l_real.detach(), l_fake.detach())
    return {"d_loss": float(loss.detach()), "d_acc_real": acc_real, "d_acc_fake": acc_fake}


def _fill_buffer(refiner, draw_rnn, buffer: HistoryBuffer) -> None:
    """Generate B refined motions with the initial R ("we generate B fake data in the very beginning")."""
    chunks, n = [], 0
    with torch.no_grad():
        while n < buffer.capacity:
            x, off = draw_rnn()
            chunks.append(refiner.discriminator_input(refiner(x, off), off))
            n += len(chunks[-1])
    buffer.fill(torch.cat(chunks)[: buffer.capacity])


def train_refiner(refiner: Refiner, discriminator: Discriminator, sample_rnn_batch, sample_real_batch, *,
                  iterations: int, config: RefinerConfig | None = None, schedule: AdversarialSchedule | None = None,
                  generator: torch.Generator | None = None, seed: int = 0, progress: bool = True,
                  max_refiner_updates: int | None = None):
    """Adversarial training of R and D, sec. 4.2.2 -> a History (history.py).

    sample_rnn_batch() -> (N, T, D) normalised x_RNN, sample_real_batch() -> (N', T, D) normalised
    mocap windows (N >= b/2, N' >= 1; the same normalisation as ``refiner.mean/std``); either may return
    (features, offsets (N, J, 3)) instead, each motion's rest offsets for the kinematics of R and D.
    Recipe: fill the HistoryBuffer with B refined motions; warm-up: ``schedule.warmup`` R updates on the
    self-regularisation term of eq. (13), then as many D updates (eq. 10); then ``iterations`` rounds,
    each of r R updates (eq. 13) and one D update, with r adapted by ``schedule.record(d_loss)``.
    Every D batch is b/2 current refined motions + b/2 from the buffer, then b/2 buffer entries are
    replaced.  RMSProp, lr ``config.lr_refiner`` / ``config.lr_discriminator``, alpha ``config.rmsprop_decay``.
    max_refiner_updates: stop after the round in which R's adversarial updates reach this many (a CPU budget;
    the rounds then number fewer than ``iterations`` when r grows).

    History.step, one value per round: "loss" (R's eq. 13 loss, mean over the round's R updates),
    "adversarial", "root", "d_loss", "d_acc_real", "d_acc_fake" (D's loss and accuracies on the batch of
    its update) and "r_updates" (the r used in that round).  ``history.warmup`` is a History with one
    value per warm-up update: "loss" (R's lambda * root term), "root", "d_loss", "d_acc_real", "d_acc_fake".
    """
    from tqdm.auto import tqdm

    c = config or refiner.config
    if not isinstance(iterations, int) or iterations < 0:
        raise ValueError(f"iterations must be an int >= 0, got {iterations!r}")
    schedule = schedule or AdversarialSchedule.from_config(c)
    generator = generator or torch.Generator().manual_seed(int(seed))
    buffer = HistoryBuffer(c.buffer_size, generator)
    half = c.d_batch // 2
    opt_r = torch.optim.RMSprop(refiner.parameters(), lr=c.lr_refiner, alpha=c.rmsprop_decay)
    opt_d = torch.optim.RMSprop(discriminator.parameters(), lr=c.lr_discriminator, alpha=c.rmsprop_decay)

    def rnn() -> tuple:
        return _draw(sample_rnn_batch, "sample_rnn_batch", c.dim, half)

    def real() -> tuple:
        return _draw(sample_real_batch, "sample_real_batch", c.dim, 1)

    history, warm, start = History(), History(), time.perf_counter()
    history.warmup = warm
    refiner.train()
    discriminator.train()
    _fill_buffer(refiner, rnn, buffer)
    n_r, n_d = schedule.next_round() if schedule.warmup > 0 else (0, 0)
    for _ in range(n_r):  # warm-up of R: self-regularisation only
        t = _refiner_step(refiner, discriminator, opt_r, rnn(), c.lam, adversarial=False)
        warm.log_step({"loss": t["loss"], "root": t["root"]})
    for _ in range(n_d):  # warm-up of D: real vs refined
        warm.log_step(_discriminator_step(refiner, discriminator, opt_d, buffer, rnn(), real(), half))
    bar = dict(desc="refiner GAN") if progress else dict(disable=True)  # TQDM_DISABLE=1 is honoured
    done = 0
    for _ in tqdm(range(iterations), **bar):
        if max_refiner_updates is not None and done >= max_refiner_updates:
            break
        n_r, n_d = schedule.next_round()
        steps = [_refiner_step(refiner, discriminator, opt_r, rnn(), c.lam, adversarial=True) for _ in range(n_r)]
        logs = {k: float(np.mean([s[k] for s in steps])) for k in ("loss", "adversarial", "root", "pose")}
        for _ in range(n_d):
            logs.update(_discriminator_step(refiner, discriminator, opt_d, buffer, rnn(), real(), half))
        logs["r_updates"] = n_r
        done += n_r
        schedule.record(logs["d_loss"])
        history.log_step(logs)
    history.end_epoch()
    history.seconds = time.perf_counter() - start
    return history
