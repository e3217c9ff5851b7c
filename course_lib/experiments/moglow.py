"""Lesson 06 experiment: MoGlow (Henter et al. 2019) on the course's locomotion data, its variants and baselines.

    python -m course_lib.reproduce moglow              # data, train 4 models, evaluation -> results/moglow.json
    python -m course_lib.reproduce moglow --eval-only  # the evaluation from checkpoints/moglow*.pt

Data as sec. 5.1: the locomotion dataset (1800 clips of 4 s, 45 subjects) at 20 fps in
``positions_control`` -- 21 joint positions in the floor-projected root frame (63) as the output
x_t and (forward velocity, sideways velocity, yaw rate) as the control c_t (the paper's per-frame
displacements times fps: the same after standardisation) -- standardised with the training split's
statistics, mirrored and time-reversed (4x the clips), one 4-s window (80 frames) per clip, tau = 10.
The Hips' floor-frame x and z are 0 by construction: these two fixed values are not modelled
(a density on a constant is infinite) and are restored on output, so the flow sees D = 61.
Split by subject (`split_by_subject`, seed 0): 80 % train, 10 % validation, 10 % held out.

Models (all `MoGlowConfig.cpu()`, same optimiser, steps and seed):
``moglow`` (LSTM, autoregressive dropout 0.95), ``moglow_nodrop`` (dropout 0), ``moglow_markov``
(feed-forward conditioning, dropout 0.95), ``moglow_gaussian`` (conditional diagonal Gaussian with
the LSTM conditioning, dropout 0.95).

Evaluation (`eval_moglow`): held-out NLL per frame; invertibility on held-out windows; control
consistency under a zero and a walking control; 20-s samples against lesson 03's freeze floor;
foot skate, jitter, FID and C2ST against held-out mocap, driven by the mocap's own controls.
FID and C2ST need rotations: samples and mocap alike go positions -> rotations through
`representations.motion_from_positions` (no bone twist is observable from positions), so both sets
lose the same information.  Nothing runs at import time.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import torch

from course_lib.paths import CHECKPOINTS
from course_lib.results import rounded

ROOT = Path(__file__).resolve().parents[2]
COMMAND = "python -m course_lib.reproduce moglow"
FPS = 20.0  # sec. 5.1: 120 -> 20 fps
WINDOW = 80  # frames per training window (4 s)
TAU = 10  # history frames (0.5 s)
STEPS = 5000  # optimiser steps per model (~27 epochs of the 5920 augmented training windows; ~10 min on one core)
BATCH = 32
LR = 1e-3  # the paper: 1e-4 with a Noam schedule over 80k steps; ours is a short run
# The LR falls (half cosine) from LR to LR_FLOOR x LR over the steps after LR_DECAY_FROM x STEPS (None: constant).
# study moglow_lr_decay measured it against the constant LR of the earlier models, same 5000 steps: held-out NLL
# -155.1 vs -130.4 nats/frame (dropout model), zero-control stepping ratio 0.249-0.264 vs 0.301-0.314 (5 seeds).
LR_DECAY_FROM = 0.6
LR_FLOOR = 0.01
GRAD_CLIP = 5.0  # StyleGestures' max_grad_clip
ONE_BODY = False  # the subjects' own bodies; True puts every clip on the canonical skeleton, as the paper's data
# were retargeted to one (study moglow_dropout_history: on one body the feet slide as much)
EVAL_SEEDS = 3  # generation seeds of the distribution scores
MIN_DISTRIBUTION_CLIPS = 20  # FID / C2ST need at least this many held-out clips
BLOW_UP = 20.0  # |standardised pose value| beyond this (20 sd) = a sample that exploded
MODELS = {"moglow": {}, "moglow_nodrop": {"dropout": 0.0}, "moglow_markov": {"conditioner": "markov"},
          "moglow_gaussian": {"next_step": "gaussian"}}
LABELS = {"moglow": "MoGlow (LSTM, dropout 0.95)", "moglow_nodrop": "MoGlow, no dropout",
          "moglow_markov": "Markov (MLP), dropout 0.95", "moglow_gaussian": "Gaussian (LSTM), dropout 0.95"}


# ----------------------------------------------------------------------------- data


@dataclasses.dataclass
class MoGlowData:
    """Standardised tensors: poses (N, T, D) without the fixed values, controls (N, T, 3), and what maps back."""

    train: dict
    val: dict
    test: dict
    stats: tuple  # (mean, std) of the 66 positions_control features (training split, augmented)
    fixed: np.ndarray  # (63,) bool: pose features not modelled (the Hips' floor-frame x, z)
    test_clips: list  # the held-out Motions at 20 fps, in the order of test["poses"]

    @property
    def pose_dim(self) -> int:
        return int((~self.fixed).sum())

    def control_range(self) -> tuple[np.ndarray, np.ndarray]:
        """The training split's control range: (low (3,), high (3,)) in raw units (forward m/s, sideways m/s,
        yaw rate rad/s), over every frame of every training window."""
        c = self.train["controls"].double().numpy().reshape(-1, 3) * self.stats[1][63:] + self.stats[0][63:]
        return c.min(0), c.max(0)

    def within_control_range(self, controls: torch.Tensor, who: str) -> torch.Tensor:
        """Standardised controls (..., 3) clamped to the training split's range, with a warning that says which
        values were outside and where the range is: the model has never seen them (clamping is what it can do)."""
        mean, std = self.stats[0][63:], self.stats[1][63:]
        low, high = self.control_range()
        lo = torch.as_tensor((low - mean) / std, dtype=controls.dtype)
        hi = torch.as_tensor((high - mean) / std, dtype=controls.dtype)
        clamped = torch.maximum(torch.minimum(controls, hi), lo)
        if not torch.equal(clamped, controls):
            raw = controls.double().numpy().reshape(-1, 3) * std + mean
            names = ("forward m/s", "sideways m/s", "yaw rate rad/s")
            outside = [f"{n} {raw[:, k].min():.2f}..{raw[:, k].max():.2f} (data {low[k]:.2f}..{high[k]:.2f})"
                       for k, n in enumerate(names)
                       if raw[:, k].min() < low[k] - 1e-9 or raw[:, k].max() > high[k] + 1e-9]
            warnings.warn(f"{who}: control outside the training data's range, clamped: {'; '.join(outside)}",
                          stacklevel=3)
        return clamped

    def features(self, poses: torch.Tensor, controls: torch.Tensor) -> np.ndarray:
        """Standardised (N, T, D), (N, T, 3) -> raw positions_control features (N, T, 66) (fixed values restored)."""
        mean, std = self.stats
        N, T = poses.shape[:2]
        out = np.empty((N, T, len(mean)))
        out[..., :63][..., ~self.fixed] = poses.double().numpy()
        out[..., :63][..., self.fixed] = 0.0
        out[..., 63:] = controls.double().numpy()
        return out * std + mean

    def positions(self, poses: torch.Tensor, controls: torch.Tensor, starts=None) -> np.ndarray:
        """-> world joint positions (N, T, 21, 3), the control integrated to a root path from `starts`."""
        from course_lib.representations import decode_positions

        feats = self.features(poses, controls)
        starts = starts or [(0.0, 0.0, 0.0)] * len(feats)
        return np.stack([decode_positions(f, FPS, s) for f, s in zip(feats, starts, strict=True)])


def _tensors(ds, fixed: np.ndarray) -> dict:
    x = torch.stack([ds[i]["x"] for i in range(len(ds))])  # (N, T, 66) standardised
    keep = torch.from_numpy(np.concatenate((~fixed, np.zeros(3, bool))))
    return {"poses": x[..., keep].contiguous(), "controls": x[..., 63:].contiguous()}


def load_data(mode: str | None = "full", seed: int = 0, one_body: bool = ONE_BODY, extra_clips: int = 0) -> MoGlowData:
    """The locomotion clips at 20 fps, split by subject; train mirrored + time-reversed (sec. 5.1).  With
    `one_body` every clip is first put on the canonical skeleton (`Motion.retarget`), as the paper's data were
    retargeted to one skeleton.  `extra_clips`: that many more clips generated for training only (generator seed
    seed + 1: other subjects, named "extra-sNN"); the validation and held-out clips are unchanged."""
    from course_lib.datasets import FixedDofs, WindowDataset, generate_locomotion_set, load_dataset, split_by_subject

    clips = load_dataset("locomotion", mode=mode, fps=FPS)
    train, val, test = split_by_subject(clips, (0.8, 0.1, 0.1), seed=seed)
    if extra_clips:
        more = generate_locomotion_set(extra_clips, seed + 1, FPS)
        train = train + [dataclasses.replace(m, subject=f"extra-{m.subject}") for m in more]
    if one_body:
        from course_lib.skeleton import Skeleton

        train, val, test = ([m.retarget(Skeleton.canonical()) for m in part] for part in (train, val, test))
    ds = WindowDataset(train, "positions_control", WINDOW, fps=FPS, mirror=True, reverse=True)
    fixed = FixedDofs.from_stats(*ds.stats).mask[:63]
    held = WindowDataset(test, "positions_control", WINDOW, fps=FPS, stats=ds.stats)
    validation = WindowDataset(val, "positions_control", WINDOW, fps=FPS, stats=ds.stats)
    clips_test = [held.clips[c] for c, _ in held.index]
    return MoGlowData(_tensors(ds, fixed), _tensors(validation, fixed), _tensors(held, fixed), ds.stats, fixed,
                      clips_test)


def batches(data: dict, batch: int, seed: int):
    """An endless iterator of random batches {"poses", "controls"}."""
    gen = torch.Generator().manual_seed(seed)
    n = len(data["poses"])
    while True:
        for idx in torch.randperm(n, generator=gen).split(batch):
            if len(idx) == batch:
                yield {"poses": data["poses"][idx], "controls": data["controls"][idx]}


# ----------------------------------------------------------------------------- training and checkpoints


def config_for(name: str, pose_dim: int):
    from course_lib.models.moglow import MoGlowConfig

    return MoGlowConfig.cpu(pose_dim, 3, TAU, **MODELS[name])


def lr_factor(step: int, steps: int, decay_from: float | None = LR_DECAY_FROM, floor: float = LR_FLOOR) -> float:
    """The learning rate of optimiser step `step` (0-based) of `steps`, as a fraction of LR: 1 until
    ``decay_from * steps``, then a half cosine down to `floor` at the last step (None: 1 throughout)."""
    if decay_from is None:
        return 1.0
    start = decay_from * steps
    if step <= start:
        return 1.0
    t = min(1.0, (step - start) / max(1.0, steps - 1 - start))
    return floor + (1 - floor) * 0.5 * (1 + math.cos(math.pi * t))


def train_model(name: str, data: MoGlowData, steps: int = STEPS, seed: int = 0, progress: bool = False,
                decay_from: float | None = LR_DECAY_FROM):
    """-> (model, History) of one variant (the LR schedule of `lr_factor`, set before every step)."""
    from course_lib.models.moglow import MoGlow
    from course_lib.training import fit, seed_everything

    def schedule(info):  # called after step info.step (1-based): set the LR of the next one
        for group in info.optimizer.param_groups:
            group["lr"] = LR * lr_factor(info.step, steps, decay_from)

    seed_everything(seed)
    model = MoGlow(config_for(name, data.pose_dim))
    hist = fit(model, batches(data.train, BATCH, seed), steps=steps, lr=LR, grad_clip=GRAD_CLIP, progress=progress,
               desc=name, callback=schedule if decay_from is not None else None)  # lr_factor is 1 at step 0
    return model.eval(), hist


def train_resumable(name: str, data: MoGlowData, steps: int, state: Path, until: int | None = None,
                    chunk: int = 10_000, seed: int = 0, progress: bool = False):
    """Train like `train_model` (the LR schedule of `lr_factor` over all `steps`) in chunks of `chunk` steps,
    saving weights, optimiser state and step to `state` after each, so that a run longer than one sitting
    continues where it stopped: -> (model, step reached).  Stops at `until` (a multiple of `chunk`; default
    `steps`).  Chunk k draws its batches and dropout masks from seed (seed, k), so a resumed run is the same
    run.  `state` must be this variant's (its name, config, steps, chunk and seed are checked)."""
    from course_lib.models.moglow import MoGlow
    from course_lib.training import fit, seed_everything

    until = steps if until is None else until
    if not 0 < until <= steps or until % chunk and until != steps:
        raise ValueError(f"train_resumable: until={until} must be a multiple of chunk={chunk} in (0, {steps}]")
    config = config_for(name, data.pose_dim)
    run = {"name": name, "config": dataclasses.asdict(config), "steps": steps, "chunk": chunk, "seed": seed,
           "train_windows": len(data.train["poses"])}
    seed_everything(seed)
    model, opt_state, done = MoGlow(config), None, 0
    state = Path(state)
    if state.exists():
        saved = torch.load(state, weights_only=True)
        if saved["run"] != run:
            raise ValueError(f"train_resumable: {state} holds the run {saved['run']}, not {run}; "
                             "give another state path or delete that file")
        model.load_state_dict(saved["model"])
        opt_state, done = saved["optimizer"], saved["step"]
    while done < until:
        n = min(chunk, steps - done)
        k, kept = done // chunk, {}

        def schedule(info, offset=done, kept=kept):  # after global step offset + info.step: set the next LR
            for group in info.optimizer.param_groups:
                group["lr"] = LR * lr_factor(offset + info.step, steps)
            kept["optimizer"] = info.optimizer

        seed_everything(seed * 1_000_003 + k)
        fit(model, batches(data.train, BATCH, seed * 1_000_003 + k), steps=n, lr=LR * lr_factor(done, steps),
            grad_clip=GRAD_CLIP, progress=progress, desc=f"{name} {done}-{done + n}", callback=schedule,
            optimizer_state=opt_state)
        done += n
        opt_state = kept["optimizer"].state_dict()
        tmp = state.with_suffix(".tmp")
        torch.save({"run": run, "model": model.state_dict(), "optimizer": opt_state, "step": done}, tmp)
        tmp.replace(state)
    return model.eval(), done


