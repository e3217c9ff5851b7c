"""Feature representations of a `Motion`, each invertible: Motion -> (T, D) features -> Motion / positions.

Three representations, one per family of papers (see DESIGN.md):

- ``positions_control`` (Habibie et al. 2017 sec. 4.1, paper A; MoGlow sec. 5,
  paper D): 21 joint positions in the character's floor frame (63) + control
  (3): forward velocity, sideways velocity (m/s), yaw rate (rad/s).  Positions
  only, so it decodes to joint positions (T, J, 3), not to rotations.
  (MoGlow's control is the per-frame displacement: ours divided by fps.)
- ``state_features`` (Wang, Chai et al. 2021, paper B, eq. 3): dx, dz, dyaw
  (root displacement and heading change per frame in the previous frame's
  floor frame), root height, root pitch and roll, the 20 non-root joints'
  local rotations as expmaps (60), 2 foot-contact bits (68 for 21 joints).
  Decodes with the global-transform integration of eq. 4.
- ``quaternion_root`` (Ghorbani et al. 2020 sec. 3.1, paper C): the 21 local
  quaternions (84; the root's with its heading removed) + 6 root features:
  forward velocity, sideways velocity (m/s), root height, yaw rate (rad/s),
  pitch, roll (90 for 21 joints).  Differs from the paper: the initial facing
  direction is +Z (the course's convention), not +X.

Conventions, stated once:

- Heading (yaw) of the character: the Hips' forward axis (+Z) rotated by the
  root rotation and projected on the floor, ``yaw = atan2(f_x, f_z)``; facing
  +X is yaw = +pi/2.  The root rotation splits exactly as
  ``R_y(yaw) R_x(pitch) R_z(roll)`` (intrinsic Euler 'YXZ' of rotations.py), so
  pitch and roll are the root's tilt relative to the heading frame.  (Holden et
  al. take the heading from the hip/shoulder across vectors instead; the Hips'
  forward axis gives the same direction up to the pelvis' own yaw sway, and
  makes the split exact.)
- Floor frame of frame t: origin at the root's floor projection (x_t, 0, z_t),
  axes rotated by yaw_t: local +Z is forward, local +X the character's left.
- Root motion is the displacement from frame t-1 to frame t expressed in the
  floor frame of frame t-1, and yaw_t - yaw_{t-1} wrapped to [-pi, pi)
  (Wang eq. 4: M_t = M_{t-1} M_t,local).  Frame 0 has no predecessor: it
  repeats frame 1's value, and decoding ignores it; the decoders start from
  ``init = (x0, z0, yaw0)``, the first frame's floor transform (`root_start`).
  Velocities are per second (displacement x fps) in positions_control and
  quaternion_root, per frame in state_features (as in the paper).

Lesson 03's RNN reads the state features *anchored on the feet* (`anchor_on_feet` / `unanchor_feet`,
torch, on a given skeleton): the root's floor step replaced by the slip of the lower toe, the root height by
the lower toe's height.  `local_positions` is the torch FK of the state features in each frame's floor frame,
`root_trajectory` their root path (eq. 4) in torch.

Every encoder returns float64; round trips reproduce joint positions to
float64 precision (tests/test_representations.py checks 1e-4 m).

Taught in notebooks/00_data_and_skeletons.ipynb.
"""

from __future__ import annotations

import numpy as np
import torch

from course_lib.motion import Motion, foot_contacts
from course_lib.rotations import (
    euler_to_quat,
    expmap_to_quat,
    matrix_to_quat,
    quat_canonical,
    quat_to_euler,
    quat_to_expmap,
)
from course_lib.skeleton import Skeleton

REPRESENTATIONS = ("positions_control", "state_features", "quaternion_root")
CONTROL_NAMES = ("vel_forward", "vel_sideways", "yaw_rate")
STATE_ROOT_NAMES = ("dx", "dz", "dyaw", "root_height", "root_pitch", "root_roll")
CONTACT_NAMES = ("contact_left", "contact_right")
QUAT_ROOT_NAMES = ("vel_forward", "vel_sideways", "root_height", "yaw_rate", "root_pitch", "root_roll")
DIMS = {"positions_control": 66, "state_features": 68, "quaternion_root": 90}  # canonical 21 joints


