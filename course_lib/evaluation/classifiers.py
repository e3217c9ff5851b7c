"""Motion classifiers for action (walk, jog, jump, lift) and style (A, B): Ghorbani et al. 2020, Table 1.

    3 x [Conv1D + ReLU] -> AdaptiveAvgPool1D -> FC(N_C)

The input is the ``quaternion_root`` representation (Ghorbani's own: 21 local
quaternions + 6 root features = 90 channels) at 30 fps, normalised with the
training set's per-channel mean and std (stored as buffers in the checkpoint),
with two deliberate choices about channels that barely vary (`set_normalization`):

- the *fixed* degrees of freedom of the training data (28 of the 84 quaternion
  channels: hinge joints' off-axis components, shoulders and hands,
  `course_lib.datasets.FixedDofs`) are dropped (multiplied by 0): the network
  never saw them vary, so their first-layer weights never learned anything and
  any value there would be scored by random weights;
- every other channel's scale is floored at ``scale_floor`` = 0.05 (a quaternion
  component of 0.05 is a turn of about 6 degrees; 0.05 m/s, m or rad for the root
  features), so that a channel with a tiny spread (the root's residual yaw: sd 0.002)
  is not amplified into a detector of invisible changes.
The pooled 64-D vector before the final FC layer is the feature space of FID
(eq. 29); the softmax of the FC output gives p(a|X) for the Inception Score
(eq. 27-28).  The classifiers are trained on half of the training subjects
(as Ghorbani: "on 50% of training data") and tested on held-out subjects.

Reproduce the shipped checkpoints and print held-out accuracies::

    python -m course_lib.evaluation.classifiers --train action --out checkpoints/action_classifier.pt
    python -m course_lib.evaluation.classifiers --train style --out checkpoints/style_classifier.pt
    python -m course_lib.evaluation.classifiers --eval

Taught in notebooks/05_hierarchical_vrnn.ipynb.

Differs from the paper: trained on synthetic clips (``course_lib.synthetic``)
instead of AMASS; 2-s windows (60 frames at 30 fps) instead of 4 s; 64 channels,
kernel 5 (Table 1 gives no sizes); Adam lr 5e-3 as the paper, but a fixed number
of steps instead of 30 epochs (CPU budget).  Style is the synthetic analogue of
the paper's gender attribute (the generator's styles differ in arm swing, hip sway,
cadence, trunk lean and, for lift, technique).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from pathlib import Path

import numpy as np
import torch
from torch import nn

from course_lib.datasets import FixedDofs
from course_lib.motion import Motion
from course_lib.paths import CHECKPOINTS
from course_lib.representations import encode_quaternion_root

__all__ = ["ClassifierConfig", "MotionClassifier", "accuracy", "checkpoint_path", "load_classifier",
           "motions_to_batch"]

ACTIONS = ("walk", "jog", "jump", "lift")
STYLES = ("A", "B")
STYLED_ACTIONS = ACTIONS  # the actions the style classifier is trained and tested on
CHECKPOINT_DIR = CHECKPOINTS  # course_lib.paths: the repository's checkpoints/, or $COURSE_CHECKPOINTS


@dataclasses.dataclass
class ClassifierConfig:
    """One attribute classifier; the defaults are the shipped action classifier's."""

    task: str = "action"  # the Motion label it predicts: 'action' or 'style'
    classes: tuple[str, ...] = ACTIONS  # label names, in logit order
    in_channels: int = 90  # quaternion_root for 21 joints: 21 * 4 + 6
    hidden: int = 64  # channels of each Conv1D (Table 1 gives no size)
    kernel: int = 5  # Conv1D kernel, frames (1/6 s at 30 fps)
    fps: float = 30.0  # frame rate the inputs are resampled to (Ghorbani: 30)
    window: int = 60  # frames per training window (2 s)
    actions: tuple[str, ...] = ACTIONS  # the actions whose clips it is trained and tested on
    scale_floor: float = 0.05  # smallest per-channel scale of the input normalisation (about 6 degrees)
    drop_fixed: bool = True  # drop the training data's fixed degrees of freedom from the input (False: naive)

    @classmethod
    def for_task(cls, task: str) -> "ClassifierConfig":
        if task not in ("action", "style"):
            raise ValueError(f"task must be 'action' or 'style', got {task!r}")
        if task == "action":
            return cls(task=task, classes=ACTIONS)
        return cls(task=task, classes=STYLES, actions=STYLED_ACTIONS)


