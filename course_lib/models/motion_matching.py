"""Motion matching: the industry's baseline, search the database and play it (Clavet 2016; Holden et al. 2020).

Taught in notebooks/07_benchmark.ipynb (section "Motion matching").  No network is trained: the "model" is the
training clips themselves, a feature vector per frame, and a nearest-neighbour search.  Every ``search_every``
frames the character asks: which database frame has the pose I am in now and the future path I am asked for?
It jumps there and plays the database on, frame after frame, until the next search.

The feature vector of frame t (27 values, Holden et al. 2020 sec. 3 "Motion Matching"), all in the character's
floor frame at t (origin under the root, +Z its facing direction, so position and heading do not count):

    x_t = [ p_lfoot (3), p_rfoot (3),          foot positions (m)
            v_lfoot (3), v_rfoot (3),          foot velocities (m/s)
            v_hip (3),                         the root's velocity (m/s)
            r_{t+10}, r_{t+20}, r_{t+30} (2 each),   the future root positions on the floor (m)
            d_{t+10}, d_{t+20}, d_{t+30} (2 each) ]  the future facing directions (unit vectors)

at 30 fps: the future path 1/3, 2/3 and 1 s ahead.  Each of the five groups is divided by its own spread over the
database (the mean sd of its columns) and weighted (`MotionMatchingConfig.weights`), so that no group wins because
of its unit.  The search is an exact nearest neighbour in this 27-D space, scipy's ``cKDTree`` (a k-d tree).

The query: the pose part (feet and hip) comes from the frame being played, the path part from the request.
- controlled: the request is a control program (forward, sideways, yaw rate per frame); the future path is that
  control integrated over the next second from where the character stands;
- free (random generation): the request is the played clip's own future path; each search takes one of the
  ``k`` nearest frames at random (seeded), so that samples from one start differ.

Jumping from one frame to another would pop: inertialisation (Bollo 2016) keeps the pose continuous.  At a jump
the offset o = (old pose) - (new pose) is added to the new frames and decays to 0 over ``blend_seconds``
(a smoothstep, not Bollo's quintic); the root's velocity (the control) is blended the same way.

Differs from Holden et al. 2020: positions, not rotations (the course's positions_control representation: joint
positions in the floor frame + the control); no foot-locking IK; the velocities are differences between frames in
the floor frame of the later one; a smoothstep decay instead of the critically damped spring; the end of a clip
forces a search (only frames with 1 s of future are searchable).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from course_lib.representations import encode_positions_control, integrate_root

FEET = ("LeftFoot", "RightFoot")
GROUPS = ("feet_position", "feet_velocity", "hip_velocity", "path_position", "path_direction")


@dataclasses.dataclass
class MotionMatchingConfig:
    """Motion matching's settings (Holden et al. 2020's defaults, rescaled to 30 fps)."""

    fps: float = 30.0  # the database's frame rate (the benchmark's)
    future: tuple = (10, 20, 30)  # frames ahead of the path features: 1/3, 2/3, 1 s at 30 fps
    search_every: int = 5  # frames between searches (1/6 s; Holden: 10 frames at 60 fps)
    blend_seconds: float = 0.2  # inertialisation's decay time after a jump
    k: int = 4  # free generation: a search takes one of the k nearest frames at random
    skip_near: int = 3  # a best match within this many frames of the played one (same clip) is no jump
    weights: dict = dataclasses.field(default_factory=lambda: {
        "feet_position": 1.0, "feet_velocity": 1.0, "hip_velocity": 1.0, "path_position": 1.0,
        "path_direction": 1.5})  # Holden's: the path a little above the pose


def future_path(control: np.ndarray, fps: float, future=(10, 20, 30)) -> np.ndarray:
    """control (T, 3) (forward m/s, sideways m/s, yaw rate rad/s) from the current frame on -> (len(future), 4):
    the root's floor position (x, z) and facing direction (sin, cos of the turn) k frames ahead, in the current
    floor frame.  T must exceed max(future)."""
    k = max(future)
    if len(control) <= k:
        raise ValueError(f"future_path: needs more than {k} control frames, got {len(control)}")
    c = control[: k + 1] / fps
    xz, yaw = integrate_root(np.stack((c[:, 1], c[:, 0]), -1), c[:, 2])  # row 0 (now) at the origin
    f = list(future)
    return np.concatenate((xz[f], np.stack((np.sin(yaw[f]), np.cos(yaw[f])), -1)), 1)


class MotionMatching:
    """The database of positions_control frames, their 27-D features and a k-d tree over them.

    clips: Motions (any frame rate, resampled to config.fps), all on one skeleton."""

    def __init__(self, clips, config: MotionMatchingConfig | None = None):
        from scipy.spatial import cKDTree

        self.config = cfg = config or MotionMatchingConfig()
        if not clips:
            raise ValueError("MotionMatching: no clips for the database")
        self.skeleton = clips[0].skeleton
        self.feet = [self.skeleton.index(n) for n in FEET]
        self.frames = [encode_positions_control(m.resample(cfg.fps)) for m in clips]  # each (T, 66)
        feats, where = [], []
        for c, f in enumerate(self.frames):
            ok = range(1, len(f) - max(cfg.future))  # a previous frame (velocities) and 1 s of future
            feats += [self._raw(f, t) for t in ok]
            where += [(c, t) for t in ok]
        if not where:
            raise ValueError(f"MotionMatching: clips shorter than {max(cfg.future) + 2} frames at {cfg.fps} fps")
        raw = np.stack(feats)  # (F, 27)
        self.where = np.array(where)  # (F, 2): clip, frame
        self.slices = self._slices()
        self.scale = np.concatenate([np.full(s.stop - s.start, raw[:, s].std(0).mean() / cfg.weights[g])
                                     for g, s in self.slices.items()])
        self.tree = cKDTree(raw / self.scale)
        self.index = {(int(c), int(t)): i for i, (c, t) in enumerate(self.where)}
        self.search_seconds, self.searches, self.frames_made = 0.0, 0, 0  # the search's cost, for the record

    def _slices(self) -> dict:
        n = 2 * len(self.config.future)
        sizes = {"feet_position": 6, "feet_velocity": 6, "hip_velocity": 3, "path_position": n,
                 "path_direction": n}
        out, at = {}, 0
        for g in GROUPS:
            out[g] = slice(at, at + sizes[g])
            at += sizes[g]
        return out

    def pose_features(self, frames: np.ndarray, t: int) -> np.ndarray:
        """positions_control frames (T, 66), t >= 1 -> (15,): feet positions, feet velocities, hip velocity."""
        fps = self.config.fps
        pose = frames[t, :-3].reshape(-1, 3)
        prev = frames[t - 1, :-3].reshape(-1, 3)
        feet_v = (pose[self.feet] - prev[self.feet]) * fps  # (2, 3) in the floor frame of t
        fwd, side = frames[t, -3], frames[t, -2]
        hip = np.array([side, (pose[0, 1] - prev[0, 1]) * fps, fwd])  # (x sideways, y up, z forward)
        return np.concatenate((pose[self.feet].ravel(), feet_v.ravel(), hip))

    def _raw(self, frames: np.ndarray, t: int, control: np.ndarray | None = None) -> np.ndarray:
        """Frame t's 27 features; the path from ``control`` (the request) or else from the frames' own control."""
        c = frames[t:, -3:] if control is None else control
        c = np.concatenate((c, np.repeat(c[-1:], max(0, max(self.config.future) + 1 - len(c)), 0)))  # hold the end
        path = future_path(c, self.config.fps, self.config.future)  # (3, 4)
        return np.concatenate((self.pose_features(frames, t), path[:, :2].ravel(), path[:, 2:].ravel()))

    def features(self, frames: np.ndarray, t: int, control: np.ndarray | None = None) -> np.ndarray:
        """The normalised, weighted query of frame t of ``frames`` (T, 66) -> (27,)."""
        return self._raw(frames, t, control) / self.scale

    def search(self, query: np.ndarray, k: int = 1) -> np.ndarray:
        """query (27,) normalised -> the k nearest database entries' indices (rows of ``where``), nearest first."""
        t0 = time.perf_counter()
        _, i = self.tree.query(query, k=k)
        self.search_seconds += time.perf_counter() - t0
        self.searches += 1
        return np.atleast_1d(i)

    def generate(self, start: np.ndarray, frames: int, control: np.ndarray | None = None,
                 rng: np.random.Generator | None = None) -> np.ndarray:
        """Play the database on from a start.

        start: positions_control frames (>= 2, 66) of the context, its last frame the current one; control:
        (>= 1, 3) the request per frame from the first new frame on, held at its last value past its end
        (None: free generation, one of the k nearest at random by ``rng``) -> positions_control (frames, 66):
        the new frames, whose root is the database's (decode with `representations.decode_positions` from the
        start's last frame)."""
        cfg = self.config
        rng = rng or np.random.default_rng(0)
        k = 1 if control is not None else cfg.k
        if control is not None and (control.ndim != 2 or control.shape[1] != 3):
            raise ValueError(f"MotionMatching.generate: control must be (T, 3), got {control.shape}")
        if control is not None:  # past its end the request holds its last value
            need = frames + max(cfg.future) + 1
            control = np.concatenate((control, np.repeat(control[-1:], max(0, need - len(control)), 0)))
        blend = max(1, int(round(cfg.blend_seconds * cfg.fps)))
        out = np.zeros((frames, start.shape[1]))
        self.frames_made += frames
        offset, left = start[-1] * 0.0, 0  # the inertialisation offset and its frames left
        cur, played, at = start, len(start) - 1, None  # the frames being played and the frame now
        for t in range(frames):
            if t % cfg.search_every == 0 or at is None or at[1] + 1 >= len(self.frames[at[0]]) - max(cfg.future):
                request = control[t:] if control is not None else (
                    np.repeat(start[-1:, -3:], max(cfg.future) + 1, 0) if at is None else None)  # free: hold the
                q = self.features(cur, played, request)  # start's control for the first search, then the clip's own
                cand = self.search(q, k)
                pick = self.where[cand[rng.integers(len(cand))] if k > 1 else cand[0]]
                same = at is not None and pick[0] == at[0] and abs(pick[1] - at[1]) <= cfg.skip_near
                if not same:  # jump: inertialise from the pose shown now to the new one
                    shown = cur[played] + (offset * _decay(left, blend) if left else 0.0)
                    at = (int(pick[0]), int(pick[1]))
                    offset, left = shown - self.frames[at[0]][at[1]], blend
            at = (at[0], at[1] + 1)
            cur, played = self.frames[at[0]], at[1]
            left = max(left - 1, 0)
            out[t] = cur[played] + offset * _decay(left, blend)
        return out


def _decay(left: int, blend: int) -> float:
    """Smoothstep from 1 (``left`` = blend frames to go) to 0 (none left)."""
    s = left / blend
    return float(s * s * (3 - 2 * s))
