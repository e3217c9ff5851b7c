"""Motion denoising (Wang, Chai et al. 2021, sec. 5.4): the MAP filter of eq. (24)-(25) with the GMM-RNN prior.

    E = prior (eq. 15-16) + contact (eq. 18)
      + sum_i ||c_root,i - root(s_i)||^2 / (2 sigma_root^2)                               -- eq. (25)
      + sum_i sum_j ||angle_j(c_i) - angle_j(s_i)||^2 / (2 sigma_angle^2)

c: the noisy input (its root positions and joint angles), s: the filtered frames; root(s_i) through eq. (4).
The frames s themselves (their free columns) and d are the variables, started at the input, solved by L-BFGS;
the RNN starts from the eq. (26) state estimated on the input's first two frames (initial_state.py).

Taught in notebooks/04_map_control.ipynb.

Differs from the paper: sigma_root, sigma_angle are not given; ours are the noise model's scales
(synthetic.add_noise: root 5 mm, joint jitter 0.02 rad) widened to 1 cm and 0.05 rad.  Angles are the
expmaps of eq. (3) and the root's pitch and roll; the contact bits are the input's (derived from its pose).
Frame 0 is kept as given (the start the integration of eq. 4 needs).
Minimising eq. (15) through the RNN's inputs as well let L-BFGS move earlier frames to where the model is most
confident (its sigmas are floored at 0.01 of the data's std): the prior fell to -200 nats/frame (mocap: -80) and
the joint error rose from 2.0 to 3.0 cm on a held-out walk.  We therefore alternate: fix every frame's mixture as
predicted from the current estimate, minimise eq. (19) over the frames with those mixtures (d = 0), repeat
(``rounds``); ``rounds=0`` is the plain joint minimisation.  Even with fixed mixtures, the model's 0.01 sigma
floor made some joint angles of an unseen subject cost 17 sigma (its style is not the training subjects'), so the
energy floors the sigmas at ``prior_min_std`` = 0.3 (normalised units).  Measured (mean joint error, noisy ->
filtered, held-out walks, spike rate 0.05): 2.12 -> 2.11 cm and 2.44 -> 2.08 cm; a 2-s walk of an unseen subject:
1.84 -> 1.40 cm.  The spikes are not removed (max error 0.75 m stays): a Gaussian data term follows them.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import torch

from course_lib.control.initial_state import estimate_initial_state
from course_lib.control.lbfgs import LbfgsConfig, minimise_lbfgs
from course_lib.control.rnn_prior import RnnPrior
from course_lib.control.window import WindowEnergy
from course_lib.motion import Motion

__all__ = ["DenoiseConfig", "denoise"]


@dataclass
class DenoiseConfig:
    """Denoising settings (the paper gives none)."""

    sigma_root: float = 0.01  # m, eq. (25)
    sigma_angle: float = 0.05  # rad, eq. (25)
    iterations: int = 80  # L-BFGS function evaluations per round
    initial_state_steps: int = 100  # eq. (26) gradient steps; 0: the zero state
    prior_min_std: float | None = 0.3  # floor on the prior's sigmas, normalised units (see "differs"); None: 0.01
    rounds: int = 3  # fixed-history rounds (see "differs"); 0: eq. (15) with gradients through the history
    weights: dict = field(default_factory=dict)  # a factor per term of eq. (19) ("prior", "contact", ...); {}: all 1


def denoise(motion: Motion, seed: int = 0, *, prior: RnnPrior | None = None,
            config: DenoiseConfig | None = None) -> Motion:
    """A noisy motion (at the RNN's 30 fps, >= 3 frames) -> the filtered motion, same skeleton and length.

    seed: torch's seed for the run (the solver is deterministic; kept for a uniform interface)."""
    from course_lib.control.design import default_prior, stance_plane
    from course_lib.representations import decode_state_features, encode_state_features, root_start

    if not isinstance(motion, Motion):
        raise ValueError(f"denoise: motion must be a Motion, got {type(motion).__name__}")
    config = config or DenoiseConfig()
    prior = prior or default_prior()
    if config.prior_min_std is not None:
        prior = replace(prior, min_std=config.prior_min_std)
    fps = float(prior.model.config.fps)
    if abs(motion.fps - fps) > 1e-6:
        raise ValueError(f"denoise: motion must be at the RNN's {fps} fps, got {motion.fps} (use motion.resample)")
    if len(motion) < 3:
        raise ValueError(f"denoise: motion needs at least 3 frames, got {len(motion)}")
    if not (np.isfinite(motion.rotations).all() and np.isfinite(motion.root_positions).all()):
        raise ValueError("denoise: motion contains NaN or inf")
    torch.manual_seed(seed)
    skel = motion.skeleton
    c = prior.clean(torch.from_numpy(encode_state_features(motion)))[None]  # (1, T, D) the input c
    init = torch.tensor(root_start(motion), dtype=torch.float64)
    state = None
    if config.initial_state_steps:
        state, _ = estimate_initial_state(prior, c[:, :2], skel, config.initial_state_steps)
    c_root = torch.from_numpy(motion.root_positions[1:])[None]  # (1, T-1, 3)
    angles = [4, 5] + list(range(6, prior.dim - 2))  # pitch, roll, the expmaps

    def data_term(xz, yaw, raw):  # eq. (25)
        root = torch.stack((xz[..., 0], raw[..., 3], xz[..., 1]), -1)
        e_root = ((c_root - root) ** 2).sum((-1, -2)) / (2 * config.sigma_root ** 2)
        e_angle = ((c[:, 1:, angles] - raw[..., angles]) ** 2).sum((-1, -2)) / (2 * config.sigma_angle ** 2)
        return e_root + e_angle

    energy = WindowEnergy(prior, skel, c[:, :1], state, init, data_term, stance_plane(motion),
                          weights=config.weights)
    bits = c[:, 1:, prior.contact_cols]
    z, d = energy.to_z(c[:, 1:]), torch.zeros(1, len(motion) - 1, prior.dim, dtype=torch.float64)
    lb = LbfgsConfig(iterations=config.iterations)
    if not config.rounds:
        (z, d), _ = minimise_lbfgs(lambda z_, d_: energy.terms(energy.frames(z_, bits), d_)["total"].sum(), [z, d], lb)
    for _ in range(config.rounds):  # each frame's mixture from the current estimate of the frames before it
        params = prior.predictions(c[:, :1], energy.frames(z, bits), state, skel)

        def total(z_, params=params):
            raw = energy.frames(z_, bits)
            return energy.terms(raw, None, prior.nll_given(c[:, :1], raw, params, skel).double())["total"].sum()
        (z,), _ = minimise_lbfgs(total, [z], lb)
    raw = torch.cat((c[:, :1], energy.frames(z, bits)), 1)[0].numpy()
    out = decode_state_features(raw, skel, fps, tuple(float(v) for v in init))
    return replace(out, action=motion.action, style=motion.style, subject=motion.subject,
                   meta=dict(motion.meta, denoised=True))