def feature_dim(name: str, num_joints: int = 21) -> int:
    """Feature count D of a representation for a skeleton of num_joints joints (66, 68, 90 for 21)."""
    dims = {"positions_control": 3 * num_joints + 3, "state_features": 6 + 3 * (num_joints - 1) + 2,
            "quaternion_root": 4 * num_joints + 6}
    return dims[_check_name(name)]


def feature_names(name: str, skeleton: Skeleton | None = None) -> list[str]:
    """The D feature names of a representation, in column order (canonical skeleton by default)."""
    names = (skeleton or Skeleton.canonical()).names
    if _check_name(name) == "positions_control":
        return [f"{j}_{a}" for j in names for a in "xyz"] + list(CONTROL_NAMES)
    if name == "state_features":
        return list(STATE_ROOT_NAMES) + [f"{j}_r{a}" for j in names[1:] for a in "xyz"] + list(CONTACT_NAMES)
    return [f"{j}_q{a}" for j in names for a in "wxyz"] + list(QUAT_ROOT_NAMES)


def _check_name(name: str) -> str:
    if name not in REPRESENTATIONS:
        raise ValueError(f"unknown representation {name!r}; choose one of {', '.join(REPRESENTATIONS)}")
    return name


def _check_features(features, name: str, num_joints: int) -> np.ndarray:
    f = np.asarray(features, dtype=np.float64)
    D = feature_dim(name, num_joints)
    if f.ndim != 2 or f.shape[1] != D or f.shape[0] < 1:
        raise ValueError(f"{name}: features must be (T, {D}) for {num_joints} joints, got {f.shape}")
    if not np.isfinite(f).all():
        raise ValueError(f"{name}: features contain NaN or inf")
    return f


# --- the root's floor frame -------------------------------------------------------------


def root_yaw_pitch_roll(motion: Motion) -> np.ndarray:
    """motion -> (T, 3) (yaw, pitch, roll) of the root rotation, R = R_y(yaw) R_x(pitch) R_z(roll); yaw = heading."""
    return quat_to_euler(torch.from_numpy(motion.rotations[:, 0]), "YXZ").numpy()


