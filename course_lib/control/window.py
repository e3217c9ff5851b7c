"""The MAP energy of Wang, Chai et al. 2021, eq. (19), on one window of frames that follows known frames:

    E = -log(P_prior P_noise P_control P_contact)
      = nll_RNN(s | s_0, d) + ||d||^2 / (2 sigma_noise^2) + E_control(root(s)) + E_contact(f(s))     -- eq. (19)

shared by offline design (E_control = eq. 17), online control (eq. 22-23) and denoising (eq. 25).  root(s) and
f(s) come from integrating eq. (4) from the last known frame and forward kinematics, all in torch, so the
gradient of E flows back through every later frame (BPTT).

Taught in notebooks/04_map_control.ipynb.  The variables are the frames' free columns in the stats' normalised
units, z = (s - mean) / std (fixed columns stay at the data's constants); the contact bits are held as given.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import torch

from course_lib.control.energy import SIGMA_CON, SIGMA_CON_Y, contact_energy, stance_plane
from course_lib.control.kinematics import integrate_root, second_pose, toe_positions
from course_lib.control.rnn_prior import SIGMA_NOISE, RnnPrior, expand_state, noise_energy
from course_lib.control.rollout import rollout
from course_lib.representations import encode_state_features, root_start
from course_lib.skeleton import Skeleton

__all__ = ["WindowEnergy", "Control"]

# control(root_xz (N, T, 2), yaw (N, T), raw (N, T, D)) -> (N,) energy of the user's constraints
Control = Callable[[torch.Tensor, torch.Tensor, torch.Tensor], torch.Tensor]


@dataclass
class WindowEnergy:
    """Eq. (19) for windows of frames after ``prev`` (1, P, D) raw known frames; ``state`` the RNN state before
    prev's last frame; ``init`` (3,) = (x, z, yaw) of prev's last frame; ``plane`` the contact plane height."""

    prior: RnnPrior
    skeleton: Skeleton
    prev: torch.Tensor
    state: tuple | None
    init: torch.Tensor
    control: Control | None = None
    plane: float = 0.0244
    sigma_noise: float = SIGMA_NOISE
    sigma_con: float = SIGMA_CON
    sigma_con_y: float = SIGMA_CON_Y
    weights: dict = field(default_factory=dict)  # optional factor per term name (all 1: the paper)
    contact_height: float | None = None  # m: a toe below it also counts as in contact in eq. (18), whatever its bit

    def __post_init__(self):
        self.prev = self.prev.double()
        self.init = torch.as_tensor(self.init, dtype=torch.float64)
        last = self.prev[:, -1:].clone()
        last[..., :3] = 0.0  # the known frame itself, at init
        self.prev_toes = toe_positions(last, self.skeleton, self.init)[:, 0]  # (1, 2, 3)
        self.mean = torch.from_numpy(self.prior.mean)
        self.std = torch.from_numpy(self.prior.std)
        self.free = torch.from_numpy(self.prior.free)
        self.prev_model = self.prior.to_model(self.prev, self.skeleton)  # (1, P, D): the same for every rollout

    @classmethod
    def for_motion(cls, prior: RnnPrior, motion, control: Control | None = None, **kw):
        """Eq. (19) on a motion's own frames (at the RNN's fps): its first two frames known (sec. 4.1.4's start,
        zero state), the rest scored -> (energy, the rest as raw frames (1, T - 2, D))."""
        raw = prior.clean(torch.from_numpy(encode_state_features(motion)))[None]  # (1, T, D)
        state = prior.start_state(raw[:, :2], motion.skeleton)
        init = second_pose(raw[:, :2], torch.tensor(root_start(motion), dtype=torch.float64))
        kw.setdefault("plane", stance_plane(motion))
        return cls(prior, motion.skeleton, raw[:, :2], state, init, control, **kw), raw[:, 2:]

    # --- variables <-> frames ------------------------------------------------------------------------------

    def to_z(self, raw: torch.Tensor) -> torch.Tensor:
        """Raw frames (N, T, D) -> their free columns, normalised (N, T, F)."""
        return ((raw.double() - self.mean) / self.std)[..., self.free]

    def frames(self, z: torch.Tensor, bits: torch.Tensor) -> torch.Tensor:
        """z (N, T, F) free normalised columns, bits (N, T, 2) raw contact bits -> raw frames (N, T, D)."""
        N, T = z.shape[:2]
        raw = self.mean.expand(N, T, -1).clone()
        raw[..., self.free] = self.mean[self.free] + z * self.std[self.free]
        raw[..., self.prior.contact_cols] = bits.to(raw.dtype)
        return raw

    # --- eq. (19) ----------------------------------------------------------------------------------------

    def terms(self, raw: torch.Tensor, d: torch.Tensor | None = None, prior: torch.Tensor | None = None,
              toes: torch.Tensor | None = None) -> dict:
        """Raw frames (N, T, D), d (N, T, D) or None -> {"prior", "noise", "control", "contact", "total"}: (N,).
        prior: the frames' -log p (N,) if already known (`rollout` computes it on the way); toes: their toes
        relative to the root (N, T, 2, 3) if known (`rollout` again)."""
        N = len(raw)
        init = self.init.expand(N, 3)
        if prior is None:
            prior = self.prior.nll(self.prev.expand(N, -1, -1), raw, self.state, self.skeleton, d).double()
        noise = torch.zeros(N, dtype=torch.float64) if d is None else noise_energy(d.double(), self.sigma_noise)
        xz, yaw = integrate_root(raw[..., 0:2], raw[..., 2], init)
        control = torch.zeros(N, dtype=torch.float64) if self.control is None else self.control(xz, yaw, raw)
        toes = toe_positions(raw, self.skeleton, init, toes)  # (N, T, 2, 3)
        bits = (raw[..., self.prior.contact_cols] > 0.5).double()
        if self.contact_height is not None:  # the toes low enough for foot_skate to count them (ours, see design.py)
            bits = torch.maximum(bits, (toes[..., 1].detach() < self.contact_height).double())
        contact = contact_energy(toes, bits, self.prev_toes.expand(N, 2, 3), self.plane, self.sigma_con,
                                 self.sigma_con_y)
        out = {"prior": prior, "noise": noise, "control": control, "contact": contact}
        out["total"] = sum(self.weights.get(k, 1.0) * v for k, v in out.items())
        return out

    def sampled(self, eps: torch.Tensor, gumbel: torch.Tensor, d: torch.Tensor | None = None,
                bias: float = 0.0) -> tuple[torch.Tensor, dict]:
        """Eq. (19) of the frames the RNN's sampler makes from eps (N, T, D), gumbel (N, T, M) and d (rollout.py)
        -> (raw frames (N, T, D), terms)."""
        N = len(eps)
        raw, nll, self.last_state, toes = rollout(self.prior, self.prev.expand(N, -1, -1),
                                                  expand_state(self.state, N), eps, gumbel, self.skeleton, d, bias,
                                                  self.prev_model, with_toes=True)
        # last_state: after frames[:-1]
        return raw, self.terms(raw, d, nll, toes)

    def end_pose(self, raw: torch.Tensor) -> torch.Tensor:
        """Raw frames (1, T, D) -> (3,) (x, z, yaw) of the last frame."""
        xz, yaw = integrate_root(raw[..., 0:2].double(), raw[..., 2].double(), self.init[None])
        return torch.cat((xz[0, -1], yaw[0, -1:]))
