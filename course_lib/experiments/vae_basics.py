"""Lesson 01's data: single poses of the synthetic locomotion, normalised for the pose VAE.

Taught in notebooks/01_vae_basics.ipynb (section 3).  A pose is one frame of `positions_control` without
its 3 control values: 21 joint positions (63 numbers) in the character's floor frame.  Each is divided by
its subject's body scale (leg length over the canonical skeleton's: the model need not learn body size),
then the training mean is subtracted and the result divided by ONE global scale (the training poses' RMS
deviation), so that a centimetre of error costs the same on a foot as on the hips.  Clips are split by
subject; the training clips are mirrored left-right (twice the poses).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from course_lib.skeleton import Skeleton

__all__ = ["PoseData", "body_scale", "load_pose_data", "pose_table"]

LEG_BONES = slice(1, 5)  # canonical hip-to-toe chain: LeftUpLeg, LeftLeg, LeftFoot, LeftToeBase offsets


def body_scale(motion) -> float:
    """Leg length (hip to toe) of the motion's skeleton over the canonical skeleton's."""
    canonical = np.linalg.norm(Skeleton.canonical().offsets[LEG_BONES], axis=-1).sum()
    return float(np.linalg.norm(motion.skeleton.offsets[LEG_BONES], axis=-1).sum() / canonical)


def pose_table(clips) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Motions -> poses (N, 63) divided by body scale, body scale (N,), gait index (N,), every frame of every clip."""
    from course_lib.representations import encode

    P, S, G = [], [], []
    for m in clips:
        f = encode(m, "positions_control")[:, :63]  # (T, 63): joint positions in the floor frame
        gait = np.asarray(m.meta["gait"])  # per generated frame: map it to this clip's frames
        G.append(gait[np.round(np.linspace(0, len(gait) - 1, len(f))).astype(int)])
        P.append(f / body_scale(m))
        S.append(np.full(len(f), body_scale(m)))
    return np.concatenate(P), np.concatenate(S), np.concatenate(G)


@dataclass
class PoseData:
    """Normalised poses x (N, 63) float32, body scales s (N,), gaits y (N,), per split; mean (63,), std (one scale)."""

    x_train: torch.Tensor
    s_train: np.ndarray
    y_train: np.ndarray
    x_test: torch.Tensor
    s_test: np.ndarray
    y_test: np.ndarray
    mean: np.ndarray
    std: float
    train_clips: list
    test_clips: list

    def to_metres(self, x, scale) -> np.ndarray:
        """Normalised (N, 63) -> joint positions (N, 21, 3) in metres of each pose's subject (scale (N,) or one)."""
        x = x.detach().numpy() if torch.is_tensor(x) else np.asarray(x)
        return (x * self.std + self.mean).reshape(-1, 21, 3) * np.asarray(scale).reshape(-1, 1, 1)

    def joint_error_cm(self, model, x, scale, label=None) -> float:
        """Mean over poses and joints of |x - decode(mean of q(z|x))|, in cm of each subject's size."""
        x_hat = model.reconstruct(x, label)
        return float(100 * np.linalg.norm(self.to_metres(x_hat, scale) - self.to_metres(x, scale), axis=-1).mean())


def load_pose_data(n_clips: int, n_subjects: int, seed: int = 0, fps: float = 30.0) -> PoseData:
    """Generate locomotion clips, split them by subject (3:1), mirror the training clips, normalise -> PoseData."""
    from course_lib.datasets import generate_locomotion_set, split_by_subject

    clips = generate_locomotion_set(n_clips, seed=seed, fps=fps, n_subjects=n_subjects)
    train, _, test = split_by_subject(clips, fractions=(0.75, 0.0, 0.25), seed=seed)
    train = train + [m.mirror() for m in train]  # left-right mirrored copies: twice the poses
    P_train, s_train, y_train = pose_table(train)
    P_test, s_test, y_test = pose_table(test)
    mean = P_train.mean(0)  # (63,)
    std = float(np.sqrt(((P_train - mean) ** 2).mean()))  # one global scale (m)
    as_x = lambda P: torch.tensor((P - mean) / std, dtype=torch.float32)  # noqa: E731
    return PoseData(as_x(P_train), s_train, y_train, as_x(P_test), s_test, y_test, mean, std, train, test)
