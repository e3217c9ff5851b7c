"""The `Motion` container: one clip of skeletal motion and what derives from it.

A Motion holds local joint rotations (T, J, 4) as unit quaternions (w, x, y, z),
the root joint's world position (T, 3) in metres, its `Skeleton`, the frame
rate, and optional labels.  Arrays are float64 numpy; `positions()` runs the
torch forward kinematics of skeleton.py.

Taught in notebooks/00_skeletons_and_rotations.ipynb.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field, replace

import numpy as np
import torch

from course_lib.rotations import quat_slerp
from course_lib.skeleton import Skeleton, forward_kinematics

# Foot-contact thresholds (metres, metres/second), floor at y = 0.  A foot is in
# contact when its ankle or its toe joint is both low and slow.  The heights sit
# a few cm above the canonical rest heights (ankle 0.08 m, toe 0.025 m).
CONTACT_HEIGHT = {"Foot": 0.12, "ToeBase": 0.05}
CONTACT_SPEED = 0.3


@dataclass(eq=False)
class Motion:
    """rotations (T, J, 4) local unit quaternions, root_positions (T, 3) metres, skeleton, fps."""

    rotations: np.ndarray
    root_positions: np.ndarray
    skeleton: Skeleton
    fps: float
    action: str | None = None
    style: str | None = None
    subject: str | None = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        if not isinstance(self.skeleton, Skeleton):
            raise TypeError("Motion: skeleton must be a course_lib.skeleton.Skeleton, "
                            f"got {type(self.skeleton).__name__}")
        self.fps = check_fps(self.fps, "Motion")
        self.rotations = np.asarray(self.rotations, dtype=np.float64)
        self.root_positions = np.asarray(self.root_positions, dtype=np.float64)
        J = self.skeleton.num_joints
        if self.rotations.ndim != 3 or self.rotations.shape[1:] != (J, 4):
            raise ValueError(f"Motion: rotations must be (T, {J}, 4) for a {J}-joint skeleton, "
                             f"got {self.rotations.shape}")
        T = self.rotations.shape[0]
        if self.root_positions.shape != (T, 3):
            raise ValueError(f"Motion: root_positions must be ({T}, 3), got {self.root_positions.shape}")
        if not (np.isfinite(self.rotations).all() and np.isfinite(self.root_positions).all()):
            raise ValueError("Motion: rotations or root_positions contain NaN or inf")
        norms = np.linalg.norm(self.rotations, axis=-1)
        if T and np.abs(norms - 1).max() > 1e-3:
            raise ValueError(f"Motion: rotations must be unit quaternions (norms range "
                             f"{norms.min():.4f}..{norms.max():.4f})")
        self.rotations = self.rotations / norms[..., None] if T else self.rotations

    def __len__(self) -> int:
        return self.rotations.shape[0]

    @property
    def num_frames(self) -> int:
        return len(self)

    @property
    def duration(self) -> float:
        """Seconds spanned by the frames (0 for one frame or none)."""
        return max(len(self) - 1, 0) / self.fps

    def __getitem__(self, frames) -> "Motion":
        """m[t] -> a one-frame Motion (IndexError outside -T..T-1, like a sequence); m[a:b:s] -> the frames
        a, a+s, ... at fps / |s|, so the clip still plays at its real speed.  Other indices are refused."""
        T = len(self)
        fps = self.fps
        if isinstance(frames, numbers.Integral) and not isinstance(frames, bool):
            t = int(frames)
            if not -T <= t < T:
                raise IndexError(f"Motion: frame index {t} out of range for a {T}-frame motion")
            t %= T
            frames = slice(t, t + 1)
        elif isinstance(frames, slice):
            step = 1 if frames.step is None else frames.step
            if not isinstance(step, numbers.Integral) or step == 0:
                raise ValueError(f"Motion: slice step must be a non-zero integer, got {frames.step!r}")
            fps = self.fps / abs(int(step))
        else:
            raise TypeError(f"Motion: index with an integer or a slice, got {type(frames).__name__} "
                            "(frames picked at uneven times would not have one frame rate)")
        return replace(self, rotations=self.rotations[frames], root_positions=self.root_positions[frames],
                       fps=fps, meta=dict(self.meta))

    def _fk(self) -> tuple[torch.Tensor, torch.Tensor]:
        # The arrays can be written after construction: check again before any value is derived from them.
        if not np.isfinite(self.root_positions).all():
            raise ValueError("Motion: root_positions contain NaN or inf (written after the Motion was made?)")
        if not np.isfinite(self.rotations).all():
            raise ValueError("Motion: rotations contain NaN or inf (written after the Motion was made?)")
        return forward_kinematics(torch.from_numpy(self.rotations), torch.from_numpy(self.root_positions),
                                  torch.from_numpy(self.skeleton.offsets), self.skeleton.parents)

    def positions(self) -> np.ndarray:
        """(T, J, 3) world joint positions, metres."""
        return self._fk()[0].numpy()

    def global_rotations(self) -> np.ndarray:
        """(T, J, 4) world rotations of each joint."""
        return self._fk()[1].numpy()

    def contacts(self) -> np.ndarray:
        """(T, 2) bool foot contacts (left, right), from joint heights and speeds; see CONTACT_*."""
        return foot_contacts(self.positions(), self.skeleton, self.fps)

    def resample(self, fps: float) -> "Motion":
        """The same motion at another frame rate: slerp for rotations, linear for the root."""
        fps = check_fps(fps, "resample")
        T = len(self)
        if T == 0:
            return replace(self, fps=float(fps), meta=dict(self.meta))
        n = int(np.floor(self.duration * fps + 1e-9)) + 1
        t = np.arange(n) * (self.fps / fps)  # new frame times in old frame units
        i0 = np.clip(np.floor(t).astype(int), 0, T - 1)
        i1 = np.clip(i0 + 1, 0, T - 1)
        a = t - i0
        rot = torch.from_numpy(self.rotations)
        q = quat_slerp(rot[i0], rot[i1], torch.from_numpy(a)[:, None].expand(n, rot.shape[1]))
        root = (1 - a)[:, None] * self.root_positions[i0] + a[:, None] * self.root_positions[i1]
        return replace(self, rotations=q.numpy(), root_positions=root, fps=float(fps), meta=dict(self.meta))

    def mirror(self) -> "Motion":
        """Left-right mirror image (reflection x -> -x); exact for a symmetric skeleton."""
        m = list(self.skeleton.mirror_map)
        # Reflecting space by diag(-1, 1, 1) maps a rotation (w, x, y, z) to (w, x, -y, -z).
        rot = self.rotations[:, m] * np.array([1.0, 1.0, -1.0, -1.0])
        root = self.root_positions * np.array([-1.0, 1.0, 1.0])
        return replace(self, rotations=rot, root_positions=root, meta=dict(self.meta, mirrored=True))

    def retarget(self, skeleton: Skeleton) -> "Motion":
        """The same joint rotations on ``skeleton`` (same joints and hierarchy), the root path scaled by the
        ratio of the two leg lengths so that strides and the hip height fit the new legs: what a retargeted
        mocap set does to put every performer on one body."""
        if skeleton.names != self.skeleton.names or skeleton.parents != self.skeleton.parents:
            raise ValueError("retarget: the skeleton must have the same joints and hierarchy "
                             f"({self.skeleton.num_joints} joints here, {skeleton.num_joints} given)")
        ratio = skeleton.leg_length() / self.skeleton.leg_length()
        return replace(self, root_positions=self.root_positions * ratio, skeleton=skeleton,
                       meta=dict(self.meta, retargeted_from=self.subject, root_scale=ratio))

    def __repr__(self) -> str:
        labels = ", ".join(f"{k}={v!r}" for k, v in
                           (("action", self.action), ("style", self.style), ("subject", self.subject)) if v)
        tail = f", {labels}" if labels else ""
        return f"Motion({len(self)} frames @ {self.fps:g} fps, {self.skeleton.num_joints} joints{tail})"


def check_fps(fps, name: str) -> float:
    """A frame rate as a float: a finite number > 0, else a ValueError that names ``name`` and the value."""
    try:
        value = None if isinstance(fps, (bool, str, bytes)) else float(fps)
    except (TypeError, ValueError):
        value = None
    if value is None or not math.isfinite(value) or not value > 0:
        raise ValueError(f"{name}: fps must be positive and finite (frames per second), got {fps!r}")
    return value


STANCE_MAX_ABOVE = 0.05  # m: a toe flagged in contact this far above the other toe is in the air


def trusted_contacts(bits, toe_heights, max_above: float = STANCE_MAX_ABOVE):
    """Contact bits (..., 2) of the two toes and the toes' heights (..., 2) -> the bits the pose can support: a toe
    flagged more than ``max_above`` (m) above the other toe is in the air, so its bit is dropped (mocap's flagged toes
    are within 4 cm of the other toe in 99 % of frames).  numpy arrays or torch tensors (the type of the inputs)."""
    if torch.is_tensor(toe_heights):
        lower = toe_heights.min(-1, keepdim=True).values
    else:
        lower = np.min(toe_heights, axis=-1, keepdims=True)
    return bits & (toe_heights <= lower + max_above)


def foot_contacts(positions: np.ndarray, skeleton: Skeleton, fps: float, speed: float = CONTACT_SPEED) -> np.ndarray:
    """positions (..., T, J, 3) -> (..., T, 2) bool contacts (left, right).

    A foot touches the floor on a frame where its ankle (`Foot`) or toe joint
    (`ToeBase`) is below CONTACT_HEIGHT and moves slower than ``speed`` (m/s, default CONTACT_SPEED;
    central differences; one-sided at the ends).
    """
    positions = np.asarray(positions)
    vel = np.gradient(positions, axis=-3) * fps if positions.shape[-3] > 1 else np.zeros_like(positions)
    joint_speed = np.linalg.norm(vel, axis=-1)  # (..., T, J)
    out = []
    for side in ("Left", "Right"):
        touch = np.zeros(positions.shape[:-2], dtype=bool)
        for part, h in CONTACT_HEIGHT.items():
            j = skeleton.index(side + part)
            touch |= (positions[..., j, 1] < h) & (joint_speed[..., j] < speed)
        out.append(touch)
    return np.stack(out, -1)
