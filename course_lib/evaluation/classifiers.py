"""Motion classifiers for action (walk, jog, jump, lift) and style (A, B): Ghorbani et al. 2020, Table 1.

    3 x [Conv1D + ReLU] -> AdaptiveAvgPool1D -> FC(N_C)

The input is the ``quaternion_root`` representation (Ghorbani's own: 21 local
quaternions + 6 root features = 90 channels) at 30 fps, normalised with the
training set's per-channel mean and std (stored as buffers in the checkpoint).
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
the paper's gender attribute.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
import torch
from torch import nn

from course_lib.motion import Motion
from course_lib.representations import encode_quaternion_root

__all__ = ["ClassifierConfig", "MotionClassifier", "accuracy", "checkpoint_path", "load_classifier",
           "motions_to_batch"]

ACTIONS = ("walk", "jog", "jump", "lift")
STYLES = ("A", "B")
CHECKPOINT_DIR = Path(__file__).resolve().parents[2] / "checkpoints"


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

    @classmethod
    def for_task(cls, task: str) -> "ClassifierConfig":
        if task not in ("action", "style"):
            raise ValueError(f"task must be 'action' or 'style', got {task!r}")
        return cls(task=task, classes=ACTIONS if task == "action" else STYLES)


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

    def features(self, x: torch.Tensor) -> torch.Tensor:
        """(N, T, C) -> (N, H) pooled activations of the last Conv1D block (FID's feature space)."""
        if x.ndim != 3 or x.shape[-1] != self.config.in_channels:
            raise ValueError(f"MotionClassifier: expected (N, T, {self.config.in_channels}), got {tuple(x.shape)}")
        z = ((x - self.mean) / self.std).transpose(1, 2)  # (N, C, T)
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
