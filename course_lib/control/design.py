"""Offline motion design (Wang, Chai et al. 2021, sec. 5.2): a motion whose root follows a user's floor curve,
as the MAP estimate of eq. (14) with the energy of eq. (19) (prior eq. 15-16, curve eq. 17, contact eq. 18).

Taught in notebooks/04_map_control.ipynb.

Sliding windows of 34 frames overlapping by 17 ("spatial temporal optimisation"): for each window
1. sample candidates from the GMM-RNN after the frames fixed so far (the first candidate continues the previous
   window's unused half),
2. particle swarm optimisation (pso.py) from the candidates, d = 0, until the loss stops falling,
3. L-BFGS (lbfgs.py) on the frames (through the sampler's noise) and d, gradients by BPTT through eq. (4),
then keep the window's first 17 frames and read them into the RNN.

Differs from the paper:
- the variables are the RNN sampler's noise (eps, Gumbel) and d, not the frames (rollout.py says why); L-BFGS
  holds the Gumbel variables (the mixture components) fixed.  ``space="frames"`` searches the paper's variables.
- sigma_fit^2 = 0.0025 m^2 (the paper: 0.5): against our prior's scale, 0.5 lets a walk drift well off the curve
  and 0.01 still lost cases to the simpler searches.
- eq. (17) is measured against the stretch of the curve just ahead: from the arc length reached so far (it never
  decreases; `energy.arc_position`) to what the window can cover (`polyline_between`).  Against the whole curve a
  walk could turn back to a nearer part, and a closed circle is ambiguous at its start.
- a progress term (ours; ``sigma_speed`` = 0.1 m/s, eq. 22's form): eq. (17) alone is met by standing at the
  curve's start.  The arc length gained by the window's last kept frame (the motion's last frame in the last
  window) is asked to be the remaining length times the window's share of the remaining time, weighted by the
  window's frames: a walk that is behind is asked to go faster, and at the end it is asked to arrive.
  ``progress="net"`` asks each window's net speed instead, in any direction, which lets walks stop short.
- retries (ours): a window whose control energy ends above ``retry_control`` (50; windows that follow the curve
  end well under it), or whose total energy ends more than ``retry_rise`` (200) above the median of the windows
  before it, is searched again from ``retry_factor`` (4) x the candidates, fresh samples; the better end is kept.
  Otherwise one window that drifts into poses the prior finds unlikely is never recovered by later ones.  Both
  thresholds were set at sigma_fit^2 = 0.01, where the same offset costs a quarter as much.
- eq. (18)'s contact labels c_i are the RNN's contact bits or a toe below ``contact_height`` (5 cm, foot_skate's
  own height): with the bits alone, low swing toes whose bit is off slide.
- planting (ours, ``plant``): after the windows, every toe in contact (its pose's own contacts, foot low and
  slow) or below ``contact_height`` is held still by the leg angles alone (planting.py, as denoising does); the
  root is not moved, so the curve's distance and end are the search's own.  Eq. (18) inside the energy leaves
  the walks skating.
- the number of candidates, PSO and L-BFGS iterations are not given; ours are in `DesignConfig`.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass, field

import numpy as np
import torch

from course_lib.control.energy import (
    arc_length_at,
    arc_position,
    check_curve,
    curve_energy,
    polyline_between,
    stance_plane,
)
from course_lib.control.kinematics import heading_yaw, second_pose
from course_lib.control.lbfgs import LbfgsConfig, minimise_lbfgs
from course_lib.control.planting import plant_with_prior
from course_lib.control.pso import PsoConfig, pso
from course_lib.control.rnn_prior import RnnPrior
from course_lib.control.rollout import draw_noise
from course_lib.control.starts import held_out_start
from course_lib.control.window import WindowEnergy
from course_lib.motion import CONTACT_HEIGHT, Motion
from course_lib.representations import decode_state_features, encode_state_features, root_start

SPACES = ("noise", "frames")

__all__ = ["SPACES", "DesignConfig", "design_motion", "default_prior", "prepare_start", "solve_windows"]


@dataclass
class DesignConfig:
    """Offline design settings (sizes of sec. 5.2; the search budgets are ours)."""

    window: int = 34  # frames per window (sec. 5.2)
    hop: int = 17  # frames kept per window: windows overlap by window - hop = 17 (sec. 5.2)
    candidates: int = 24  # RNN samples per window, the PSO's particles
    sample_bias: float = 1.0  # Graves' sampling bias of the candidates (lesson 03's generation uses 2)
    sigma_fit2: float = 0.0025  # eq. (17), m^2; the paper: 0.5 (see "differs")
    pso: PsoConfig = field(default_factory=lambda: PsoConfig(iterations=30, patience=5, rel_tol=1e-3))
    lbfgs: LbfgsConfig = field(default_factory=lambda: LbfgsConfig(iterations=40))
    sigma_speed: float | None = 0.1  # m/s, the progress term (not in the paper); None: eq. (17) alone
    speed: float | None = None  # m/s the progress term asks for; None: the curve's length / seconds
    progress: str = "arc"  # "arc": arc length gained along the curve, paced to end on time; "net": net speed
    use_pso: bool = True  # False: L-BFGS from the best candidate alone (a baseline)
    use_lbfgs: bool = True  # False: PSO (or the best candidate) alone (a baseline)
    space: str = "noise"  # the variables: "noise" (the sampler's eps, Gumbel draws, d: ours) or "frames" (the paper's)
    retry_control: float | None = 50.0  # a window whose control energy ends above this is searched again ...
    retry_factor: int = 4  # ... from this many times the candidates (fresh samples); the better end is kept
    retry_rise: float | None = 200.0  # so is a window whose total energy ends this far above the median of the
    # windows before it (a drift into poses the prior finds unlikely shows there before the control term rises)
    contact_height: float | None = CONTACT_HEIGHT["ToeBase"]  # m: eq. (18) also holds toes below this height,
    # whatever their bits (ours; None: the bits alone, the paper's)
    contact_weight: float = 1.0  # factor on eq. (18) in eq. (19) (1: the paper's sum)
    plant: bool = True  # after the windows, hold every toe in contact or below contact_height still by the leg
    # angles alone (planting.py; the root, and so the curve measures, as designed: ours); False, or contact_height
    # None (the paper's labels): the search's motion
    plant_sigma_slide: float = 0.001  # m per frame, as denoising's (planting.py)

    def __post_init__(self):
        if not 0 < self.hop <= self.window:
            raise ValueError(f"DesignConfig: need 0 < hop <= window, got hop={self.hop}, window={self.window}")
        if self.progress not in ("arc", "net"):
            raise ValueError(f"DesignConfig: progress must be 'arc' or 'net', got {self.progress!r}")
        if self.candidates < 1:
            raise ValueError(f"DesignConfig: candidates must be >= 1, got {self.candidates}")

    @classmethod
    def tiny(cls, **overrides) -> DesignConfig:
        """Small budgets for tests: 8 candidates, 5 PSO and 10 L-BFGS iterations."""
        kw = dict(candidates=8, pso=PsoConfig(iterations=5), lbfgs=LbfgsConfig(iterations=10))
        return cls(**{**kw, **overrides})


@functools.lru_cache(maxsize=1)
def default_prior() -> RnnPrior:
    """The pretrained GMM-RNN of lesson 03 as a prior (loaded once per process)."""
    return RnnPrior.from_checkpoints()


def prepare_start(start: Motion | None, gait: str, seed: int, init, prior: RnnPrior, fps: float = 30.0):
    """-> (raw (1, 2, D) the two start frames, init (3,) the pose of frame 0 placed at init = (x, z, yaw) or
    the clip's own when init is None, the start Motion)."""
    if start is None:
        start = held_out_start(gait, seed, fps=fps)
    if not isinstance(start, Motion):
        raise ValueError(f"start must be a Motion or None, got {type(start).__name__}")
    if abs(start.fps - fps) > 1e-6:
        start = start.resample(fps)
    if len(start) < 2:
        raise ValueError(f"start must have at least 2 frames at {fps} fps, got {len(start)}")
    raw = torch.from_numpy(prior.clean(torch.from_numpy(encode_state_features(start)))[:2].numpy())[None]
    init = root_start(start) if init is None else init
    return raw, torch.tensor(init, dtype=torch.float64), start


def design_motion(curve, seconds: float, gait: str = "walk", seed: int = 0, start: Motion | None = None, *,
                  prior: RnnPrior | None = None, config: DesignConfig | None = None) -> Motion:
    """A motion of ``seconds`` (30 fps) whose root follows ``curve`` (K, 2) floor points (x, z), metres.

    It starts at the curve's first point facing along its first segment, from the first two frames of ``start``
    (None: a held-out start of ``gait`` drawn with ``seed``).  motion.meta["design"] holds each window's loss
    histories (PSO, L-BFGS) and the wall time."""
    c = check_curve(curve)
    if not (isinstance(seconds, (int, float)) and math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"seconds must be a positive finite number, got {seconds!r}")
    config = config or DesignConfig()
    prior = prior or default_prior()
    fps = float(prior.model.config.fps)
    seg = c[1:] - c[:-1]
    first = seg[np.linalg.norm(seg, axis=1) > 1e-9][0]
    init0 = (c[0, 0], c[0, 1], float(heading_yaw(torch.from_numpy(first))))
    raw0, init0, start_m = prepare_start(start, gait, seed, init0, prior, fps)
    speed = float(np.linalg.norm(seg, axis=1).sum() / seconds) if config.speed is None else config.speed

    length = float(np.linalg.norm(seg, axis=1).sum())
    progress = [0.0]  # arc length reached so far: it only grows

    def control(init, left):  # eq. (17) on the curve just ahead of the window's start (see "differs"), + progress
        reach = 2.0 * config.window * speed / fps + 0.5  # m of curve a window can cover, with room to spare
        progress[0] = arc_position(c, init[:2].numpy(), progress[0], progress[0] + reach)
        if config.progress == "arc":  # behind (ahead of) schedule: the pace due is faster (slower)
            reach = max(reach, 2.0 * config.window * (length - progress[0]) / max(left, 1) + 0.5)
        curve_t = torch.from_numpy(polyline_between(c, progress[0], progress[0] + reach))
        remaining = length - progress[0]

        def energy(xz, yaw, raw):
            e = curve_energy(xz, curve_t, config.sigma_fit2)
            if config.sigma_speed is None:
                return e
            if config.progress == "net":  # the net displacement's speed, in any direction (a baseline rule)
                net = (xz[:, -1] - xz[:, 0]).norm(dim=-1) * fps / (xz.shape[1] - 1)  # (N,) m/s
                return e + (net - speed) ** 2 / config.sigma_speed ** 2 * (xz.shape[1] - 1)
            # arc length gained along the curve by the window's last frame that will be kept at the end
            # (the motion's last frame in the last window), against the pace that reaches the end on time
            n = min(xz.shape[1], left)
            gained = arc_length_at(xz[:, n - 1], curve_t)  # (N,) m, from the window's start
            due = remaining * n / left
            return e + ((gained - due) * fps / n) ** 2 / config.sigma_speed ** 2 * n
        return energy

    frames, info = solve_windows(prior, start_m, raw0, second_pose(raw0, init0), control,
                                 max(int(round(seconds * fps)), 3) - 2, config, seed)
    feats = torch.cat((raw0[0], frames), 0).numpy()
    motion = decode_state_features(feats, start_m.skeleton, fps, tuple(float(v) for v in init0))
    motion.meta = dict(motion.meta, design=info, curve=c, contacts_bits=feats[:, prior.contact_cols])
    if config.plant and config.contact_height is not None:  # planting uses the low-toe rule (planting.py)
        motion = plant_with_prior(motion, prior, config.contact_height, config.plant_sigma_slide)
    return motion


def solve_windows(prior: RnnPrior, start_m: Motion, raw0: torch.Tensor, init1: torch.Tensor, control, total: int,
                  config: DesignConfig, seed: int) -> tuple[torch.Tensor, dict]:
    """The sliding-window MAP of sec. 5.2 for ``total`` frames after the two start frames raw0 (1, 2, D), frame 1
    at init1; control(init, left) -> the control energy of a window whose previous frame is at init = (x, z, yaw),
    with ``left`` frames still to make
    -> (raw frames (total, D), info)."""
    t0 = time.perf_counter()
    if config.space not in SPACES:
        raise ValueError(f"DesignConfig.space must be one of {SPACES}, got {config.space!r}")
    solve = _solve_window_frames if config.space == "frames" else _solve_window
    g = torch.Generator().manual_seed(seed)
    skel, plane = start_m.skeleton, stance_plane(start_m)
    prev, init = raw0.double(), init1
    state = prior.start_state(raw0, skel)
    out, carry, windows, done = [], None, [], 0
    while done < total:
        energy = WindowEnergy(prior, skel, prev, state, init, control(init, total - done), plane,
                              weights={"contact": config.contact_weight}, contact_height=config.contact_height)
        raw, u, hist = solve(energy, carry, config, g)
        if _needs_retry(hist["terms"], [w["terms"]["total"] for w in windows], config):
            from dataclasses import replace

            wide = replace(config, candidates=config.candidates * config.retry_factor)  # fresh, more samples
            again = solve(energy, None, wide, g)
            if again[2]["terms"]["total"] < hist["terms"]["total"]:
                raw, u, hist = again
            hist["retried"] = True
        left = total - done
        k = config.hop if left > config.window else min(left, config.window)
        keep = raw[:, :k]
        state = prior.advance(prev, keep, state, skel, u[2][:, :k])
        init = energy.end_pose(keep)
        prev = torch.cat((prev, keep), 1)[:, -2:]
        carry = tuple(v[:, k:] for v in u) if k < raw.shape[1] else None
        out.append(keep[0])
        windows.append(hist)
        done += k
    return torch.cat(out, 0)[:total], {"windows": windows, "seconds": time.perf_counter() - t0}


def _needs_retry(terms: dict, before: list[float], config: DesignConfig) -> bool:
    """Is a window searched again: its control energy above ``retry_control``, or its total energy more than
    ``retry_rise`` above the median total of the windows ``before`` it?"""
    if config.retry_control is not None and terms["control"] > config.retry_control:
        return True
    return config.retry_rise is not None and bool(before) and terms["total"] > np.median(before) + config.retry_rise


def _solve_window(energy: WindowEnergy, carry, config: DesignConfig, g: torch.Generator):
    """Candidates -> PSO -> L-BFGS on one window -> (raw (1, T, D), its (eps, gumbel, d), {"pso", "lbfgs"}).

    carry: the previous window's unused (eps, gumbel, d); the first candidate continues it."""
    prior, T, C, b = energy.prior, config.window, config.candidates, config.sample_bias
    M, D = prior.model.config.mixtures, prior.dim
    eps0, g0 = draw_noise(C, T, prior, g)  # C random samples of the RNN (sec. 4.1.4)
    if carry is not None:
        n = carry[0].shape[1]
        eps0[0, :n], g0[0, :n] = carry[0][0], carry[1][0]

    def loss(x):  # PSO particles (P, T (D + M)) -> (P,) eq. (19) with d = 0
        x = x.reshape(len(x), T, D + M)
        return energy.sampled(x[..., :D], x[..., D:], None, b)[1]["total"]

    x0 = torch.cat((eps0, g0), -1).reshape(C, -1)
    if config.use_pso:
        res = pso(loss, x0, config.pso, g)
        best, pso_hist = res.best.reshape(1, T, D + M), res.history
    else:  # the best candidate
        with torch.no_grad():
            f = loss(x0)
        best, pso_hist = x0[int(f.argmin())].reshape(1, T, D + M), [float(f.min())]
    eps, gum, d = best[..., :D], best[..., D:], torch.zeros(1, T, D, dtype=torch.float64)
    lb_hist = []
    if config.use_lbfgs:
        def total(e, dd):
            return energy.sampled(e, gum, dd, b)[1]["total"].sum()
        (eps, d), lb_hist = minimise_lbfgs(total, [eps, d], config.lbfgs)
        with torch.no_grad():
            e_end = float(energy.sampled(eps, gum, d, b)[1]["total"])
        if not e_end <= pso_hist[-1]:  # a component switch can make the energy jump: keep the better end
            eps, d = best[..., :D], torch.zeros_like(d)
    with torch.no_grad():
        raw, terms = energy.sampled(eps, gum, d, b)
    return raw, (eps, gum, d), {"pso": pso_hist, "lbfgs": lb_hist,
                                "terms": {k: float(v) for k, v in terms.items()}}


def _solve_window_frames(energy: WindowEnergy, carry, config: DesignConfig, g: torch.Generator):
    """The same search as `_solve_window` over the paper's variables: the window's frames s (their free columns,
    normalised) and d.  The candidates are RNN samples' frames; the stance bits are the best candidate's, held
    fixed (a bit is not differentiable).  -> (raw (1, T, D), (frames, bits, d), {"pso", "lbfgs", "terms"}).

    carry: the previous window's unused (frames, bits, d); the first candidate starts with those frames."""
    prior, T, C, b = energy.prior, config.window, config.candidates, config.sample_bias
    eps0, g0 = draw_noise(C, T, prior, g)
    with torch.no_grad():
        raw0, terms0 = energy.sampled(eps0, g0, None, b)  # (C, T, D) candidate frames
    raw0 = raw0.clone()
    if carry is not None:
        n = carry[0].shape[1]
        raw0[0, :n] = carry[0][0]
    bits = raw0[int(terms0["total"].argmin()), None, :, prior.contact_cols]  # (1, T, 2)
    z0 = energy.to_z(raw0)  # (C, T, F)
    F = z0.shape[-1]

    def loss(x):  # PSO particles (P, T F) -> (P,) eq. (19) with d = 0
        z = x.reshape(len(x), T, F)
        return energy.terms(energy.frames(z, bits.expand(len(x), -1, -1)))["total"]

    x0 = z0.reshape(C, -1)
    if config.use_pso:
        res = pso(loss, x0, config.pso, g)
        best, pso_hist = res.best.reshape(1, T, F), res.history
    else:
        with torch.no_grad():
            f = loss(x0)
        best, pso_hist = x0[int(f.argmin())].reshape(1, T, F), [float(f.min())]
    z, d = best.clone(), torch.zeros(1, T, prior.dim, dtype=torch.float64)
    lb_hist = []
    if config.use_lbfgs:
        def total(z_, dd):
            return energy.terms(energy.frames(z_, bits), dd)["total"].sum()
        (z, d), lb_hist = minimise_lbfgs(total, [z, d], config.lbfgs)
        with torch.no_grad():
            e_end = float(total(z, d))
        if not e_end <= pso_hist[-1]:  # L-BFGS can end above its start here too: keep the better end
            z, d = best.clone(), torch.zeros_like(d)
    with torch.no_grad():
        raw = energy.frames(z, bits)
        terms = energy.terms(raw, d)
    return raw, (raw, bits, d), {"pso": pso_hist, "lbfgs": lb_hist,
                                 "terms": {k: float(v) for k, v in terms.items()}}