def load_model(name: str, checkpoints: Path = CHECKPOINTS):
    from course_lib.models.moglow import MoGlow, MoGlowConfig
    from course_lib.training import load_checkpoint

    if name not in MODELS:
        raise KeyError(f"load_model: no lesson-06 model {name!r}; choose one of {', '.join(MODELS)}")
    return load_checkpoint(checkpoints / f"{name}.pt", MoGlow, MoGlowConfig).eval()


def stats_file(checkpoints: Path = CHECKPOINTS) -> Path:
    return checkpoints / "moglow_stats.npz"


def save_stats(data: MoGlowData, checkpoints: Path = CHECKPOINTS) -> Path:
    from course_lib.datasets import write_npz
    from course_lib.manifest import record_file

    path = write_npz({"mean": data.stats[0], "std": data.stats[1]}, stats_file(checkpoints), overwrite=True)
    record_file(path, command=COMMAND)
    return path


# ----------------------------------------------------------------------------- measures


@torch.no_grad()
def nll_per_frame(model, data: dict, batch: int = 64) -> float:
    """Held-out negative log-likelihood, nats per frame (the standardised 61-D pose, frames after tau)."""
    total, frames = 0.0, 0
    for i in range(0, len(data["poses"]), batch):
        p, c = data["poses"][i:i + batch], data["controls"][i:i + batch]
        total -= model.log_prob(p, c).sum().item()
        frames += p.shape[0] * (p.shape[1] - model.config.tau)
    return total / frames


