"""Lesson 03 (Wang, Chai et al. 2021): the contact-aware GMM-RNN, its adversarial refiner, and the
stand-in for the paper's user study (Fig. 12).

    python -m course_lib.reproduce gmm_rnn              # data, RNN, GAN1/GAN2 x 3 seeds, evaluation -> JSON
    python -m course_lib.reproduce gmm_rnn --eval-only  # the evaluation from checkpoints/ only
    python -m course_lib.reproduce gmm_rnn --only gans  # keep the RNN checkpoint, retrain the refiners

Data: lesson 02's synthetic locomotion clips (corpus.DataSpec: 400 clips of 4 s, 10
subjects, 3 held out) resampled to 30 fps and encoded as ``state_features`` (eq. 3 + 2 contact bits).
Models: the GMM-RNN (sec. 4.1), GAN1 (refiner without contact awareness) and GAN2 (contact-aware
refiner, sec. 4.3), each refiner trained for three seeds.  The RNN reads the clips' state features anchored on
their feet (representations.anchor_on_feet, on each clip's own skeleton; `to_rnn` / `from_rnn` / `generate`
convert), models only the columns the data vary, with Bernoulli contact bits; R and D compute end effectors on
each motion's own skeleton, and GAN2's D sees the contact bits.  Evaluation: for every held-out clip the RNN
continues its first two frames for 4 s; GAN1/GAN2 refine that motion; "GAN2 + contacts" adds the
contact handling (models/contact_cleanup.py: the predicted contacts enforced on the root).  Every row
gets foot skate, jitter, FID, IS and the C2ST accuracy against the held-out mocap.  Long generation:
100 motions of 20 s from one start frame.
"""

from __future__ import annotations

import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch

from course_lib.corpus import DataSpec, load_clips
from course_lib.datasets import FixedDofs, WindowDataset, load_stats
from course_lib.evaluation.contacts import contact_agreement, lower_toe
from course_lib.evaluation.freezing import freeze_floor, joint_speed  # lesson 06 imports them from here
from course_lib.motion import Motion
from course_lib.paths import CHECKPOINTS
from course_lib.representations import decode_state_features, encode_state_features, root_start
from course_lib.results import rounded

ROOT = Path(__file__).resolve().parents[2]
ROWS = ("Mocap", "RNN", "GAN1", "GAN2", "GAN2 + contacts")
COMMAND = "python -m course_lib.reproduce gmm_rnn"


@dataclass
class Lesson03Spec:
    """Every setting of the lesson-03 reproduction (sizes are the CPU ones, see the notebook's table)."""

    fps: float = 30.0  # sec. 4.1.3
    rnn_steps: int = 6000  # teacher forcing on 50-frame windows, batch 20 (sec. 4.1.3); ~14 epochs
    # then fine-tuning stages (true frames, own predictions, steps): inputs alternate true frames and the
    # model's own predictions (not in the paper; see gmm_rnn.py "differs")
    finetune: tuple = ()  # e.g. ((10, 10, 1000),)
    finetune_lr: float = 5e-4
    sample_bias: float = 2.0  # Graves' sampling bias at generation (0 = the paper's sampling)
    sample_angle_noise: float = 0.3  # scale of the per-dimension draw in the joint angles (0: component means)
    sample_root_noise: float = 1.0  # the same for the six root columns
    # what the RNN reads: "feet_anchored" (representations.anchor_on_feet: the root's floor step as the anchor
    # toe's slip, the root height as the lower toe's height) or "state_features" (eq. 3 as it is)
    rnn_features: str = "feet_anchored"
    rnn_anchor_tau: float = 0.0  # 0: the anchor is the lower toe; > 0 (m): both toes weighted by height (soft)
    rnn_anchor_rule: str = "lower"  # "contact": the anchor follows the contact bits, the root in a flight
    # columns with absolute means: the slip, the toe height, pitch and roll; dyaw and the joint angles residual
    rnn_absolute_dims: tuple = (0, 1, 3, 4, 5)
    rnn_fixed_dims: bool = True  # the columns the data never vary are not modelled
    rnn_bernoulli_contacts: bool = True  # contact bits from a Bernoulli head
    # joint limits at generation (not in the paper; GmmRnn "differs"): each sampled frame's joint angles clamped to
    # the training data's range (stored with the RNN, training_limits); False samples without them
    joint_limits: bool = True
    contact_method: str = "legs"  # "legs": root + leg angles (plant_feet); "root": the root alone (enforce_contacts)
    contact_smooth: int = 5  # frames over which the "root" contact handling's corrections are averaged
    window_stride: int = 5  # frames between training windows
    rnn_width: int = 256  # FC, LSTM and output widths of the RNN (the paper: 500; 128 jitters more)
    rnn_noise: float = 0.1  # sd of the input noise, normalised units (the paper: 0.05; studies/03_gmm_rnn_refiner)
    refiner_window: int = 64  # frames per refiner/discriminator training sequence
    refiner_iterations: int = 3000  # at most this many adversarial rounds after the warm-up (sec. 4.2.2) ...
    refiner_updates: int = 2500  # ... and at most this many adversarial R updates (the CPU budget)
    max_r_updates: int = 40  # cap on R's adaptive update count per round (the paper has none)
    # the balance rule of sec. 4.2.2 on D's mean cross-entropy (chance ln 2): r doubles below d_loss_low (D too
    # strong) and halves above d_loss_high (D near chance), on the mean of the last schedule_smooth rounds; the
    # paper's 0.01 / 1 on single batches almost never fire on this scale
    d_loss_low: float = 0.3
    d_loss_high: float = 0.6
    schedule_smooth: int = 5
    refiner_pose_lam: float = 10.0  # R's pose self-regularisation (SimGAN, not eq. 13; RefinerConfig "differs")
    refiner_leg_pose_lam: float = 30.0  # ... again on the leg angles (RefinerConfig; studies/03_gmm_rnn_refiner)
    discriminator_joints: str = "end_effectors"  # D sees eq. 12's end effectors, or "all" joints (RefinerConfig)
    discriminator_contacts: bool = True  # GAN2's D also sees the contact bits (sec. 4.3 "augment ... input and output")
    pool_sequences: int = 320  # RNN motions generated once for refiner training
    pool_frames: int = 240  # frames per pooled RNN motion (8 s)
    seeds: tuple = (0, 1, 2)  # refiner seeds, one checkpoint per seed and refiner
    eval_seconds: float = 4.0  # generated length compared with the 4-s held-out clips
    n_random: int = 100  # long-generation test
    random_seconds: float = 20.0
    data_seed: int = 2017  # lesson 02's DataSpec seed


