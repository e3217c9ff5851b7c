"""Reference answers and self-checks for the exercises of notebooks/07_benchmark.ipynb.

Students write their own version in the notebook; each ``check_*`` runs it on fixed inputs and compares it with
the reference below, raising an AssertionError that says what is wrong.
"""

from __future__ import annotations

import numpy as np

from course_lib import benchmark as B
from course_lib.motion import CONTACT_HEIGHT
from course_lib.skeleton import Skeleton

__all__ = ["HeldPose", "check_flight_fraction", "check_flight_table", "check_held_pose", "check_which_measures",
           "flight_fraction", "flight_table", "which_measures"]

TOES = ("LeftToeBase", "RightToeBase")


# ----------------------------------------------------------------------------- reference answers


def flight_fraction(positions: np.ndarray, skeleton: Skeleton | None = None,
                    height: float = CONTACT_HEIGHT["ToeBase"]) -> float:
    """positions (N, T, 21, 3) -> the fraction of frames on which both toes are above ``height`` (m): the body
    is in the air (a run's flight phase, or a character floating)."""
    sk = skeleton or Skeleton.canonical()
    toes = positions[..., [sk.index(n) for n in TOES], 1]  # (N, T, 2)
    return float((toes > height).all(-1).mean())


def flight_table(rows: list, proto: B.Protocol, idx, seed: int = 0) -> dict:
    """{row name: flight_fraction of its sample from the clips idx}."""
    return {row.name: flight_fraction(row.generate(proto, idx, seed).positions) for row in rows}


class HeldPose:
    """A baseline a person would reject at once: the context's last pose, carried along at the context's last
    root velocity (a statue sliding on)."""

    name, controlled = "Held pose", False

    def _run(self, p: B.Protocol, idx, frames: int) -> np.ndarray:
        ctx = np.stack([p.clips[i].resample(B.FPS).positions()[: p.c0] for i in idx])  # (n, c0, 21, 3)
        v = ctx[:, -1, 0] - ctx[:, -2, 0]  # (n, 3) the root's last step per frame
        v[:, 1] = 0.0  # along the floor
        steps = np.arange(1, frames + 1)[None, :, None, None] * v[:, None, None, :]
        return ctx[:, -1:] + steps  # (n, frames, 21, 3)

    def generate(self, p: B.Protocol, idx, seed: int) -> B.Sample:
        return B.Sample(self._run(p, idx, p.frames), p.skeletons(idx))

    def long(self, p: B.Protocol, idx, seed: int) -> np.ndarray:
        return self._run(p, idx, len(B.long_times(p)))


def which_measures(result: dict, mocap: dict, factor: float = 2.0) -> set:
    """The lower-is-better measures on which ``result`` is above ``factor`` x the mocap's (or above 0.1 when the
    mocap's is 0), of those both measured."""
    keys = ("foot_skate", "penetration", "bone_length", "fid", "c2st", "frozen")
    return {k for k in keys if k in result and k in mocap and result[k] > max(factor * mocap[k], 0.1 * (mocap[k] == 0))}


# ----------------------------------------------------------------------------- checks


def _walk_on_floor(n: int = 2, T: int = 40) -> np.ndarray:
    """Canonical rest poses carried along +Z, the toes on the floor."""
    import torch

    sk = Skeleton.canonical()
    identity = torch.zeros(1, sk.num_joints, 4, dtype=torch.float64)
    identity[..., 0] = 1.0
    rest = sk.fk(identity, torch.zeros(1, 3, dtype=torch.float64)).numpy()[0]  # (21, 3) the rest pose
    rest = rest - [0.0, rest[:, 1].min(), 0.0]  # the lowest joint on the floor
    pos = np.repeat(rest[None, None], T, 1).repeat(n, 0).copy()
    pos[..., 2] += np.linspace(0, 2, T)[None, :, None]
    return pos


def check_flight_fraction(fn) -> None:
    """fn(positions (N, T, 21, 3)) -> float, compared with the reference on known answers."""
    pos = _walk_on_floor()
    got = fn(pos)
    assert abs(got) < 1e-12, f"both feet on the floor on every frame: expected 0, got {got}"
    up = pos.copy()
    up[..., 1] += 0.5
    assert abs(fn(up) - 1.0) < 1e-12, f"half a metre up on every frame: expected 1, got {fn(up)}"
    mixed = pos.copy()
    mixed[0, :10, :, 1] += 0.5  # 10 of 80 frames in the air
    sk = Skeleton.canonical()
    mixed[1, 10:20, sk.index("LeftToeBase"), 1] += 0.5  # one foot up: not flight
    want = flight_fraction(mixed)
    assert abs(fn(mixed) - want) < 1e-12, f"10 of 80 frames in the air: expected {want}, got {fn(mixed)}"


def check_flight_table(table: dict, rows: list, proto: B.Protocol, idx, seed: int = 0) -> None:
    want = flight_table(rows, proto, idx, seed)
    assert set(table) == set(want), f"expected a value for the rows {sorted(want)}, got {sorted(table)}"
    for name, v in want.items():
        assert abs(table[name] - v) < 1e-9, f"{name}: expected flight fraction {v:.4f}, got {table[name]}"


def check_held_pose(cls, proto: B.Protocol) -> None:
    """cls: the student's adapter class; its sample from clips 0-3 is compared with the reference's."""
    idx = np.arange(4)
    row = cls()
    got, want = row.generate(proto, idx, 0), HeldPose().generate(proto, idx, 0)
    assert isinstance(got, B.Sample), f"generate must return a benchmark.Sample, got {type(got).__name__}"
    assert got.positions.shape == want.positions.shape, \
        f"positions must be (4, {proto.frames}, 21, 3) at 30 fps, got {got.positions.shape}"
    gap = np.abs(got.positions[:, 0] - want.positions[:, 0]).max()
    assert gap < 1e-6, f"the first measured frame is off by {gap:.3f} m: the last context pose plus one step"
    err = np.abs(got.positions - want.positions).max()
    assert err < 1e-6, f"the pose must slide on at the last root step per frame: off by {err:.3f} m"
    assert row.long(proto, idx, 0).shape == (4, len(B.long_times(proto)), 21, 3), "long() must give 20 s at 30 fps"


def check_which_measures(found: set, result: dict, mocap: dict) -> None:
    want = which_measures(result, mocap)
    assert set(found) == want, f"expected {sorted(want)}, got {sorted(found)}"
