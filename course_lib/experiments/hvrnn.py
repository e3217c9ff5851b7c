"""Lesson 05 experiment: the hierarchical VRNN of Ghorbani et al. 2020, its ablations and baselines.

    python -m course_lib.reproduce hvrnn              # data, DAE, train 6 models, Table 2 -> results/hvrnn.json
    python -m course_lib.reproduce hvrnn --eval-only  # Table 2 etc. from checkpoints/hvrnn_*.pt

Data: the actions dataset (walk, jog, jump, lift x styles A/B, one clip per subject, action and
style; 40 subjects) resampled to 30 fps, in ``quaternion_root``; each clip gives one sequence of
``SEQ_LEN`` = 90 frames (3 s) from its first frame, clips shorter than that (jumps, 2.6-3.2 s)
padded by holding their last frame (the character stands still after landing), plus the
left-right mirrored copies.  The root's velocities and height are retargeted to the canonical
skeleton's legs (`retarget_root`): every sample is decoded on that skeleton.  Split by subject: the
last fifth of the subjects (s32-s39) is held out as the real reference of FID.  The shipped
evaluation classifiers were trained on s00-s05 (half of the classifiers' training subjects,
`ClassifierData`); the classifiers of the loss
L_CL (eq. 24) are trained here on s06-s31 and never used for evaluation, so that no model is
optimised against the network that scores it.  The denoising autoencoder is trained on a
different subset (the locomotion dataset) and applied to the training sequences.

Evaluation (all seeded, repeated for EVAL_SEEDS = 3 generation seeds: mean and sd): 100 samples per
action x style (800 per model) of 90 frames; IS and FID (Ghorbani eq. 27-29) on the shipped
classifiers' centre 2-s windows against all held-out sequences, IS over the 8 attribute
combinations (product of the action and style classifiers' probabilities, as the paper's 8
classes) and over the 4 actions; the classifier two-sample test (C2ST) in the same features; the
fraction of collapsed jump/lift samples; the APD of one attribute.  Every generator's output has
the training data's fixed degrees of freedom set to their constants (`PoseCoding.from_model`), and
the classifiers drop them from their inputs.  Nothing runs at import time.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np
import torch

from course_lib.datasets import ACTIONS, STYLES
from course_lib.motion import Motion
from course_lib.paths import CHECKPOINTS
from course_lib.results import rounded

ROOT = Path(__file__).resolve().parents[2]
FPS = 30.0
SEQ_LEN = 90  # frames per training / generated sequence (3 s at 30 fps); the paper: 200
COMMAND = "python -m course_lib.reproduce hvrnn"
STEPS = 1200  # optimiser steps of the ablations and baselines (about 75 epochs of the 512 training sequences)
PROPOSED_STEPS = 3600  # the Proposed model's: its leg rotations need them to keep a planted foot still
PROPOSED_BATCH = 32  # its batch (Ghorbani: 64)
DAE_STEPS = 1875  # the denoising autoencoder's: 300 epochs of its 200 clips at batch 32 (Ghorbani: 300 epochs)
RETARGET = True  # root velocities and height scaled to the canonical skeleton's legs (`retarget_root`)
EVAL_SEEDS = 3  # generation seeds of the evaluation: FID, IS, C2ST, collapse and APD are mean +- sd over them
# Ghorbani et al. 2020, Table 2 (AMASS, 8 attribute combinations; their real data IS 7.64, FID 0 by definition)
PAPER_TABLE2 = {"QuaterNet": {"IS": 5.12, "FID": 92.31}, "ERD": {"IS": 5.91, "FID": 86.42},
                "Proposed(SL)": {"IS": 6.45, "FID": 31.41}, "Proposed(NL)": {"IS": 7.11, "FID": 17.3},
                "Proposed(NC)": {"IS": 7.43, "FID": 11.92}, "Proposed": {"IS": 7.52, "FID": 10.45},
                "Real data": {"IS": 7.64, "FID": 0.0}}


# ----------------------------------------------------------------------------- data


def retarget_root(features: np.ndarray, skeleton, to=None) -> np.ndarray:
    """(T, 90) quaternion_root features of a clip on `skeleton` -> the same with the root's velocities and
    height scaled to the legs of `to` (default: the canonical skeleton), leg_length(to) / leg_length(skeleton).
    Every sample is decoded on the canonical skeleton: without this, a long-legged subject's stride and hip
    height, played on shorter legs, slide the planted foot and push it through the floor."""
    from course_lib.skeleton import Skeleton

    to = Skeleton.canonical() if to is None else to
    f = np.array(features, dtype=np.float64, copy=True)
    f[:, -6:-3] *= to.leg_length() / skeleton.leg_length()  # forward, sideways velocity (m/s), root height (m)
    return f


PADS = ("hold", "loop")  # how a clip shorter than the sequence is filled: its last frame held, or itself again


def to_sequence(m: Motion, length: int = SEQ_LEN, retarget: bool = RETARGET, pad: str = "hold") -> np.ndarray:
    """One clip -> (length, 90) quaternion_root features at 30 fps from its first frame, the root retargeted to
    the canonical skeleton (`retarget_root`); a shorter clip is padded by repeating its last frame (``pad`` =
    "hold"; Ghorbani pad with zeros, which are no valid quaternions) or by playing it again from its start
    ("loop": the features are velocities and local angles, so a loop has no jump of position)."""
    from course_lib.representations import encode_quaternion_root

    if pad not in PADS:
        raise ValueError(f"pad must be one of {', '.join(PADS)}, got {pad!r}")
    f = encode_quaternion_root(m if m.fps == FPS else m.resample(FPS))
    if retarget:
        f = retarget_root(f, m.skeleton)
    if len(f) < length:
        fill = np.repeat(f[-1:], length - len(f), 0) if pad == "hold" else np.resize(f, (length - len(f), f.shape[1]))
        f = np.concatenate((f, fill))
    return f[:length].astype(np.float32)


def held_frames(x) -> np.ndarray:
    """Sequences (N, T, D) -> (N,) how many frames at each one's end repeat its last frame exactly: the padding
    `to_sequence` adds to a clip shorter than the sequence (0 for a clip that fills it)."""
    x = np.asarray(x)
    same = np.all(x == x[:, -1:], axis=-1)  # (N, T): the frame equals the last one
    run = np.cumprod(same[:, ::-1], axis=1)  # 1 while the run of equal frames back from the end lasts
    return run.sum(1) - 1  # the last frame itself is not padding


def sequences(motions: list[Motion], length: int = SEQ_LEN, mirror: bool = False, retarget: bool = RETARGET,
              pad: str = "hold") -> dict:
    """Clips -> {"x": (N, length, 90) float32 tensor, "action_id": (N,), "style_id": (N,), "subject": [N]}."""
    clips = list(motions) + ([m.mirror() for m in motions] if mirror else [])
    if not clips:
        raise ValueError("sequences: no clips")
    return {"x": torch.from_numpy(np.stack([to_sequence(m, length, retarget, pad) for m in clips])),
            "action_id": torch.tensor([ACTIONS.index(m.action) for m in clips]),
            "style_id": torch.tensor([STYLES.index(m.style) for m in clips]),
            "subject": [m.subject for m in clips]}


def subset(data: dict, keep) -> dict:
    """Rows of a `sequences` dict where the boolean list/array `keep` is True."""
    keep = torch.as_tensor(np.asarray(keep, bool))
    return {"x": data["x"][keep], "action_id": data["action_id"][keep], "style_id": data["style_id"][keep],
            "subject": [s for s, k in zip(data["subject"], keep.tolist(), strict=True) if k]}


def split_subjects(motions: list[Motion]) -> tuple[list[Motion], list[Motion]]:
    """-> (train, test) clips: the last fifth of the subjects (at least one) is held out."""
    subjects = sorted({m.subject for m in motions})
    test = set(subjects[len(subjects) - max(1, len(subjects) // 5):])
    return [m for m in motions if m.subject not in test], [m for m in motions if m.subject in test]


def classifier_subjects() -> set[str]:
    """The subjects whose clips trained the shipped evaluation classifiers."""
    from course_lib.evaluation.classifiers import ClassifierData

    return {s.name for s in ClassifierData().split()[0]}


def load_data(mode: str | None = None, progress: bool = False, retarget: bool = RETARGET, pad: str = "hold") -> dict:
    """-> {"train": sequences (mirrored), "test": held-out sequences (mirrored), "train_clips", "test_clips"};
    short clips padded by ``pad`` (`to_sequence`)."""
    from course_lib.datasets import load_dataset

    train, test = split_subjects(load_dataset("actions", mode=mode, fps=FPS, progress=progress))
    return {"train": sequences(train, mirror=True, retarget=retarget, pad=pad),
            "test": sequences(test, mirror=True, retarget=retarget, pad=pad), "train_clips": train, "test_clips": test}


def batches(data: dict, batch: int, seed: int):
    """An endless iterator of random batches {"x", "action_id", "style_id"} of a `sequences` dict."""
    gen = torch.Generator().manual_seed(seed)
    n = len(data["x"])
    while True:
        for idx in torch.randperm(n, generator=gen).split(batch):
            if len(idx) == batch or n < batch:
                yield {"x": data["x"][idx], "action_id": data["action_id"][idx], "style_id": data["style_id"][idx]}


# ----------------------------------------------------------------------------- helpers: DAE, loss classifiers


def _locomotion_clips(n: int, mode: str | None) -> list[Motion]:
    """The first n clips of the locomotion dataset at 30 fps (the file's, else load_dataset's generated set)."""
    from course_lib.datasets import DATA_DIR, load_dataset, load_motions, resample_clips
    from course_lib.modes import course_mode

    path = DATA_DIR / "locomotion.npz"
    if (mode or course_mode()) != "ci" and path.exists():
        return resample_clips(load_motions(path)[:n], FPS)
    return load_dataset("locomotion", mode=mode, fps=FPS)[:n]


def train_dae(steps: int, seed: int = 0, mode: str | None = None, progress: bool = False,
              retarget: bool = RETARGET):
    """The Table-1 denoising autoencoder trained on 90-frame windows of the locomotion dataset (a different
    subset from the actions data, as the paper's "rest of AMASS") -> (model, History)."""
    from course_lib.models.hvrnn import DaeConfig, DenoisingAutoencoder
    from course_lib.training import fit, seed_everything

    clips = _locomotion_clips(200, mode)
    x = sequences([dataclasses.replace(m, action="walk", style="A") for m in clips], retarget=retarget)["x"]
    seed_everything(seed)
    model = DenoisingAutoencoder(DaeConfig())
    model.set_stats(x)
    hist = fit(model, batches({"x": x, "action_id": torch.zeros(len(x)), "style_id": torch.zeros(len(x)),
                               "subject": [""] * len(x)}, 32, seed), steps=steps, lr=1e-3, progress=progress,
               desc="DAE")
    return model.eval(), hist


@torch.no_grad()
def denoise(model, x: torch.Tensor, chunk: int = 256) -> torch.Tensor:
    """Apply the DAE to sequences (N, T, 90) -> (N, T, 90)."""
    return torch.cat([model(x[i:i + chunk]) for i in range(0, len(x), chunk)])


def clean(dae, x: torch.Tensor) -> torch.Tensor:
    """The DAE applied to training sequences (N, T, 90), then the data's fixed degrees of freedom put back
    (the residual network nudges every channel a little) and the quaternions renormalised."""
    from course_lib.datasets import FixedDofs
    from course_lib.models.hvrnn import normalize_pose

    return normalize_pose(FixedDofs.detect(x).apply(denoise(dae, x)))


def train_loss_classifiers(data: dict, steps: int = 300, seed: int = 0, progress: bool = False) -> list:
    """Action and style classifiers for L_CL (eq. 24), Table 1's network, trained on the training
    sequences of the subjects the shipped evaluation classifiers never saw."""
    from course_lib.evaluation.classifiers import ClassifierConfig, MotionClassifier, _window_sampler
    from course_lib.training import fit, seed_everything

    held = classifier_subjects()
    keep = [s not in held for s in data["subject"]]
    part = subset(data, keep) if any(keep) else data
    feats = [f.numpy() for f in part["x"]]
    out = []
    for task, labels in (("action", part["action_id"]), ("style", part["style_id"])):
        seed_everything(seed)
        config = ClassifierConfig.for_task(task)
        clf = MotionClassifier(config)
        clf.set_normalization(part["x"].reshape(-1, part["x"].shape[-1]))  # as the evaluation classifiers
        sampler = _window_sampler(feats, labels.numpy(), config.window, 32, np.random.default_rng(seed))
        fit(clf, sampler, steps=steps, lr=5e-3, progress=progress, desc=f"L_CL {task} classifier")
        out.append(clf.eval())
    return out


# ----------------------------------------------------------------------------- the models


@dataclasses.dataclass
class ModelSpec:
    """One row of Table 2: checkpoint name, label, class, config, optimiser steps."""

    name: str
    label: str
    cls: type
    config: object
    steps: int
    batch: int = 32  # Ghorbani: 64 (halved for the CPU budget)
    lr_end: float = 1.0  # the learning rate's factor at the last step, cosine from 1 over the second half (1: constant)


def lr_factor(spec: ModelSpec, step: int) -> float:
    """The factor on Adam's 1e-3 for optimiser step ``step`` (0-based) of a run of spec.steps: 1 in the first half,
    then a cosine down to spec.lr_end at the last step."""
    half = spec.steps // 2
    if spec.lr_end == 1.0 or step < half:
        return 1.0
    t = (step - half) / max(1, spec.steps - 1 - half)
    return spec.lr_end + (1.0 - spec.lr_end) * 0.5 * (1.0 + math.cos(math.pi * min(t, 1.0)))


def _set_lr(spec: ModelSpec, offset: int = 0):
    """A `fit` callback that sets the learning rate of the next step by `lr_factor` (``offset``: steps run before)."""
    def callback(info):
        for group in info.optimizer.param_groups:
            group["lr"] = 1e-3 * lr_factor(spec, offset + info.step)
    return callback


def model_specs(scale: float = 1.0) -> dict[str, ModelSpec]:
    """name -> ModelSpec of the six generators, STEPS optimiser steps each (the Proposed model PROPOSED_STEPS);
    scale multiplies the steps and the schedules (CI runs use a few dozen)."""
    from course_lib.models.baselines import AttributeRnn, AttributeRnnConfig
    from course_lib.models.hvrnn import HierarchicalVrnn, HvrnnConfig

    def s(fraction):  # a fraction of the shipped STEPS, scaled
        return max(2, int(fraction * STEPS * scale))

    # lambda_KL: 0 for the first 1/12, to 1 by half-way; lambda_CL from half-way, to its final value by 11/12;
    # word dropping to drop_max by 2/3.  The Proposed model drops up to 0.6 of its words (the ablations 0.3) and
    # decays its rate over the second half (lr_end): together they plant its free-running feet
    # (studies/05_hierarchical_vrnn, hvrnn_skate_fix)
    def schedules(k):  # the same fractions of a run of k x STEPS steps
        return dict(kl_warmup=s(k / 12), kl_anneal=s(5 * k / 12), cl_start=s(k / 2), cl_ramp=s(5 * k / 12),
                    drop_ramp=s(2 * k / 3))

    sched, k = schedules(1), PROPOSED_STEPS / STEPS
    specs = [
        ModelSpec("hvrnn_proposed", "Proposed", HierarchicalVrnn, HvrnnConfig.cpu(drop_max=0.6, **schedules(k)),
                  s(k), PROPOSED_BATCH, lr_end=0.1),
        ModelSpec("hvrnn_sl", "Proposed(SL)", HierarchicalVrnn, HvrnnConfig.cpu(hierarchical=False, **sched), s(1)),
        ModelSpec("hvrnn_nl", "Proposed(NL)", HierarchicalVrnn, HvrnnConfig.cpu(use_alpha=False, **sched), s(1)),
        ModelSpec("hvrnn_nc", "Proposed(NC)", HierarchicalVrnn, HvrnnConfig.cpu(lambda_cl=0.0, **sched), s(1)),
        ModelSpec("hvrnn_erd", "ERD", AttributeRnn, AttributeRnnConfig.cpu(kind="erd"), s(1)),
        ModelSpec("hvrnn_quaternet", "QuaterNet", AttributeRnn,
                  AttributeRnnConfig.cpu(kind="quaternet", sample_ramp=s(2 / 3)), s(1)),
    ]
    return {m.name: m for m in specs}


def train_model(spec: ModelSpec, train: dict, classifiers: list, seed: int = 0, progress: bool = False,
                keep_at: int | None = None):
    """Adam 1e-3, gradient-norm clip 0.1 (Ghorbani sec. 4.2), the rate scaled by `lr_factor` -> (model, History).

    keep_at: after that many steps, keep the whole training state (weights, optimiser, torch's RNG) in
    ``hist.kept`` for `continue_training`: the ablation NC is the Proposed model until lambda_CL turns on."""
    from course_lib.training import fit, seed_everything

    seed_everything(seed)
    model = spec.cls(spec.config)
    model.set_stats(train["x"])
    if hasattr(model, "set_classifiers") and getattr(spec.config, "lambda_cl", 0) > 0:
        model.set_classifiers(classifiers)
    kept, t0 = {}, time.perf_counter()

    set_lr = _set_lr(spec)

    def on_step(info):
        set_lr(info)
        if info.step == keep_at:
            kept.update(steps=info.step, state=copy.deepcopy(info.model.state_dict()), rng=torch.get_rng_state(),
                        optimizer=copy.deepcopy(info.optimizer.state_dict()), seconds=time.perf_counter() - t0,
                        curve=list(info.history.step["loss"]))

    hist = fit(model, batches(train, spec.batch, seed), steps=spec.steps, lr=1e-3, grad_clip=0.1, progress=progress,
               desc=spec.name, callback=on_step)
    hist.kept = kept
    return model.eval(), hist


def forkable(specs: dict) -> bool:
    """Whether NC's run is the Proposed run until lambda_CL turns on (same sizes, schedules, steps and batch), so
    that `continue_training` can fork it from the Proposed run's state."""
    p, nc = specs["hvrnn_proposed"], specs["hvrnn_nc"]
    return (nc.config == dataclasses.replace(p.config, lambda_cl=0.0) and nc.steps == p.steps
            and nc.batch == p.batch and nc.lr_end == p.lr_end)


def continue_training(spec: ModelSpec, kept: dict, train: dict, seed: int = 0, progress: bool = False):
    """Train `spec` from another run's state kept by `train_model(keep_at=n)` to spec.steps -> (model, History
    of the remaining steps).  Exact when the two recipes agree on the first n steps (same seed, data and
    sizes; NC and Proposed differ only in lambda_CL, which is 0 until cl_start)."""
    from course_lib.training import fit

    model = spec.cls(spec.config)
    model.load_state_dict(kept["state"])
    data = batches(train, spec.batch, seed)
    for _ in range(kept["steps"]):  # the batches the first run has used
        next(data)
    torch.set_rng_state(kept["rng"])
    hist = fit(model, data, steps=spec.steps - kept["steps"], lr=1e-3, grad_clip=0.1, progress=progress,
               desc=f"{spec.name} (from step {kept['steps']})", optimizer_state=kept["optimizer"],
               callback=_set_lr(spec, kept["steps"]))
    return model.eval(), hist


def load_model(name: str, checkpoints: Path = CHECKPOINTS):
    """The shipped checkpoint of generator `name` (eval mode)."""
    from course_lib.training import load_checkpoint

    specs = model_specs()
    if name not in specs:
        raise KeyError(f"load_model: no lesson-05 generator {name!r}; choose one of {', '.join(specs)}")
    spec = specs[name]
    return load_checkpoint(checkpoints / f"{name}.pt", spec.cls, type(spec.config))


# ----------------------------------------------------------------------------- evaluation


def attribute_grid(n_per: int) -> tuple[torch.Tensor, torch.Tensor]:
    """-> action ids, style ids (8 n_per,): n_per of every action x style, in order."""
    a = torch.arange(len(ACTIONS)).repeat_interleave(len(STYLES) * n_per)
    s = torch.arange(len(STYLES)).repeat_interleave(n_per).repeat(len(ACTIONS))
    return a, s


def generate(model, n_per: int = 100, frames: int = SEQ_LEN, seed: int = 0, attribute: tuple[str, str] | None = None
             ) -> dict:
    """n_per samples per action x style (or of the one (action, style) `attribute`) -> a `sequences`-like dict
    of raw features (8 n_per or n_per, frames, 90)."""
    if attribute is None:
        a, s = attribute_grid(n_per)
    else:
        if len(attribute) != 2 or attribute[0] not in ACTIONS or attribute[1] not in STYLES:
            raise ValueError(f"generate: attribute must be (action, style) with action one of {ACTIONS} and style "
                             f"one of {STYLES}, got {attribute!r}")
        a, s = torch.full((n_per,), ACTIONS.index(attribute[0])), torch.full((n_per,), STYLES.index(attribute[1]))
    x = model.sample(a, s, frames, generator=torch.Generator().manual_seed(seed))
    return {"x": x.float(), "action_id": a, "style_id": s, "subject": ["generated"] * len(a)}


def to_motions(data: dict) -> list[Motion]:
    """Sequences (raw features) -> Motions on the canonical skeleton, labelled, at 30 fps."""
    from course_lib.representations import decode_quaternion_root
    from course_lib.skeleton import Skeleton

    skel = Skeleton.canonical()
    out = []
    for x, a, s, subj in zip(data["x"].double().numpy(), data["action_id"].tolist(), data["style_id"].tolist(),
                             data["subject"], strict=True):
        m = decode_quaternion_root(x, skel, FPS)
        out.append(dataclasses.replace(m, action=ACTIONS[a], style=STYLES[s], subject=subj))
    return out


def _positions(motions: list[Motion]) -> np.ndarray:
    """-> root-relative joint positions (N, T, J, 3)."""
    p = np.stack([m.positions() for m in motions])
    return p - p[:, :, :1]


def last_second_activity(motions: list[Motion], fps: float = FPS) -> tuple[np.ndarray, np.ndarray]:
    """-> (mean joint speed m/s, pose variance m^2) of each clip's last second, root-relative positions (N,)."""
    p = _positions(motions)[:, -int(fps):]  # (N, fps, J, 3)
    speed = np.linalg.norm(np.diff(p, axis=1), axis=-1).mean((1, 2)) * fps
    var = p.var(axis=1).sum(-1).mean(-1)  # per joint: trace of the covariance over time, mean over joints
    return speed, var


def collapse_thresholds(real: list[Motion], quantile: float = 0.05, factor: float = 0.5) -> tuple[float, float]:
    """(speed, variance) thresholds: `factor` x the `quantile` of the real clips' last-second values."""
    speed, var = last_second_activity(real)
    return factor * float(np.quantile(speed, quantile)), factor * float(np.quantile(var, quantile))


def collapsed_fraction(motions: list[Motion], thresholds: tuple[float, float]) -> float:
    """Fraction of clips whose last second has speed AND pose variance below the thresholds (mean-pose collapse)."""
    speed, var = last_second_activity(motions)
    return float(np.mean((speed < thresholds[0]) & (var < thresholds[1])))


@torch.no_grad()
def joint_errors(model, data: dict, seed: int = 0) -> np.ndarray:
    """Teacher-forced reconstruction (posterior z, the data's words) of a `sequences` dict -> mean geodesic
    error d1 (eq. 17) of each joint's rotation, degrees (J,)."""
    from course_lib.rotations import quat_geodesic

    J = model.config.num_joints
    out = model.reconstruct(data["x"], data["action_id"], data["style_id"], torch.Generator().manual_seed(seed))
    q, q_hat = data["x"][..., : 4 * J].unflatten(-1, (J, 4)), out["x_hat"][..., : 4 * J].unflatten(-1, (J, 4))
    return torch.rad2deg(quat_geodesic(q.double(), q_hat.double(), "d1")).mean((0, 1)).numpy()


GAITS = ("walk", "jog")  # the actions whose feet the skate measures (jumps and lifts leave the floor)
SKIP = 15  # frames dropped from the start of every sample before measuring (lesson 07's 0.5-s context)


def foot_quality(motions: list[Motion], skip: int = SKIP) -> dict:
    """Clips at 30 fps -> {"foot_skate" (m/s, `foot_skate_at_floor`: the floor at y = 0), "penetration" (m),
    "jitter" (m/s^3)} of their world positions from frame `skip` on (lesson 07's measures)."""
    from course_lib.evaluation import foot_skate_at_floor, ground_penetration, jitter

    cut = [m[skip:] for m in motions]
    return {"foot_skate": foot_skate_at_floor(cut), "penetration": ground_penetration(cut), "jitter": jitter(cut)}


def gait_samples(model, n: int, frames: int = 4 * int(FPS), seed: int = 0) -> list[Motion]:
    """n free-running samples of the gaits (walk or jog, either style, seeded at random), `frames` long, on the
    canonical skeleton -- what lesson 07's benchmark asks of the model."""
    g = torch.Generator().manual_seed(seed)
    a = torch.tensor([ACTIONS.index(GAITS[i]) for i in torch.randint(len(GAITS), (n,), generator=g)])
    s = torch.randint(len(STYLES), (n,), generator=g)
    x = model.sample(a, s, frames, generator=g)
    return to_motions({"x": x.float(), "action_id": a, "style_id": s, "subject": ["generated"] * n})


def gait_mocap(clips: list[Motion], frames: int = 4 * int(FPS)) -> list[Motion]:
    """The walk and jog clips among `clips`, at 30 fps on their own skeletons, cut to `frames`."""
    return [m.resample(FPS)[:frames] for m in clips if m.action in GAITS]


def _facing_positions(motions: list[Motion]) -> np.ndarray:
    """-> root-relative joint positions with each frame's heading turned to +Z (the pose alone), (N, T, J, 3)."""
    from course_lib.representations import root_yaw_pitch_roll

    pos = _positions(motions)
    yaw = np.stack([root_yaw_pitch_roll(m)[:, 0] for m in motions])[..., None]  # (N, T, 1)
    c, s = np.cos(-yaw), np.sin(-yaw)  # a turn about +Y by -yaw
    return np.stack([c * pos[..., 0] + s * pos[..., 2], pos[..., 1], -s * pos[..., 0] + c * pos[..., 2]], -1)


def nearest_distance(motions: list[Motion], reference: list[Motion]) -> float:
    """Mean over `motions` of the distance (APD's: mean over frames and joints, facing positions, m) to the
    nearest clip of `reference` -- how far samples stray from real ones.  Reference clips of a clip's own
    subject (itself, its mirrored copy) are skipped, so that real data against itself is a fair floor."""
    a, b = _facing_positions(motions), _facing_positions(reference)
    d = np.stack([np.linalg.norm(x[None] - b, axis=-1).mean(axis=(1, 2)) for x in a])  # (N, M)
    same = np.array([[x.subject is not None and x.subject == y.subject for y in reference] for x in motions])
    if same.all(1).any():
        raise ValueError("nearest_distance: a clip has no reference clip of another subject")
    return float(np.where(same, np.inf, d).min(1).mean())


def diversity(motions: list[Motion], classifier, reference: list[Motion] | None = None) -> dict:
    """Clips of one requested action -> {"apd": APD of root-relative positions (m), "apd_facing": the same with
    each frame's heading removed (the pose alone), "recognised": fraction the action classifier labels as that
    action, "travel": mean floor distance of the root from first to last frame (m), "turn": mean change of
    heading from first to last frame (degrees), and with `reference` (real clips) "nearest_real": the mean
    distance from each clip to its nearest real one (`nearest_distance`)}.  An APD above real data's is no
    virtue when the extra spread is motion of another kind (travelling, turning) or away from real motion."""
    from course_lib.evaluation import apd, classifier_features, motions_to_batch
    from course_lib.representations import root_yaw_pitch_roll

    yaw = np.stack([root_yaw_pitch_roll(m)[:, 0] for m in motions])  # (N, T)
    probs = classifier_features(motions_to_batch(motions, classifier.config), classifier, kind="proba")
    ok = probs.argmax(1) == np.array([classifier.config.classes.index(m.action) for m in motions])
    root = np.stack([m.root_positions[[0, -1]] for m in motions])  # (N, 2, 3)
    turn = np.degrees(np.abs(np.angle(np.exp(1j * (yaw[:, -1] - yaw[:, 0])))))
    out = {"apd": apd(_positions(motions)), "apd_facing": apd(_facing_positions(motions)),
           "recognised": float(ok.mean()),
           "travel": float(np.linalg.norm(root[:, 1, [0, 2]] - root[:, 0, [0, 2]], axis=-1).mean()),
           "turn": float(turn.mean())}
    if reference is not None:
        out["nearest_real"] = nearest_distance(motions, reference)
    return out


def scores(motions: list[Motion], reference: list[Motion], classifiers: dict, seed: int = 0) -> dict:
    """IS (8 combinations and 4 actions), FID (action and style classifier features), label accuracies, and
    the C2ST accuracy with its 95 % interval (both classifiers' features)."""
    from course_lib.evaluation import c2st, classifier_features, fid, inception_score, motions_to_batch

    out = {}
    probs = {}
    for task, clf in classifiers.items():
        x = motions_to_batch(motions, clf.config)
        probs[task] = classifier_features(x, clf, kind="proba")
        fg, fr = classifier_features(x, clf), classifier_features(reference, clf)
        out[f"FID_{task}"] = fid(fr, fg, clf)
        labels = np.array([clf.config.classes.index(getattr(m, task)) for m in motions])
        out[f"accuracy_{task}"] = float((probs[task].argmax(1) == labels).mean())
    joint = (probs["action"][:, :, None] * probs["style"][:, None, :]).reshape(len(motions), -1)
    out["IS"] = inception_score(joint)
    out["IS_action"] = inception_score(probs["action"])
    out["FID"] = out["FID_action"]
    test = c2st(reference, motions, seed=seed, classifiers=[classifiers["action"], classifiers["style"]])
    out.update(C2ST=test["accuracy"], C2ST_low=test["ci_low"], C2ST_high=test["ci_high"])
    return out


def evaluate(generated: dict[str, list[Motion]], real_test: list[Motion], real_train: list[Motion],
             apd_attribute=("jump", "A"), seed: int = 0) -> dict:
    """Table 2 (IS/FID per model and for real data), collapse fractions for jump/lift, APD for one attribute."""
    from course_lib.evaluation import apd, load_classifier

    classifiers = {"action": load_classifier("action"), "style": load_classifier("style")}
    held = classifier_subjects()
    # real clips no classifier was trained on (in CI's tiny data there are none: all training clips then)
    real_other = [m for m in real_train if m.subject not in held] or real_train
    rows = {label: scores(ms, real_test, classifiers, seed) for label, ms in generated.items()}
    rows["Real data"] = scores(real_other, real_test, classifiers, seed)
    real_all = real_train + real_test
    thresholds = {a: collapse_thresholds([m for m in real_all if m.action == a]) for a in ("jump", "lift")}
    collapse = {label: {a: collapsed_fraction([m for m in ms if m.action == a], thresholds[a]) for a in thresholds}
                for label, ms in {**generated, "Real data": real_all}.items()}
    act, sty = apd_attribute

    def pick(ms):
        return [m for m in ms if m.action == act and m.style == sty and not m.meta.get("mirrored")]

    apds = {label: apd(_positions(pick(ms))) for label, ms in generated.items()}
    apds["Real data"] = apd(_positions(pick(real_all)))
    return {"table2": rows, "collapse": collapse,
            "collapse_thresholds": {a: {"speed_m_s": t[0], "variance_m2": t[1]} for a, t in thresholds.items()},
            "apd": apds, "apd_attribute": f"{act}/{sty}",
            "counts": {"generated_per_model": len(next(iter(generated.values()))), "real_test": len(real_test),
                       "real_train_unseen_by_classifiers": len(real_other)}}


def eval_hvrnn(seed: int = 0, progress: bool = True, checkpoints: Path = CHECKPOINTS, n_per: int = 100,
               mode: str | None = "full", models: dict | None = None, seeds: int = EVAL_SEEDS) -> dict:
    """Generate n_per samples per action x style with every shipped model, `seeds` times (generation seeds
    seed, seed + 1, ...), and score them -> JSON-able dict: "table2", "collapse", "apd" are means over the
    seeds, "table2_sd", "collapse_sd", "apd_sd" their standard deviations, "per_seed" each run; "feet": each
    model's `foot_quality` on n_per walk-or-jog samples of 4 s (`gait_samples`, as lesson 07 asks) and the held-out
    walks and jogs' ("Real data"), with "feet_sd"."""
    from course_lib.evaluation import over_seeds

    t0 = time.perf_counter()
    data = load_data(mode)
    models = models or {name: load_model(name, checkpoints) for name in model_specs()}
    labels = {name: spec.label for name, spec in model_specs().items()}
    real_test = to_motions(data["test"])
    real_train = to_motions(data["train"])
    real_gaits = foot_quality(gait_mocap(data["test_clips"]))
    runs = []
    for s in range(seed, seed + seeds):
        generated = {labels[n]: to_motions(generate(m, n_per, SEQ_LEN, s)) for n, m in models.items()}
        runs.append(evaluate(generated, real_test, real_train, seed=s))
        runs[-1]["feet"] = {labels[n]: foot_quality(gait_samples(m, n_per, seed=s)) for n, m in models.items()}
        runs[-1]["feet"]["Real data"] = real_gaits
        print(f"hvrnn eval seed {s}: " + ", ".join(f"{k} FID {r['FID']:.0f}" for k, r in runs[-1]["table2"].items()),
              file=sys.stderr)
    out = dict(runs[0])  # thresholds, attribute and counts are the same in every run
    for key in ("table2", "collapse", "apd", "feet"):
        out[key], out[f"{key}_sd"] = over_seeds([r[key] for r in runs])
    out["per_seed"] = {str(s): {k: r[k] for k in ("table2", "collapse", "apd", "feet")} for s, r in
                       zip(range(seed, seed + seeds), runs, strict=True)}
    out["generation_seeds"] = list(range(seed, seed + seeds))
    out["eval_seconds"] = round(time.perf_counter() - t0, 1)
    return rounded(out, 4)


def train_hvrnn(seed: int = 0, progress: bool = True, only=None, checkpoints: Path = CHECKPOINTS,
                mode: str | None = "full", scale: float = 1.0) -> dict:
    """DAE, loss classifiers, every generator (or those in `only`); checkpoints + manifest, metrics and
    evaluation in results/hvrnn.json -> eval results."""
    from course_lib.training import save_checkpoint

    t0 = time.perf_counter()
    data = load_data(mode)
    dae, dae_hist = train_dae(max(2, int(DAE_STEPS * scale)), seed, mode, progress)
    train = dict(data["train"], x=clean(dae, data["train"]["x"]))
    timings = {"data_and_dae_seconds": round(time.perf_counter() - t0, 1)}
    save_checkpoint(dae, dae.config, checkpoints / "hvrnn_dae.pt", command=COMMAND, overwrite=True,
                    metrics={"train_seconds": round(dae_hist.seconds, 1), "steps": dae_hist.num_steps,
                             "final_loss": round(dae_hist.final("loss", 20), 6)})
    classifiers = train_loss_classifiers(train, max(2, int(300 * scale)), seed, progress)
    specs, kept = model_specs(scale), {}
    for name, spec in specs.items():
        if only and name not in only:
            continue
        if name == "hvrnn_nc" and kept and forkable(specs):  # NC = Proposed until lambda_CL turns on
            model, hist = continue_training(spec, kept, train, seed, progress)
            shared, curve = kept["seconds"], kept["curve"] + list(hist.step["loss"])
            metrics = {"forked_from": "hvrnn_proposed", "forked_at_step": kept["steps"]}
        else:
            keep_at = specs["hvrnn_nc"].config.cl_start if name == "hvrnn_proposed" and forkable(specs) else None
            model, hist = train_model(spec, train, classifiers, seed, progress, keep_at=keep_at)
            kept = hist.kept or kept
            shared, curve, metrics = 0.0, list(hist.step["loss"]), {}
        timings[name] = round(shared + hist.seconds, 1)  # NC: its share of the Proposed run + its own steps
        metrics.update({"train_seconds": timings[name], "steps": len(curve), "batch": spec.batch,
                        "lr": 1e-3, "lr_end": spec.lr_end,
                        "final_loss": round(hist.final("loss", 20), 6), "final_rec": round(hist.final("rec", 20), 6),
                        "train_sequences": len(train["x"]), "seq_len": SEQ_LEN, "train_seed": seed,
                        "curve": [round(float(v), 4) for v in curve[:: max(1, len(curve) // 100)]]})
        save_checkpoint(model, spec.config, checkpoints / f"{name}.pt", command=COMMAND, metrics=metrics,
                        overwrite=True)
        print(f"{name}: {hist}", file=sys.stderr)
    out = eval_hvrnn(seed, progress, checkpoints, mode=mode)
    out["train_seconds"] = timings
    out["total_seconds"] = round(time.perf_counter() - t0, 1)
    record_results(out, checkpoints)
    return out


def record_results(results: dict, checkpoints: Path = CHECKPOINTS) -> dict:
    """Store the evaluation with the Proposed checkpoint's metrics in results/hvrnn.json
    (``["checkpoints"]["hvrnn_proposed"]["tables"]``); the checkpoint is not rewritten.  Returns its manifest
    entry."""
    from course_lib.training import record_metrics

    spec = model_specs()["hvrnn_proposed"]
    return record_metrics(checkpoints / "hvrnn_proposed.pt", spec.cls, type(spec.config), tables=results)


def recorded_results(checkpoints: Path = CHECKPOINTS) -> dict:
    """The evaluation stored by `record_results` (the shipped >= 100-samples-per-attribute numbers)."""
    from course_lib.training import recorded_metrics

    tables = recorded_metrics(checkpoints / "hvrnn_proposed.pt").get("tables")
    if tables is None:
        raise KeyError(f"no recorded evaluation for {checkpoints / 'hvrnn_proposed.pt'}: run {COMMAND}")
    return tables
