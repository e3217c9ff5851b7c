"""Motion-quality metrics on joint positions: prediction error, physics, control, diversity.

Every metric takes world joint positions, either a float array ``(N, T, J, 3)``
(or one clip ``(T, J, 3)``), numpy or torch, in metres, Y up, floor at y = 0,
or a list of :class:`~course_lib.motion.Motion` (their FK positions; the
Motion's own skeleton and fps are then used).  Inputs are validated: a wrong
joint count, NaN/inf values or mismatched shapes raise a ValueError naming the
problem.  Units are stated on each function.

Taught in notebooks/02_vae_lstm.ipynb (prediction/pose error) and
notebooks/07_benchmark.ipynb (everything else).

Differs from the papers:
- Habibie et al. 2017 (sec. 4.3, Tables 1-2) report "mean squared error between
  generated joint positions and ground truth" without units; their numbers are
  in their own (likely normalised) data units.  Ours are in m^2: compare trends
  and model rankings with the paper, not the values.
- NPSS (Gopalakrishnan et al. 2019) is computed on any per-frame features (the
  paper used Euler angles); we use the one-sided power spectrum (rfft) since the
  spectrum of a real signal is symmetric.
- APD is the mean per-joint Euclidean distance in metres (not the flattened-
  sequence L2 norm of DLow), so it does not grow with clip length.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from course_lib.motion import CONTACT_HEIGHT, Motion, check_fps
from course_lib.skeleton import Skeleton

__all__ = [
    "apd", "bone_length_violation", "facing_yaw", "foot_skate", "foot_skate_at_floor", "ground_penetration",
    "heading_error",
    "jitter", "npss", "path_distance", "pose_error", "prediction_error", "root_jerk_split", "root_relative",
    "speed_error",
]


# ----------------------------------------------------------------------------- input checks


def _finite(x: np.ndarray, name: str) -> np.ndarray:
    if not np.isfinite(x).all():
        raise ValueError(f"{name}: contains NaN or inf values")
    return x


def _to_numpy(x, name: str) -> np.ndarray:
    if isinstance(x, torch.Tensor):
        x = x.detach().cpu().numpy()
    try:
        return np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{name}: expected a numeric array or a list of Motions, got {type(x).__name__}") from err


def _clips(x, name: str, skeleton: Skeleton | None = None, fps: float | None = None, min_frames: int = 1
           ) -> tuple[list[np.ndarray], Skeleton, float | None]:
    """Motions or (N, T, J, 3) / (T, J, 3) positions -> list of (T, J, 3) arrays, skeleton, fps.

    Motions carry their own frame rate and skeleton: all must share them (the message names the first clip
    that differs), and an ``fps`` or ``skeleton`` argument that disagrees with them is refused, not used.
    Every clip needs at least ``min_frames`` frames (each measure states its own)."""
    if isinstance(x, Motion):
        x = [x]
    if isinstance(x, (list, tuple)) and not x:
        raise ValueError(f"{name}: no clips given (an empty list)")
    if isinstance(x, (list, tuple)) and all(isinstance(m, Motion) for m in x):
        skel, rate = x[0].skeleton, float(x[0].fps)
        for i, m in enumerate(x):
            if float(m.fps) != rate:
                raise ValueError(f"{name}: clip {i} is at {m.fps:g} fps and clip 0 at {rate:g} fps; resample them "
                                 "to one rate first (Motion.resample)")
            if m.skeleton.names != skel.names:
                raise ValueError(f"{name}: clip {i} has {m.skeleton.num_joints} joints and clip 0 has "
                                 f"{skel.num_joints} (or other joint names); measure clips of one skeleton together")
        if fps is not None and float(fps) != rate:
            raise ValueError(f"{name}: fps={fps!r} given, but the Motions are at {rate:g} fps; leave fps out "
                             "(a Motion's own rate is used) or resample the Motions")
        if skeleton is not None and skeleton.names != skel.names:
            raise ValueError(f"{name}: the skeleton given has {skeleton.num_joints} joints, the Motions' "
                             f"{skel.num_joints}; leave skeleton out (a Motion's own is used)")
        fps = rate
        clips = [m.positions() for m in x]
    else:
        if isinstance(x, (list, tuple)) and any(isinstance(m, Motion) for m in x):
            raise ValueError(f"{name}: a list mixing Motions and arrays; give Motions or one (N, T, J, 3) array")
        arr = _to_numpy(x, name)
        if arr.ndim == 3:
            arr = arr[None]
        if arr.ndim != 4 or arr.shape[-1] != 3:
            raise ValueError(f"{name}: positions must be (N, T, J, 3) or (T, J, 3), got shape {arr.shape}")
        skel = skeleton or Skeleton.canonical()
        clips = list(arr)
        if fps is not None:
            fps = check_fps(fps, name)
    if not clips:
        raise ValueError(f"{name}: no clips given")
    for i, c in enumerate(clips):
        if c.shape[1] != skel.num_joints:
            raise ValueError(f"{name}: expected {skel.num_joints} joints (skeleton), got {c.shape[1]} in clip {i}")
        if len(c) < min_frames:
            raise ValueError(f"{name}: clip {i} has {len(c)} frames; this measure needs at least {min_frames}")
        _finite(c, name)
    return clips, skel, fps


def _batch(x, name: str, skeleton: Skeleton | None = None, fps: float | None = None, min_frames: int = 1
           ) -> tuple[np.ndarray, Skeleton]:
    """Like `_clips` but all clips must have the same length -> (N, T, J, 3), skeleton."""
    clips, skel, _ = _clips(x, name, skeleton, fps, min_frames)
    lengths = sorted({len(c) for c in clips})
    if len(lengths) > 1:
        raise ValueError(f"{name}: clips have different lengths {lengths}; crop them to a common length")
    return np.stack(clips), skel


def _pair(pred, target, skeleton: Skeleton | None) -> tuple[np.ndarray, np.ndarray, Skeleton]:
    p, skel = _batch(pred, "pred", skeleton)
    t, _ = _batch(target, "target", skel)
    if p.shape != t.shape:
        raise ValueError(f"pred and target have mismatched shapes {p.shape} vs {t.shape} "
                         "(clips, frames, joints, 3)")
    return p, t, skel


def _need_fps(fps, name: str) -> float:
    if fps is None:
        raise ValueError(f"{name}: give fps (frames per second, > 0) for position arrays")
    return check_fps(fps, name)


def _frames(frames, T: int) -> list[int]:
    frames = list(range(T)) if frames is None else [int(f) for f in np.atleast_1d(frames)]
    bad = [f for f in frames if not 0 <= f < T]
    if bad:
        raise ValueError(f"frames {bad} are outside the clips' 0..{T - 1} frame range")
    return frames


# ----------------------------------------------------------------------------- prediction error (Habibie 4.3)


def prediction_error(pred, target, frames=None, skeleton: Skeleton | None = None) -> dict[int, float]:
    """Motion prediction error per frame (Habibie et al. 2017, sec. 4.3, Table 1), in m^2.

    pred, target: (N, T, J, 3) world positions (or lists of Motions) -> {frame: error}.
    error(f) = 1/(N J) sum_n sum_j ||pred[n, f, j] - target[n, f, j]||^2, i.e. the
    squared Euclidean joint distance averaged over clips and joints, world space
    (root translation and facing included).  frames: 0-based indices (default all).
    """
    p, t, _ = _pair(pred, target, skeleton)
    sq = ((p - t) ** 2).sum(-1).mean(axis=(0, 2))  # (T,)
    return {f: float(sq[f]) for f in _frames(frames, p.shape[1])}


def facing_yaw(positions, skeleton: Skeleton | None = None) -> np.ndarray:
    """(N, T, J, 3) positions -> (N, T) facing angle about +Y, radians (0 = facing +Z).

    The facing direction is forward = across x up, with across = LeftUpLeg - RightUpLeg
    projected on the floor (the character's left is +X when it faces +Z).
    """
    x, skel = _batch(positions, "positions", skeleton)
    across = x[..., skel.index("LeftUpLeg"), :] - x[..., skel.index("RightUpLeg"), :]  # (N, T, 3)
    # forward = across x (0, 1, 0) = (-across_z, 0, across_x)
    return np.arctan2(-across[..., 2], across[..., 0])


def root_relative(positions, skeleton: Skeleton | None = None) -> np.ndarray:
    """(N, T, J, 3) world positions -> (N, T, J, 3) in each frame's root frame (translation and yaw removed)."""
    x, skel = _batch(positions, "positions", skeleton)
    yaw = facing_yaw(x, skel)  # (N, T)
    local = x - x[..., :1, :] * np.array([1.0, 0.0, 1.0])  # subtract the root's floor projection
    c, s = np.cos(-yaw)[..., None], np.sin(-yaw)[..., None]  # rotate by -yaw about +Y
    out = local.copy()
    out[..., 0] = c * local[..., 0] + s * local[..., 2]
    out[..., 2] = -s * local[..., 0] + c * local[..., 2]
    return out


def pose_error(pred, target, frames=None, skeleton: Skeleton | None = None) -> dict[int, float]:
    """Pose prediction error per frame (Habibie et al. 2017, Table 2), in m^2.

    pred, target: (N, T, J, 3) -> {frame: error}.  Like `prediction_error`, but each
    pose is first expressed relative to its own root: the root's horizontal
    translation and its facing yaw (see `facing_yaw`) are removed, root height kept.
    """
    p, t, skel = _pair(pred, target, skeleton)
    return prediction_error(root_relative(p, skel), root_relative(t, skel), frames, skel)


# ----------------------------------------------------------------------------- physical plausibility


FLOOR_WINDOW_S = 1.0  # foot_skate's floor: the lowest toe within this many seconds either side of a frame
SKATE_INTERVAL_S = 0.1  # foot_skate's speed: the toe's floor displacement over this interval


def foot_skate(motions, fps: float | None = None, skeleton: Skeleton | None = None,
               joints: Sequence[str] = ("LeftToeBase", "RightToeBase"),
               height: float = CONTACT_HEIGHT["ToeBase"], floor: float | str = "auto",
               interval: float | None = SKATE_INTERVAL_S) -> float:
    """Mean horizontal speed of feet in contact with the floor, m/s (0 for a perfect motion).

    motions: list of Motions or (N, T, J, 3) positions (then give fps).  A toe (each joint in ``joints``)
    is in contact over an interval of ``interval`` seconds (k = round(interval * fps) frames, at least 1)
    when it stays below ``height`` above the floor on every frame of it; its skate there is its horizontal
    displacement over the interval divided by the interval.  Returns the mean over all such intervals
    (0.0 if no foot ever touches the floor).  There is no speed gate: a sliding foot must count.

    ``floor="auto"`` (the default) estimates the floor from the data, as real capture needs: on each frame,
    the lowest toe height within ``FLOOR_WINDOW_S`` = 1 s either side (a floor that is offset, or tilted
    along a walk, is followed).  A number is a known, level floor (the synthetic data's is 0).  Measuring
    over 0.1 s rather than one frame makes the answer the same at 30, 60 and 120 fps: one frame's marker
    noise would otherwise add speed as the frame rate grows.  ``interval=None`` measures frame to frame.
    `foot_skate_at_floor` is the rule for data whose floor is known: y = 0, frame to frame.
    """
    clips, skel, fps = _clips(motions, "foot_skate", skeleton, fps, min_frames=2)
    fps = _need_fps(fps, "foot_skate")
    if isinstance(floor, str) and floor != "auto":
        raise ValueError(f"foot_skate: floor must be 'auto' or a height in metres, got {floor!r}")
    if interval is not None and not (np.isfinite(interval) and interval > 0):
        raise ValueError(f"foot_skate: interval must be a positive number of seconds or None, got {interval!r}")
    idx = [skel.index(n) for n in joints]
    speeds = []
    for c in clips:
        f = c[:, idx]  # (T, F, 3)
        y = f[..., 1]
        if floor == "auto":
            w = max(1, int(round(FLOOR_WINDOW_S * fps)))
            lowest = y.min(1)
            level = np.array([lowest[max(0, t - w):t + w + 1].min() for t in range(len(lowest))])[:, None]
        else:
            level = float(floor)
        low = y - level < height  # (T, F)
        k = 1 if interval is None else int(min(max(1, round(interval * fps)), len(f) - 1))
        held = np.ones_like(low[k:])
        for j in range(k + 1):  # below the height on every frame of the interval
            held &= low[j:len(low) - k + j]
        v = np.linalg.norm(f[k:, :, [0, 2]] - f[:-k, :, [0, 2]], axis=-1) * fps / k  # (T-k, F)
        speeds.append(v[held])
    speeds = np.concatenate(speeds)
    return float(speeds.mean()) if speeds.size else 0.0


def foot_skate_at_floor(motions, fps: float | None = None, skeleton: Skeleton | None = None,
                        joints: Sequence[str] = ("LeftToeBase", "RightToeBase"),
                        height: float = CONTACT_HEIGHT["ToeBase"], floor: float = 0.0) -> float:
    """Foot skate when the floor is known and level (the synthetic data: y = 0), m/s: for each toe and each
    frame pair (t, t+1) on which it is below ``height`` above ``floor`` on both frames, its horizontal
    speed ||(x, z)_{t+1} - (x, z)_t|| * fps, averaged.  The course's targets for generated motion are on this
    rule (`foot_skate` with floor=0.0, interval=None).  On real capture, whose floor is not at y = 0, use
    `foot_skate`."""
    return foot_skate(motions, fps, skeleton, joints, height, floor=float(floor), interval=None)


def ground_penetration(motions, skeleton: Skeleton | None = None) -> float:
    """Mean depth below the floor (y = 0) of the lowest joint, m, over all frames.

    motions: list of Motions or (N, T, J, 3) -> float.  Per frame
    depth_t = max(0, -min_j y_{t,j}); joints above the floor contribute 0.
    """
    clips, _, _ = _clips(motions, "ground_penetration", skeleton)
    depth = np.concatenate([np.maximum(0.0, -c[..., 1].min(-1)) for c in clips])
    return float(depth.mean())


def jitter(motions, fps: float | None = None, skeleton: Skeleton | None = None) -> float:
    """Mean jerk magnitude, m/s^3: mean over clips, frames and joints of ||d^3 x / dt^3||.

    motions: list of Motions or (N, T, J, 3) (give fps) -> float.  The jerk is the third
    finite difference times fps^3, so the value depends on the frame rate: compare at equal fps.
    """
    clips, _, fps = _clips(motions, "jitter", skeleton, fps, min_frames=4)  # a third difference needs 4 frames
    fps = _need_fps(fps, "jitter")
    jerk = np.concatenate([np.linalg.norm(np.diff(c, n=3, axis=0), axis=-1).ravel() for c in clips])
    return float(jerk.mean() * fps**3)


def root_jerk_split(motions, fps: float | None = None, skeleton: Skeleton | None = None, window: int = 2) -> dict:
    """The root's jerk (m/s^3, as `jitter` computes it, on the root joint alone) split by the frames near a change
    of support: {"all", "near_change", "elsewhere", "near_share"} (near_share: the fraction of the root's jerk that
    lies near a change).  A change of support is a frame whose lower toe (LeftToeBase / RightToeBase, by height)
    is not the previous frame's; a jerk sample (frames k..k+3) is near one when frame k+1 or k+2 lies within
    ``window`` frames of a change.  Mocap's root moves smoothly through its changes of support; a model that
    places its root by a foot jumps there (lesson 03)."""
    clips, skel, fps = _clips(motions, "root_jerk_split", skeleton, fps, min_frames=4)
    fps = _need_fps(fps, "root_jerk_split")
    if int(window) != window or window < 0:
        raise ValueError(f"root_jerk_split: window must be a whole number of frames >= 0, got {window!r}")
    toes, w = [skel.index("LeftToeBase"), skel.index("RightToeBase")], int(window)
    near_all, jerk_all = [], []
    for c in clips:
        low = c[:, toes, 1].argmin(-1)
        change = np.r_[False, low[1:] != low[:-1]]
        near = np.convolve(change.astype(float), np.ones(2 * w + 1))[w:w + len(c)] > 0  # within w frames of one
        jerk_all.append(np.linalg.norm(np.diff(c[:, 0], n=3, axis=0), axis=-1) * fps**3)  # (T-3,)
        near_all.append(near[1:-2] | near[2:-1])
    jerk, near = np.concatenate(jerk_all), np.concatenate(near_all)
    total = float(jerk.sum())
    return {"all": float(jerk.mean()), "near_change": float(jerk[near].mean()) if near.any() else 0.0,
            "elsewhere": float(jerk[~near].mean()) if (~near).any() else 0.0,
            "near_share": float(jerk[near].sum() / total) if total > 0 else 0.0}


def bone_length_violation(motions, skeleton: Skeleton | None = None) -> float:
    """Max relative bone-length deviation, unitless: max_{t,j} |l_{t,j} - L_j| / L_j.

    motions: list of Motions (L from each Motion's skeleton) or (N, T, J, 3) positions
    (L from ``skeleton``, default the canonical one) -> float.  l_{t,j} is the distance
    from joint j to its parent on frame t; zero-length bones are skipped.
    """
    if isinstance(motions, (list, tuple)) and motions and all(isinstance(m, Motion) for m in motions):
        return max(bone_length_violation([m.positions()], m.skeleton) for m in motions)  # each with its own bones
    clips, skel, _ = _clips(motions, "bone_length_violation", skeleton)
    child = np.array([j for j in range(1, skel.num_joints)])
    parent = np.array([skel.parents[j] for j in child])
    rest = skel.bone_lengths()[child]
    keep = rest > 1e-9
    worst = 0.0
    for c in clips:
        length = np.linalg.norm(c[:, child] - c[:, parent], axis=-1)  # (T, J-1)
        worst = max(worst, float((np.abs(length - rest) / np.where(keep, rest, 1.0))[:, keep].max()))
    return worst


# ----------------------------------------------------------------------------- control following


def _per_frame_target(target, shape: tuple[int, int], name: str) -> np.ndarray:
    tgt = _finite(_to_numpy(target, name), name)
    try:
        return np.broadcast_to(tgt, shape)
    except ValueError:
        raise ValueError(f"{name}: shape {tgt.shape} does not broadcast to the (clips, frames) {shape}") from None


def speed_error(positions, target_speed, fps: float | None = None, skeleton: Skeleton | None = None) -> float:
    """Mean |root horizontal speed - target speed|, m/s.

    positions: (N, T, J, 3) or Motions; target_speed: (N, T), (T,) or a scalar, m/s -> float.
    Root speed by central differences of the root's (x, z), times fps.
    """
    x, skel = _batch(positions, "speed_error", skeleton, fps, min_frames=2)  # checks fps against Motions' own
    fps = _need_fps(fps if fps is not None else _motion_fps(positions), "speed_error")
    root = x[..., 0, :][..., [0, 2]]  # (N, T, 2)
    speed = np.linalg.norm(np.gradient(root, axis=1), axis=-1) * fps  # (N, T)
    return float(np.abs(speed - _per_frame_target(target_speed, speed.shape, "target_speed")).mean())


def heading_error(positions, target_heading, skeleton: Skeleton | None = None) -> float:
    """Mean absolute angle between the facing direction and a target heading, radians in [0, pi].

    positions: (N, T, J, 3) or Motions; target_heading: (N, T), (T,) or scalar yaw about +Y
    in radians, 0 = facing +Z, pi/2 = facing +X (the convention of `facing_yaw`) -> float.
    """
    yaw = facing_yaw(positions, skeleton)  # (N, T)
    diff = yaw - _per_frame_target(target_heading, yaw.shape, "target_heading")
    return float(np.abs(np.angle(np.exp(1j * diff))).mean())  # wrapped to [-pi, pi]


def path_distance(positions, path, skeleton: Skeleton | None = None) -> float:
    """Mean distance from the root's floor projection to a polyline path, metres.

    positions: (N, T, J, 3) or Motions; path: (P, 2) floor points (x, z) or (P, 3) world
    points (y ignored), P >= 1 -> float.  Distance = min over the path's segments.
    """
    x, _ = _batch(positions, "positions", skeleton)
    pts = _finite(_to_numpy(path, "path"), "path")
    if pts.ndim != 2 or pts.shape[1] not in (2, 3) or len(pts) < 1:
        raise ValueError(f"path: must be (P, 2) floor points (x, z) or (P, 3), got shape {pts.shape}")
    pts = pts[:, [0, 2]] if pts.shape[1] == 3 else pts
    a, b = (pts[:-1], pts[1:]) if len(pts) > 1 else (pts, pts)  # segments (S, 2)
    q = x[..., 0, :][..., [0, 2]].reshape(-1, 1, 2)  # (N*T, 1, 2)
    ab = b - a
    u = np.clip(((q - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12), 0.0, 1.0)  # (N*T, S)
    d = np.linalg.norm(q - (a + u[..., None] * ab), axis=-1).min(-1)
    return float(d.mean())


def _motion_fps(x) -> float | None:
    if isinstance(x, Motion):
        return x.fps
    if isinstance(x, (list, tuple)) and x and isinstance(x[0], Motion):
        return x[0].fps
    return None


# ----------------------------------------------------------------------------- diversity and spectra


def apd(samples, skeleton: Skeleton | None = None) -> float:
    """Average pairwise distance between S samples generated for the same control, metres.

    samples: (S, T, J, 3) or (N, S, T, J, 3) (N controls, S samples each), or a list of S
    Motions -> float.  APD = mean_{n} 1/(S(S-1)) sum_{i != j} mean_{t,k} ||x_i[t,k] - x_j[t,k]||.
    """
    arr = None
    if not (isinstance(samples, (list, tuple)) and samples and isinstance(samples[0], Motion)):
        arr = _to_numpy(samples, "samples")
    if arr is not None and arr.ndim == 5:
        return float(np.mean([apd(group, skeleton) for group in arr]))
    x, _ = _batch(samples if arr is None else arr, "samples", skeleton)  # (S, T, J, 3)
    S = len(x)
    if S < 2:
        raise ValueError(f"apd: needs at least 2 samples, got {S}")
    d = np.linalg.norm(x[:, None] - x[None, :], axis=-1).mean(axis=(2, 3))  # (S, S)
    return float(d.sum() / (S * (S - 1)))


def npss(pred, target) -> float:
    """Normalized power spectrum similarity (Gopalakrishnan et al. 2019), lower is better, >= 0.

    pred, target: (N, T, D) features (or (N, T, J, 3) positions, flattened to D = 3J) -> float.
    Per clip n and feature d: power spectrum P = |rfft(x[n, :, d])|^2 normalised to sum 1,
    emd_{n,d} = sum_f |cumsum(P_pred) - cumsum(P_target)|; NPSS is the average of emd
    weighted by the target's total power in (n, d).
    """
    p, t = (_finite(_to_numpy(a, name), name) for a, name in ((pred, "pred"), (target, "target")))
    if p.shape != t.shape:
        raise ValueError(f"npss: pred and target have mismatched shapes {p.shape} vs {t.shape}")
    if p.ndim == 4:
        p, t = p.reshape(*p.shape[:2], -1), t.reshape(*t.shape[:2], -1)
    if p.ndim != 3 or p.shape[1] < 2:
        raise ValueError(f"npss: expected (N, T, D) or (N, T, J, 3) with T >= 2, got shape {p.shape}")
    pow_p = np.abs(np.fft.rfft(p, axis=1)) ** 2  # (N, F, D)
    pow_t = np.abs(np.fft.rfft(t, axis=1)) ** 2
    tot_p, tot_t = pow_p.sum(1), pow_t.sum(1)  # (N, D)
    if tot_t.sum() <= 0:
        raise ValueError("npss: the target has zero power in every feature")
    cdf_p = np.cumsum(pow_p / np.maximum(tot_p, 1e-300)[:, None], axis=1)
    cdf_t = np.cumsum(pow_t / np.maximum(tot_t, 1e-300)[:, None], axis=1)
    emd = np.abs(cdf_p - cdf_t).sum(1)  # (N, D)
    return float((emd * tot_t).sum() / tot_t.sum())
