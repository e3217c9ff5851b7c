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
"""

from __future__ import annotations

from dataclasses import dataclass, replace

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
    iterations: int = 150  # L-BFGS function evaluations
    initial_state_steps: int = 100  # eq. (26) gradient steps; 0: the zero state


def denoise(motion: Motion, seed: int = 0, *, prior: RnnPrior | None = None,
            config: DenoiseConfig | None = None) -> Motion:
    """A noisy motion (at the RNN's 30 fps, >= 3 frames) -> the filtered motion, same skeleton and length.

    seed: torch's seed for the run (the solver is deterministic; kept for a uniform interface)."""
    from course_lib.control.design import default_prior, stance_plane
    from course_lib.representations import decode_state_features, encode_state_features, root_start

    if not isinstance(motion, Motion):
        raise ValueError(f"denoise: motion must be a Motion, got {type(motion).__name__}")
    prior = prior or default_prior()
    config = config or DenoiseConfig()
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

    energy = WindowEnergy(prior, skel, c[:, :1], state, init, data_term, stance_plane(motion))
    bits = c[:, 1:, prior.contact_cols]
    z0, d0 = energy.to_z(c[:, 1:]), torch.zeros(1, len(motion) - 1, prior.dim, dtype=torch.float64)
    (z, d), _ = minimise_lbfgs(lambda z_, d_: energy.terms(energy.frames(z_, bits), d_)["total"].sum(), [z0, d0],
                               LbfgsConfig(iterations=config.iterations))
    raw = torch.cat((c[:, :1], energy.frames(z, bits)), 1)[0].numpy()
    out = decode_state_features(raw, skel, fps, tuple(float(v) for v in init))
    return replace(out, action=motion.action, style=motion.style, subject=motion.subject,
                   meta=dict(motion.meta, denoised=True))
