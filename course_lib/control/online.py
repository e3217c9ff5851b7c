"""Online motion control (Wang, Chai et al. 2021, sec. 5.3): the user steers speed and direction while the
character moves; each call optimises the next short batch of frames, MAP with eq. (20)-(23):

    E = prior (eq. 15-16) + contact (eq. 18)
      + ((1/T) sum_i speed_i - c_speed)^2 / sigma_speed^2                               -- eq. (22)
      + 2 (1 - cos(yaw_T - c_direction)) / sigma_direction^2                            -- eq. (23)

speed_i = ||root_xz_i - root_xz_{i-1}|| fps; yaw_T the heading of the batch's last frame (2 (1 - cos x) ~ x^2,
without the jump at +-pi).  Per call: a few RNN samples, the best one, then a few L-BFGS evaluations on its
sampler noise and d (rollout.py; gradients by BPTT); the lowest-energy batch evaluated is the one returned.
`python -m course_lib.timings --only online` times a step.

Latency: a command given to ``step`` shapes the ``batch`` frames that call returns (10 frames = 0.33 s at
30 fps); its speed is the batch's average, its direction is asked of the batch's last frame.

Taught in notebooks/04_map_control.ipynb.

Differs from the paper:
- sigma_speed, sigma_direction and the batch length are not given; ours are in `OnlineConfig`.
- the direction asked of one batch is the current heading turned towards the command by at most ``max_turn``
  (60 degrees): a 180-degree command is reached over several batches instead of asking the prior for a U-turn
  in 0.33 s.
- the batch's speed is its net displacement / duration, not the mean per-frame speed of eq. (22): a model of
  feet-anchored features met the per-frame mean by zig-zagging.
- a second L-BFGS pass (ours, ``speed_retry``): within 1 s (3 batches) of a change of the speed command (by more
  than 10 % from the command at the last change), a batch whose net speed is still more than 10 % off is
  searched again; without it some speed changes took over a second to settle.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import torch

from course_lib.control.design import default_prior, prepare_start
from course_lib.control.energy import stance_plane
from course_lib.control.kinematics import second_pose
from course_lib.control.lbfgs import LbfgsConfig, minimise_lbfgs
from course_lib.control.rnn_prior import RnnPrior
from course_lib.control.rollout import draw_noise
from course_lib.control.window import WindowEnergy
from course_lib.motion import Motion
from course_lib.representations import decode_state_features
from course_lib.synthetic.locomotion import GAIT_PARAMS

# The fastest commanded speed the training data holds (m/s): the top of the run's range.
MAX_SPEED = max(p.speed[1] for p in GAIT_PARAMS.values())

__all__ = ["MAX_SPEED", "OnlineConfig", "OnlineController", "speed_energy", "direction_energy"]


@dataclass
class OnlineConfig:
    """Online control settings (ours; the paper gives none)."""

    batch: int = 10  # frames optimised and returned per step (the latency)
    candidates: int = 4  # RNN samples per step; the best starts L-BFGS
    lbfgs_iterations: int = 5  # energy evaluations of L-BFGS per step (its max_iter and max_eval); the RNN's
    # samples keep its pace, so a speed change must come from L-BFGS: fewer hold the commanded speed less often,
    # more cost frames/s (studies/04_map_control/README.md, control_online_budget)
    sigma_speed: float = 0.05  # m/s, eq. (22)
    sigma_direction: float = 0.01  # rad, eq. (23); a wider sigma turns to a 180-degree command more slowly
    max_turn: float = math.radians(60)  # the most the asked direction differs from the heading, per batch
    sample_bias: float = 1.0  # Graves' bias of the samples
    speed_retry: float = 0.1  # > 0: a batch whose net speed misses the command by more than this fraction (at least
    # 0.05 m/s) gets a second L-BFGS pass (ours; 0: never; see "differs") ...
    speed_retry_batches: int = 3  # ... within this many batches of a change of the speed command by more than that
    # fraction (0: any batch) ...
    speed_retry_iterations: int = 5  # ... of this many L-BFGS evaluations (3 left some changes over 1 s)

    def __post_init__(self):
        if self.batch < 2 or self.candidates < 1 or self.lbfgs_iterations < 0 or self.speed_retry_iterations < 1:
            raise ValueError(f"OnlineConfig: need batch >= 2, candidates >= 1, lbfgs_iterations >= 0, "
                             f"speed_retry_iterations >= 1, got {self}")


def speed_energy(root_xz: torch.Tensor, prev_xz: torch.Tensor, speed: float, fps: float, sigma: float,
                 net: bool = True):
    """Eq. (22): root_xz (N, T, 2), prev_xz (N, 2) the frame before -> (N,).  net=True: the batch's speed is its
    net displacement / duration (see "differs"); False: the mean of the per-frame speeds, as printed in eq. (22)."""
    path = torch.cat((prev_xz[:, None], root_xz), 1)  # (N, T + 1, 2)
    if net:
        v = ((path[:, -1] - path[:, 0]) ** 2).sum(-1).clamp(min=1e-12).sqrt() * fps / root_xz.shape[1]  # (N,)
    else:
        v = (((path[:, 1:] - path[:, :-1]) ** 2).sum(-1).clamp(min=1e-12).sqrt() * fps).mean(-1)  # (N,) m/s
    return (v - speed) ** 2 / sigma ** 2


def direction_energy(yaw: torch.Tensor, direction: float, sigma: float):
    """Eq. (23): yaw (N, T) -> (N,), 2 (1 - cos(yaw_T - direction)) / sigma^2."""
    return 2 * (1 - torch.cos(yaw[:, -1] - direction)) / sigma ** 2


def _misses(value: float, target: float, fraction: float) -> bool:
    """|value - target| over ``fraction`` of the target, and over 0.05 m/s: the speed retry's tolerance."""
    return abs(value - target) > max(fraction * target, 0.05)


