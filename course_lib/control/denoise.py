"""Motion denoising (Wang, Chai et al. 2021, sec. 5.4): the MAP filter of eq. (24)-(25) with the GMM-RNN prior.

    E = prior (eq. 15-16) + contact (eq. 18)
      + sum_i ||c_root,i - root(s_i)||^2 / (2 sigma_root^2)                               -- eq. (25)
      + sum_i sum_j ||angle_j(c_i) - angle_j(s_i)||^2 / (2 sigma_angle^2)

c: the noisy input (its root positions and joint angles), s: the filtered frames; root(s_i) through eq. (4).
The frames s themselves (their free columns) are the variables, solved by L-BFGS from the input low-passed at
4 Hz (lowpass.py) with its dropped frames interpolated first (dropouts.py); the RNN starts from the eq. (26)
state estimated on the input's first two frames (initial_state.py).

Taught in notebooks/04_map_control.ipynb.

Differs from the paper (which gives no sigmas, no start and no noise model beyond eq. 25's Gaussians):
- sigma_root = 1 cm and sigma_angle = 0.03 rad: the noise model's scales (synthetic.add_noise: root 5 mm, joint
  jitter 0.02 rad) widened, sigma_angle chosen on tuning clips.  Angles are the expmaps of eq. (3) and the root's
  pitch and roll.  The contact bits are the input's, derived from its pose (``contact_bits`` takes them from the
  start or re-derives them each round).  Frame 0 is kept as given: the integration of eq. (4) starts there
  (``first_frame="start"`` takes the search start's).
- fixed-mixture rounds (``rounds`` = 3): each round fixes every frame's mixture as predicted from the current
  estimate and minimises eq. (19) over the frames with those mixtures (d = 0).  Minimising eq. (15) through the
  RNN's inputs as well (``rounds=0``) lets L-BFGS move earlier frames to where the model is most confident: the
  prior then rates the estimate far above mocap and the joint error grows.  The prior's sigmas are floored at
  ``prior_min_std`` = 0.3 normalised units (the model's floor: 0.01), else a joint angle of an unseen subject
  costs many sigmas.
- the start: from the noisy input itself L-BFGS stops in a minimum near the input; the 4-Hz low-pass is a start
  a reader can compute instead.
- dropped frames: a capture's lost frame holds the last good frame bit for bit (make_noisy does the same).  Such a
  frame is left out of eq. (25) (a missing observation, not a measurement of a frozen pose) and interpolated in
  the start (``held_frames="fill"``; runs of at most dropouts.MAX_RUN frames with a good frame after them: a
  longer stillness is real).
- spikes (ours, ``spike_angle`` = 0.35 rad): eq. (25)'s Gaussian follows a spike part of the way.  A joint farther
  than that from the median of its 3 frames around it (spikes.py) is a missing observation: its columns are left
  out of eq. (25), and its rotation is interpolated in the input (the eq. 26 state and the contact bits come from
  that) and in the start.  The first and last frame cannot be tested, so frame 0 is kept even if it is spiked.
- planting (ours, ``plant``): eq. (18) as a soft term leaves the estimate's feet skating several times as much as
  the clean motion's, since neither the prior nor a 3-cm contact sigma resolves the half millimetre a frame a
  planted toe may move (studies/04_map_control/README.md, control_denoise_prior).  So the estimate is followed by
  `planting.plant_with_prior`: every toe that the estimate's own pose has in contact, or that is below 5 cm
  (design.py's rule), is held still and on the floor by the hip, knee and ankle angles alone, the root as
  filtered (moving the root as well, as lesson 03's contact handling does, costs joint error).  Its sigma_slide is
  1 mm a frame (lesson 03's: 3 mm), chosen on the tuning clips.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import torch

from course_lib.control.design import default_prior
from course_lib.control.dropouts import dropped_mask, fill_held
from course_lib.control.energy import stance_plane
from course_lib.control.initial_state import estimate_initial_state
from course_lib.control.kinematics import integrate_root
from course_lib.control.lbfgs import LbfgsConfig, minimise_lbfgs
from course_lib.control.lowpass import BUTTER_MIN_FRAMES, lowpass
from course_lib.control.planting import plant_with_prior
from course_lib.control.rnn_prior import RnnPrior
from course_lib.control.spikes import SPIKE_ANGLE, despike, spike_mask
from course_lib.control.window import WindowEnergy
from course_lib.motion import CONTACT_HEIGHT, CONTACT_SPEED, Motion, foot_contacts
from course_lib.representations import decode_state_features, encode_state_features, root_start

__all__ = ["CONTACT_BITS", "FIRST_FRAME", "HELD_FRAMES", "DenoiseConfig",
           "DenoiseProblem", "cleaned_input", "denoise", "denoise_problem", "spikes_of"]

CONTACT_BITS = ("input", "start", "rounds")
FIRST_FRAME = ("input", "start")
HELD_FRAMES = ("fill", "keep")


@dataclass
class DenoiseConfig:
    """Denoising settings (the paper gives none)."""

    sigma_root: float = 0.01  # m, eq. (25)
    sigma_angle: float = 0.03  # rad, eq. (25) (chosen on tuning clips, see "differs")
    iterations: int = 80  # L-BFGS function evaluations per round
    initial_state_steps: int = 100  # eq. (26) gradient steps; 0: the zero state
    prior_min_std: float | None = 0.3  # floor on the prior's sigmas, normalised units (see "differs"); None: 0.01
    rounds: int = 3  # fixed-history rounds (see "differs"); 0: eq. (15) with gradients through the history
    weights: dict = field(default_factory=dict)  # a factor per term of eq. (19) ("prior", "contact", ...); {}: all 1
    contact_bits: str = "input"  # eq. (18)'s stance bits: "input", "start" (the start's), "rounds" (see "differs")
    stance_speed: float = CONTACT_SPEED  # m/s: a foot below its contact height and slower than this is in stance,
    # for the bits taken from the start or an estimate (motion.foot_contacts)
    held_frames: str = "fill"  # dropped frames: "fill" (interpolated in the start, out of eq. 25) or "keep"
    first_frame: str = "input"  # frame 0 and the root's start: "input" (as given) or "start" (the search start's)
    start_cutoff_hz: float | None = 4.0  # Hz: search from the input low-passed so (lowpass.py); None: the input
    contact_height: float | None = None  # m: eq. (18) also holds toes below this height, whatever their bits
    # (design.py's rule; None: the bits alone)
    plant: bool = True  # after the MAP estimate, hold every toe in contact or below plant_height still and on the
    # floor by the leg angles alone (planting.py; the root as filtered: ours); False: the MAP estimate alone
    plant_height: float = CONTACT_HEIGHT["ToeBase"]  # m: toes below this are held too, whatever their bits
    plant_sigma_slide: float = 0.001  # m per frame, plant_feet's slide sigma (tuning clips, see "differs")
    spike_angle: float | None = SPIKE_ANGLE  # rad: a joint this far from its 3-frame running median is a spike,
    # out of eq. (25) and interpolated (spikes.py, see "differs"); None: every joint is data, as eq. (25) is printed


@dataclass
class DenoiseProblem:
    """Eq. (19) with eq. (25)'s data term for one input motion: what `denoise` minimises, exposed so that an
    experiment can score or differentiate any frames.

    c (1, T, D): the input's raw frames (fixed columns at the data's constants); the variables are frames
    1..T-1 (frame 0 is kept); bits (1, T-1, 2) the input's contact bits; energy the WindowEnergy whose
    "control" term is eq. (25)."""

    prior: RnnPrior
    c: torch.Tensor
    c_root: torch.Tensor  # (1, T-1, 3) the input's world root positions, frames 1..
    energy: WindowEnergy
    bits: torch.Tensor
    state: tuple | None
    config: DenoiseConfig
    weight: torch.Tensor | None = None  # (1, T-1, 1): 1 where eq. (25) sees the input's frame, 0 on held frames
    angle_weight: torch.Tensor | None = None  # (1, T-1, A) over `angle_cols`: 0 on a spiked joint's columns

    def data_terms(self, raw: torch.Tensor) -> dict:
        """Raw frames (N, T-1, D) -> eq. (25)'s {"root", "angle"} (N,) each."""
        xz, _ = integrate_root(raw[..., 0:2], raw[..., 2], self.energy.init.expand(len(raw), 3))
        root = torch.stack((xz[..., 0], raw[..., 3], xz[..., 1]), -1)
        cfg, cols = self.config, angle_cols(self.prior.dim)
        w = 1.0 if self.weight is None else self.weight
        wa = w if self.angle_weight is None else w * self.angle_weight
        return {"root": (w * (self.c_root - root) ** 2).sum((-1, -2)) / (2 * cfg.sigma_root ** 2),
                "angle": (wa * (self.c[:, 1:, cols] - raw[..., cols]) ** 2).sum((-1, -2)) / (2 * cfg.sigma_angle ** 2)}

    def terms(self, raw: torch.Tensor, params: dict | None = None) -> dict:
        """Raw frames (N, T-1, D) -> eq. (19)'s terms (N,) each ("control" = eq. 25), the prior under the fixed
        mixtures ``params`` (`mixtures`) or, with None, eq. (15) through the frames' own history."""
        if params is None:
            return self.energy.terms(raw)
        nll = self.prior.nll_given(self.c[:, :1], raw, params, self.energy.skeleton).double()
        return self.energy.terms(raw, None, nll)

    def mixtures(self, raw: torch.Tensor) -> dict:
        """Every frame's mixture predicted from the frames before it (held fixed in a round)."""
        return self.prior.predictions(self.c[:, :1], raw, self.state, self.energy.skeleton)

    def motion(self, raw: torch.Tensor, like: Motion) -> Motion:
        """Raw frames (1, T-1, D) -> the Motion (frame 0 the input's)."""
        feats = torch.cat((self.c[:, :1], raw), 1)[0].numpy()
        out = decode_state_features(feats, like.skeleton, like.fps, tuple(float(v) for v in self.energy.init))
        return replace(out, action=like.action, style=like.style, subject=like.subject,
                       meta=dict(like.meta, denoised=True))


