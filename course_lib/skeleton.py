"""Skeletons and forward kinematics.

A `Skeleton` is a tree of joints: names, a parents array (parent index before
child, root first with parent -1), rest offsets of each joint from its parent
in metres, and End Site offsets (BVH's end effectors, not joints).

The canonical skeleton of the course has 21 CMU-like joints; Y is up and the
character faces +Z at rest, so its left side is +X.  Rest pose: standing
straight, arms stretched sideways (T-pose, as in CMU files).

Taught in notebooks/00_skeletons_and_rotations.ipynb.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
import torch

from course_lib.rotations import check_unit, expmap_to_matrix, quat_mul, quat_rotate, quat_to_matrix

CANONICAL_JOINTS = (
    "Hips",
    "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase",
    "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase",
    "Spine", "Spine1", "Neck", "Head",
    "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
    "RightShoulder", "RightArm", "RightForeArm", "RightHand",
)
CANONICAL_PARENTS = (-1, 0, 1, 2, 3, 0, 5, 6, 7, 0, 9, 10, 11, 10, 13, 14, 15, 10, 17, 18, 19)

# Rest offsets (metres) of an adult about 1.75 m tall; hips 0.96 m above the floor,
# ankles 0.08 m, toe joints (ball of the foot) 0.025 m.
_CANONICAL_OFFSETS = (
    (0.0, 0.0, 0.0),
    (0.09, -0.055, 0.0), (0.0, -0.415, 0.0), (0.0, -0.41, 0.0), (0.0, -0.055, 0.13),
    (-0.09, -0.055, 0.0), (0.0, -0.415, 0.0), (0.0, -0.41, 0.0), (0.0, -0.055, 0.13),
    (0.0, 0.11, 0.0), (0.0, 0.19, 0.0), (0.0, 0.21, 0.0), (0.0, 0.10, 0.02),
    (0.035, 0.17, 0.0), (0.14, 0.0, 0.0), (0.28, 0.0, 0.0), (0.25, 0.0, 0.0),
    (-0.035, 0.17, 0.0), (-0.14, 0.0, 0.0), (-0.28, 0.0, 0.0), (-0.25, 0.0, 0.0),
)
_CANONICAL_END_SITES = {
    "LeftToeBase": (0.0, 0.0, 0.06), "RightToeBase": (0.0, 0.0, 0.06),
    "Head": (0.0, 0.12, 0.0), "LeftHand": (0.09, 0.0, 0.0), "RightHand": (-0.09, 0.0, 0.0),
}


@dataclass(frozen=True, eq=False)
class Skeleton:
    """names (J,), parents (J,) with parents[j] < j, offsets (J, 3) metres, end_sites {joint: (3,)}."""

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    end_sites: dict[int, np.ndarray] = field(default_factory=dict)

    def __post_init__(self):
        offsets = np.asarray(self.offsets, dtype=np.float64)
        J = len(self.names)
        if offsets.shape != (J, 3):
            raise ValueError(f"Skeleton: offsets must be ({J}, 3) for {J} joints, got {offsets.shape}")
        if len(self.parents) != J:
            raise ValueError(f"Skeleton: {len(self.parents)} parents for {J} joints")
        if self.parents[0] != -1 or any(not (0 <= p < j) for j, p in enumerate(self.parents) if j):
            raise ValueError("Skeleton: parents must list the root first (-1) and each parent before its child")
        if not np.isfinite(offsets).all():
            raise ValueError("Skeleton: offsets contain NaN or inf")
        if len(set(self.names)) != J:
            raise ValueError("Skeleton: joint names must be unique")
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "parents", tuple(int(p) for p in self.parents))
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "end_sites", {int(k): np.asarray(v, np.float64) for k, v in self.end_sites.items()})

    @classmethod
    def canonical(cls) -> "Skeleton":
        """The course's 21-joint skeleton."""
        idx = {n: i for i, n in enumerate(CANONICAL_JOINTS)}
        ends = {idx[n]: np.array(v) for n, v in _CANONICAL_END_SITES.items()}
        return cls(CANONICAL_JOINTS, CANONICAL_PARENTS, np.array(_CANONICAL_OFFSETS), ends)

    @property
    def num_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"Skeleton has no joint named {name!r}; joints: {', '.join(self.names)}") from None

    def children(self, j: int) -> list[int]:
        return [c for c, p in enumerate(self.parents) if p == j]

    def bone_lengths(self) -> np.ndarray:
        """(J,) length of the bone from each joint's parent to it (0 for the root)."""
        return np.linalg.norm(self.offsets, axis=-1)

    @property
    def mirror_map(self) -> tuple[int, ...]:
        """(J,) index of each joint's left/right counterpart (itself on the midline)."""
        def swap(n: str) -> str:
            if n.startswith("Left"):
                return "Right" + n[4:]
            if n.startswith("Right"):
                return "Left" + n[5:]
            return n
        return tuple(self.names.index(swap(n)) if swap(n) in self.names else j
                     for j, n in enumerate(self.names))

    @property
    def end_effectors(self) -> tuple[int, ...]:
        """Joints with no children (feet's toes, hands, head)."""
        return tuple(j for j in range(self.num_joints) if not self.children(j))

    @property
    def feet(self) -> tuple[int, int, int, int]:
        """(LeftFoot, LeftToeBase, RightFoot, RightToeBase) indices."""
        return tuple(self.index(n) for n in ("LeftFoot", "LeftToeBase", "RightFoot", "RightToeBase"))

    def scaled(self, factors: float | np.ndarray) -> "Skeleton":
        """A skeleton with each bone scaled: a float, or (J,) per-joint factors."""
        f = np.broadcast_to(np.asarray(factors, np.float64), (self.num_joints,))
        ends = {j: v * f[j] for j, v in self.end_sites.items()}
        return Skeleton(self.names, self.parents, self.offsets * f[:, None], ends)

    def leg_length(self) -> float:
        """Rest-pose height of the root above the lower toe joint (m): how long the legs are."""
        rest = self.fk(torch.tensor([1.0, 0.0, 0.0, 0.0], dtype=torch.float64).expand(self.num_joints, 4),
                       torch.zeros(3, dtype=torch.float64))
        toes = [self.index(n) for n in ("LeftToeBase", "RightToeBase")]
        return float(-rest[toes, 1].min())

    def fk(self, rotations, root_positions) -> torch.Tensor:
        """Positions of this skeleton's joints, see `forward_kinematics`."""
        rot = torch.as_tensor(rotations)
        off = torch.as_tensor(self.offsets, dtype=rot.dtype)
        return forward_kinematics(rot, torch.as_tensor(root_positions, dtype=rot.dtype), off, self.parents)[0]

    def __repr__(self) -> str:
        return f"Skeleton({self.num_joints} joints, root {self.names[0]!r})"


