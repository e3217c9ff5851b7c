"""Property-based rules of the public API under misuse (hypothesis draws the inputs):

- every measure returns a finite number, or raises a ValueError that names the measure: never NaN, inf, another
  exception type, or a number computed at the wrong frame rate;
- every writer changes no file but its named output and documented companions, and those only when asked to
  replace them (the folder is hashed before and after);
- a Motion is made only with a finite positive frame rate, and indexing it behaves like a sequence.
"""

from __future__ import annotations

import hashlib
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from course_lib import render
from course_lib.bvh import write_bvh
from course_lib.datasets import data_card, dataset_paths, save_motions, write_dataset, write_npz
from course_lib.evaluation import metrics
from course_lib.motion import Motion
from course_lib.skeleton import Skeleton

SKELETON = Skeleton.canonical()
EXAMPLES = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])

FPS = st.one_of(st.none(), st.sampled_from([0.0, -30.0, math.inf, -math.inf, math.nan, "30", True]),
                st.floats(min_value=1.0, max_value=240.0))
VALUES = st.sampled_from(["ok", "nan", "inf"])


def walk(frames: int, fps: float = 30.0, speed: float = 1.0, seed: int = 0, wobble: float = 0.02) -> Motion:
    """A standing body gliding along +Z at ``speed`` m/s, joints wobbling by about ``wobble`` rad (seeded)."""
    rng = np.random.default_rng(seed)
    rot = np.zeros((frames, SKELETON.num_joints, 4))
    rot[..., 0] = 1.0
    rot[..., 1:] = rng.normal(0, wobble, (frames, SKELETON.num_joints, 3))
    rot /= np.linalg.norm(rot, axis=-1, keepdims=True)
    root = np.zeros((frames, 3))
    root[:, 1] = 0.95
    root[:, 2] = speed * np.arange(frames) / fps
    return Motion(rot, root, SKELETON, fps)