def angle_cols(dim: int) -> list:
    """The columns of eq. (25)'s angle term: the root's pitch and roll, the joints' expmaps (not the contacts)."""
    return [4, 5] + list(range(6, dim - 2))


def spikes_of(motion: Motion, config: DenoiseConfig) -> np.ndarray:
    """-> (T, J) bool, the input's spiked joints (spikes.py) as `denoise` sees them: tested on the frames that are
    not dropped (held frames repeat their source exactly and are interpolated anyway, if config.held_frames is
    "fill"); all False if config.spike_angle is None."""
    if config.spike_angle is None:
        return np.zeros(motion.rotations.shape[:2], bool)
    if not (np.isfinite(config.spike_angle) and config.spike_angle > 0):
        raise ValueError(f"denoise: spike_angle must be an angle > 0 (rad) or None, got {config.spike_angle!r}")
    frames = ~dropped_mask(motion) if config.held_frames == "fill" else None
    return spike_mask(motion, config.spike_angle, frames=frames)


def cleaned_input(motion: Motion, config: DenoiseConfig, spikes: np.ndarray) -> Motion:
    """The input with its dropped frames (if config.held_frames is "fill") and its spiked joints interpolated
    between good frames, in one pass (a spike next to a dropped frame is not used as an end of either)."""
    if config.held_frames != "fill":
        return despike(motion, spikes) if spikes.any() else motion
    dropped = dropped_mask(motion)
    base = fill_held(motion)  # the root positions (and rotations) of the dropped frames
    return despike(base, spikes | dropped[:, None]) if spikes.any() else base