@lru_cache(maxsize=64)
def chain_subset(parents: tuple[int, ...], joints: tuple[int, ...]) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The joints and every ancestor of theirs, in skeleton order (the root first), and their parents re-indexed
    within that list: forward kinematics of these alone gives the same positions for them (the toes of the
    canonical skeleton need 9 joints in 4 levels, not 21 in 6)."""
    keep = set()
    for j in joints:
        if not 0 <= j < len(parents):
            raise ValueError(f"chain_subset: joint {j} is not one of the {len(parents)} joints")
        while j >= 0 and j not in keep:
            keep.add(j)
            j = parents[j]
    idx = tuple(sorted(keep))
    at = {j: i for i, j in enumerate(idx)}
    return idx, tuple(-1 if parents[j] < 0 else at[parents[j]] for j in idx)


def chain_positions(root_rotation: torch.Tensor, expmaps: torch.Tensor, root_positions: torch.Tensor,
                    offsets: torch.Tensor, parents, joints=None) -> torch.Tensor:
    """Forward kinematics of some joints over their chains only (`chain_subset`): root_rotation (..., 4) a unit
    quaternion, expmaps (..., J-1, 3) the local rotations of joints 1..J-1 (eq. 3 of Wang et al.), root_positions
    (..., 3), offsets (J, 3) or (..., J, 3), joints: indices (default every joint) -> positions (..., len(joints), 3),
    the same as `forward_kinematics`' for those joints.

    With rotation matrices (Rodrigues), one matrix product per depth level for the rotations and one for the
    offsets: the control energies of lesson 04 run this inside every rollout and its gradient, where the
    quaternion chain's few dozen small operations per level took twice as long (forward + backward)."""
    J = len(parents)
    want = tuple(range(J)) if joints is None else tuple(int(j) for j in joints)
    idx, sub = chain_subset(tuple(int(p) for p in parents), want)
    chain = expmaps[..., [j - 1 for j in idx[1:]], :]
    if not bool(torch.isfinite(chain.detach()).all()):  # a NaN angle would give NaN positions, not an error
        raise ValueError("chain_positions: the expmaps contain NaN or inf")
    local = expmap_to_matrix(chain)  # (..., n-1, 3, 3)
    order, steps, inverse = _depth_levels(sub)
    rot = torch.cat((quat_to_matrix(root_rotation).unsqueeze(-3), local), -3).index_select(-3, order)
    off = offsets[..., list(idx), :].to(rot.dtype).index_select(-2, order)[..., None]  # (..., n, 3, 1) level order
    glob, pos = [rot[..., :1, :, :]], [root_positions.unsqueeze(-2)]  # level 0: the root
    for start, L, parent_sel in steps:
        parent_rot = _take(glob[-1], parent_sel, -3)  # (..., L, 3, 3)
        # x_j = x_p + R_p o_j ;  R_j = R_p r_j
        pos.append(_take(pos[-1], parent_sel, -2) + (parent_rot @ off[..., start:start + L, :, :])[..., 0])
        glob.append(parent_rot @ rot[..., start:start + L, :, :])
    pick = torch.tensor([int(inverse[idx.index(j)]) for j in want])  # level order -> the joints asked for
    return torch.cat(pos, -2).index_select(-2, pick)


