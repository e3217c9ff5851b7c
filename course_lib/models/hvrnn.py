"""Hierarchical variational RNN of Ghorbani et al. 2020 (paper C): Motion Words + Motion Cells.

Taught in notebooks/05_hierarchical_vrnn.ipynb.

A sequence of poses x_{1:T} (``quaternion_root``: 21 local unit quaternions + 6 root features
= 90 values at 30 fps) is cut into N = T / l sub-sequences of l frames; each becomes a Motion
Word w_n = f_enc^w(x_{nl:(n+1)l}) (eq. 1).  A Motion Cell -- a conditional VAE attached to two
stacked GRU cells (eq. 4-13) -- models the words autoregressively, conditioned on the attributes
a_n = f_c(action, style) (eq. 2), and f_dec^w turns each output word back into l poses (eq. 3),
whose quaternions are normalised to unit length.  The loss is eq. 14-15: the hierarchical
geodesic reconstruction (eq. 17-23), lambda_KL x KL(posterior || prior) with warm-up /
annealing / cool-down, lambda_CL x the classifier loss (eq. 24) scheduled from 0 upward and the
unit-norm constraint (eq. 26).  Exposure bias: scheduled dropping of Motion Words (sec. 4.2),
or input noise as the alternative.  Sampling is Algorithm 2 from a learned Gaussian initial
state per attribute combination.  Ablations are configurations: ``hierarchical=False`` (SL),
``use_alpha=False`` (NL), ``lambda_cl=0`` (NC).  The 1-D convolutional denoising autoencoder
of Table 1 is `DenoisingAutoencoder`.

Differs from the paper:
- sizes shrunk for a 2-core CPU in ``HvrnnConfig.cpu()``: GRUs 2 x 512 -> 2 x 128 (h of 256),
  D_w 96 -> 64, D_z 96 -> 32, encoder/prior MLPs 4 -> 2 hidden layers of 128; the defaults are
  the paper's sizes (Table 1);
- the 6 root features (velocities, height, yaw rate, pitch, roll) have no loss in the paper's
  text; here they are standardised inside the model and get a squared error with weight
  ``root_weight``;
- the impact factors alpha_k (eq. 23) are divided by their mean, so that the NL ablation
  (all alpha_k = 1) has the same overall scale; a leaf's alpha is its end-site length;
- the reconstruction and KL terms are averaged per frame (the paper sums over the sequence;
  a constant factor) and the reconstruction is multiplied by ``rec_weight`` (the implicit
  observation noise of a deterministic decoder);
- scheduled word dropping replaces the word fed to the transition f_h (not the posterior,
  which must see the data) by the cell's own output w~_n, with a rate growing linearly;
- the classifiers of L_CL (eq. 24) are frozen `MotionClassifier`s passed in with
  `set_classifiers`; β is one weight for the feature l2 term (made relative to the size of the
  real features) and one for the cross-entropy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from course_lib.datasets import FixedDofs
from course_lib.models.vae import linear_beta
from course_lib.rotations import matrix_geodesic, quat_geodesic, quat_to_matrix
from course_lib.skeleton import Skeleton

__all__ = ["DaeConfig", "DenoisingAutoencoder", "HierarchicalVrnn", "HvrnnConfig", "PoseCoding", "cl_weight",
           "diag_gaussian_kl", "geodesic", "impact_factors", "kl_weight", "normalize_pose", "normalize_quaternions",
           "reconstruction_loss", "unit_norm_loss", "word_drop_rate"]

NUM_ROOT = 6  # root features of quaternion_root


# ----------------------------------------------------------------------------- configuration


@dataclass
class HvrnnConfig:
    """Hierarchical VRNN; defaults are the paper's sizes (Table 1), ``cpu()`` the course's preset."""

    num_joints: int = 21  # pose = num_joints x 4 quaternion values + 6 root features
    n_actions: int = 4  # walk, jog, jump, lift
    n_styles: int = 2  # A, B (the analogue of the paper's gender)
    d_a: int = 8  # attribute features a_n = f_c(c_n)
    word_len: int = 3  # l, frames per Motion Word (paper's best)
    d_w: int = 96  # Motion Word size (32 DoF x 3 frames)
    d_z: int = 96  # latent size
    gru: int = 512  # each of the two stacked GRU cells (h of 1024)
    mlp: int = 128  # hidden width of every MLP of Table 1
    enc_layers: int = 4  # hidden layers of f_enc^mu/sigma and f_prior^mu/sigma (Table 1: 4)
    hierarchical: bool = True  # False: Proposed(SL), poses fed to the Motion Cell directly
    use_alpha: bool = True  # False: Proposed(NL), all alpha_k = 1
    distance: str = "d1"  # d1 | d2 | d3 (eq. 17, 18, 20) | log (eq. 21, via rotation matrices)
    rec_weight: float = 10.0  # multiplies the reconstruction term
    root_weight: float = 1.0  # weight of the root features' squared error (standardised units)
    lambda_ang: float = 0.1  # weight of the unit-norm constraint, eq. (26)
    lambda_cl: float = 0.1  # final lambda_CL of eq. (14) (the paper plots it, gives no value); 0 = Proposed(NC)
    cl_feature_weight: float = 1.0  # beta of the feature-layer l2 term of eq. (24)
    cl_label_weight: float = 1.0  # beta of the label cross-entropy of eq. (24)
    kl_warmup: int = 200  # steps with lambda_KL = 0 (warm-up phase)
    kl_anneal: int = 1000  # steps from 0 to 1 (annealing); then 1 (cool-down)
    cl_start: int = 300  # steps with lambda_CL = 0
    cl_ramp: int = 1000  # steps from 0 to lambda_cl
    exposure: str = "drop"  # drop (scheduled word dropping) | noise (input noise) | none
    drop_max: float = 0.3  # final word-dropping rate / input-noise std (normalised word units)
    drop_ramp: int = 2000  # steps from 0 to drop_max
    init_std_floor: float = 1e-3  # smallest std of the learned initial state

    @classmethod
    def cpu(cls, **overrides) -> HvrnnConfig:
        """GRU 2 x 128, D_w 64, D_z 32, 2-layer encoder/prior MLPs (a few minutes on one CPU core)."""
        return cls(**{"gru": 128, "d_w": 64, "d_z": 32, "enc_layers": 2, **overrides})

    def __post_init__(self):
        if self.distance not in ("d1", "d2", "d3", "log"):
            raise ValueError(f"distance must be d1, d2, d3 or log, got {self.distance!r}")
        if self.exposure not in ("drop", "noise", "none"):
            raise ValueError(f"exposure must be drop, noise or none, got {self.exposure!r}")
        if min(self.word_len, self.d_w, self.d_z, self.gru, self.mlp, self.d_a) < 1:
            raise ValueError(f"sizes must be positive: {self}")

    @property
    def pose_dim(self) -> int:
        return 4 * self.num_joints + NUM_ROOT

    @property
    def frames_per_word(self) -> int:
        return self.word_len if self.hierarchical else 1


# ----------------------------------------------------------------------------- the formulas


def impact_factors(skeleton: Skeleton, normalize: bool = True) -> np.ndarray:
    """Hierarchical impact factors alpha_k (J,) from bone lengths -- Ghorbani eq. (23):

        alpha_k = max_{j in children(k)} (alpha_j + l_{k-j}),

    the longest path from joint k down to an end effector; a leaf's alpha is the length of its end
    site (0 without one).  normalize: divide by the mean so that sum_k alpha_k = J.
    """
    lengths = skeleton.bone_lengths()  # (J,) bone from parent to joint
    alpha = np.zeros(skeleton.num_joints)
    for k in reversed(range(skeleton.num_joints)):  # parents come before children
        kids = skeleton.children(k)
        if kids:
            alpha[k] = max(alpha[j] + lengths[j] for j in kids)
        elif k in skeleton.end_sites:
            alpha[k] = float(np.linalg.norm(skeleton.end_sites[k]))
    if normalize:
        if alpha.sum() <= 0:
            raise ValueError("impact_factors: every alpha is 0 (a skeleton with no bone lengths)")
        alpha = alpha / alpha.mean()
    return alpha


def geodesic(q: torch.Tensor, q_hat: torch.Tensor, kind: str = "d1") -> torch.Tensor:
    """(..., 4), (..., 4) unit quaternions -> (...) distance: d1/d2/d3 (eq. 17, 18, 20) or 'log', the
    SO(3) log-map angle of eq. (21) on the rotation matrices (rotations.py holds the formulas)."""
    if kind == "log":
        return matrix_geodesic(quat_to_matrix(q), quat_to_matrix(q_hat))
    return quat_geodesic(q, q_hat, kind)


def normalize_quaternions(q: torch.Tensor, num_joints: int = 21) -> torch.Tensor:
    """(..., 4J) raw quaternion outputs -> each quaternion divided by its norm (Fig. 2's red block)."""
    q = q.unflatten(-1, (num_joints, 4))
    return (q / q.norm(dim=-1, keepdim=True).clamp_min(1e-6)).flatten(-2)


def normalize_pose(x: torch.Tensor, num_joints: int = 21) -> torch.Tensor:
    """(..., 4J + 6) raw outputs -> the same with unit quaternions (root features unchanged)."""
    return torch.cat((normalize_quaternions(x[..., : 4 * num_joints], num_joints), x[..., 4 * num_joints:]), -1)


def unit_norm_loss(q_raw: torch.Tensor) -> torch.Tensor:
    """L_q-norm = sum_k | ||q~_k||^2 - 1 |  -- eq. (26).  q_raw: (..., J, 4) -> (...)."""
    return (q_raw.pow(2).sum(-1) - 1.0).abs().sum(-1)


def reconstruction_loss(q: torch.Tensor, q_hat: torch.Tensor, alpha: torch.Tensor, kind: str = "d1") -> torch.Tensor:
    """L_rec(t) = sum_k alpha_k d(X_t^k, X~_t^k)  -- eq. (22).  q, q_hat: (..., J, 4), alpha (J,) -> (...)."""
    return (alpha * geodesic(q, q_hat, kind)).sum(-1)


def diag_gaussian_kl(mu_q, std_q, mu_p, std_p) -> torch.Tensor:
    """KL(N(mu_q, diag std_q^2) || N(mu_p, diag std_p^2)), summed over the last dim: (..., D) x 4 -> (...)."""
    var_q, var_p = std_q.pow(2), std_p.pow(2)
    return 0.5 * (torch.log(var_p / var_q) + (var_q + (mu_q - mu_p).pow(2)) / var_p - 1.0).sum(-1)


def kl_weight(step: int, warmup: int, anneal: int) -> float:
    """lambda_KL: 0 for `warmup` steps, then linear to 1 over `anneal` steps, then 1 (sec. 3.5.1, supp. Fig. 1)."""
    return linear_beta(max(0, step - warmup), anneal)


def cl_weight(step: int, start: int, ramp: int, final: float) -> float:
    """lambda_CL: 0 for `start` steps, then linear to `final` over `ramp` steps (supp. Fig. 1)."""
    return linear_beta(max(0, step - start), ramp, final)


def word_drop_rate(step: int, ramp: int, final: float) -> float:
    """Scheduled dropping rate of Motion Words (sec. 4.2, strategy ii): linear 0 -> final over `ramp` steps."""
    return linear_beta(step, ramp, final)


# ----------------------------------------------------------------------------- building blocks


def mlp(d_in: int, hidden: int, layers: int, d_out: int, last: nn.Module | None = None) -> nn.Sequential:
    """layers x [FC(hidden) + ELU] + FC(d_out) (+ last), Table 1's pattern; Kaiming-initialised (sec. 4.2)."""
    mods, d = [], d_in
    for _ in range(layers):
        mods += [nn.Linear(d, hidden), nn.ELU()]
        d = hidden
    mods.append(nn.Linear(d, d_out))
    if last is not None:
        mods.append(last)
    net = nn.Sequential(*mods)
    for m in net:
        if isinstance(m, nn.Linear):
            nn.init.kaiming_normal_(m.weight, nonlinearity="relu")
            nn.init.zeros_(m.bias)
    return net


class GaussianHead(nn.Module):
    """(f^mu, f^sigma): two MLPs of Table 1, the second ending in Softplus.  x (..., D) -> mu, sigma (..., d_z)."""

    def __init__(self, d_in: int, hidden: int, layers: int, d_z: int):
        super().__init__()
        self.mu = mlp(d_in, hidden, layers, d_z)
        self.sigma = mlp(d_in, hidden, layers, d_z, nn.Softplus())

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.mu(x), self.sigma(x) + 1e-4  # + 1e-4: sigma > 0 for the KL's log


def check_poses(x: torch.Tensor, dim: int, name: str = "x") -> None:
    """Raise a ValueError naming the problem unless x is a finite (N, T, dim) tensor."""
    if not torch.is_tensor(x) or x.ndim != 3 or x.shape[-1] != dim:
        shape = tuple(x.shape) if torch.is_tensor(x) else type(x).__name__
        raise ValueError(f"{name} must be (N, T, {dim}) quaternion_root features ({(dim - NUM_ROOT) // 4} joints "
                         f"x 4 + {NUM_ROOT}), got {shape}")
    if not torch.isfinite(x).all():
        raise ValueError(f"{name} contains NaN or inf")


# ----------------------------------------------------------------------------- the model


class PoseCoding:
    """What every lesson-05 generator shares (HierarchicalVrnn, baselines.AttributeRnn): raw poses <->
    model space (root features standardised with buffers root_mean/root_std), the training data's fixed
    degrees of freedom (buffers fixed_mask/fixed_values, `datasets.FixedDofs`) and attribute coding."""

    def register_pose_buffers(self, pose_dim: int) -> None:
        """The normalisation statistics, set by `set_stats` and saved with the weights."""
        self.register_buffer("root_mean", torch.zeros(NUM_ROOT))
        self.register_buffer("root_std", torch.ones(NUM_ROOT))
        self.register_buffer("fixed_mask", torch.zeros(pose_dim, dtype=torch.bool))
        self.register_buffer("fixed_values", torch.zeros(pose_dim))

    def set_stats(self, x: torch.Tensor) -> None:
        """Root-feature mean/std and the fixed degrees of freedom from training poses x (N, T, D) (or (M, D)),
        and a data-dependent start: the output layer begins at the mean training pose, its weights scaled
        down by 10 (faster early training)."""
        root = x.reshape(-1, x.shape[-1])[:, -NUM_ROOT:].double()
        self.root_mean.copy_(root.mean(0).float())
        self.root_std.copy_(root.std(0).clamp_min(1e-3).float())
        fixed = FixedDofs.detect(x)
        self.fixed_mask.copy_(torch.from_numpy(fixed.mask))
        self.fixed_values.copy_(torch.from_numpy(fixed.values).float())
        last, frames = self.output_layer()
        with torch.no_grad():
            last.weight.mul_(0.1)
            last.bias.copy_(self.to_model(x.reshape(-1, x.shape[-1])).mean(0).repeat(frames))

    def to_model(self, x: torch.Tensor) -> torch.Tensor:
        """raw poses (..., D) -> model space: quaternions as they are, root standardised."""
        return torch.cat((x[..., :-NUM_ROOT], (x[..., -NUM_ROOT:] - self.root_mean) / self.root_std), -1)

    def fixed_dofs(self):
        """The training data's fixed degrees of freedom (`datasets.FixedDofs`) recorded by `set_stats`."""
        return FixedDofs(mask=self.fixed_mask.numpy(), values=self.fixed_values.double().numpy())

    def from_model(self, y: torch.Tensor) -> torch.Tensor:
        """model-space outputs (..., D) -> raw poses with unit quaternions, the fixed degrees of freedom at
        the data's constants (the same rule for every lesson-05 generator)."""
        raw = torch.cat((y[..., :-NUM_ROOT], y[..., -NUM_ROOT:] * self.root_std + self.root_mean), -1)
        raw = torch.where(self.fixed_mask, self.fixed_values.to(raw.dtype), raw)
        return normalize_pose(raw, self.config.num_joints)

    def attributes(self, action, style) -> tuple[torch.Tensor, torch.Tensor]:
        """action (N,), style (N,) ids -> a = f_c(one-hot) (N, d_a), combination index (N,)."""
        c = self.config
        action, style = torch.as_tensor(action).long().reshape(-1), torch.as_tensor(style).long().reshape(-1)
        if len(action) != len(style):
            raise ValueError(f"action and style must have the same length, got {len(action)} and {len(style)}")
        if (action < 0).any() or (action >= c.n_actions).any() or (style < 0).any() or (style >= c.n_styles).any():
            raise ValueError(f"action ids must be in [0, {c.n_actions}) and style ids in [0, {c.n_styles})")
        onehot = torch.cat((F.one_hot(action, c.n_actions), F.one_hot(style, c.n_styles)), -1).float()
        return self.f_c(onehot), action * c.n_styles + style


class HierarchicalVrnn(PoseCoding, nn.Module):
    """Motion Words (eq. 1-3) + Motion Cells (Algorithms 1-2, eq. 4-13) + the loss of eq. 14-26.

    Poses are raw ``quaternion_root`` features (N, T, 4J + 6); the root part is standardised
    inside with buffers set by `set_stats`.  Attributes are integer ids action (N,), style (N,).
    """

    def __init__(self, config: HvrnnConfig | None = None):
        super().__init__()
        self.config = c = config or HvrnnConfig()
        D, L = c.pose_dim, c.frames_per_word
        d_w = c.d_w if c.hierarchical else D
        self.f_c = nn.Linear(c.n_actions + c.n_styles, c.d_a)  # a_n = f_c(c_n)
        if c.hierarchical:  # eq. (1), (3); Table 1
            self.f_enc_w = mlp(L * D, c.mlp, 2, d_w, nn.ELU())
            self.f_dec_w = mlp(d_w, c.mlp, 2, L * D)
        d_fw = c.d_w  # size of the word and latent features f_w(w), f_z(z) (Table 1: 96)
        self.f_w = mlp(d_w, c.mlp, 2, d_fw, nn.ELU())  # Motion Word features
        self.f_z = mlp(c.d_z, c.mlp, 2, d_fw, nn.ELU())  # latent features
        H = 2 * c.gru
        self.posterior = GaussianHead(d_fw + H + c.d_a, c.mlp, c.enc_layers, c.d_z)  # eq. (5)
        self.prior = GaussianHead(H + c.d_a, c.mlp, c.enc_layers, c.d_z)  # eq. (8)
        self.f_dec = mlp(d_fw + H + c.d_a, c.mlp, 2, d_w, nn.ELU() if c.hierarchical else None)  # eq. (10)
        self.gru1 = nn.GRUCell(2 * d_fw, c.gru)  # f_h: two stacked GRU cells, eq. (11)
        self.gru2 = nn.GRUCell(c.gru, c.gru)
        n_attr = c.n_actions * c.n_styles  # a learned Gaussian initial state per attribute combination
        self.h0_mu = nn.Parameter(torch.zeros(n_attr, H))
        self.h0_logstd = nn.Parameter(torch.full((n_attr, H), math.log(0.1)))
        skel = Skeleton.canonical()
        alpha = impact_factors(skel) if c.use_alpha else np.ones(c.num_joints)
        if len(alpha) != c.num_joints:
            raise ValueError(f"the canonical skeleton has {len(alpha)} joints, config says {c.num_joints}")
        self.register_buffer("alpha", torch.tensor(alpha, dtype=torch.float32))
        self.register_pose_buffers(c.pose_dim)
        self.register_buffer("step", torch.zeros((), dtype=torch.long))  # optimiser steps seen (schedules)
        self.classifiers: list = []  # frozen MotionClassifiers for L_CL, not part of the state_dict

    # --- data plumbing -------------------------------------------------------------------

    def output_layer(self) -> tuple[nn.Linear, int]:
        """The last linear layer of the pose output (f_dec^w, or f_dec for SL) and the frames it emits."""
        return (self.f_dec_w if self.config.hierarchical else self.f_dec)[-1], self.config.frames_per_word

    def set_classifiers(self, classifiers: list) -> None:
        """Frozen attribute classifiers (task 'action' / 'style') for L_CL, eq. (24)."""
        for clf in classifiers:
            clf.eval().requires_grad_(False)
        self.classifiers = list(classifiers)

    def initial_state(self, combo: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        """h_0 ~ N(mu_c, diag sigma_c^2) of each sequence's attribute combination: (N,) -> (N, 2 gru)."""
        std = self.h0_logstd[combo].exp().clamp_min(self.config.init_std_floor)
        eps = torch.randn(std.shape, generator=generator)
        return self.h0_mu[combo] + std * eps

    def words(self, y: torch.Tensor) -> torch.Tensor:
        """model-space poses (N, T, D) -> Motion Words (N, T / l, d_w)  -- eq. (1)."""
        N, T, D = y.shape
        L = self.config.frames_per_word
        if T % L:
            raise ValueError(f"sequence length {T} is not a multiple of the word length {L}")
        blocks = y.reshape(N, T // L, L * D)
        return self.f_enc_w(blocks) if self.config.hierarchical else blocks

    def poses(self, w: torch.Tensor) -> torch.Tensor:
        """Motion Words (N, n, d_w) -> model-space poses (N, n l, D), quaternions not yet normalised  -- eq. (3)."""
        out = self.f_dec_w(w) if self.config.hierarchical else w
        return out.reshape(w.shape[0], -1, self.config.pose_dim)

    def transition(self, fw: torch.Tensor, fz: torch.Tensor, h: torch.Tensor) -> torch.Tensor:
        """h_n = f_h(f_w(w_n), f_z(z_n), h_{n-1}): two stacked GRU cells, h = [h1, h2]  -- eq. (11)."""
        g = self.config.gru
        h1 = self.gru1(torch.cat((fw, fz), -1), h[:, :g])
        h2 = self.gru2(h1, h[:, g:])
        return torch.cat((h1, h2), -1)

    # --- Algorithm 1 (training) -----------------------------------------------------------

    def cell_forward(self, w: torch.Tensor, a: torch.Tensor, h: torch.Tensor, eps: torch.Tensor | None = None):
        """FORWARD of Algorithm 1: w_n (N, d_w), a_n (N, d_a), h_{n-1} (N, H) -> (w~_n, f_w(w_n), f_z(z_n), mu_q,
        sigma_q, mu_p, sigma_p), before the state update (done by the caller with the word it chooses)."""
        fw = self.f_w(w)
        mu_q, sd_q = self.posterior(torch.cat((fw, h, a), -1))  # eq. (5)
        eps = torch.randn_like(mu_q) if eps is None else eps
        z = mu_q + sd_q * eps  # eq. (6), reparameterisation
        mu_p, sd_p = self.prior(torch.cat((h, a), -1))  # eq. (8)
        fz = self.f_z(z)
        w_out = self.f_dec(torch.cat((fz, h, a), -1))  # eq. (10)
        return w_out, fw, fz, mu_q, sd_q, mu_p, sd_p

    def _exposure(self, w: torch.Tensor, w_out: torch.Tensor, fw: torch.Tensor) -> torch.Tensor:
        """The word feature fed to f_h: the data's, or (scheduled dropping) the cell's own output, or noisy."""
        c = self.config
        if not self.training or c.exposure == "none":
            return fw
        rate = word_drop_rate(int(self.step), c.drop_ramp, c.drop_max)
        if c.exposure == "noise":
            return self.f_w(w + rate * torch.randn_like(w))
        keep = (torch.rand(w.shape[0], 1) >= rate).float()
        return keep * fw + (1 - keep) * self.f_w(w_out)

    def reconstruct(self, x: torch.Tensor, action, style, generator: torch.Generator | None = None) -> dict:
        """Teacher-forced pass (Algorithm 1 over all words).  x (N, T, D) raw -> dict with "y_hat" model-space
        outputs (N, T, D) (quaternions raw), "x_hat" raw poses with unit quaternions, and the Gaussians
        (N, n, d_z) "mu_q", "sd_q", "mu_p", "sd_p"."""
        check_poses(x, self.config.pose_dim)
        a, combo = self.attributes(action, style)
        if len(a) != len(x):
            raise ValueError(f"{len(x)} sequences but {len(a)} attribute ids")
        w = self.words(self.to_model(x))  # (N, n, d_w)
        h = self.initial_state(combo, generator)
        outs, stats = [], []
        for n in range(w.shape[1]):
            eps = torch.randn((len(x), self.config.d_z), generator=generator)
            w_out, fw, fz, *gauss = self.cell_forward(w[:, n], a, h, eps)
            h = self.transition(self._exposure(w[:, n], w_out, fw), fz, h)
            outs.append(w_out)
            stats.append(gauss)
        y_hat = self.poses(torch.stack(outs, 1))  # (N, T, D)
        mu_q, sd_q, mu_p, sd_p = (torch.stack(s, 1) for s in zip(*stats, strict=True))
        return {"y_hat": y_hat, "x_hat": self.from_model(y_hat), "mu_q": mu_q, "sd_q": sd_q, "mu_p": mu_p,
                "sd_p": sd_p}

    def classifier_loss(self, x: torch.Tensor, x_hat: torch.Tensor, labels: dict) -> torch.Tensor:
        """L_CL = sum_c [beta_f ||l(X) - l(X~)||^2 / ||l(X)||^2 + beta_y CE(p(a|X~), a)]  -- eq. (24);
        (N, T, D) x 2 -> ().  The l2 term is relative to the size of the real features (batch means)."""
        c, total = self.config, x.new_zeros(())
        for clf in self.classifiers:
            with torch.no_grad():
                f_real = clf.features(x)
            f_fake = clf.features(x_hat)
            # relative l2 error of the feature layer: scale-free, whatever the classifier's activation sizes
            total = total + c.cl_feature_weight * F.mse_loss(f_fake, f_real) / f_real.pow(2).mean().clamp_min(1e-6)
            total = total + c.cl_label_weight * F.cross_entropy(clf.fc(f_fake), labels[clf.config.task])
        return total

    def loss(self, batch: dict, generator: torch.Generator | None = None) -> dict:
        """batch {"x": (N, T, D) raw poses, "action_id": (N,), "style_id": (N,)} -> loss terms of eq. (14)."""
        c = self.config
        x = batch["x"]
        out = self.reconstruct(x, batch["action_id"], batch["style_id"], generator)
        J, T = c.num_joints, x.shape[1]
        q = x[..., : 4 * J].unflatten(-1, (J, 4))
        q_raw = out["y_hat"][..., : 4 * J].unflatten(-1, (J, 4))
        q_hat = out["x_hat"][..., : 4 * J].unflatten(-1, (J, 4))
        rec_q = reconstruction_loss(q, q_hat, self.alpha, c.distance).mean()  # eq. (22), per frame
        rec_root = (out["y_hat"][..., -NUM_ROOT:] - self.to_model(x)[..., -NUM_ROOT:]).pow(2).sum(-1).mean()
        kl = diag_gaussian_kl(out["mu_q"], out["sd_q"], out["mu_p"], out["sd_p"]).sum(1).mean() / T  # per frame
        ang = unit_norm_loss(q_raw).mean()  # eq. (26)
        step = int(self.step)
        lam_kl, lam_cl = kl_weight(step, c.kl_warmup, c.kl_anneal), cl_weight(step, c.cl_start, c.cl_ramp, c.lambda_cl)
        cl = x.new_zeros(())
        if self.classifiers and lam_cl > 0:
            labels = {"action": torch.as_tensor(batch["action_id"]).long(),
                      "style": torch.as_tensor(batch["style_id"]).long()}
            cl = self.classifier_loss(x, out["x_hat"], labels)
        rec = c.rec_weight * (rec_q + c.root_weight * rec_root)
        total = rec + lam_kl * kl + lam_cl * cl + c.lambda_ang * ang  # eq. (14)-(15)
        if self.training:
            self.step += 1
        return {"loss": total, "rec": rec_q, "rec_root": rec_root, "kl": kl, "cl": cl, "ang": ang,
                "lambda_kl": lam_kl, "lambda_cl": lam_cl}

    # --- Algorithm 2 (sampling) -----------------------------------------------------------

    @torch.no_grad()
    def sample(self, action, style, frames: int, generator: torch.Generator | None = None) -> torch.Tensor:
        """Algorithm 2 from h_0 ~ N(mu_c, sigma_c): action (N,), style (N,) ids -> raw poses (N, frames, D)
        with unit quaternions (frames rounded up to whole words, then cut)."""
        if frames < 1:
            raise ValueError(f"frames must be >= 1, got {frames}")
        a, combo = self.attributes(action, style)
        h = self.initial_state(combo, generator)
        n_words = -(-frames // self.config.frames_per_word)
        words = []
        for _ in range(n_words):
            mu_p, sd_p = self.prior(torch.cat((h, a), -1))  # eq. (8)
            z = mu_p + sd_p * torch.randn(mu_p.shape, generator=generator)  # eq. (12)
            fz = self.f_z(z)
            w_out = self.f_dec(torch.cat((fz, h, a), -1))  # eq. (10)
            h = self.transition(self.f_w(w_out), fz, h)  # eq. (13)
            words.append(w_out)
        return self.from_model(self.poses(torch.stack(words, 1)))[:, :frames]


# ----------------------------------------------------------------------------- denoising autoencoder


@dataclass
class DaeConfig:
    """1-D convolutional denoising autoencoder of Table 1 (sec. 3.1, 4.2)."""

    dim: int = 90  # quaternion_root features
    channels: int = 128  # Conv1D width (Table 1 gives no size)
    kernel: int = 5
    corrupt_fraction: float = 0.1  # fraction of input values corrupted while training (sec. 4.2)
    noise_std: float = 0.5  # std of their Gaussian noise (normalised units)


class DenoisingAutoencoder(nn.Module):
    """2 x [Conv1D + ReLU] + ConvTranspose1D + ReLU + ConvTranspose1D (Table 1), on standardised features.

    x: (N, T, D) raw features -> denoised raw features (N, T, D) with unit quaternions (T even).
    """

    def __init__(self, config: DaeConfig | None = None):
        super().__init__()
        self.config = c = config or DaeConfig()
        k, p = c.kernel, c.kernel // 2
        self.encoder = nn.Sequential(nn.Conv1d(c.dim, c.channels, k, padding=p), nn.ReLU(),
                                     nn.Conv1d(c.channels, c.channels, k, stride=2, padding=p), nn.ReLU())
        self.decoder = nn.Sequential(nn.ConvTranspose1d(c.channels, c.channels, 4, stride=2, padding=1), nn.ReLU(),
                                     nn.ConvTranspose1d(c.channels, c.dim, k, padding=p))
        self.register_buffer("mean", torch.zeros(c.dim))
        self.register_buffer("std", torch.ones(c.dim))

    def set_stats(self, x: torch.Tensor) -> None:
        flat = x.reshape(-1, x.shape[-1]).double()
        self.mean.copy_(flat.mean(0).float())
        self.std.copy_(flat.std(0).clamp_min(1e-3).float())

    def _net(self, z: torch.Tensor) -> torch.Tensor:
        """standardised (N, T, D) -> standardised (N, T, D): a residual correction."""
        if z.shape[1] % 2:
            raise ValueError(f"DenoisingAutoencoder: T must be even, got {z.shape[1]}")
        return z + self.decoder(self.encoder(z.transpose(1, 2))).transpose(1, 2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        check_poses(x, self.config.dim)
        z = self._net((x - self.mean) / self.std)
        return normalize_pose(z * self.std + self.mean, (self.config.dim - NUM_ROOT) // 4)

    def loss(self, batch, generator: torch.Generator | None = None) -> dict:
        """batch (N, T, D) clean raw features (or {"x": ...}) -> {"loss": MSE of the denoised standardised
        features}, the input corrupted on `corrupt_fraction` of its values with N(0, noise_std^2)."""
        x = batch["x"] if isinstance(batch, dict) else batch
        check_poses(x, self.config.dim)
        z = (x - self.mean) / self.std
        mask = (torch.rand(z.shape, generator=generator) < self.config.corrupt_fraction).float()
        noisy = z + mask * self.config.noise_std * torch.randn(z.shape, generator=generator)
        return {"loss": F.mse_loss(self._net(noisy), z)}