@torch.no_grad()
def round_trip_error(model, data: dict, n: int = 64) -> dict:
    """max |decode(encode(x)) - x| over n held-out windows (standardised units): ``one_step`` inverts each frame
    from the true history (float32), ``float32`` and ``float64`` decode autoregressively, each new pose feeding
    the next frame's history, so float32 rounding (1e-6) is amplified by the generator's own dynamics."""
    import copy

    p, c = data["poses"][:n], data["controls"][:n]
    z, _ = model.encode(p, c)
    h, _ = model.condition(model.condition_inputs(p, c))
    out = {"one_step": float((model.flow_inverse(z, h, model.weight_inverses()) - p[:, model.config.tau:]).abs().max()),
           "float32": float((model.decode(z, p[:, :model.config.tau], c) - p).abs().max())}
    wide, p, c = copy.deepcopy(model).double(), p.double(), c.double()
    z, _ = wide.encode(p, c)
    out["float64"] = float((wide.decode(z, p[:, :model.config.tau], c) - p).abs().max())
    return out


def constant_control(data: MoGlowData, n: int, frames: int, forward: float = 0.0, sideways: float = 0.0,
                     yaw_rate: float = 0.0) -> torch.Tensor:
    """A constant raw control (m/s, m/s, rad/s) for n sequences of `frames` -> standardised (n, frames, 3)."""
    mean, std = data.stats[0][63:], data.stats[1][63:]
    c = (np.array([forward, sideways, yaw_rate]) - mean) / std
    if not np.isfinite(c).all():
        raise ValueError(f"constant_control: forward, sideways and yaw_rate must be finite, got "
                         f"{forward}, {sideways}, {yaw_rate}")
    c = data.within_control_range(torch.from_numpy(c), "constant_control").float()
    return c.expand(n, frames, 3).contiguous()