def positions(n: int, frames: int, joints: int, dim: int, values: str, seed: int) -> np.ndarray:
    x = np.random.default_rng(seed).normal(0, 0.5, (n, frames, joints, dim))
    if values != "ok" and x.size:
        x.flat[x.size // 2] = math.nan if values == "nan" else math.inf
    return x


def assert_finite_or_clear(fn_name: str, call):
    try:
        out = call()
    except ValueError as err:
        assert fn_name in str(err) or "fps must be positive" in str(err), f"{fn_name}: unclear message {err}"
        return None
    values = out.values() if isinstance(out, dict) else [out]
    assert all(isinstance(v, float) and math.isfinite(v) for v in values), f"{fn_name} returned {out}"
    return out


MEASURES_WITH_FPS = ("foot_skate", "jitter", "root_jerk_split")
MEASURES = (*MEASURES_WITH_FPS, "ground_penetration", "bone_length_violation")


@EXAMPLES
@given(fn=st.sampled_from(MEASURES), n=st.integers(0, 3), frames=st.integers(0, 7), joints=st.sampled_from([20, 21]),
       dim=st.sampled_from([2, 3]), values=VALUES, fps=FPS, seed=st.integers(0, 9))
def test_a_measure_of_any_array_is_finite_or_a_clear_value_error(fn, n, frames, joints, dim, values, fps, seed):
    x = positions(n, frames, joints, dim, values, seed)
    kwargs = {"fps": fps} if fn in MEASURES_WITH_FPS else {}
    out = assert_finite_or_clear(fn, lambda: getattr(metrics, fn)(x, **kwargs))
    if out is not None:  # it answered: then the input was one it can answer
        assert n >= 1 and joints == 21 and dim == 3 and values == "ok"


@EXAMPLES
@given(fn=st.sampled_from(MEASURES), lengths=st.lists(st.integers(0, 8), min_size=0, max_size=3),
       rates=st.lists(st.sampled_from([30.0, 60.0]), min_size=3, max_size=3), fps=FPS)
def test_a_measure_of_motions_uses_their_own_rate_or_refuses(fn, lengths, rates, fps):
    clips = [walk(T, rates[i]) for i, T in enumerate(lengths)]
    kwargs = {"fps": fps} if fn in MEASURES_WITH_FPS and fps is not None else {}
    out = assert_finite_or_clear(fn, lambda: getattr(metrics, fn)(clips, **kwargs))
    if out is not None and fn in MEASURES_WITH_FPS:
        assert len({m.fps for m in clips}) == 1, "clips at two rates were measured together"
        assert "fps" not in kwargs or float(kwargs["fps"]) == clips[0].fps, "an fps argument overrode the clips'"


@EXAMPLES
@given(frames=st.integers(2, 12), fps=st.sampled_from([15.0, 30.0, 60.0, 120.0]), speed=st.floats(0.1, 3.0),
       step=st.integers(1, 3))
def test_foot_skate_of_a_glide_is_its_speed_at_any_rate_and_stride(frames, fps, speed, step):
    """Known answer: the toes of the gliding body (1.5 cm above the floor, no wobble) slide at the glide's speed,
    whatever the rate and the stride of the slice (m[::step] is at fps / step)."""
    m = walk(frames * step, fps, speed, wobble=0.0)[::step]
    assert metrics.foot_skate([m]) == pytest.approx(speed, rel=1e-9)
    assert metrics.jitter([m]) == pytest.approx(0.0, abs=1e-6) if len(m) >= 4 else True


@EXAMPLES
@given(fps=FPS.filter(lambda f: f is not None))
def test_a_motion_is_made_only_at_a_finite_positive_rate(fps):
    ok = isinstance(fps, float) and math.isfinite(fps) and fps > 0
    if ok:
        assert walk(3, fps).fps == fps
    else:
        with pytest.raises(ValueError, match="fps must be positive"):
            Motion(walk(3).rotations, walk(3).root_positions, SKELETON, fps)


@EXAMPLES
@given(frames=st.integers(0, 8), index=st.integers(-12, 12))
def test_indexing_a_motion_is_like_indexing_a_list(frames, index):
    m, frame_list = walk(frames), list(range(frames))
    try:
        expected = frame_list[index]
    except IndexError:
        with pytest.raises(IndexError, match="out of range"):
            m[index]
        return
    one = m[np.int64(index)]
    assert len(one) == 1 and one.fps == m.fps
    np.testing.assert_array_equal(one.root_positions[0], m.root_positions[expected])


@EXAMPLES
@given(frames=st.integers(0, 12), start=st.one_of(st.none(), st.integers(-12, 12)),
       stop=st.one_of(st.none(), st.integers(-12, 12)), step=st.sampled_from([None, 1, 2, 3, -1, -2]))
def test_slicing_a_motion_keeps_real_time(frames, start, stop, step):
    m = walk(frames)
    sub = m[start:stop:step]
    assert len(sub) == len(list(range(frames))[start:stop:step])
    assert sub.fps == m.fps / abs(step or 1)


# ----------------------------------------------------------------------------- writers


def snapshot(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.iterdir() if p.is_file()}


def _dataset(path, overwrite):
    card = data_card([walk(4)], name="probe", seed=0, command="pytest", description="a probe")
    write_dataset([walk(4)], path, card=card, overwrite=overwrite)


def test_a_dataset_with_a_malformed_card_writes_nothing(tmp_path):
    with pytest.raises(ValueError, match="the card lacks 'description'"):
        write_dataset([walk(4)], tmp_path / "set.npz", card={"name": "probe"})
    assert list(tmp_path.iterdir()) == []


WRITERS = {  # name -> (write(path, overwrite), the files it may write given its path)
    "write_npz": (lambda p, o: write_npz({"a": np.zeros(2)}, p, overwrite=o), lambda p: [p]),
    "save_motions": (lambda p, o: save_motions([walk(3)], p, overwrite=o), lambda p: [p]),
    "write_dataset": (_dataset, lambda p: list(dataset_paths(p))),
    "write_bvh": (lambda p, o: write_bvh(walk(3), p, overwrite=o), lambda p: [p]),
    "write_mp4": (lambda p, o: render.write_mp4(np.zeros((2, 16, 16, 3), np.uint8), 5, p, overwrite=o),
                  lambda p: [p]),
}
SUFFIX = {"write_npz": ".npz", "save_motions": ".npz", "write_dataset": ".npz", "write_bvh": ".bvh",
          "write_mp4": ".mp4"}
NEIGHBOURS = ["out{s}", "out.card.json", "out.card.md", "out.md", "out.json", "other{s}", "out{s}.sha256", "notes.txt"]


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(writer=st.sampled_from(sorted(WRITERS)), existing=st.sets(st.sampled_from(NEIGHBOURS)), overwrite=st.booleans())
def test_a_writer_changes_only_its_outputs_and_those_only_when_asked(writer, existing, overwrite):
    write, outputs = WRITERS[writer]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name in existing:
            (folder / name.format(s=SUFFIX[writer])).write_text(f"the user's {name}\n")
        target = folder / f"out{SUFFIX[writer]}"
        allowed = {p.name for p in outputs(target)}
        before = snapshot(folder)
        clash = sorted(allowed & set(before))
        try:
            write(target, overwrite)
        except FileExistsError as err:
            assert clash and not overwrite, f"{writer} refused without reason: {err}"
            assert any(name in str(err) for name in clash), f"{writer}: the message names no file: {err}"
            assert snapshot(folder) == before, f"{writer} refused but changed files"
            return
        after = snapshot(folder)
        assert not clash or overwrite, f"{writer} replaced {clash} without overwrite=True"
        changed = {name for name in before if after.get(name) != before[name]}
        assert changed <= allowed, f"{writer} changed {changed - allowed}, not among its outputs {allowed}"
        assert set(after) - set(before) <= allowed | {n + ".sha256" for n in allowed}