# ----------------------------------------------------------------------------- data


def lesson03_data(spec: Lesson03Spec, progress: bool = True) -> tuple[list[Motion], list[Motion], WindowDataset]:
    """-> (train clips, held-out clips) at spec.fps and the training WindowDataset (50-frame windows,
    mirrored clips added, normalisation from the training split)."""
    data = DataSpec(seed=spec.data_seed)
    clips = [m.resample(spec.fps) for m in load_clips(data, progress=progress)]
    test = [m for m in clips if m.subject in data.test_subjects]
    train = [m for m in clips if m.subject not in data.test_subjects]
    ds = WindowDataset(train, "state_features", length=50, stride=spec.window_stride, mirror=True)
    return train, test, ds


def window_sampler(features: list[np.ndarray], length: int, batch: int, generator: torch.Generator, offsets=None):
    """features: normalised (T_i, D) arrays -> a callable returning (batch, length, D) random windows; with
    offsets (one (J, 3) rest-offset array per sequence) it returns (windows, their sequences' offsets (batch, J, 3))."""
    keep = [i for i, f in enumerate(features) if len(f) >= length]
    if not keep:
        raise ValueError(f"window_sampler: no sequence has {length} frames")
    feats = [torch.from_numpy(np.asarray(features[i], np.float32)) for i in keep]
    offs = None if offsets is None else torch.from_numpy(np.stack([np.asarray(offsets[i], np.float32) for i in keep]))

    def sample():
        idx = torch.randint(len(feats), (batch,), generator=generator)
        out = []
        for i in idx.tolist():
            s = int(torch.randint(len(feats[i]) - length + 1, (1,), generator=generator))
            out.append(feats[i][s:s + length])
        return torch.stack(out) if offs is None else (torch.stack(out), offs[idx])

    return sample


def clip_offsets(clips: list[Motion]) -> torch.Tensor:
    """-> (N, J, 3) float32 rest offsets of each clip's own skeleton (for the refiner's kinematics)."""
    return torch.from_numpy(np.stack([m.skeleton.offsets for m in clips]).astype(np.float32))


# ----------------------------------------------------------------------------- training


# the clamp tests' column groups of the state features, by joint name (root: the first 6 columns)
COLUMN_GROUPS = {"legs": ("UpLeg", "Leg_", "Foot", "ToeBase"),
                 "upper body": ("Spine", "Neck", "Head", "Shoulder", "Arm", "Hand")}


def column_groups() -> dict[str, list[int]]:
    """{"legs", "upper body", "root"} -> their state-feature columns (the clamp tests put one group back)."""
    from course_lib.representations import feature_names

    names = feature_names("state_features")
    cols = {g: [i for i, c in enumerate(names) if any(k in c for k in keys)] for g, keys in COLUMN_GROUPS.items()}
    return cols | {"root": list(range(6))}


def rnn_config(spec: Lesson03Spec, rnn_stats):
    """The GmmRnnConfig `train_rnn` trains with: spec's sizes and choices; the columns the data never vary (fixed,
    left out of the mixture) from ``rnn_stats``, the (mean, std) of the RNN's features on its training windows
    (`rnn_features`; a trained model keeps them as ``feature_mean`` / ``feature_std``)."""
    from course_lib.models.gmm_rnn import GmmRnnConfig

    fixed = tuple(int(c) for c in np.flatnonzero(FixedDofs.from_stats(*rnn_stats).mask)) if spec.rnn_fixed_dims else ()
    return GmmRnnConfig.cpu(fc_width=spec.rnn_width, lstm_width=spec.rnn_width, out_width=spec.rnn_width,
                            fps=spec.fps, noise_std=spec.rnn_noise, absolute_dims=spec.rnn_absolute_dims,
                            features=spec.rnn_features, anchor_tau=spec.rnn_anchor_tau,
                            anchor_rule=spec.rnn_anchor_rule, fixed_dims=fixed,
                            bernoulli_contacts=spec.rnn_bernoulli_contacts)