class OnlineController:
    """Speed and direction control of a walking (or other gait) character.

    ``step(speed, direction)``: speed in m/s, direction the wanted heading in radians (0 faces +Z, pi/2 +X)
    -> the next ``config.batch`` frames as a Motion (world coordinates, continuing the previous ones)."""

    def __init__(self, gait: str = "walk", seed: int = 0, start: Motion | None = None, prior: RnnPrior | None = None,
                 config: OnlineConfig | None = None):
        import torch._dynamo  # noqa: F401  -- torch.optim imports it on its first optimiser (slow): not in step 1

        self.prior = prior or default_prior()
        self.config = config or OnlineConfig()
        self.fps = float(self.prior.model.config.fps)
        raw0, init0, start_m = prepare_start(start, gait, seed, None, self.prior, self.fps)
        self.skeleton, self.plane = start_m.skeleton, stance_plane(start_m)
        self.generator = torch.Generator().manual_seed(seed)
        self.prev, self.pose = raw0.double(), second_pose(raw0, init0)  # (1, 2, D), (3,) of frame 1
        self.state = self.prior.start_state(raw0, self.skeleton)
        self.frames = [raw0[0]]  # raw features so far, from the two start frames
        self.init0 = init0
        self._speed_cmd, self._since_change = None, 0  # the speed command at its last change, batches since then

    @property
    def heading(self) -> float:
        """The current heading (yaw, radians)."""
        return float(self.pose[2])

    def _target_direction(self, direction: float) -> float:
        delta = (direction - self.heading + math.pi) % (2 * math.pi) - math.pi
        return self.heading + float(np.clip(delta, -self.config.max_turn, self.config.max_turn))

    def step(self, speed: float, direction: float) -> Motion:
        """speed (m/s) >= 0, direction (rad) -> the next batch of frames."""
        if not (math.isfinite(speed) and math.isfinite(direction)) or speed < 0:
            raise ValueError(f"step: need a finite speed >= 0 and a finite direction, got {speed!r}, {direction!r}")
        if speed > MAX_SPEED:  # beyond every gait of the training data: the model has never seen it
            warnings.warn(f"step: speed {speed:g} m/s is outside the training data's 0..{MAX_SPEED:g} m/s "
                          f"(course_lib.synthetic.GAIT_PARAMS, the run's fastest); clamped to {MAX_SPEED:g}",
                          stacklevel=2)
            speed = MAX_SPEED
        cfg, prior = self.config, self.prior
        # a change: the command moved by more than the retry's tolerance from the one at the last change (a joystick's
        # small drift is not one)
        if self._speed_cmd is None or _misses(speed, self._speed_cmd, cfg.speed_retry):
            self._speed_cmd, self._since_change = speed, 0
        else:
            self._since_change += 1
        retry = cfg.speed_retry > 0 and (cfg.speed_retry_batches == 0 or self._since_change < cfg.speed_retry_batches)
        target = self._target_direction(float(direction))
        prev_xz = self.pose[None, :2]

        def control(xz, yaw, raw):
            return (speed_energy(xz, prev_xz.expand(len(xz), 2), speed, self.fps, cfg.sigma_speed)
                    + direction_energy(yaw, target, cfg.sigma_direction))

        energy = WindowEnergy(prior, self.skeleton, self.prev, self.state, self.pose, control, self.plane)
        eps, gum = draw_noise(cfg.candidates, cfg.batch, prior, self.generator)
        with torch.no_grad():
            k = int(energy.sampled(eps, gum, None, cfg.sample_bias)[1]["total"].argmin())
        eps, gum = eps[k:k + 1], gum[k:k + 1]
        d = torch.zeros(1, cfg.batch, prior.dim, dtype=torch.float64)
        best = {}  # the lowest-energy batch evaluated: committed as it is, without a further rollout

        def total(e, dd):
            raw, terms = energy.sampled(e, gum, dd, cfg.sample_bias)
            value = terms["total"].sum()
            if not best or float(value.detach()) < best["energy"]:
                best.update(energy=float(value.detach()), raw=raw.detach(),
                            state=tuple(s.detach() for s in energy.last_state))
            return value

        if cfg.lbfgs_iterations:
            n = cfg.lbfgs_iterations
            xs, _ = minimise_lbfgs(total, [eps, d], LbfgsConfig(iterations=n, evaluations=n))
            if retry and _misses(self._net_speed(energy, best["raw"]), speed, cfg.speed_retry):
                m = cfg.speed_retry_iterations
                minimise_lbfgs(total, xs, LbfgsConfig(iterations=m, evaluations=m))
        else:
            with torch.no_grad():
                total(eps, d)
        return self._commit(energy, best["raw"], best["state"])

    def _net_speed(self, energy: WindowEnergy, raw: torch.Tensor) -> float:
        """The batch's net speed (m/s): its end's floor distance from the current pose over its duration."""
        end = energy.end_pose(raw)
        return float(torch.linalg.vector_norm(end[:2] - self.pose[:2])) * self.fps / raw.shape[1]

    def _commit(self, energy: WindowEnergy, raw: torch.Tensor, state) -> Motion:
        pose = self.pose
        self.state = state  # the RNN has read prev's last frame and raw[:-1] (+ d)
        self.pose = energy.end_pose(raw)
        self.prev = torch.cat((self.prev, raw), 1)[:, -2:]
        self.frames.append(raw[0])
        feats = torch.cat((raw[0, :1], raw[0]), 0).numpy()  # a placeholder row 0 at ``pose`` (the decoder skips it)
        m = decode_state_features(feats, self.skeleton, self.fps, tuple(float(v) for v in pose))
        return m[1:]

    def motion(self) -> Motion:
        """Everything generated so far, from the two start frames."""
        feats = torch.cat(self.frames, 0).numpy()
        return decode_state_features(feats, self.skeleton, self.fps, tuple(float(v) for v in self.init0))
