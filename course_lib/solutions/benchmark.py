"""Reference answers and self-checks for the exercises of notebooks/07_benchmark.ipynb.

Students write their own version in the notebook; each ``check_*`` runs it on fixed inputs and compares it with
the reference below, raising an AssertionError that says what is wrong.
"""

from __future__ import annotations

import numpy as np

from course_lib import benchmark as B
from course_lib.motion import CONTACT_HEIGHT
from course_lib.skeleton import Skeleton

__all__ = ["HeldPose", "apd_per_start", "apd_samples", "check_apd_per_start", "check_flight_fraction",
           "check_flight_table", "check_held_pose", "check_which_measures", "check_which_measures_prediction",
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


def apd_samples(row, proto: B.Protocol, seed: int = 0) -> tuple[np.ndarray, int]:
    """The raw samples of the benchmark's APD test for one generation seed, as `B.evaluate_seed` draws them:
    ``apd_samples`` draws from each of the first ``apd_starts`` starts of half B, generation seed + 100.
    -> (positions (starts * S, T, 21, 3), each start's S draws one after another; S)."""
    _, b = B.halves(len(proto.clips), seed)
    starts, samples = proto.spec.apd_starts, proto.spec.apd_samples
    return row.generate(proto, np.repeat(b[:starts], samples), seed + 100).positions, samples


def apd_per_start(raw: np.ndarray, samples: int) -> np.ndarray:
    """raw (starts * S, T, J, 3), each start's S samples one after another -> (starts,) APD of each start, m:
    1/(S(S-1)) sum_{i != j} mean_{t,k} ||x_i[t,k] - x_j[t,k]||."""
    x = raw.reshape(-1, samples, *raw.shape[1:])  # (starts, S, T, J, 3)
    d = np.linalg.norm(x[:, :, None] - x[:, None, :], axis=-1).mean(axis=(3, 4))  # (starts, S, S)
    return d.sum(axis=(1, 2)) / (samples * (samples - 1))


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


def check_apd_per_start(fn, row, proto: B.Protocol, seed: int = 0) -> None:
    """fn(raw (starts * S, T, 21, 3), S) -> (starts,) APD per start: on known answers, then on the row's raw samples,
    whose mean must be the benchmark's APD of that row and seed."""
    T = 6
    base = np.random.default_rng(0).normal(size=(1, T, 21, 3))
    copies = np.repeat(base, 3, 0)  # one start, 3 identical samples
    got = np.asarray(fn(copies, 3), float)
    assert got.shape == (1,), f"one start of 3 samples: expected an array of 1 value, got shape {got.shape}"
    assert abs(got[0]) < 1e-12, f"3 identical samples: expected APD 0, got {got[0]}"
    two = np.concatenate([base, base + [1.0, 0.0, 0.0], base, base + [0.0, 0.0, 2.0]])  # 2 starts of 2 samples
    got = np.asarray(fn(two, 2), float)
    assert got.shape == (2,), f"2 starts of 2 samples: expected 2 values, got shape {got.shape}"
    assert np.allclose(got, [1.0, 2.0]), (f"samples 1 m and 2 m apart at every joint: expected [1, 2], got {got}"
                                          + (" (average over ordered pairs i != j: divide by S(S-1))"
                                             if np.allclose(got, [0.5, 1.0]) else "")
                                          + (" (samples are grouped per start: reshape to (starts, S, ...))"
                                             if np.allclose(got, [1.0, 1.0]) or np.allclose(got, [1.5, 1.5]) else ""))
    raw, samples = apd_samples(row, proto, seed)
    mine = np.asarray(fn(raw, samples), float)
    want = apd_per_start(raw, samples)
    assert mine.shape == want.shape and np.allclose(mine, want, rtol=1e-9), \
        f"{row.name}'s raw samples: per start expected {np.round(want, 4)}, got {np.round(mine, 4)}"
    _, b = B.halves(len(proto.clips), seed)
    bench = B.apd_of(row, proto, b[:proto.spec.apd_starts], samples, seed + 100)
    assert abs(mine.mean() - bench) < 1e-9, \
        f"the mean over starts {mine.mean():.5f} differs from the benchmark's {bench:.5f}"
    print(f"{row.name}, seed {seed}: APD per start {np.round(mine, 3)} m; their mean {mine.mean():.4f} m "
          f"= the benchmark's {bench:.4f} m")


def check_which_measures_prediction(predicted, proto: B.Protocol, reference: list, floor: float) -> None:
    """predicted: the set of measures on which the held pose scores above twice the Mocap row, written before the
    run; the check runs both rows through `B.evaluate_seed` (seed 0) and compares."""
    keys = ("foot_skate", "penetration", "bone_length", "fid", "c2st", "frozen")
    assert isinstance(predicted, (set, frozenset, list, tuple)), f"give a set of measure names, got {predicted!r}"
    unknown = set(predicted) - set(keys)
    assert not unknown, f"{sorted(unknown)} are not among the measures asked about: {keys}"
    held = B.evaluate_seed(HeldPose(), proto, 0, reference, floor)
    mocap = B.evaluate_seed(B.Mocap(), proto, 0, reference, floor)
    print(f"{'measure':12s} {'held pose':>10s} {'mocap':>10s}")
    for k in keys:
        print(f"{k:12s} {held[k]:10.4g} {mocap[k]:10.4g}")
    want = which_measures(held, mocap)
    missed, extra = sorted(want - set(predicted)), sorted(set(predicted) - want)
    assert not missed and not extra, (f"the run says {sorted(want)}; you predicted {sorted(predicted)}"
                                      + (f": {missed} see the statue" if missed else "")
                                      + (f"; {extra} do not" if extra else ""))