@lru_cache(maxsize=64)
def _depth_levels(parents: tuple[int, ...]) -> tuple[torch.Tensor, list[tuple[int, int, object]], torch.Tensor]:
    """Joints grouped by depth in the tree; each level's parents all sit in the level above.

    -> order (J,): joints in level order; per level >= 1: (start in level order, size L,
    parents' positions within the level above as a slice (one shared parent, or consecutive
    ones) or an index tensor); inverse (J,): each joint's position in level order.
    """
    depth: list[int] = []
    for p in parents:
        depth.append(0 if p < 0 else depth[p] + 1)
    levels = [[j for j, d in enumerate(depth) if d == k] for k in range(max(depth) + 1)]
    within = {j: i for lv in levels for i, j in enumerate(lv)}
    steps, start = [], 1
    for lv in levels[1:]:
        ps = [within[parents[j]] for j in lv]
        if len(set(ps)) == 1:  # one shared parent: a (1, ...) view that broadcasts
            sel = slice(ps[0], ps[0] + 1)
        elif ps == list(range(ps[0], ps[0] + len(ps))):
            sel = slice(ps[0], ps[0] + len(ps))
        else:
            sel = torch.tensor(ps)
        steps.append((start, len(lv), sel))
        start += len(lv)
    order = [j for lv in levels for j in lv]
    return torch.tensor(order), steps, torch.tensor([order.index(j) for j in range(len(parents))])


def _take(x: torch.Tensor, sel, dim: int = 0) -> torch.Tensor:
    """Rows of x along dim by a slice (a view, no copy) or an index tensor."""
    if isinstance(sel, slice):
        return x[(slice(None),) * (dim % x.dim()) + (sel,)]
    return x.index_select(dim, sel)


def forward_kinematics(
    rotations: torch.Tensor, root_positions: torch.Tensor, offsets: torch.Tensor, parents
) -> tuple[torch.Tensor, torch.Tensor]:
    """Local joint rotations -> world joint positions and global rotations.

    rotations: (..., J, 4) local unit quaternions; root_positions: (..., 3) world
    position of joint 0; offsets: (J, 3) or (..., J, 3) rest offsets; parents: (J,)
    -> positions (..., J, 3), global rotations (..., J, 4).  Tensors or numpy arrays (converted);
    a zero, NaN or non-unit rotation (| |q| - 1 | > rotations.UNIT_TOL) raises ValueError,
    because it would stretch the bones (doubled quaternions make a thigh 4x as long).

    Joints of equal depth are done together (6 steps for the canonical skeleton, not
    20) on a (J, 4, B) layout, so each step is a few dozen vectorised ops over B frames.
    """
    rotations, root_positions, offsets = (torch.from_numpy(np.ascontiguousarray(x)) if isinstance(x, np.ndarray)
                                          else x for x in (rotations, root_positions, offsets))
    J = len(parents)
    if rotations.shape[-2:] != (J, 4):
        raise ValueError(f"forward_kinematics: rotations must be (..., {J}, 4), got {tuple(rotations.shape)}")
    lead = rotations.shape[:-2]
    if root_positions.shape != lead + (3,):
        raise ValueError(f"forward_kinematics: root_positions must be {tuple(lead) + (3,)}, "
                         f"got {tuple(root_positions.shape)}")
    if offsets.shape[-2:] != (J, 3):
        raise ValueError(f"forward_kinematics: offsets must be ({J}, 3) or (..., {J}, 3), got {tuple(offsets.shape)}")
    check_unit(rotations, "forward_kinematics rotations")
    order, steps, inverse = _depth_levels(tuple(int(p) for p in parents))
    q = rotations.reshape(-1, J, 4).permute(1, 2, 0).index_select(0, order)  # (J, 4, B) in level order
    off = offsets.to(rotations.dtype)
    if off.dim() == 2:
        o = off.index_select(0, order)[:, :, None]  # (J, 3, 1), broadcast over frames
    else:
        o = off.expand(*lead, J, 3).reshape(-1, J, 3).permute(1, 2, 0).index_select(0, order)  # (J, 3, B)
    glob, pos = [q[:1]], [root_positions.reshape(1, -1, 3).transpose(1, 2)]  # level 0: the root
    for start, L, parent_sel in steps:
        parent_rot = _take(glob[-1], parent_sel)  # (L, 4, B)
        # x_j = x_p + R_p o_j ;  R_j = R_p r_j
        pos.append(_take(pos[-1], parent_sel) + quat_rotate(parent_rot, o[start:start + L], dim=1))
        glob.append(quat_mul(parent_rot, q[start:start + L], dim=1))
    # back to joint order; the (B, J, .) results are views of (J, ., B) buffers, not copies
    positions = torch.cat(pos, 0).index_select(0, inverse).permute(2, 0, 1)  # (B, J, 3)
    rots = torch.cat(glob, 0).index_select(0, inverse).permute(2, 0, 1)  # (B, J, 4)
    return positions.reshape(*lead, J, 3), rots.reshape(*lead, J, 4)