class MotionClassifier(nn.Module):
    """x: (N, T, C) quaternion_root features -> logits (N, K); `features(x)` -> (N, H) for FID."""

    def __init__(self, config: ClassifierConfig):
        super().__init__()
        self.config = config
        c, h, k = config.in_channels, config.hidden, config.kernel
        # Ghorbani Table 1: 3 x [Conv1D + ReLU] + AdaptiveAvgPool1D + FC(N_C)
        self.convs = nn.Sequential(
            nn.Conv1d(c, h, k, padding=k // 2), nn.ReLU(),
            nn.Conv1d(h, h, k, padding=k // 2), nn.ReLU(),
            nn.Conv1d(h, h, k, padding=k // 2), nn.ReLU(),
        )
        self.pool = nn.AdaptiveAvgPool1d(1)  # any input length -> one vector
        self.fc = nn.Linear(h, len(config.classes))
        self.register_buffer("mean", torch.zeros(c))  # input normalisation, set from the training set
        self.register_buffer("std", torch.ones(c))
        self.register_buffer("keep", torch.ones(c))  # 0 on the fixed degrees of freedom: dropped from the input

    def set_normalization(self, frames) -> None:
        """Input normalisation from training frames (M, C) (numpy or torch): mean, std floored at
        config.scale_floor, and keep = 0 on the channels the frames never vary (`FixedDofs`)."""
        f = torch.as_tensor(np.asarray(frames, np.float64)).reshape(-1, self.config.in_channels)
        fixed = FixedDofs.detect(f)
        self.mean.copy_(f.mean(0).float())
        self.std.copy_(f.std(0).clamp_min(self.config.scale_floor).float())
        self.keep.copy_(torch.from_numpy(~fixed.mask if self.config.drop_fixed else np.ones_like(fixed.mask)).float())

    def fixed_dofs(self):
        """The fixed degrees of freedom of the classifier's training data (`FixedDofs`: mask, constants)."""
        return FixedDofs(mask=(self.keep == 0).numpy(), values=self.mean.double().numpy())

    def features(self, x: torch.Tensor) -> torch.Tensor:
        """(N, T, C) -> (N, H) pooled activations of the last Conv1D block (FID's feature space)."""
        if x.ndim != 3 or x.shape[-1] != self.config.in_channels:
            raise ValueError(f"MotionClassifier: expected (N, T, {self.config.in_channels}), got {tuple(x.shape)}")
        z = ((x - self.mean) / self.std * self.keep).transpose(1, 2)  # (N, C, T), fixed channels dropped
        return self.pool(self.convs(z)).squeeze(-1)  # (N, H)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc(self.features(x))  # (N, K)

    def loss(self, batch: tuple[torch.Tensor, torch.Tensor]) -> dict:
        """batch = (x (N, T, C), y (N,) class indices) -> {'loss': cross-entropy, 'accuracy'}."""
        x, y = batch
        logits = self(x)
        return {"loss": nn.functional.cross_entropy(logits, y),
                "accuracy": (logits.argmax(-1) == y).float().mean()}


def checkpoint_path(task: str) -> Path:
    """checkpoints/<task>_classifier.pt of the repository."""
    return CHECKPOINT_DIR / f"{task}_classifier.pt"


def load_classifier(task: str = "action", path: str | Path | None = None) -> MotionClassifier:
    """The shipped classifier for 'action' or 'style' (eval mode), via training.load_checkpoint."""
    from course_lib.training import load_checkpoint

    ClassifierConfig.for_task(task)  # validates the name
    path = Path(path) if path is not None else checkpoint_path(task)
    if not path.exists():
        raise FileNotFoundError(f"{path} not found; build it with: python -m course_lib.evaluation.classifiers "
                                f"--train {task} --out {path}")
    return load_checkpoint(path, MotionClassifier, ClassifierConfig)


def motions_to_batch(motions: list[Motion], config: ClassifierConfig, length: int | None = None) -> np.ndarray:
    """Motions -> (N, L, C) float32 quaternion_root features at config.fps, each centre-cropped to
    L = length (default: min(config.window, shortest clip))."""
    if not motions or not all(isinstance(m, Motion) for m in motions):
        raise ValueError("motions_to_batch: expected a non-empty list of Motions")
    names = motions[0].skeleton.names
    for i, m in enumerate(motions):
        if m.skeleton.names != names:
            raise ValueError(f"motions_to_batch: clip {i} has {m.skeleton.num_joints} joints and clip 0 has "
                             f"{len(names)} (or other joint names); the classifiers read the canonical "
                             "21-joint skeleton (map a CMU clip with bvh.map_to_canonical)")
    feats = [encode_quaternion_root(m if m.fps == config.fps else m.resample(config.fps)) for m in motions]
    shortest = min(len(f) for f in feats)
    L = length or min(config.window, shortest)
    if L > shortest or L < 1:
        raise ValueError(f"motions_to_batch: crop length {L} frames but the shortest clip has {shortest} "
                         f"at {config.fps:g} fps")
    return np.stack([f[(len(f) - L) // 2:(len(f) - L) // 2 + L] for f in feats]).astype(np.float32)


def labels_of(motions: list[Motion], config: ClassifierConfig) -> np.ndarray:
    """(N,) class indices of each Motion's label named config.task; raises on a missing/unknown label."""
    values = [getattr(m, config.task) for m in motions]
    bad = sorted({str(v) for v in values if v not in config.classes})
    if bad:
        raise ValueError(f"labels_of: {config.task} labels {bad} are not among {config.classes}")
    return np.array([config.classes.index(v) for v in values])


@torch.no_grad()
def accuracy(classifier: MotionClassifier, motions: list[Motion]) -> float:
    """Fraction of motions whose label (classifier.config.task) is predicted, on centre windows."""
    x = torch.from_numpy(motions_to_batch(motions, classifier.config))
    y = torch.from_numpy(labels_of(motions, classifier.config))
    return float((classifier.eval()(x).argmax(-1) == y).float().mean())


# ----------------------------------------------------------------------------- data and training


@dataclasses.dataclass
class ClassifierData:
    """Which synthetic clips train and test the classifiers: subjects of make_subjects(num_subjects, seed).

    s00..s{n-test-1} are the training subjects (the "actions" dataset's population); the
    classifiers train on the first half of them (Ghorbani: "50% of training data"); the
    last ``test_subjects`` are held out.  Clip k = 0 of (subject, action, style) is the very
    clip of datasets.generate_actions_set; k >= 1 are extra takes with their own seeds.
    """

    num_subjects: int = 16  # population size
    test_subjects: int = 4  # the last subjects, held out for accuracy and tests
    takes: int = 3  # clips per (subject, action, style) for training
    test_takes: int = 2  # clips per (subject, action, style) for the held-out accuracy
    seed: int = 0  # population and clip seeds (datasets' default)
    generate_fps: float = 30.0  # clip frame rate (the generator works at 120 fps and resamples)

    def split(self) -> tuple[list, list]:
        """-> (classifier-training subjects, held-out subjects)."""
        from course_lib.synthetic import make_subjects

        subjects = make_subjects(self.num_subjects, self.seed)
        n_train = self.num_subjects - self.test_subjects
        return subjects[: n_train // 2], subjects[n_train:]

    def motions(self, subjects, takes: int = 1, progress: bool = False) -> list[Motion]:
        """takes clips per (subject, action, style), labelled by the generator."""
        from tqdm.auto import tqdm

        from course_lib.datasets import _clip_seed
        from course_lib.synthetic import generate_action

        jobs = [(s, a, st, k) for s in subjects for a in range(len(ACTIONS)) for st in range(len(STYLES))
                for k in range(takes)]
        out = []
        for s, a, st, k in tqdm(jobs, desc="clips", leave=False, **({} if progress else {"disable": True})):
            sid = int(s.name[1:])
            seed = _clip_seed(self.seed, sid, a, st) if k == 0 else _clip_seed(self.seed, sid, a, st, k)
            out.append(generate_action(s, ACTIONS[a], STYLES[st], fps=self.generate_fps, seed=seed))
        return out


def _window_sampler(feats: list[np.ndarray], labels: np.ndarray, window: int, batch_size: int,
                    rng: np.random.Generator):
    """-> callable returning a batch (x (B, window, C), y (B,)) of random windows of random clips."""
    def sample():
        idx = rng.integers(len(feats), size=batch_size)
        starts = [rng.integers(0, len(feats[i]) - window + 1) for i in idx]
        x = np.stack([feats[i][s:s + window] for i, s in zip(idx, starts, strict=True)]).astype(np.float32)
        return torch.from_numpy(x), torch.from_numpy(labels[idx])
    return sample


def train_classifier(task: str, data: ClassifierData | None = None, steps: int = 400, batch_size: int = 32,
                     lr: float = 5e-3, seed: int = 0, progress: bool = True, config: ClassifierConfig | None = None):
    """Train the `task` classifier on half of the training subjects; -> (model, history, held-out accuracy).

    Adam, lr 5e-3 as Ghorbani sec. 4.2, on random 2-s windows; evaluated on the centre
    window of every clip of the held-out subjects.  config: default ``ClassifierConfig.for_task(task)``
    (give another to try, e.g., the naive normalisation: scale_floor=1e-3, drop_fixed=False).
    """
    from course_lib.training import fit, seed_everything

    data = data or ClassifierData()
    config = config or ClassifierConfig.for_task(task)
    seed_everything(seed)
    train_subjects, test_subjects = data.split()
    train = [m for m in data.motions(train_subjects, data.takes, progress) if m.action in config.actions]
    feats = [encode_quaternion_root(m if m.fps == config.fps else m.resample(config.fps)) for m in train]
    window = min(config.window, min(len(f) for f in feats))
    model = MotionClassifier(dataclasses.replace(config, window=window))
    model.set_normalization(np.concatenate(feats))
    sampler = _window_sampler(feats, labels_of(train, config), window, batch_size, np.random.default_rng(seed))
    history = fit(model, sampler, steps=steps, steps_per_epoch=50, lr=lr, seed=seed, progress=progress,
                  desc=f"{task} classifier")
    test = [m for m in data.motions(test_subjects, data.test_takes, progress) if m.action in config.actions]
    return model.eval(), history, accuracy(model, test)


def _main(argv=None) -> None:
    parser = argparse.ArgumentParser(prog="python -m course_lib.evaluation.classifiers", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--train", choices=("action", "style"), help="train this classifier and save it")
    parser.add_argument("--out", help="checkpoint path (default checkpoints/<task>_classifier.pt)")
    parser.add_argument("--steps", type=int, default=400, help="optimiser steps (default 400)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--eval", action="store_true", help="print held-out accuracy of the shipped classifiers")
    args = parser.parse_args(argv)
    if not args.train and not args.eval:
        parser.error("give --train {action,style} and/or --eval")
    if args.train:
        _train_and_save(args)
    if args.eval:
        for name, acc in evaluate_shipped().items():
            print(f"{name}: held-out accuracy {acc:.4f}")


def _train_and_save(args) -> None:
    from course_lib.training import save_checkpoint

    out = Path(args.out) if args.out else checkpoint_path(args.train)
    t0 = time.perf_counter()
    model, history, acc = train_classifier(args.train, steps=args.steps, seed=args.seed)
    seconds = time.perf_counter() - t0
    shown = args.out or os.path.relpath(out, CHECKPOINT_DIR.parent)
    command = (f"python -m course_lib.evaluation.classifiers --train {args.train} --out {shown} "
               f"--steps {args.steps} --seed {args.seed}")
    save_checkpoint(model, model.config, out, command=command, overwrite=True,
                    metrics={"heldout_accuracy": round(acc, 4), "fit_seconds": round(history.seconds, 1),
                             "total_seconds": round(seconds, 1)})
    print(f"{args.train} classifier: held-out accuracy {acc:.4f}, {history.num_steps} steps in "
          f"{history.seconds:.1f} s, {seconds:.1f} s in all (data + training + evaluation) -> {out}")


def evaluate_shipped(data: ClassifierData | None = None) -> dict[str, float]:
    """Held-out accuracies of the shipped checkpoints on the clips of the actions each was trained for:
    {'action': acc, 'style': acc}."""
    data = data or ClassifierData()
    test = data.motions(data.split()[1], data.test_takes)
    out = {}
    for task in ("action", "style"):
        clf = load_classifier(task)
        out[task] = accuracy(clf, [m for m in test if m.action in clf.config.actions])
    return out


if __name__ == "__main__":
    _main()