def start_frames(data: MoGlowData, n: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    """The first tau poses and controls of n held-out windows (seeded choice, with replacement)."""
    idx = torch.randint(len(data.test["poses"]), (n,), generator=torch.Generator().manual_seed(seed))
    return data.test["poses"][idx, :TAU], data.test["controls"][idx, :TAU]


def generate(model, data: MoGlowData, controls: torch.Tensor, seed: int, temperature: float = 1.0,
             starts: torch.Tensor | None = None, history_fn=None) -> torch.Tensor:
    """controls (N, T, 3) from frame tau on -> standardised poses (N, T, D) from held-out starting poses;
    history_fn: `MoGlow.sample`'s hook on the poses fed back (experiments only)."""
    x0, c0 = starts if starts is not None else start_frames(data, len(controls), seed)
    controls = torch.cat((c0, controls[:, TAU:]), 1)
    gen = torch.Generator().manual_seed(seed)
    if history_fn is None:  # any model with MoGlow.sample's first four arguments (tests pass stand-ins)
        return model.sample(controls, x0, temperature, generator=gen), controls
    return model.sample(controls, x0, temperature, generator=gen, history_fn=history_fn), controls


STEP_LAG = 5  # frames (0.25 s, shorter than a swing): the lag of the "stepping" feet speed


def foot_speed(positions_local: np.ndarray, lag: int = 1) -> float:
    """Floor-frame positions (N, T, 21, 3) -> mean horizontal speed of the four foot joints in the root frame,
    m/s, from displacements over `lag` frames.  lag = 1 is the frame-to-frame speed, which also counts each
    frame's independent sampling noise (noise of sd s adds about sqrt(2) s * fps / lag); lag = STEP_LAG is the
    *stepping* speed, which a foot that steps keeps and per-frame noise mostly loses (tests: known answers)."""
    from course_lib.skeleton import Skeleton

    if not 1 <= lag < positions_local.shape[1]:
        raise ValueError(f"foot_speed: lag must be in [1, T), got {lag} for T = {positions_local.shape[1]}")
    feet = list(Skeleton.canonical().feet)
    f = positions_local[:, :, feet][..., [0, 2]]
    return float(np.linalg.norm(f[:, lag:] - f[:, :-lag], axis=-1).mean() * FPS / lag)


def local_positions(data: MoGlowData, poses: torch.Tensor, controls: torch.Tensor) -> np.ndarray:
    return data.features(poses, controls)[..., :63].reshape(*poses.shape[:2], 21, 3)


def stride_frequency(positions_local: np.ndarray, lo: float = 0.3, hi: float = 3.0) -> np.ndarray:
    """Floor-frame positions (N, T, 21, 3) -> (N,) stride frequency (cycles/s) = the peak of a fine-grid
    periodogram of the feet's forward separation z_left - z_right (one period = one stride = two steps)."""
    from course_lib.skeleton import Skeleton

    sk = Skeleton.canonical()
    s = positions_local[:, :, sk.index("LeftFoot"), 2] - positions_local[:, :, sk.index("RightFoot"), 2]
    s = s - s.mean(1, keepdims=True)
    t = np.arange(s.shape[1]) / FPS
    freqs = np.arange(lo, hi, 0.005)
    basis = np.exp(-2j * np.pi * freqs[:, None] * t[None])  # (F, T)
    power = np.abs(s @ basis.T) ** 2  # (N, F)
    return freqs[power.argmax(1)]


def steady_runs(speed: np.ndarray, target: float, tol: float, min_frames: int) -> list[slice]:
    """speed (T,) m/s -> the maximal runs of frames within target +- tol that last at least min_frames."""
    ok = np.concatenate(([False], np.abs(np.asarray(speed, float) - target) < tol, [False]))
    edges = np.flatnonzero(np.diff(ok.astype(int)))  # starts at even, ends at odd positions
    return [slice(a, b) for a, b in zip(edges[::2], edges[1::2], strict=True) if b - a >= min_frames]


def data_gait(data: MoGlowData, speed: float, tol: float = 0.15, min_seconds: float = 1.5) -> dict:
    """The data's gait at `speed`: the generator's cadence (clip meta, steps/s) over every held-out frame
    that walks (meta gait) at speed +- tol m/s, and its stride speed / (cadence / 2) (m); beside it, the
    samples' estimator on every run of >= min_seconds of such frames, as its check.  Whole clips cannot
    be the reference: a 4-s clip of a random control program is rarely steady (the speed std is above
    0.15 m/s in 72 of the 74 held-out walk clips, and no 2-s run stays within 0.15 m/s of the median)."""
    from course_lib.representations import encode_positions_control

    cadence, v_all, runs = [], [], []
    for m in data.test_clips:
        if m.action != "walk" or m.meta.get("mirrored"):
            continue
        v = np.asarray(m.meta["speed"], float)[: m.num_frames]
        walking = np.asarray(m.meta["gait"])[: m.num_frames] == list(m.meta["gait_names"]).index("walk")
        v_masked = np.where(walking, v, np.inf)
        ok = np.abs(v_masked - speed) < tol
        cadence += list(np.asarray(m.meta["cadence"], float)[: m.num_frames][ok])
        v_all += list(v[ok])
        local = None
        for r in steady_runs(v_masked, speed, tol, int(min_seconds * FPS)):
            local = encode_positions_control(m)[:, :63].reshape(-1, 21, 3) if local is None else local
            runs.append((stride_frequency(local[r][None])[0], v[r].mean()))
    if not cadence:
        return {"clips": 0, "frames": 0}
    out = {"frames": len(cadence), "cadence": float(np.median(cadence)), "speed": float(np.mean(v_all)),
           "clips": len(runs)}
    out["stride_m"] = out["speed"] / (out["cadence"] / 2)
    if runs:
        f, v = np.array(runs).T
        out["estimator_cadence"] = float(np.median(2 * f))
        out["estimator_stride_m"] = float(np.median(v / f))
    return out


def data_idle_feet_speed(data: MoGlowData) -> dict:
    """The held-out mocap's feet speed in the root frame (lag STEP_LAG and frame to frame) over its runs of
    idle frames (>= 1 s), and over every frame: where a model standing still should sit."""
    local = local_positions(data, data.test["poses"], data.test["controls"])
    runs = []
    for clip, pos in zip(data.test_clips, local, strict=True):
        idle = np.asarray(clip.meta["gait"])[: len(pos)] == list(clip.meta["gait_names"]).index("idle")
        runs += [pos[r] for r in steady_runs(np.where(idle, 0.0, 1.0), 0.0, 0.5, int(FPS))]
    out = {"all_frames": foot_speed(local, STEP_LAG), "all_frames_frame": foot_speed(local), "idle_runs": len(runs)}
    if runs:
        out["idle"] = float(np.mean([foot_speed(r[None], STEP_LAG) for r in runs]))
        out["idle_frame"] = float(np.mean([foot_speed(r[None]) for r in runs]))
    return out


def control_consistency(models: dict, data: MoGlowData, seed: int, n: int = 32) -> dict:
    """Zero control for 10 s: feet speed in the root frame (stepping, lag STEP_LAG, and frame to frame), with
    the data's own on its idle frames; walking control: cadence and stride against the data's."""
    speed = float(np.median([np.mean(m.meta["speed"]) for m in data.test_clips if m.action == "walk"]))
    ref = data_gait(data, speed)
    out = {"walk_speed": speed, "data": ref, "models": {}, "data_idle": data_idle_feet_speed(data)}
    T = TAU + int(10 * FPS)
    for name, model in models.items():
        poses, ctl = generate(model, data, constant_control(data, n, T), seed)
        local = local_positions(data, poses[:, TAU:], ctl[:, TAU:])
        still, frame_speed = foot_speed(local, STEP_LAG), foot_speed(local)
        poses, ctl = generate(model, data, constant_control(data, n, T, forward=speed), seed)
        f = stride_frequency(local_positions(data, poses[:, TAU + 40:], ctl[:, TAU + 40:]))  # the last 8 s
        row = {"zero_control_feet_speed": still, "zero_control_frame_speed": frame_speed,
               "walk_cadence": float(np.median(2 * f)),
               "walk_stride_m": float(np.median(speed / f))}
        if ref.get("frames"):
            row["cadence_ratio"] = row["walk_cadence"] / ref["cadence"]
            row["stride_ratio"] = row["walk_stride_m"] / ref["stride_m"]
        out["models"][name] = row
    if "moglow" in out["models"] and "moglow_nodrop" in out["models"]:
        drop, nodrop = out["models"]["moglow"], out["models"]["moglow_nodrop"]
        out["zero_control_ratio"] = drop["zero_control_feet_speed"] / nodrop["zero_control_feet_speed"]
        out["zero_control_frame_ratio"] = drop["zero_control_frame_speed"] / nodrop["zero_control_frame_speed"]
    return out


def long_program(data: MoGlowData, seed: int, n: int = 16, seconds: float = 20.0) -> dict:
    """The control program of `long_samples`: n sequences of tau held-out starting frames, then `seconds` of
    held-out clips' controls back to back (their frames after tau, seeded choice) -> {"controls" (n, T, 3),
    "poses" (n, T, D) the mocap that goes with them, "seams": the frames where a new clip starts}."""
    k = int(np.ceil(seconds * FPS / (WINDOW - TAU)))
    pick = np.random.default_rng(seed).integers(0, len(data.test["controls"]), size=(n, k))
    x0, c0 = start_frames(data, n, seed)
    T = TAU + int(seconds * FPS)
    out = {"seams": list(range(TAU, T, WINDOW - TAU))}
    for key, start in (("controls", c0), ("poses", x0)):
        parts = [start] + [data.test[key][pick[:, j], TAU:] for j in range(k)]
        out[key] = torch.cat(parts, 1)[:, :T]
    return out


def exploded(poses: torch.Tensor) -> torch.Tensor:
    """poses (N, T, D) standardised -> (N,) bool: any value beyond BLOW_UP sd, or NaN."""
    return ~(torch.nan_to_num(poses, nan=np.inf).abs() < BLOW_UP).all(-1).all(-1)


def long_samples(models: dict, data: MoGlowData, seed: int, n: int = 16, seconds: float = 20.0) -> dict:
    """20-s samples under the held-out clips' controls (5 clips back to back, `long_program`): joint-speed
    variance of the last 5 s against lesson 03's freeze floor (a tenth of the least-varying mocap clip's
    variance); a sample with any standardised pose value beyond BLOW_UP (or NaN) counts as exploded and is
    left out of the rest."""
    from course_lib.experiments.gmm_rnn import freeze_floor, joint_speed

    floor = freeze_floor(data.test_clips)
    prog = long_program(data, seed, n, seconds)
    ctl, starts = prog["controls"], (prog["poses"][:, :TAU], prog["controls"][:, :TAU])
    out = {"freeze_floor": floor, "seconds": seconds, "models": {}}
    for name, model in models.items():
        poses, c = generate(model, data, ctl, seed, starts=starts)
        sane = ~exploded(poses)  # (n,)
        row = {"n": n, "exploded": int((~sane).sum()), "finite": bool(torch.isfinite(poses).all())}
        if sane.any():
            pos = data.positions(poses[sane], c[sane])
            var = joint_speed(pos[:, -int(5 * FPS):], FPS).var(-1)  # (n_sane,)
            row.update(min_speed_var=float(var.min()), median_speed_var=float(np.median(var)),
                       frozen=int((var < floor).sum()))
        out["models"][name] = row
    return out


def to_motions(positions: np.ndarray, clips: list) -> list:
    """World positions (N, T, 21, 3) -> Motions on each clip's skeleton (rotations fitted, no twist)."""
    from course_lib.representations import motion_from_positions

    return [motion_from_positions(p, m.skeleton, FPS) for p, m in zip(positions, clips, strict=True)]


def _mocap_halves(data: MoGlowData, seed: int) -> tuple:
    """The held-out mocap decoded as `quality` decodes samples, split in two random halves (seed) -> (the action
    classifier, the root starts, the decoded mocap, indices a, indices b)."""
    from course_lib.evaluation import load_classifier
    from course_lib.representations import root_start

    starts = [root_start(m) for m in data.test_clips]
    real = to_motions(data.positions(data.test["poses"], data.test["controls"], starts), data.test_clips)
    if len(real) < MIN_DISTRIBUTION_CLIPS:
        raise ValueError(f"quality: FID/C2ST need >= {MIN_DISTRIBUTION_CLIPS} held-out clips, got {len(real)} "
                         "(CI's tiny data: use the recorded results)")
    half = np.random.default_rng(seed).permutation(len(real))
    return load_classifier("action"), starts, real, half[: len(real) // 2], half[len(real) // 2:]


def _scores(gen: list, real_a: list, b, clf, seed: int) -> dict:
    """One row of `quality`: gen (a Motion per held-out clip) scored against mocap half a on its half b."""
    from course_lib.evaluation import c2st, fid, foot_skate_at_floor, jitter

    gen_b = [gen[i] for i in b]  # the half whose mocap is not the reference: the same protocol as mocap's row
    test = c2st(real_a, gen_b, seed=seed)
    return {"foot_skate": foot_skate_at_floor(gen), "jitter": jitter(gen), "FID": fid(real_a, gen_b, clf),
            "C2ST": test["accuracy"], "C2ST_low": test["ci_low"], "C2ST_high": test["ci_high"]}


def quality(models: dict, data: MoGlowData, seed: int) -> dict:
    """Samples driven by every held-out clip's control from its first tau frames, the control integrated to
    a root path from the clip's start: foot skate (m/s), jitter (m/s^3), FID and C2ST (shared classifiers).
    FID and C2ST compare one random half of the mocap (a) with the *other* half's samples (b), so that the
    mocap row (a vs the mocap of b) is the same protocol with the same sample sizes (FID is biased upward
    at small n: a floor measured on halves is not comparable with a model scored on every clip)."""
    from course_lib.evaluation import c2st, fid, foot_skate_at_floor, jitter

    clf, starts, real, a, b = _mocap_halves(data, seed)
    real_a, real_b = [real[i] for i in a], [real[i] for i in b]
    native_b = [data.test_clips[i] for i in b]
    floor = c2st(real_a, real_b, seed=seed)
    rows = {"Mocap (half vs half)": {"foot_skate": foot_skate_at_floor(real_b), "jitter": jitter(real_b),
                                     "FID": fid(real_a, real_b, clf), "C2ST": floor["accuracy"]},
            "Mocap (native rotations)": {"FID": fid(real_a, native_b, clf), "foot_skate": foot_skate_at_floor(native_b),
                                         "jitter": jitter(native_b)}}
    x0, c0 = data.test["poses"][:, :TAU], data.test["controls"][:, :TAU]
    for name, model in models.items():
        poses, c = generate(model, data, data.test["controls"], seed, starts=(x0, c0))
        rows[name] = _scores(to_motions(data.positions(poses, c, starts), data.test_clips), real_a, b, clf, seed)
    return rows


def noisy_mocap(data: MoGlowData, sds, seed: int, shaped: bool = False) -> dict:
    """Known answer for `quality`'s measures: the held-out mocap with Gaussian noise of sd `sd` per feature (in the
    standardised pose units a MoGlow samples in; controls and root path untouched), independent over frames,
    scored exactly as a model's samples are -> {sd: row}.  shaped=False: independent over features (covariance
    sd^2 I); shaped=True: correlated like the training poses (covariance sd^2 C, C their correlation matrix: the
    same total variance, along the directions the data vary in).  Frame-to-frame noise a person sees as shaking
    must move jitter and skate; whether it moves FID and C2ST is what this measures."""
    clf, starts, real, a, b = _mocap_halves(data, seed)
    real_a = [real[i] for i in a]
    g = torch.Generator().manual_seed(seed)
    poses = data.test["poses"]
    shape = torch.eye(poses.shape[-1])
    if shaped:
        x = data.train["poses"].reshape(-1, poses.shape[-1]).double()
        corr = torch.corrcoef(x.T)
        shape = torch.linalg.cholesky(corr + 1e-6 * torch.eye(len(corr))).float()
    rows = {}
    for sd in sds:
        noisy = poses + sd * torch.randn(poses.shape, generator=g) @ shape.T
        gen = to_motions(data.positions(noisy, data.test["controls"], starts), data.test_clips)
        rows[float(sd)] = _scores(gen, real_a, b, clf, seed)
    return rows


def evaluate(models: dict, data: MoGlowData, seed: int = 0, seeds: int = EVAL_SEEDS) -> dict:
    """Every must-show measure of lesson 06 -> JSON-able dict."""
    from course_lib.evaluation import over_seeds

    out = {"nll_per_frame": {name: nll_per_frame(m, data.test) for name, m in models.items()},
           "val_nll_per_frame": {name: nll_per_frame(m, data.val) for name, m in models.items()},
           "round_trip_max_error": {name: round_trip_error(m, data.test) for name, m in models.items()},
           "control": control_consistency(models, data, seed),
           "long": long_samples(models, data, seed)}
    if len(data.test_clips) >= MIN_DISTRIBUTION_CLIPS:
        runs = [quality(models, data, s) for s in range(seed, seed + seeds)]
        out["quality"], out["quality_sd"] = over_seeds(runs)
        out["generation_seeds"] = list(range(seed, seed + seeds))
    out["counts"] = {"train": len(data.train["poses"]), "val": len(data.val["poses"]),
                     "test": len(data.test["poses"]), "pose_dim": data.pose_dim}
    return out


# ----------------------------------------------------------------------------- the commands


def eval_moglow(seed: int = 0, checkpoints: Path = CHECKPOINTS, mode: str | None = "full", models=None) -> dict:
    """The evaluation from the shipped checkpoints (or the given models)."""
    t0 = time.perf_counter()
    data = load_data(mode)
    models = models or {name: load_model(name, checkpoints) for name in MODELS}
    out = evaluate(models, data, seed)
    out["eval_seconds"] = round(time.perf_counter() - t0, 1)
    return rounded(out, 5)


def train_moglow(seed: int = 0, only=None, checkpoints: Path = CHECKPOINTS, mode: str | None = "full",
                 steps: int = STEPS, progress: bool = False) -> dict:
    """Train every variant (or those in `only`), save checkpoints + stats, evaluate, record in results/moglow.json."""
    from course_lib.training import save_checkpoint

    t0 = time.perf_counter()
    data = load_data(mode, seed)
    save_stats(data, checkpoints)
    timings = {}
    for name in MODELS:
        if only and name not in only:
            continue
        model, hist = train_model(name, data, steps, seed, progress)
        timings[name] = round(hist.seconds, 1)
        curve = list(hist.step["loss"])
        save_checkpoint(model, model.config, checkpoints / f"{name}.pt", command=COMMAND, overwrite=True,
                        metrics={"train_seconds": timings[name], "steps": len(curve), "batch": BATCH, "lr": LR,
                                 "lr_decay_from": LR_DECAY_FROM, "lr_floor": LR_FLOOR,
                                 "final_nll_frame": round(hist.final("loss", 50), 4), "train_seed": seed,
                                 "train_sequences": len(data.train["poses"]),
                                 "curve": [round(float(v), 3) for v in curve[:: max(1, len(curve) // 150)]]})
        print(f"{name}: {hist}", file=sys.stderr)
    out = eval_moglow(seed, checkpoints, mode)
    out["train_seconds"] = timings
    out["total_seconds"] = round(time.perf_counter() - t0, 1)
    record_results(out, checkpoints)
    return out


def record_results(results: dict, checkpoints: Path = CHECKPOINTS) -> dict:
    """Store the evaluation with the main model's metrics in results/moglow.json
    (``["checkpoints"]["moglow"]["results"]``); the checkpoint is not rewritten.  Returns its manifest entry."""
    from course_lib.models.moglow import MoGlow, MoGlowConfig
    from course_lib.training import record_metrics

    return record_metrics(checkpoints / "moglow.pt", MoGlow, MoGlowConfig, results=results)


def recorded_results(checkpoints: Path = CHECKPOINTS) -> dict:
    """The evaluation stored by `record_results`."""
    from course_lib.training import recorded_metrics

    results = recorded_metrics(checkpoints / "moglow.pt").get("results")
    if results is None:
        raise KeyError(f"no recorded evaluation for {checkpoints / 'moglow.pt'}: run {COMMAND}")
    return results


def training_curve(name: str, checkpoints: Path = CHECKPOINTS) -> list[float]:
    """The recorded training curve (NLL per frame, every ~1/150 of the run) of a shipped model."""
    from course_lib.training import recorded_metrics

    return recorded_metrics(checkpoints / f"{name}.pt")["curve"]