def _angle_weight(spikes: np.ndarray) -> torch.Tensor:
    """(T, J) spiked joints -> (1, T-1, A) weights over `angle_cols`: joint 0 is the root's pitch and roll (2
    columns), joint j >= 1 its 3 expmap columns."""
    w = np.repeat(~spikes[1:, 1:], 3, axis=1)
    root = np.repeat(~spikes[1:, :1], 2, axis=1)
    return torch.from_numpy(np.concatenate((root, w), 1).astype(np.float64))[None]


def denoise_problem(motion: Motion, prior: RnnPrior | None = None, config: DenoiseConfig | None = None,
                    first: Motion | None = None) -> DenoiseProblem:
    """A noisy motion (at the RNN's 30 fps, >= 3 frames) -> the MAP problem `denoise` solves (eq. 19, 25).

    first: the motion whose frame 0 (kept, not a variable), root start (x0, z0, yaw0) and first two frames (for
    the eq. 26 state) the filtered motion starts from; same length; None: the input's, its spikes interpolated."""
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
    skel = motion.skeleton
    spikes = spikes_of(motion, config)
    # the input; with spikes, its spiked joints (and its dropped frames, the spikes' neighbours) interpolated
    observed = cleaned_input(motion, config, spikes) if spikes.any() else motion
    c = prior.clean(torch.from_numpy(encode_state_features(observed)))[None]  # (1, T, D) the input c
    first = observed if first is None else first
    if len(first) != len(motion):
        raise ValueError(f"denoise: first must have the input's {len(motion)} frames, got {len(first)}")
    a = c if first is observed else prior.clean(torch.from_numpy(encode_state_features(first)))[None]
    c[:, 0] = a[:, 0]  # frame 0 is never in eq. (25)'s sum: it only starts the motion
    init = torch.tensor(root_start(first), dtype=torch.float64)
    state = None
    if config.initial_state_steps:
        state, _ = estimate_initial_state(prior, a[:, :2], skel, config.initial_state_steps)
    c_root = torch.from_numpy(motion.root_positions[1:])[None]  # (1, T-1, 3)
    problem = DenoiseProblem(prior, c, c_root, None, c[:, 1:, prior.contact_cols], state, config)
    if config.held_frames == "fill":
        problem.weight = torch.from_numpy(~dropped_mask(motion)[1:]).double()[None, :, None]
    if spikes.any():
        problem.angle_weight = _angle_weight(spikes)

    def data_term(xz, yaw, raw):  # eq. (25)
        return sum(problem.data_terms(raw).values())

    problem.energy = WindowEnergy(prior, skel, c[:, :1], state, init, data_term, stance_plane(motion),
                                  weights=config.weights, contact_height=config.contact_height)
    return problem