def train_rnn(ds: WindowDataset, spec: Lesson03Spec, seed: int = 0, steps: int | None = None,
              finetune_steps: int | None = None, progress: bool = True, config=None, device: str = "cpu"):
    """The GMM-RNN of sec. 4.1 on ds's windows -> (model, History, fine-tuning History).

    Teacher forcing with input noise, RMSProp lr 1e-3 x 0.95 per epoch (sec. 4.1.3); then the stages of
    spec.finetune with ``self_feed`` inputs (true frames alternating with the model's own predictions) at
    spec.finetune_lr; finetune_steps overrides every stage's step count."""
    from course_lib.history import History
    from course_lib.models.gmm_rnn import GmmRnn
    from course_lib.training import fit

    features, rnn_stats = rnn_features(ds, spec.rnn_features, spec.rnn_anchor_tau, spec.rnn_anchor_rule)
    config = config or rnn_config(spec, rnn_stats)
    torch.manual_seed(seed)
    model = GmmRnn(config, stats=rnn_stats).to(device)
    cpu_sample = window_sampler(features, config.window, config.batch_size, torch.Generator().manual_seed(seed))

    def sample() -> torch.Tensor:
        return cpu_sample().to(device)
    steps_per_epoch = max(1, len(ds) // config.batch_size)
    hist = fit(model, sample, steps=spec.rnn_steps if steps is None else steps, lr=config.lr, optimizer="rmsprop",
               lr_schedule=config.lr_factor, steps_per_epoch=steps_per_epoch, progress=progress, seed=seed,
               desc="GMM-RNN")
    ft = History()
    for i, (k, m, n) in enumerate(spec.finetune):
        n = n if finetune_steps is None else finetune_steps
        if n > 0:
            config.self_feed = (int(k), int(m))
            stage = fit(model, sample, steps=n, lr=spec.finetune_lr, optimizer="rmsprop", progress=progress,
                        seed=seed + 1 + i, desc=f"GMM-RNN self-fed {k}/{m}")
            for v in stage.step["loss"]:
                ft.log_step({"loss": v})
            ft.seconds += stage.seconds
    model.cpu().eval()
    return model, hist, ft


def rnn_features(ds: WindowDataset, kind: str = "feet_anchored", tau: float = 0.0,
                 rule: str = "lower") -> tuple[list[np.ndarray], tuple]:
    """ds's clips in the RNN's features -> (normalised (T_i, D) float32 arrays, their (mean, std)); "state_features"
    returns ds's own.  "feet_anchored": each clip anchored on its own skeleton (representations.anchor_on_feet,
    with its tau and rule)."""
    from course_lib.datasets import compute_stats
    from course_lib.representations import anchor_on_feet

    if kind == "state_features":
        return ds.features, ds.stats
    raw = [anchor_on_feet(torch.from_numpy(ds.denormalize(f.astype(np.float64))), m.skeleton, tau=tau,
                           rule=rule).numpy()
           for f, m in zip(ds.features, ds.clips, strict=True)]
    mean, std = compute_stats(raw)
    return [((r - mean) / std).astype(np.float32) for r in raw], (mean, std)


def training_limits(model, ds: WindowDataset) -> tuple[torch.Tensor, torch.Tensor]:
    """The joint limits `GmmRnn.set_limits` stores: each joint-angle column's [min, max] over ds's clips (mirrored
    ones included) in the model's normalised features; +-inf on the root columns and the contact bits."""
    c = model.config
    feats, (mean, std) = rnn_features(ds, c.features, c.anchor_tau, c.anchor_rule)
    raw = np.concatenate(feats).astype(np.float64) * std + mean
    m, s = model.feature_mean.double().numpy(), model.feature_std.double().numpy()
    low, high = np.full(c.dim, -np.inf), np.full(c.dim, np.inf)
    angles = slice(6, c.dim - len(c.contact_dims))
    low[angles] = (raw.min(0)[angles] - m[angles]) / s[angles]
    high[angles] = (raw.max(0)[angles] - m[angles]) / s[angles]
    return torch.from_numpy(low).float(), torch.from_numpy(high).float()


def _rnn_stats(model) -> tuple[torch.Tensor, torch.Tensor]:
    return model.feature_mean.double(), model.feature_std.double()


def to_rnn(x: torch.Tensor, stats, model, offsets: torch.Tensor) -> torch.Tensor:
    """Normalised state features (N, T, D) (stats) of motions on skeletons ``offsets`` (N, J, 3) -> the model's
    normalised features."""
    from course_lib.representations import anchor_on_feet
    from course_lib.skeleton import Skeleton

    raw = x.double() * torch.as_tensor(stats[1]) + torch.as_tensor(stats[0])
    if model.config.features == "feet_anchored":
        raw = anchor_on_feet(raw, Skeleton.canonical(), offsets.double(), model.config.anchor_tau,
                             model.config.anchor_rule)
    mean, std = _rnn_stats(model)
    return ((raw - mean) / std).float()


def from_rnn(y: torch.Tensor, stats, model, offsets: torch.Tensor) -> torch.Tensor:
    """The inverse of `to_rnn`: the model's normalised features (N, T, D) -> normalised state features."""
    from course_lib.representations import unanchor_feet
    from course_lib.skeleton import Skeleton

    mean, std = _rnn_stats(model)
    raw = y.double() * std + mean
    if model.config.features == "feet_anchored":
        raw = unanchor_feet(raw, Skeleton.canonical(), offsets.double(), model.config.anchor_tau,
                             model.config.anchor_rule)
    return ((raw - torch.as_tensor(stats[0])) / torch.as_tensor(stats[1])).float()


def angle_noise(model, scale: float, root: float = 1.0) -> torch.Tensor | None:
    """-> the (D,) noise_scale of GmmRnn.sample_mixture: ``scale`` on the joint angles, ``root`` on the six root
    columns, 1 on the bits (None if all are 1)."""
    if scale == 1.0 and root == 1.0:
        return None
    out = torch.ones(model.config.dim)
    out[6:-2], out[:6] = scale, root
    return out


def generate(model, x0: torch.Tensor, steps: int, offsets: torch.Tensor, stats, generator=None,
             bias: float = 2.0, angle_scale: float = 1.0, root_scale: float = 1.0,
             limits: bool = False) -> torch.Tensor:
    """Sec. 4.1.4 in state features: x0 (N, 2, D) two normalised frames (stats) of motions on skeletons offsets
    (N, J, 3) -> (N, 2 + steps, D) normalised state features; the model samples in its own features (the joint
    angles' per-dimension draw scaled by angle_scale; limits: within the model's stored joint limits)."""
    y0 = to_rnn(x0, stats, model, offsets)
    y = model.generate(y0, steps, generator=generator, stats=_rnn_stats(model), bias=bias,
                       noise_scale=angle_noise(model, angle_scale, root_scale),
                       limits=model.limits() if limits else None)
    return torch.cat((x0, from_rnn(y, stats, model, offsets)[:, 2:]), 1)


def one_step(model, clips: list[Motion], stats, bias: float = 2.0, seed: int = 0, mean: bool = False,
             angle_scale: float = 1.0, root_scale: float = 1.0) -> torch.Tensor:
    """Teacher forcing: every frame t >= 2 of each clip predicted from the true frames before it (one sample at
    ``bias``, or the most likely component's mean) -> normalised state features (N, T, D); frames 0-1 are true."""
    x = torch.from_numpy(np.stack([(encode_state_features(m) - stats[0]) / stats[1] for m in clips])).float()
    off = clip_offsets(clips)
    y = to_rnn(x, stats, model, off)
    g = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        params, _ = model(y[:, :-1])  # row t: p(y_{t+1} | y_{<=t})
        N, T1 = params["logits"].shape[:2]
        flat = {k: v.reshape(N * T1, *v.shape[2:]) for k, v in params.items()}
        if mean:
            top = flat["logits"].argmax(-1)
            pred = flat["mu"][torch.arange(len(top)), top]
            if model.config.bernoulli_contacts:
                cols = list(model.config.contact_dims)
                bits = (flat["contact_logits"] > 0).to(pred.dtype)
                pred[:, cols] = (bits - model.feature_mean[cols]) / model.feature_std[cols]
        else:
            pred = model.sample_mixture(flat, g, bias, angle_noise(model, angle_scale, root_scale))
        pred = model.fix_contacts(pred.reshape(N, T1, -1), _rnn_stats(model))
        if model.config.fixed_dims:
            cols = list(model.config.fixed_dims)
            pred[..., cols] = y[:, 1:, cols]
    pred = torch.cat((y[:, :1], pred), 1)
    pred[:, 1] = y[:, 1]
    return from_rnn(pred, stats, model, off)


class RnnPool(NamedTuple):
    """The RNN motions the refiners train on: features (N, T, D) normalised, offsets (N, J, 3) the rest offsets of
    the subject whose frames each motion started from."""

    features: torch.Tensor
    offsets: torch.Tensor


def rnn_pool(model, ds: WindowDataset, spec: Lesson03Spec, seed: int = 0) -> RnnPool:
    """spec.pool_sequences RNN motions of spec.pool_frames frames from random training frames, with the offsets of
    the clip each one starts from, sampled as the evaluation samples (with the model's joint limits when
    spec.joint_limits)."""
    g = torch.Generator().manual_seed(seed)
    x0, off = window_sampler(ds.features, 2, spec.pool_sequences, g, clip_offsets(ds.clips))()
    feats = generate(model, x0, spec.pool_frames - 2, off, ds.stats, generator=g, bias=spec.sample_bias,
                     angle_scale=spec.sample_angle_noise, root_scale=spec.sample_root_noise, limits=spec.joint_limits)
    return RnnPool(feats, off)


def refiner_config(spec: Lesson03Spec, contacts: bool):
    """The RefinerConfig `train_gan` trains GAN1 (contacts=False) or GAN2 with: the CPU sizes, spec's
    self-regularisation and what D sees, and the balance band its schedule applies (spec.d_loss_low /
    d_loss_high; the schedule also takes spec.schedule_smooth and spec.max_r_updates, which the config has no
    field for)."""
    from course_lib.models.refiner import RefinerConfig

    return RefinerConfig.cpu(contacts=contacts, discriminator_contacts=contacts and spec.discriminator_contacts,
                             fps=spec.fps, pose_lam=spec.refiner_pose_lam, leg_pose_lam=spec.refiner_leg_pose_lam,
                             discriminator_joints=spec.discriminator_joints, d_loss_low=spec.d_loss_low,
                             d_loss_high=spec.d_loss_high)


def train_gan(pool: RnnPool, ds: WindowDataset, spec: Lesson03Spec, contacts: bool, seed: int,
              iterations: int | None = None, progress: bool = True, schedule=None):
    """R and D of sec. 4.2 on random spec.refiner_window-frame crops of the RNN pool vs mocap windows, every
    motion's kinematics on its own subject's skeleton -> (refiner, discriminator, History).  contacts=False is
    GAN1, True GAN2 (sec. 4.3; its D also sees the contact bits).  schedule: an AdversarialSchedule (default: the
    paper's rule with spec's thresholds and smoothing, r capped at spec.max_r_updates)."""
    from course_lib.models.refiner import AdversarialSchedule, Discriminator, Refiner, train_refiner

    config = refiner_config(spec, contacts)
    torch.manual_seed(seed)
    refiner, disc = Refiner(config, stats=ds.stats), Discriminator(config)
    g = torch.Generator().manual_seed(seed)
    rnn = window_sampler(list(pool.features.numpy()), spec.refiner_window, config.d_batch, g, pool.offsets)
    real = window_sampler(ds.features, spec.refiner_window, config.d_batch, g, clip_offsets(ds.clips))
    schedule = schedule or AdversarialSchedule(config.warmup, config.r_per_d, config.d_loss_low, config.d_loss_high,
                                               max_r_updates=spec.max_r_updates, smooth=spec.schedule_smooth)
    hist = train_refiner(refiner, disc, rnn, real, iterations=spec.refiner_iterations if iterations is None
                         else iterations, config=config, schedule=schedule, generator=g, progress=progress,
                         max_refiner_updates=spec.refiner_updates if iterations is None else None)
    hist.r_schedule = list(schedule.history)
    refiner.eval()
    disc.eval()
    return refiner, disc, hist


# ----------------------------------------------------------------------------- generation and evaluation


def to_motions(features: torch.Tensor, stats, like: list[Motion], fps: float) -> list[Motion]:
    """Normalised features (N, T, D) -> Motions, motion i decoded on like[i]'s skeleton from its start; the
    training data's fixed degrees of freedom (the columns at the normalisation's std floor) at their constants."""
    raw = FixedDofs.from_stats(*stats).apply(features.double().numpy() * stats[1] + stats[0])
    return [decode_state_features(f, m.skeleton, fps, root_start(m)) for f, m in zip(raw, like, strict=True)]


def contact_columns(stats, skeleton) -> list[int]:
    """The state-feature columns the leg contact handling may move: the root's floor step (0, 1) and height (3),
    and the hip, knee and ankle angles that vary in the training data (not the fixed hinge components)."""
    from course_lib.models.contact_cleanup import leg_columns

    return [0, 1, 3] + leg_columns(skeleton, FixedDofs.from_stats(*stats).mask)


def with_contacts(features: torch.Tensor, stats, like: list[Motion], smooth: int = 1,
                  method: str = "root") -> torch.Tensor:
    """Sec. 4.3's contact handling on normalised features (N, T, D), motion i on like[i]'s skeleton ->
    normalised (N, T, D).  method "root": the predicted contact bits enforced on the root alone
    (contact_cleanup.enforce_contacts, corrections averaged over ``smooth`` frames); "legs": every flagged foot
    held still and on the floor by moving the root and the leg angles (contact_cleanup.plant_feet, L-BFGS)."""
    from course_lib.models.contact_cleanup import enforce_contacts, plant_feet

    if method not in ("root", "legs"):
        raise ValueError(f"with_contacts: method must be 'root' or 'legs', got {method!r}")
    mean, std = stats
    raw = features.double().numpy() * std + mean
    if method == "legs":
        fixed = plant_feet(raw, like[0].skeleton, contact_columns(stats, like[0].skeleton),
                           offsets=np.asarray(clip_offsets(like)))
    else:
        fixed = np.stack([enforce_contacts(r, m.skeleton, smooth=smooth) for r, m in zip(raw, like, strict=True)])
    return torch.from_numpy((fixed - mean) / std).to(features.dtype)


def continuations(model, refiners: dict, clips: list[Motion], stats, spec: Lesson03Spec, seed: int = 0) -> dict:
    """For each clip: the RNN continues its first two frames for spec.eval_seconds; each refiner refines
    that -> {"RNN": features, name: features, ...} normalised (N, T, D)."""
    T = int(round(spec.eval_seconds * spec.fps))
    x0 = torch.from_numpy(np.stack([(encode_state_features(m)[:2] - stats[0]) / stats[1] for m in clips])).float()
    out = {"RNN": generate(model, x0, T - 2, clip_offsets(clips), stats, torch.Generator().manual_seed(seed),
                           spec.sample_bias, spec.sample_angle_noise, spec.sample_root_noise, spec.joint_limits)}
    with torch.no_grad():
        out.update({name: r(out["RNN"], clip_offsets(clips)) for name, r in refiners.items()})
    return out


def quality_row(motions, mocap: list[Motion], fps: float = 30.0, seed: int = 0) -> dict:
    """Foot skate (m/s), jitter (m/s^3), ground penetration (m), FID, IS and the C2ST accuracy (with its 95 %
    interval) of a set against mocap."""
    from course_lib.evaluation import c2st, fid, foot_skate_at_floor, ground_penetration, inception_score, jitter

    pos = np.stack([m.positions() for m in motions])
    test = c2st(mocap, motions, seed=seed)
    return {"foot_skate": foot_skate_at_floor(pos, fps=fps), "jitter": jitter(pos, fps=fps),
            "penetration": ground_penetration(pos, skeleton=motions[0].skeleton),
            "fid": fid(mocap, motions), "is": inception_score(motions),
            "c2st": test["accuracy"], "c2st_low": test["ci_low"], "c2st_high": test["ci_high"]}


def quality_table(model, refiners: dict, test: list[Motion], stats, spec: Lesson03Spec, seed: int = 0) -> dict:
    """The Fig. 12 stand-in: {row: quality_row} for ROWS (refiners: {"GAN1": R1, "GAN2": R2}).

    Generated rows are measured against all held-out clips; the Mocap row is a random half of them
    against the other half (the best a set of that size can score: FID > 0, C2ST ~0.5)."""
    T = int(round(spec.eval_seconds * spec.fps))
    mocap = [m[:T] for m in test]
    sets = continuations(model, refiners, test, stats, spec, seed)
    half = np.random.default_rng(seed).permutation(len(mocap))
    a, b = [mocap[i] for i in half[: len(half) // 2]], [mocap[i] for i in half[len(half) // 2:]]
    rows = {"Mocap": quality_row(b, a, fps=spec.fps, seed=seed)}  # one half of the clips against the other
    if "GAN2" in sets:
        sets["GAN2 + contacts"] = with_contacts(sets["GAN2"], stats, test, spec.contact_smooth, spec.contact_method)
    for name, feats in sets.items():
        motions = to_motions(feats, stats, test, spec.fps)
        rows[name] = quality_row(motions, mocap, fps=spec.fps, seed=seed)
        rows[name]["contact_agreement"] = contact_agreement(motions, contact_bits(feats, stats))
    return rows


def contact_bits(features: torch.Tensor, stats) -> np.ndarray:
    """Normalised features (N, T, D) -> the contact bits (N, T, 2) (left, right) in raw units."""
    return features[..., -2:].double().numpy() * stats[1][-2:] + stats[0][-2:]


def long_samples(model, start: Motion, stats, spec: Lesson03Spec, seed: int = 0) -> torch.Tensor:
    """spec.n_random RNN motions of spec.random_seconds from start's first two frames, at spec's sampling
    -> normalised state features (N, T, D)."""
    T = int(round(spec.random_seconds * spec.fps))
    x0 = torch.from_numpy((encode_state_features(start)[:2] - stats[0]) / stats[1]).float().expand(spec.n_random, 2, -1)
    return generate(model, x0.contiguous(), T - 2, clip_offsets([start] * spec.n_random), stats,
                    torch.Generator().manual_seed(seed), spec.sample_bias, spec.sample_angle_noise,
                    spec.sample_root_noise, spec.joint_limits)


def long_generation(model, refiner, start: Motion, stats, spec: Lesson03Spec, mocap: list[Motion],
                    seed: int = 0) -> dict:
    """spec.n_random motions of spec.random_seconds from start's first two frames, RNN and refined (refiner None:
    the RNN only).

    -> the mocap's root-height range, highest lower-toe height and freeze floor, and per set ("RNN", "GAN2",
    "GAN2 + contacts"): NaN count, root-height range, motions whose root height stays within the data's range
    +- 5 cm (all 20 s / first 10 s), motions whose feet stay grounded (the lower toe never more than 5 cm above
    the data's highest lower toe; all 20 s / first 10 s) and the fraction of grounded frames, freezing (motions
    whose last-5-s joint-speed variance is under `freeze_floor`) and APD (m) over the whole motion."""
    from course_lib.evaluation import apd

    rnn = long_samples(model, start, stats, spec, seed)
    T = rnn.shape[1]
    sets = {"RNN": rnn}
    if refiner is not None:
        with torch.no_grad():
            sets["GAN2"] = refiner(rnn, clip_offsets([start] * len(rnn)))
        sets["GAN2 + contacts"] = with_contacts(sets["GAN2"], stats, [start] * len(rnn), spec.contact_smooth,
                                                 spec.contact_method)
    heights = np.concatenate([m.root_positions[:, 1] for m in mocap])
    toe_top = float(max(lower_toe(m.positions(), m.skeleton).max() for m in mocap))
    floor, last, ten = freeze_floor(mocap), int(5 * spec.fps), int(10 * spec.fps)
    out = {"data_root_height": [float(heights.min()), float(heights.max())], "data_lower_toe_max": toe_top,
           "freeze_floor": floor, "frames": T}
    for name, feats in sets.items():
        nan = int((~torch.isfinite(feats)).any(-1).any(-1).sum())
        motions = to_motions(feats, stats, [start] * len(feats), spec.fps)
        pos = np.stack([m.positions() for m in motions])  # (N, T, J, 3)
        h = pos[:, :, 0, 1]
        var = joint_speed(pos[:, -last:], spec.fps).var(-1)  # (N,)
        lo, hi = out["data_root_height"]
        inside = (h >= lo - 0.05) & (h <= hi + 0.05)  # (N, T): within the data's range +- 5 cm
        grounded = lower_toe(pos, start.skeleton) <= toe_top + 0.05  # (N, T)
        out[name] = {"nan_motions": nan, "root_height": [float(h.min()), float(h.max())],
                     "in_range_motions": int(inside.all(1).sum()),
                     "in_range_first_10s": int(inside[:, :ten].all(1).sum()),
                     "grounded_motions": int(grounded.all(1).sum()),
                     "grounded_first_10s": int(grounded[:, :ten].all(1).sum()),
                     "grounded_frames": float(grounded.mean()),
                     "frozen": int((var < floor).sum()), "min_speed_var": float(var.min()),
                     "apd_m": apd(pos)}
    return out


# ----------------------------------------------------------------------------- checkpoints and the commands


def _stats_path(checkpoints: Path) -> Path:
    return checkpoints / "gmm_rnn_stats.npz"


def refiner_file(name: str, seed: int) -> str:
    """Checkpoint file of a refiner: "GAN1"/"GAN2" trained with one seed."""
    return f"refiner_{name.lower()}_seed{seed}.pt"


def load_models(checkpoints: Path = CHECKPOINTS, seed: int = 0) -> tuple:
    """-> (GMM-RNN, {"GAN1": refiner, "GAN2": refiner} of refiner seed ``seed``, stats) from checkpoints/."""
    from course_lib.models.refiner import Refiner, RefinerConfig
    from course_lib.training import load_checkpoint

    refiners = {name: load_checkpoint(checkpoints / refiner_file(name, seed), Refiner, RefinerConfig)
                for name in ("GAN1", "GAN2")}
    return load_models_rnn(checkpoints), refiners, load_stats(_stats_path(checkpoints), "state_features")


def evaluate(model, refiners: dict, stats, spec: Lesson03Spec, test: list[Motion], seed: int = 0) -> dict:
    """The quality table and the long-generation test of one RNN + refiner pair."""
    t0 = time.perf_counter()
    out = {"quality": quality_table(model, refiners, test, stats, spec, seed),
           "long_generation": long_generation(model, refiners["GAN2"], test[0], stats, spec, test, seed)}
    out["eval_seconds"] = time.perf_counter() - t0
    return out


def evaluate_seeds(spec: Lesson03Spec, test: list[Motion], seed: int = 0, checkpoints: Path = CHECKPOINTS) -> dict:
    """evaluate() for every refiner seed of spec.seeds from the checkpoints -> {"per_seed": {seed: ...}}; each
    seed's entry also carries its GAN training summary (the refiners' recorded metrics, results/gmm_rnn.json)."""
    from course_lib.training import recorded_metrics

    out = {"per_seed": {}, "test_clips": len(test)}
    for s in spec.seeds:
        model, refiners, stats = load_models(checkpoints, s)
        res = evaluate(model, refiners, stats, spec, test, seed)
        res["gan"] = {name: {k: v for k, v in recorded_metrics(checkpoints / refiner_file(name, s)).items()
                             if k in _GAN_KEYS} for name in refiners}
        out["per_seed"][str(s)] = res
        print(f"seed {s}: " + ", ".join(f"{k} skate {v['foot_skate']:.3f}" for k, v in res["quality"].items()),
              file=sys.stderr)
    return out


def eval_gmm_rnn(spec: Lesson03Spec | None = None, seed: int = 0, progress: bool = True,
                 checkpoints: Path = CHECKPOINTS) -> dict:
    """The evaluation of every refiner seed from the pretrained checkpoints -> JSON-able dict (nothing is written)."""
    spec = spec or Lesson03Spec()
    _, test, _ = lesson03_data(spec, progress)
    return rounded(evaluate_seeds(spec, test, seed, checkpoints))


_GAN_KEYS = ("seconds", "rounds", "final_d_loss", "final_adversarial", "final_root", "final_d_acc_fake",
             "max_r_updates_used", "refiner_updates", "r_changes", "rounds_at_r1")


def _gan_summary(hist) -> dict:
    r = list(hist.step.get("r_updates", []))
    return {"seconds": hist.seconds, "rounds": hist.num_steps, "final_d_loss": hist.final("d_loss", 20),
            "final_adversarial": hist.final("adversarial", 20), "final_root": hist.final("root", 20),
            "final_pose": hist.final("pose", 20),
            "final_d_acc_fake": hist.final("d_acc_fake", 20), "max_r_updates_used": max(hist.r_schedule or [0]),
            "refiner_updates": int(sum(r)), "r_changes": int(np.count_nonzero(np.diff(r))),
            "rounds_at_r1": float(np.mean([v == 1 for v in r])) if r else 0.0}


def train_gmm_rnn(spec: Lesson03Spec | None = None, seed: int = 0, progress: bool = True, only=None,
                  checkpoints: Path = CHECKPOINTS) -> dict:
    """Train the RNN, then GAN1 and GAN2 for every seed of spec.seeds, save every checkpoint (+ stats),
    evaluate every seed and store the results with the RNN's metrics (results/gmm_rnn.json) -> results dict.

    only: None (everything), ["gans"] (keep checkpoints/gmm_rnn.pt, retrain the refiners: the same files
    as a full run, since the RNN and its pool are deterministic) or ["eval"] (re-evaluate and re-record)."""
    from course_lib.training import save_checkpoint

    spec = spec or Lesson03Spec()
    if only and not set(only) <= {"gans", "eval"}:
        raise ValueError(f"gmm_rnn: --only takes 'gans' or 'eval', got {only}")
    t0 = time.perf_counter()
    _, test, ds = lesson03_data(spec, progress)
    checkpoints.mkdir(parents=True, exist_ok=True)
    common = {"data_seed": spec.data_seed, "train_seed": seed, "train_windows": len(ds), "test_clips": len(test)}
    if not only:
        model, hist, ft = train_rnn(ds, spec, seed, progress=progress)
        print(f"GMM-RNN: {hist}", file=sys.stderr)
        ds.save_stats(_stats_path(checkpoints), command=COMMAND)
        save_checkpoint(model, model.config, checkpoints / "gmm_rnn.pt", command=COMMAND, overwrite=True, metrics={
            **common, **rounded({"seconds": hist.seconds, "steps": hist.num_steps, "final_nll": hist.final("loss", 50),
                                  "finetune_seconds": ft.seconds, "finetune_steps": ft.num_steps,
                                  "finetune_final_nll": ft.final("loss", 50) if ft.num_steps else None}),
            "spec": rounded(asdict(spec)), "loss_every_20_steps": _every_20(hist),
            "finetune_loss_every_20_steps": _every_20(ft)})
    store_limits(ds, checkpoints)  # the joint limits, from the training clips, saved with the RNN (any mode)
    if not only or "gans" in only:
        model = load_models_rnn(checkpoints)
        pool = rnn_pool(model, ds, spec, seed)
        for s in spec.seeds:
            for name in ("GAN1", "GAN2"):
                refiner, _, h = train_gan(pool, ds, spec, contacts=name == "GAN2", seed=s, progress=progress)
                save_checkpoint(refiner, refiner.config, checkpoints / refiner_file(name, s), command=COMMAND,
                                overwrite=True, metrics={**common, "refiner_seed": s, **rounded(_gan_summary(h)),
                                                         "history": rounded(_history_dict(h), 5)})
    results = rounded(evaluate_seeds(spec, test, seed, checkpoints))
    results["joint_limits"] = spec.joint_limits
    results["seconds"] = round(time.perf_counter() - t0, 1)
    record_results(results, checkpoints)
    return results


def load_models_rnn(checkpoints: Path = CHECKPOINTS):
    """The pretrained GMM-RNN alone."""
    from course_lib.models.gmm_rnn import GmmRnn, GmmRnnConfig
    from course_lib.training import load_checkpoint

    return load_checkpoint(checkpoints / "gmm_rnn.pt", GmmRnn, GmmRnnConfig)


def _resave_rnn(checkpoints: Path, change_model=None, **metrics) -> dict:
    """Load checkpoints/gmm_rnn.pt, apply change_model(model), save it again under its recorded command and
    training environment with its recorded metrics updated by ``metrics``."""
    from course_lib.manifest import read_manifest
    from course_lib.training import recorded_metrics, save_checkpoint

    path = checkpoints / "gmm_rnn.pt"
    entry = read_manifest(checkpoints / "MANIFEST.json")["gmm_rnn"]
    model = load_models_rnn(checkpoints)
    if change_model is not None:
        change_model(model)
    return save_checkpoint(model, model.config, path, command=entry["command"],
                           metrics={**recorded_metrics(path), **metrics}, overwrite=True,
                           environment=entry.get("trained_on", {}))


def store_limits(ds: WindowDataset, checkpoints: Path = CHECKPOINTS, atol: float = 1e-6) -> bool:
    """Save the pretrained RNN with `training_limits` of ds (its training windows) as its joint limits -> whether the
    file was rewritten.  Limits that equal the stored ones to ``atol`` (normalised units) are kept: another CPU's
    kernels round their last bits differently (2.6e-14 between AVX512 and AVX2), and rewriting them would change the
    RNN's sha256, which lesson 04's recorded control results name."""
    model = load_models_rnn(checkpoints)
    low, high = (torch.as_tensor(v, dtype=torch.float32) for v in training_limits(model, ds))
    if torch.allclose(model.feature_low, low, rtol=0, atol=atol) and torch.allclose(model.feature_high, high, rtol=0,
                                                                                    atol=atol):
        return False
    _resave_rnn(checkpoints, lambda m: m.set_limits(low, high))
    return True


def record_results(results: dict, checkpoints: Path = CHECKPOINTS) -> dict:
    """Store the evaluation with the GMM-RNN's metrics in results/gmm_rnn.json (``["checkpoints"]["gmm_rnn"]
    ["results"]``) so the notebook can show the 120-clip, 3-seed numbers in CI mode without re-running it.  The
    checkpoint is not rewritten.  Returns its manifest entry."""
    from course_lib.models.gmm_rnn import GmmRnn, GmmRnnConfig
    from course_lib.training import record_metrics

    return record_metrics(checkpoints / "gmm_rnn.pt", GmmRnn, GmmRnnConfig, results=results)


def _every_20(hist) -> list:
    """A training curve thinned to one mean per 20 steps (for the recorded metrics)."""
    loss = hist.step.get("loss", [])
    return rounded([float(np.mean(loss[i:i + 20])) for i in range(0, len(loss), 20)], 4)


def _history_dict(hist) -> dict:
    """The GAN training curves kept in the recorded metrics for the notebook's dynamics plot."""
    keys = ("loss", "adversarial", "root", "d_loss", "d_acc_real", "d_acc_fake", "r_updates")
    return {k: [float(v) for v in hist.step[k]] for k in keys}


def recorded_results(checkpoints: Path = CHECKPOINTS) -> dict:
    """The results stored by `train_gmm_rnn` (`record_results`) with the GMM-RNN's metrics."""
    from course_lib.training import recorded_metrics

    results = recorded_metrics(checkpoints / "gmm_rnn.pt").get("results")
    if results is None:
        raise KeyError(f"no recorded evaluation for {checkpoints / 'gmm_rnn.pt'}: run {COMMAND}")
    return results
