"""The root integration of Wang, Chai et al. eq. (4) and forward kinematics of raw ``state_features``, in torch,
so that every control energy (paper B, sec. 5.2-5.4) is differentiable with respect to the frames (BPTT).

Taught in notebooks/04_map_control.ipynb (lesson 04).  ``representations.decode_state_features`` is the numpy
decoder of the same eq. (4); tests/test_control.py checks that both give the same root path and joints.
"""

from __future__ import annotations

import torch

from course_lib.rotations import euler_to_quat
from course_lib.skeleton import Skeleton, chain_positions

__all__ = ["integrate_root", "second_pose", "world_positions", "toe_positions", "heading_yaw"]


def heading_yaw(direction) -> torch.Tensor:
    """Floor vectors (..., 2) (x, z) -> the yaw (...) that faces them: the character faces R_y(yaw) (0, 0, 1)
    = (sin yaw, cos yaw) on the floor (rest pose faces +Z)."""
    direction = torch.as_tensor(direction)
    return torch.atan2(direction[..., 0], direction[..., 1])


def integrate_root(d: torch.Tensor, dyaw: torch.Tensor, init: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Eq. (4), M_t = M_{t-1} M_t,local, for frames that follow a known frame.

    d: (..., T, 2) floor-frame displacements (dx, dz) of each frame from the one before, dyaw: (..., T),
    init: (..., 3) (x, z, yaw) of the frame before row 0 -> root_xz (..., T, 2), yaw (..., T).
    Unlike the numpy decoder, row 0 is used: it is the step from ``init`` to the first frame.
    """
    if d.shape[-1] != 2 or d.shape[:-1] != dyaw.shape or init.shape[-1] != 3:
        raise ValueError(f"integrate_root: need d (..., T, 2), dyaw (..., T), init (..., 3); got "
                         f"{tuple(d.shape)}, {tuple(dyaw.shape)}, {tuple(init.shape)}")
    init = init.to(d.dtype).expand(*d.shape[:-2], 3)  # one init for every motion, or one each
    # yaw_t = yaw_{t-1} + dyaw_t
    yaw = init[..., 2:3] + torch.cumsum(dyaw, -1)  # (..., T)
    prev_yaw = torch.cat((init[..., 2:3], yaw[..., :-1]), -1)  # (..., T)
    c, s = torch.cos(prev_yaw), torch.sin(prev_yaw)
    # p_t - p_{t-1} = R_y(yaw_{t-1}) d_t
    step = torch.stack((c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]), -1)  # (..., T, 2)
    return init[..., None, :2] + torch.cumsum(step, -2), yaw


def second_pose(raw: torch.Tensor, init0: torch.Tensor) -> torch.Tensor:
    """Two raw start frames (1, 2, D), init0 (3,) = (x, z, yaw) of frame 0 -> (3,) (x, z, yaw) of frame 1, one
    eq. (4) step from frame 0."""
    xz, yaw = integrate_root(raw[:, 1:2, 0:2], raw[:, 1:2, 2], init0[None])
    return torch.cat((xz[0, 0], yaw[0]))


def world_positions(raw: torch.Tensor, skeleton: Skeleton, init: torch.Tensor, joints=None) -> torch.Tensor:
    """Raw state features (..., T, D) of frames following the frame at init (..., 3) = (x, z, yaw)
    -> world joint positions (..., T, J', 3), metres (J' = len(joints), default every joint).

    The root rotation is R_y(yaw) R_x(pitch) R_z(roll) (representations.root_yaw_pitch_roll), the joint
    rotations the expmaps theta_2..theta_J of eq. (3); the contact bits are not used."""
    J = skeleton.num_joints
    if raw.shape[-1] != 6 + 3 * (J - 1) + 2:
        raise ValueError(f"world_positions: raw must be (..., T, {6 + 3 * (J - 1) + 2}), got {tuple(raw.shape)}")
    xz, yaw = integrate_root(raw[..., 0:2], raw[..., 2], init)
    root_q = euler_to_quat(torch.stack((yaw, raw[..., 4], raw[..., 5]), -1), "YXZ")  # (..., T, 4)
    theta = raw[..., 6:-2].unflatten(-1, (J - 1, 3))  # (..., T, J-1, 3)
    root = torch.stack((xz[..., 0], raw[..., 3], xz[..., 1]), -1)  # (..., T, 3)
    offsets = torch.as_tensor(skeleton.offsets, dtype=raw.dtype)
    want = None if joints is None else [skeleton.index(j) for j in joints]
    return chain_positions(root_q, theta, root, offsets, skeleton.parents, want)  # FK of their chains only


TOES = ("LeftToeBase", "RightToeBase")  # the contact points of eq. (18): the joints foot_skate measures


def toe_positions(raw: torch.Tensor, skeleton: Skeleton, init: torch.Tensor,
                  relative: torch.Tensor | None = None) -> torch.Tensor:
    """Raw state features (..., T, D) -> the world positions (..., T, 2, 3) of the left and right toes.
    relative: the toes relative to the root (..., T, 2, 3) (`representations.toes_relative` of raw), if known:
    then no FK, world = (x, h, z) + R_y(yaw) relative."""
    if relative is None:
        return world_positions(raw, skeleton, init, TOES)
    xz, yaw = integrate_root(raw[..., 0:2], raw[..., 2], init)
    c, s = torch.cos(yaw)[..., None], torch.sin(yaw)[..., None]  # (..., T, 1): both toes turn with the root
    rx, ry, rz = relative.unbind(-1)
    return torch.stack((xz[..., 0:1] + c * rx + s * rz, raw[..., 3:4] + ry, xz[..., 1:2] - s * rx + c * rz), -1)