def _stance_bits(motion: Motion, speed: float) -> torch.Tensor:
    """-> the motion's contact bits of frames 1..T-1 (1, T-1, 2) at the stance speed threshold ``speed``."""
    bits = foot_contacts(motion.positions(), motion.skeleton, motion.fps, speed=speed)
    return torch.from_numpy(bits[None, 1:].astype(np.float64))


def denoise(motion: Motion, seed: int = 0, *, prior: RnnPrior | None = None,
            config: DenoiseConfig | None = None, start: Motion | None = None) -> Motion:
    """A noisy motion (at the RNN's 30 fps, >= 3 frames) -> the filtered motion, same skeleton and length.

    seed: torch's seed for the run (the solver is deterministic; kept for a uniform interface).
    start: the motion the solver starts from (same length and skeleton; None: the input, its held frames
    interpolated if config.held_frames is "fill" and its spikes if config.spike_angle is set, then low-passed at
    config.start_cutoff_hz unless that is None or the input is too short to filter, under lowpass.BUTTER_MIN_FRAMES
    frames)."""
    torch.manual_seed(seed)
    config = config or DenoiseConfig()
    for name, value, allowed in (("contact_bits", config.contact_bits, CONTACT_BITS),
                                 ("first_frame", config.first_frame, FIRST_FRAME),
                                 ("held_frames", config.held_frames, HELD_FRAMES)):
        if value not in allowed:
            raise ValueError(f"denoise: {name} must be one of {allowed}, got {value!r}")
    if not (np.isfinite(config.stance_speed) and config.stance_speed > 0):
        raise ValueError(f"denoise: stance_speed must be a speed > 0 (m/s), got {config.stance_speed!r}")
    if start is None:
        base = cleaned_input(motion, config, spikes_of(motion, config))
        if config.start_cutoff_hz is not None and len(motion) >= BUTTER_MIN_FRAMES:
            start = lowpass(base, "butter", config.start_cutoff_hz)
        elif base is not motion:
            start = base
    elif len(start) != len(motion):
        raise ValueError(f"denoise: start must have the input's {len(motion)} frames, got {len(start)}")
    problem = denoise_problem(motion, prior, config, start if config.first_frame == "start" else None)
    config, prior, energy, bits = problem.config, problem.prior, problem.energy, problem.bits
    s0 = problem.c
    if start is not None:
        s0 = prior.clean(torch.from_numpy(encode_state_features(start)))[None]
    if config.contact_bits != "input":
        bits = _stance_bits(start if start is not None else motion, config.stance_speed)
    z, d = energy.to_z(s0[:, 1:]), torch.zeros(1, len(motion) - 1, prior.dim, dtype=torch.float64)
    lb = LbfgsConfig(iterations=config.iterations)
    if not config.rounds:
        (z, d), _ = minimise_lbfgs(lambda z_, d_: energy.terms(energy.frames(z_, bits), d_)["total"].sum(), [z, d], lb)
    for k in range(config.rounds):  # each frame's mixture from the current estimate of the frames before it
        if k and config.contact_bits == "rounds":  # the stance bits of the current estimate's pose
            bits = _stance_bits(problem.motion(energy.frames(z, bits), motion), config.stance_speed)
        params = problem.mixtures(energy.frames(z, bits))

        def total(z_, params=params, bits=bits):
            return problem.terms(energy.frames(z_, bits), params)["total"].sum()
        (z,), _ = minimise_lbfgs(total, [z], lb)
    out = problem.motion(energy.frames(z, bits), motion)
    if config.plant:
        out = plant_with_prior(out, prior, config.plant_height, config.plant_sigma_slide)
    return out