def _to_floor_frame(v_xz: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """World (x, z) vectors (..., 2), yaw (...) -> the same vectors in the floor frame, R_y(-yaw) v."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack((c * v_xz[..., 0] - s * v_xz[..., 1], s * v_xz[..., 0] + c * v_xz[..., 1]), -1)


def _to_world(v_xz: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Floor-frame (x, z) vectors (..., 2), yaw (...) -> world, R_y(yaw) v."""
    return _to_floor_frame(v_xz, -yaw)


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angles -> [-pi, pi)."""
    return (a + np.pi) % (2 * np.pi) - np.pi


def root_start(motion: Motion) -> tuple[float, float, float]:
    """The first frame's floor transform (x0, z0, yaw0), the decoders' ``init``."""
    yaw0 = float(root_yaw_pitch_roll(motion[:1])[0, 0])
    return float(motion.root_positions[0, 0]), float(motion.root_positions[0, 2]), yaw0


def root_deltas(root_xz: np.ndarray, yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """root_xz (T, 2), yaw (T,) -> per-frame displacement (T, 2) (sideways, forward) in the previous
    floor frame, and yaw change (T,) wrapped to [-pi, pi); frame 0 repeats frame 1 (zeros if T == 1)."""
    T = len(yaw)
    if T < 2:
        return np.zeros((T, 2)), np.zeros(T)
    d = _to_floor_frame(np.diff(root_xz, axis=0), yaw[:-1])  # (T-1, 2)
    dyaw = _wrap(np.diff(yaw))  # (T-1,)
    return np.concatenate((d[:1], d)), np.concatenate((dyaw[:1], dyaw))


def integrate_root(d: np.ndarray, dyaw: np.ndarray, init=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """The inverse of `root_deltas`, Wang eq. (4): M_t = M_{t-1} M_t,local from M_0 = init.

    d (T, 2) per-frame floor-frame displacements, dyaw (T,) -> root_xz (T, 2), yaw (T,) (unwrapped).
    Row 0 of d and dyaw is ignored: frame 0 sits at init = (x0, z0, yaw0).
    """
    x0, z0, yaw0 = (float(v) for v in init)
    yaw = yaw0 + np.concatenate(([0.0], np.cumsum(dyaw[1:])))  # yaw_t = yaw_{t-1} + dyaw_t
    step = _to_world(d[1:], yaw[:-1])  # p_t - p_{t-1} = R_y(yaw_{t-1}) d_t
    xz = np.array([x0, z0]) + np.concatenate((np.zeros((1, 2)), np.cumsum(step, axis=0)))
    return xz, yaw


def _root_motion(motion: Motion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """motion -> ypr (T, 3), floor displacement per frame (T, 2) (sideways, forward), dyaw (T,)."""
    ypr = root_yaw_pitch_roll(motion)
    d, dyaw = root_deltas(motion.root_positions[:, [0, 2]], ypr[:, 0])
    return ypr, d, dyaw


def _assemble(skeleton: Skeleton, fps: float, xz, height, ypr, local_rot) -> Motion:
    """Root floor position (T, 2), height (T,), root (yaw, pitch, roll) (T, 3), non-root local quats
    (T, J-1, 4) -> Motion."""
    root_q = euler_to_quat(torch.from_numpy(ypr), "YXZ").numpy()  # R_y(yaw) R_x(pitch) R_z(roll)
    rot = np.concatenate((root_q[:, None], local_rot), axis=1)
    root = np.stack((xz[:, 0], height, xz[:, 1]), -1)
    return Motion(rot, root, skeleton, fps)


# --- positions_control (papers A, D) ----------------------------------------------------


def encode_positions_control(motion: Motion) -> np.ndarray:
    """motion -> (T, 3J + 3): joint positions in the floor frame, then (vel_forward, vel_sideways, yaw_rate)
    in m/s and rad/s (Habibie et al. 2017 sec. 4.1; MoGlow sec. 5)."""
    ypr, d, dyaw = _root_motion(motion)
    pos = motion.positions()  # (T, J, 3) world
    rel = pos - motion.root_positions[:, None] * np.array([1.0, 0.0, 1.0])  # relative to floor projection
    local_xz = _to_floor_frame(rel[..., [0, 2]], ypr[:, 0:1])  # (T, J, 2)
    local = np.stack((local_xz[..., 0], rel[..., 1], local_xz[..., 1]), -1)  # (T, J, 3)
    control = np.stack((d[:, 1], d[:, 0], dyaw), -1) * motion.fps  # (T, 3) per second
    return np.concatenate((local.reshape(len(motion), -1), control), axis=1)


def decode_positions(features, fps: float, start=(0.0, 0.0, 0.0)) -> np.ndarray:
    """positions_control features (T, 3J + 3) -> world joint positions (T, J, 3).

    Integrates the control (per second, so fps is needed) from start = (x0, z0, yaw0)
    to the root's floor path, then places the floor-frame positions in the world.
    """
    f = np.asarray(features, dtype=np.float64)
    if f.ndim != 2 or (f.shape[1] - 3) % 3 or f.shape[1] < 6:
        raise ValueError(f"positions_control: features must be (T, 3J + 3), got {f.shape}")
    f = _check_features(f, "positions_control", (f.shape[1] - 3) // 3)
    local = f[:, :-3].reshape(len(f), -1, 3)
    vel_fwd, vel_side, yaw_rate = (f[:, -3 + i] / fps for i in range(3))
    xz, yaw = integrate_root(np.stack((vel_side, vel_fwd), -1), yaw_rate, start)
    world_xz = _to_world(local[..., [0, 2]], yaw[:, None]) + xz[:, None]
    return np.stack((world_xz[..., 0], local[..., 1], world_xz[..., 1]), -1)


def decode_positions_control(features, skeleton: Skeleton, fps: float, init=(0.0, 0.0, 0.0)) -> np.ndarray:
    """The common decode signature for positions_control: -> positions (T, J, 3) (no rotations exist)."""
    f = _check_features(features, "positions_control", skeleton.num_joints)
    return decode_positions(f, fps, init)


# --- state_features (paper B) -----------------------------------------------------------


def encode_state_features(motion: Motion) -> np.ndarray:
    """motion -> (T, 6 + 3(J-1) + 2) = [dx, dz, dyaw, t_y, pitch, roll, theta_2..theta_J (expmap), contacts].

    Wang et al. eq. (3): dx, dz, dyaw per frame in the previous frame's floor frame.
    """
    ypr, d, dyaw = _root_motion(motion)
    theta = quat_to_expmap(torch.from_numpy(motion.rotations[:, 1:])).numpy()  # (T, J-1, 3)
    contacts = foot_contacts(motion.positions(), motion.skeleton, motion.fps).astype(np.float64)  # (T, 2)
    root = np.column_stack((d[:, 0], d[:, 1], dyaw, motion.root_positions[:, 1], ypr[:, 1], ypr[:, 2]))
    return np.concatenate((root, theta.reshape(len(motion), -1), contacts), axis=1)


def decode_state_features(features, skeleton: Skeleton, fps: float, init=(0.0, 0.0, 0.0)) -> Motion:
    """(T, 6 + 3(J-1) + 2) -> Motion, integrating the root with Wang eq. (4) from init = (x0, z0, yaw0).

    The contact bits are not needed to decode (they are derived from the pose).
    """
    f = _check_features(features, "state_features", skeleton.num_joints)
    xz, yaw = integrate_root(f[:, 0:2], f[:, 2], init)
    ypr = np.column_stack((yaw, f[:, 4], f[:, 5]))
    local = expmap_to_quat(torch.from_numpy(f[:, 6:-2].reshape(len(f), -1, 3))).numpy()
    return _assemble(skeleton, fps, xz, f[:, 3], ypr, local)


# --- quaternion_root (paper C) ----------------------------------------------------------


def _continuous(q: np.ndarray) -> np.ndarray:
    """(T, J, 4) -> the same rotations with signs chosen so consecutive frames have q_t . q_{t-1} >= 0."""
    c = quat_canonical(torch.from_numpy(q)).numpy()
    flip = np.concatenate((np.zeros((1, q.shape[1])), (c[1:] * c[:-1]).sum(-1) < 0))
    return c * np.where(np.cumsum(flip, axis=0) % 2, -1.0, 1.0)[..., None]


def encode_quaternion_root(motion: Motion) -> np.ndarray:
    """motion -> (T, 4J + 6): local quaternions (root: R_x(pitch) R_z(roll), its heading removed), then
    (vel_forward, vel_sideways, root_height, yaw_rate, pitch, roll) in m/s, m, rad/s, rad (Ghorbani sec. 3.1).

    Quaternion signs are made continuous in time (first frame w >= 0).
    """
    ypr, d, dyaw = _root_motion(motion)
    q = motion.rotations.copy()
    q[:, 0] = euler_to_quat(torch.from_numpy(np.column_stack((0 * ypr[:, 0], ypr[:, 1:]))), "YXZ").numpy()
    root = np.column_stack((d[:, 1] * motion.fps, d[:, 0] * motion.fps, motion.root_positions[:, 1],
                            dyaw * motion.fps, ypr[:, 1], ypr[:, 2]))
    return np.concatenate((_continuous(q).reshape(len(motion), -1), root), axis=1)


def decode_quaternion_root(features, skeleton: Skeleton, fps: float, init=(0.0, 0.0, 0.0)) -> Motion:
    """(T, 4J + 6) -> Motion; quaternions are normalised.  The root's tilt comes from its quaternion
    (pitch/roll features are redundant inputs for the model), its heading from the integrated yaw rate."""
    f = _check_features(features, "quaternion_root", skeleton.num_joints)
    q = f[:, :-6].reshape(len(f), -1, 4)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if (norm < 1e-6).any():
        raise ValueError("quaternion_root: a quaternion has (near) zero norm")
    q = q / norm
    root = f[:, -6:]
    xz, yaw = integrate_root(np.column_stack((root[:, 1], root[:, 0])) / fps, root[:, 3] / fps, init)
    tilt = quat_to_euler(torch.from_numpy(q[:, 0]), "YXZ").numpy()  # (T, 3), yaw ~ 0
    ypr = np.column_stack((yaw + tilt[:, 0], tilt[:, 1], tilt[:, 2]))
    return _assemble(skeleton, fps, xz, root[:, 2], ypr, q[:, 1:])


# --- by name ----------------------------------------------------------------------------

_ENCODERS = {"positions_control": encode_positions_control, "state_features": encode_state_features,
             "quaternion_root": encode_quaternion_root}
_DECODERS = {"positions_control": decode_positions_control, "state_features": decode_state_features,
             "quaternion_root": decode_quaternion_root}


def encode(motion: Motion, name: str) -> np.ndarray:
    """motion -> (T, D) float64 features of representation `name`."""
    return _ENCODERS[_check_name(name)](motion)


def decode(features, name: str, skeleton: Skeleton, fps: float, init=(0.0, 0.0, 0.0)):
    """(T, D) -> Motion (state_features, quaternion_root) or positions (T, J, 3) (positions_control)."""
    return _DECODERS[_check_name(name)](features, skeleton, fps, init)


def decode_to_positions(features, name: str, skeleton: Skeleton, fps: float, init=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(T, D) -> world joint positions (T, J, 3), whatever the representation."""
    out = decode(features, name, skeleton, fps, init)
    return out if isinstance(out, np.ndarray) else out.positions()


# --- joint positions -> rotations (for BVH export of positions_control output) ----------


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Unit vectors a, b (..., 3) -> the smallest rotation matrix (..., 3, 3) taking a to b (Rodrigues)."""
    v, c = np.cross(a, b), (a * b).sum(-1)
    vx = np.zeros((*v.shape[:-1], 3, 3))
    vx[..., 0, 1], vx[..., 0, 2], vx[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    vx = vx - np.swapaxes(vx, -1, -2)
    k = 1.0 / np.maximum(1.0 + c, 1e-9)  # a = -b (a half turn) has no unique axis; never met by bones
    return np.eye(3) + vx + vx @ vx * k[..., None, None]


def _unit_rows(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def motion_from_positions(positions, skeleton: Skeleton, fps: float) -> Motion:
    """World joint positions (T, J, 3) -> a Motion whose FK points every bone of ``skeleton`` along the
    positions' bones (bone lengths stay the skeleton's).

    Per joint, parents first: with several children the global rotation is the Kabsch fit of the rest
    bone directions to the observed ones; with one child, the smallest turn of the parent's frame that
    aligns that bone (no twist is observable from positions); an end effector keeps its parent's frame.
    """
    p = np.asarray(positions, dtype=np.float64)
    J = skeleton.num_joints
    if p.ndim != 3 or p.shape[1:] != (J, 3) or not np.isfinite(p).all():
        raise ValueError(f"motion_from_positions: positions must be finite (T, {J}, 3), got {p.shape}")
    G = np.zeros((len(p), J, 3, 3))
    for j in range(J):
        parent = G[:, skeleton.parents[j]] if j else np.broadcast_to(np.eye(3), (len(p), 3, 3))
        kids = skeleton.children(j)
        rest = _unit_rows(skeleton.offsets[kids]) if kids else None
        seen = _unit_rows(p[:, kids] - p[:, j:j + 1]) if kids else None  # (T, K, 3)
        if len(kids) >= 2:  # R = argmin sum_k |R rest_k - seen_k|^2 = U diag(1, 1, det) V^T
            U, _, Vt = np.linalg.svd(np.einsum("tki,kj->tij", seen, rest))
            D = np.ones((len(p), 3))
            D[:, 2] = np.sign(np.linalg.det(U @ Vt))
            G[:, j] = (U * D[:, None]) @ Vt
        elif kids:
            G[:, j] = _rotation_between(np.einsum("tij,j->ti", parent, rest[0]), seen[:, 0]) @ parent
        else:
            G[:, j] = parent
    parents_G = np.concatenate((np.broadcast_to(np.eye(3), (len(p), 1, 3, 3)),
                                G[:, [max(q, 0) for q in skeleton.parents[1:]]]), 1)
    local = np.swapaxes(parents_G, -1, -2) @ G  # R_local = G_parent^T G
    rotations = quat_canonical(matrix_to_quat(torch.from_numpy(local))).numpy()
    return Motion(rotations, p[:, 0].copy(), skeleton, fps)


# --- state_features in torch, and anchored on the feet (lesson 03's RNN) -----------------


def _check_state_tensor(features, skeleton: Skeleton, name: str = "features") -> None:
    D = feature_dim("state_features", skeleton.num_joints)
    if not torch.is_tensor(features) or features.ndim < 2 or features.shape[-1] != D:
        shape = tuple(features.shape) if torch.is_tensor(features) else type(features).__name__
        raise ValueError(f"{name} must be (..., T, {D}) state features for {skeleton.num_joints} joints, got {shape}")
    if not torch.isfinite(features).all():
        raise ValueError(f"{name} contains NaN or inf")


def local_positions(features: torch.Tensor, skeleton: Skeleton, offsets: torch.Tensor | None = None,
                    joints: tuple[int, ...] | None = None) -> torch.Tensor:
    """Raw state features (..., T, D) -> joint positions (..., T, J, 3) in each frame's floor frame
    (origin under the root, +Z the heading): FK of R_x(pitch) R_z(roll), the expmaps, root height.
    offsets: rest offsets (J, 3) for every motion, or (..., J, 3) one skeleton per motion (default: skeleton's).
    joints: indices of the joints wanted (..., T, len(joints), 3); FK then runs over their chains only."""
    from course_lib.skeleton import chain_positions

    _check_state_tensor(features, skeleton)
    root_tilt = torch.stack((torch.zeros_like(features[..., 4]), features[..., 4], features[..., 5]), -1)
    root_q = euler_to_quat(root_tilt, "YXZ")  # (..., T, 4): R_y(0) R_x(pitch) R_z(roll)
    theta = features[..., 6:-2].unflatten(-1, (skeleton.num_joints - 1, 3))  # (..., T, J-1, 3)
    root = torch.stack((torch.zeros_like(features[..., 3]), features[..., 3], torch.zeros_like(features[..., 3])), -1)
    off = torch.as_tensor(skeleton.offsets, dtype=features.dtype) if offsets is None else \
        torch.as_tensor(offsets).to(features.dtype)
    if off.dim() == features.dim():  # one skeleton per motion: (..., J, 3) -> (..., 1, J, 3), shared by its frames
        off = off.unsqueeze(-3)
    return chain_positions(root_q, theta, root, off, skeleton.parents, joints)


def _turn(v_xz: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
    """(x, z) vectors (..., 2), yaw (...) -> R_y(yaw) v (torch `_to_world`)."""
    c, s = torch.cos(yaw), torch.sin(yaw)
    return torch.stack((c * v_xz[..., 0] + s * v_xz[..., 1], -s * v_xz[..., 0] + c * v_xz[..., 1]), -1)


def root_trajectory(features: torch.Tensor, init=(0.0, 0.0, 0.0)) -> tuple[torch.Tensor, torch.Tensor]:
    """Raw state features (..., T, D) -> world root positions (..., T, 3) and heading yaw (..., T).

    Wang eq. (4), M_t = M_{t-1} M_t,local, in torch (`integrate_root`); row 0 of the
    deltas is ignored, frame 0 sits at init = (x0, z0, yaw0).
    """
    if not torch.is_tensor(features) or features.ndim < 2 or features.shape[-1] < 6:
        raise ValueError(f"features must be (..., T, D >= 6), got {getattr(features, 'shape', type(features))}")
    x0, z0, yaw0 = (float(v) for v in init)
    dyaw = features[..., 1:, 2]
    yaw = yaw0 + torch.cat((torch.zeros_like(features[..., :1, 2]), torch.cumsum(dyaw, -1)), -1)  # (..., T)
    step = _turn(features[..., 1:, 0:2], yaw[..., :-1])  # p_t - p_{t-1} = R_y(yaw_{t-1}) d_t
    xz = torch.cat((torch.zeros_like(step[..., :1, :]), torch.cumsum(step, -2)), -2)  # (..., T, 2)
    root = torch.stack((xz[..., 0] + x0, features[..., 3], xz[..., 1] + z0), -1)
    return root, yaw


ANCHOR_RULES = ("lower", "contact")


def _contact_anchor(bits: torch.Tensor, lower: torch.Tensor) -> torch.Tensor:
    """Contact bits (..., T, 2) (raw, on above 0.5), the lower toe (..., T) -> the anchor of each step (..., T-1):
    0 / 1 the left / right toe, 2 the root.  Step t's anchor follows frame t-1's bits: the one foot in contact;
    with both in contact, step t-1's foot (the lower toe after a flight); with none (a running flight), the root.
    So the anchor passes to a foot only when the other one lifts, and in the air the slip is the root's own
    floor step (smooth), not the velocity of whichever swinging toe happens to be lower."""
    on = bits > 0.5
    only_one = on[..., 0] != on[..., 1]  # (..., T)
    foot = on[..., 1].long()  # the foot in contact where only one is
    none = ~(on[..., 0] | on[..., 1])
    anchor, out = lower[..., 0], []
    for t in range(bits.shape[-2] - 1):
        both = torch.where(anchor == 2, lower[..., t], anchor)
        anchor = torch.where(only_one[..., t], foot[..., t], torch.where(none[..., t], 2, both))
        out.append(anchor)
    return torch.stack(out, -1) if out else lower[..., :0]


def toes_relative(features: torch.Tensor, skeleton: Skeleton, offsets=None) -> torch.Tensor:
    """Raw state features (..., T, D) -> both toes (left, right) relative to the root, in each frame's floor frame
    (..., T, 2, 3): FK with the root height left out, so the pose alone decides where the toes sit."""
    flat = features.clone()
    flat[..., 3] = 0.0
    return local_positions(flat, skeleton, offsets, (skeleton.index("LeftToeBase"), skeleton.index("RightToeBase")))


def _feet_geometry(features: torch.Tensor, skeleton: Skeleton, offsets, tau: float = 0.0,
                   rule: str = "lower", toes: torch.Tensor | None = None
                   ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """-> lowest toe height above the root (..., T), the anchor toe's floor-frame (x, z) on frames t-1 and t
    (..., T-1, 2) each: with rule "lower" the anchor of step t is the toe that is lower on frame t-1; with
    "contact" it follows the contact bits (`_contact_anchor`).

    tau > 0 (metres) makes the anchor soft: both toes weighted by softmax(-height / tau) of their heights above the
    root, the weights of frame t-1 for step t's anchor point and those of frame t for the height; tau -> 0 is the hard
    choice.  A hard anchor jumps from one toe to the other, so the slip must jump with it at every change of support;
    a soft one moves between the toes over the frames both are near the floor.  toes: `toes_relative` of the
    features if the caller has it already."""
    toes = toes_relative(features, skeleton, offsets) if toes is None else toes  # (..., T, 2, 3)
    if tau > 0:
        w = torch.softmax(-toes[..., 1] / tau, dim=-1)  # (..., T, 2)
        wp = w[..., :-1, :, None]  # frame t-1's weights, for both ends of step t
        prev = (wp * toes[..., :-1, :, :]).sum(-2)[..., [0, 2]]
        cur = (wp * toes[..., 1:, :, :]).sum(-2)[..., [0, 2]]
        return (w * toes[..., 1]).sum(-1), prev, cur
    low = toes[..., 1].argmin(-1, keepdim=True)  # (..., T, 1)
    height = toes[..., 1].min(-1).values
    if rule == "contact":  # the anchor points: both toes and the root, whose floor-frame (x, z) is 0
        toes = torch.cat((toes, torch.zeros_like(toes[..., :1, :])), -2)
        step = _contact_anchor(features[..., -2:], low[..., 0])[..., None]
    else:
        step = low[..., :-1, :]
    pick = step[..., None].expand(*low.shape[:-2], low.shape[-2] - 1, 1, 3)  # (..., T-1, 1, 3)
    prev = toes[..., :-1, :, :].gather(-2, pick)[..., 0, :][..., [0, 2]]  # anchor on t-1
    cur = toes[..., 1:, :, :].gather(-2, pick)[..., 0, :][..., [0, 2]]  # the same toe on t
    return height, prev, cur


def _check_tau(tau: float, rule: str = "lower") -> None:
    if not (np.isfinite(tau) and tau >= 0):
        raise ValueError(f"anchor tau must be a finite number of metres >= 0 (0: the hard anchor), got {tau!r}")
    if rule not in ANCHOR_RULES or (tau > 0 and rule != "lower"):
        raise ValueError(f"anchor rule must be one of {ANCHOR_RULES} (a soft anchor, tau > 0, only with 'lower'), "
                         f"got {rule!r} with tau {tau}")


def anchor_on_feet(features: torch.Tensor, skeleton: Skeleton, offsets=None, tau: float = 0.0,
                   rule: str = "lower") -> torch.Tensor:
    """Raw state features (..., T, D) -> the same with the root tied to the feet (lesson 03's RNN reads these):

    column 3, the root height, becomes the lower toe's height above the floor, h_t = y_root + min_toe y_rel
    (about 0 on every subject while a foot is down); columns 0-1, the floor displacement d_t, become the slip
    of the anchor toe (the lower one on frame t-1), s_t = R_y(dyaw_t) p_t + d_t - p_{t-1} with p its floor-frame
    (x, z) (the toe's own displacement, as `refiner.end_effector_features`; about 0 while it is planted).
    Row 0 keeps d_0 (decoders ignore it).  Exactly inverted by `unanchor_feet` on the same skeleton and tau.
    tau > 0 (metres): the soft anchor of `_feet_geometry`, both toes weighted by their heights; rule "contact":
    the anchor follows the contact bits (columns -2, -1) instead of the lower toe (`_contact_anchor`)."""
    _check_state_tensor(features, skeleton)
    _check_tau(tau, rule)
    low, prev, cur = _feet_geometry(features, skeleton, offsets, tau, rule)
    out = features.clone()
    out[..., 3] = features[..., 3] + low
    out[..., 1:, 0:2] = _turn(cur, features[..., 1:, 2]) + features[..., 1:, 0:2] - prev
    return out


def unanchor_feet(anchored: torch.Tensor, skeleton: Skeleton, offsets=None, tau: float = 0.0,
                  rule: str = "lower", toes: torch.Tensor | None = None) -> torch.Tensor:
    """The inverse of `anchor_on_feet`: (..., T, D) feet-anchored features -> raw state features, on the skeleton
    (offsets (J, 3), or (..., J, 3) one per motion) that decides where the toes are, with the same tau and rule
    (anchoring leaves the pose and the contact bits as they are, so both sides pick the same anchor).
    toes: `toes_relative(anchored, skeleton, offsets)` if the caller has it (it needs only the pose)."""
    _check_state_tensor(anchored, skeleton, "anchored")
    _check_tau(tau, rule)
    low, prev, cur = _feet_geometry(anchored, skeleton, offsets, tau, rule, toes)
    out = anchored.clone()
    out[..., 3] = anchored[..., 3] - low
    out[..., 1:, 0:2] = anchored[..., 1:, 0:2] + prev - _turn(cur, anchored[..., 1:, 2])
    return out
