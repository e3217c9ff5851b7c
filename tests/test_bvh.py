"""BVH reading/writing (course_lib.bvh): the real CMU clip, crafted files, malformed files,
a hypothesis write -> read round trip and a fuzz test on the CMU text."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from course_lib.bvh import (
    CMU_SCALE,
    CMU_TO_CANONICAL,
    BVHError,
    cmu_sample_path,
    map_to_canonical,
    parse_bvh,
    read_bvh,
    retarget_names,
    write_bvh,
    write_site_sample,
)
from course_lib.motion import Motion
from course_lib.skeleton import CANONICAL_JOINTS, CANONICAL_PARENTS, Skeleton

DATA = Path(__file__).resolve().parent / "data"
ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")


@pytest.fixture(scope="module")
def cmu(cmu_bvh_path) -> Motion:
    return read_bvh(cmu_bvh_path, scale=CMU_SCALE)


def test_cmu_sample_path_is_the_packaged_clip(cmu_bvh_path, tmp_path, monkeypatch):
    """The clip is package data inside the imported course_lib, found from any working folder."""
    import course_lib

    found = cmu_sample_path()
    assert found == Path(course_lib.__file__).resolve().parent / "data" / "cmu_07_01_walk.bvh"
    assert found.is_file() and found.read_bytes() == cmu_bvh_path.read_bytes()
    monkeypatch.chdir(tmp_path)  # a folder with nothing around it: the same file
    assert cmu_sample_path() == found
    motion = read_bvh(found, scale=CMU_SCALE)
    assert motion.skeleton.num_joints == 31 and motion.fps == 120.0


def test_cmu_sample_has_a_data_card(cmu_bvh_path):
    """Beside the clip: its source, terms of use and numbers (frames counted from the file)."""
    card = (cmu_bvh_path.parent / "README.md").read_text()
    frames = int(next(line for line in cmu_bvh_path.read_text().splitlines() if line.startswith("Frames:")).split()[1])
    for fact in ("mocap.cs.cmu.edu", "subject 7", "NSF EIA-0196217", "120 fps", "31", "ZYX", "0.056444",
                 f"{frames} (`Frames: {frames}`)", "cmu_sample_path()"):
        assert fact in card, fact


def _pos(m: Motion, name: str) -> np.ndarray:
    return m.positions()[:, m.skeleton.index(name)]


# ---------------------------------------------------------------------------
# The real CMU clip
# ---------------------------------------------------------------------------

def test_cmu_loads_31_joints_120_fps(cmu):
    assert cmu.skeleton.num_joints == 31 and len(cmu) == 317 and cmu.fps == 120.0
    assert cmu.skeleton.names[:3] == ("Hips", "LHipJoint", "LeftUpLeg")
    assert cmu.skeleton.parents[cmu.skeleton.index("LThumb")] == cmu.skeleton.index("LeftHand")
    assert set(cmu.meta["channel_orders"]) == {"ZYX"} and cmu.meta["source_path"].endswith("cmu_07_01_walk.bvh")
    assert len(cmu.skeleton.end_sites) == 7  # 2 toes, head, 2 index fingers, 2 thumbs
    # LeftLeg OFFSET 2.36836 -6.50702 0 in the file, times the scale
    np.testing.assert_allclose(cmu.skeleton.offsets[3], np.array([2.36836, -6.50702, 0.0]) * CMU_SCALE)
    # root position = OFFSET (0) + channels of frame 0 (8.8721 15.7511 -31.7081)
    np.testing.assert_allclose(cmu.root_positions[0], np.array([8.8721, 15.7511, -31.7081]) * CMU_SCALE)


def test_cmu_first_frame_is_rest_pose(cmu):
    first = cmu[0]
    np.testing.assert_allclose(first.rotations[0, 0], [1, 0, 0, 0], atol=1e-12)  # root not rotated
    for side in ("Left", "Right"):
        hip, knee, ankle = (_pos(first, side + n)[0] for n in ("UpLeg", "Leg", "Foot"))
        thigh, shin = knee - hip, ankle - knee
        bend = np.degrees(np.arccos(thigh @ shin / np.linalg.norm(thigh) / np.linalg.norm(shin)))
        assert bend < 3.0, f"{side} knee bent by {bend:.1f} deg in the rest frame"
        assert np.linalg.norm((ankle - hip)[[0, 2]]) < 0.03, "legs should hang vertically"
        arm = _pos(first, side + "Hand")[0] - _pos(first, side + "Arm")[0]
        assert abs(arm[0]) > 0.95 * np.linalg.norm(arm), "arms should stretch sideways (T-pose)"
    assert abs(_pos(first, "LeftFoot")[0, 1] - _pos(first, "RightFoot")[0, 1]) < 0.01
    assert np.linalg.norm((_pos(first, "Head") - _pos(first, "Hips"))[0, [0, 2]]) < 0.05


def test_cmu_walking_speed_and_foot_heights(cmu):
    walk = cmu[1:]  # frame 0 is the rest pose
    step = walk.root_positions[-1, [0, 2]] - walk.root_positions[0, [0, 2]]
    speed = np.linalg.norm(step) / walk.duration
    assert 1.0 < speed < 1.8, f"walking speed {speed:.3f} m/s"
    pos = walk.positions()
    feet = walk.skeleton.feet  # LeftFoot, LeftToeBase, RightFoot, RightToeBase
    ground = pos[:, [feet[1], feet[3]], 1].min()
    low = pos[:, feet, 1].min(0) - ground  # (4,) lowest height of each ankle / toe joint
    assert np.all(low[[1, 3]] < 0.03), f"toes never reach the ground: {low}"
    assert np.all((0.01 < low[[0, 2]]) & (low[[0, 2]] < 0.12)), f"ankle heights implausible: {low}"
    # each foot spends part of the gait near the ground and part lifted (> 10 cm)
    assert np.all(pos[:, [feet[1], feet[3]], 1].max(0) - ground > 0.1)


def test_cmu_maps_onto_canonical_exactly(cmu):
    can = map_to_canonical(cmu)
    assert can.skeleton.names == CANONICAL_JOINTS and can.skeleton.parents == CANONICAL_PARENTS
    src = cmu.positions()
    kept = [cmu.skeleton.index(CMU_TO_CANONICAL[n]) for n in CANONICAL_JOINTS]
    err = np.abs(can.positions() - src[:, kept]).max()
    assert err < 1e-5 and can.meta["retarget_max_error"] < 1e-5
    # global rotations of the kept joints are kept too
    g = cmu.global_rotations()[:, kept]
    assert np.abs(np.abs((can.global_rotations() * g).sum(-1)) - 1).max() < 1e-9
    # CMU offsets (metres), canonical End Sites on the leaves
    np.testing.assert_allclose(can.skeleton.offsets[can.skeleton.index("LeftLeg")], cmu.skeleton.offsets[3])
    assert set(can.skeleton.end_sites) == set(can.skeleton.end_effectors)
    assert can.fps == 120.0 and can.contacts().any(0).all()


def test_naive_spine_mapping_is_not_exact_and_warns(cmu):
    """Canonical Spine = CMU Spine moves with LowerBack's rotation: no fixed offset can follow it."""
    naive = dict(CMU_TO_CANONICAL, Spine="Spine", Spine1="Spine1")
    with pytest.warns(UserWarning, match="differ from the source"):
        out = retarget_names(cmu, CANONICAL_JOINTS, CANONICAL_PARENTS, naive)
    assert out.meta["retarget_max_error"] > 1e-3


def test_mapping_errors_are_clear(cmu):
    with pytest.raises(KeyError, match="no source joint for Head"):
        retarget_names(cmu, CANONICAL_JOINTS, CANONICAL_PARENTS, {k: v for k, v in CMU_TO_CANONICAL.items()
                                                                   if k != "Head"})
    with pytest.raises(ValueError, match="not an ancestor"):
        retarget_names(cmu, CANONICAL_JOINTS, CANONICAL_PARENTS, dict(CMU_TO_CANONICAL, LeftFoot="RightFoot",
                                                                      RightFoot="LeftFoot"))


def test_cmu_write_read_round_trip_and_other_channel_orders(cmu, tmp_path):
    """Re-export in XYZ order (another '31-joint CMU file'): same positions, same canonical mapping."""
    path = write_bvh(cmu, tmp_path / "walk_xyz.bvh", order="XYZ", scale=1 / CMU_SCALE)
    again = read_bvh(path, scale=CMU_SCALE)
    assert set(again.meta["channel_orders"]) == {"XYZ"} and again.fps == 120.0
    assert np.abs(again.positions() - cmu.positions()).max() < 1e-5
    assert np.abs(map_to_canonical(again).positions() - map_to_canonical(cmu).positions()).max() < 1e-5


# ---------------------------------------------------------------------------
# Crafted files
# ---------------------------------------------------------------------------

def _reference_crafted(values: np.ndarray) -> np.ndarray:
    """(21,) channel values of crafted_mixed_orders.bvh -> (5, 3) positions, by scipy and numpy.

    Position channels place a joint by themselves (Blender, bvhio): the root's OFFSET (1, 2, 3) and
    Top's OFFSET (0.5, 3, 0) are not added."""
    def rot(order, angles):
        return Rotation.from_euler(order, angles, degrees=True)  # uppercase = intrinsic, as BVH

    g_pelvis = rot("YXZ", values[0:3])
    x_pelvis = values[[3, 5, 4]]  # channels Xposition Zposition Yposition
    g_upper = g_pelvis * rot("XYZ", values[6:9])
    x_upper = x_pelvis + g_pelvis.apply([0.0, 4.0, 0.5])
    x_top = x_upper + g_upper.apply(values[9:12])  # constant translation replaces the OFFSET
    x_arm = x_upper + g_upper.apply([3.0, 0.0, 0.0])
    x_leg = x_pelvis + g_pelvis.apply([1.0, -5.0, 0.0])
    return np.stack([x_pelvis, x_upper, x_top, x_arm, x_leg])


def test_crafted_orders_positions_tabs_crlf_match_scipy():
    path = DATA / "crafted_mixed_orders.bvh"
    assert b"\r\n" in path.read_bytes() and b"\t" in path.read_bytes()
    m = read_bvh(path)
    assert m.skeleton.names == ("Pelvis", "Upper", "Top", "Arm", "Leg")
    assert m.skeleton.parents == (-1, 0, 1, 1, 0)
    assert m.meta["channel_orders"] == ("YXZ", "XYZ", "ZXY", "XZY", "YZX")
    assert m.fps == pytest.approx(1 / 0.0333333) and len(m) == 3
    np.testing.assert_allclose(m.skeleton.end_sites[2], [0.0, 2.0, 0.0])
    rows = [ln.split() for ln in path.read_text().splitlines()[-4:] if ln.strip()]
    for t, row in enumerate(rows):
        np.testing.assert_allclose(m.positions()[t], _reference_crafted(np.array(row, float)), atol=1e-9)
    # the same file with LF and spaces gives the same motion
    plain = parse_bvh(path.read_text().replace("\r\n", "\n").replace("\t", " "))
    np.testing.assert_allclose(plain.positions(), m.positions(), atol=1e-12)
    scaled = read_bvh(path, scale=0.5)
    np.testing.assert_allclose(scaled.positions(), 0.5 * m.positions(), atol=1e-12)


BASE = """HIERARCHY
ROOT Hips
{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tJOINT Chest
\t{
\t\tOFFSET 0 10 0
\t\tCHANNELS 3 Xrotation Yrotation Zrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 5 0
\t\t}
\t}
}
MOTION
Frames: 2
Frame Time: 0.0333333
1 2 3 10 20 30 40 50 60
4 5 6 -10 -20 -30 -40 -50 -60
"""

MALFORMED = [  # ({line: replacement}, line named in the error, words of the message)
    ({20: ""}, 20, "truncated MOTION block"),
    ({17: "Frames: 3"}, 21, "truncated MOTION block"),
    ({17: "Frames: 1"}, 20, "more frame lines"),
    ({19: "1 2 3 10 20 30 40 50"}, 19, "8 values"),
    ({20: "4 5 6 -10 -20 x -40 -50 -60"}, 20, "'x' is not a number"),
    ({20: "4 5 6 -10 -20 1_0 -40 -50 -60"}, 20, "'1_0' is not a number"),
    ({19: "1 2 3 10 20 1e999 40 50 60"}, 19, "too large"),
    ({13: ""}, 16, "unbalanced braces"),
    ({15: "}\n}"}, 16, "unbalanced braces"),
    ({9: "ROTATION 3 Xrotation Yrotation Zrotation"}, 9, "unknown keyword 'ROTATION'"),
    ({8: ""}, 10, "no OFFSET"),
    ({9: ""}, 10, "no CHANNELS"),
    ({9: "CHANNELS 3 Xrotation Yrotation Wrotation"}, 9, "unknown channel name 'Wrotation'"),
    ({9: "CHANNELS 3 Xrotation Yrotation"}, 9, "says 3 channels but lists 2"),
    ({9: "CHANNELS 2 Xrotation Yrotation"}, 9, "0 or 3 rotation channels"),
    ({9: "CHANNELS 3 Xrotation Xrotation Zrotation"}, 9, "listed twice"),
    ({12: "OFFSET 0 5"}, 12, "OFFSET needs 3 numbers"),
    ({8: "OFFSET 0 ten 0"}, 8, "'ten' is not a number"),
    ({10: "End Sight"}, 10, "expected 'End Site'"),
    ({6: "JOINT Hips"}, 6, "used twice"),
    ({7: "("}, 7, "expected '{'"),
    ({1: "HIERARCH"}, 1, "starts with HIERARCHY"),
    ({16: "MOTIONS"}, 16, "expected MOTION"),
    ({17: "Frames: two"}, 17, "Frames: N"),
    ({18: "Frame Time: -1"}, 18, "Frame Time"),
    ({9: "CHANNELS 6 Xposition Yposition Zposition Xrotation Yrotation Zrotation",
      19: "1 2 3 10 20 30 0 0 0 40 50 60", 20: "4 5 6 -10 -20 -30 0 0 1 -40 -50 -60"}, 9,
     "translation channels on non-root joints are not supported"),
]


def _edit(text: str, edits: dict[int, str]) -> str:
    lines = text.split("\n")
    for n, new in edits.items():
        lines[n - 1] = new
    return "\n".join(lines)


@pytest.mark.parametrize("edits, line, words", MALFORMED, ids=[w for _, _, w in MALFORMED])
def test_malformed_file_names_line_and_problem(edits, line, words):
    with pytest.raises(BVHError, match=f"^line {line}: ") as err:
        parse_bvh(_edit(BASE, edits))
    assert err.value.line == line and words in str(err.value)


def test_base_and_edge_files_read(tmp_path):
    m = parse_bvh(BASE)
    assert m.skeleton.names == ("Hips", "Chest") and len(m) == 2 and m.meta["channel_orders"] == ("ZXY", "XYZ")
    const = parse_bvh(_edit(BASE, {9: "CHANNELS 6 Xrotation Xposition Yposition Zposition Yrotation Zrotation",
                                   19: "1 2 3 10 20 30 40 1 2 3 50 60", 20: "4 5 6 -10 -20 -30 -40 1 2 3 -50 -60"}))
    np.testing.assert_allclose(const.skeleton.offsets[1], [1.0, 2.0, 3.0])  # constant translation, not OFFSET
    np.testing.assert_allclose(const.rotations, m.rotations, atol=1e-12)
    fixed_root = parse_bvh(_edit(BASE, {4: "OFFSET 1 2 3", 5: "CHANNELS 3 Zrotation Xrotation Yrotation",
                                        19: "10 20 30 40 50 60", 20: "-10 -20 -30 -40 -50 -60"}))
    np.testing.assert_allclose(fixed_root.root_positions, [[1, 2, 3], [1, 2, 3]])
    np.testing.assert_allclose(fixed_root.rotations, m.rotations, atol=1e-12)
    empty = parse_bvh(_edit(BASE, {17: "Frames: 0", 19: "", 20: ""}))
    assert len(empty) == 0
    (tmp_path / "bad.bvh").write_bytes(BASE.encode().replace(b"-60", b"-6\xff"))
    with pytest.raises(BVHError, match="^line 20: the file is not UTF-8"):
        read_bvh(tmp_path / "bad.bvh")
    (tmp_path / "empty.bvh").write_text("")
    with pytest.raises(BVHError, match="^line 1: "):
        read_bvh(tmp_path / "empty.bvh")


# ---------------------------------------------------------------------------
# Writing
# ---------------------------------------------------------------------------

def test_write_refuses_to_overwrite_and_is_atomic(tmp_path, monkeypatch):
    m = parse_bvh(BASE)
    path = write_bvh(m, tmp_path / "out.bvh")
    before = path.read_bytes()
    with pytest.raises(FileExistsError, match="exists; pass overwrite=True"):
        write_bvh(m, path)
    assert path.read_bytes() == before

    def broken_replace(src, dst):
        raise OSError("disk full")
    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(OSError, match="disk full"):
        write_bvh(m, path, order="XYZ", overwrite=True)
    monkeypatch.undo()
    assert path.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["out.bvh"]
    write_bvh(m, path, order="XYZ", overwrite=True)
    assert read_bvh(path).meta["channel_orders"] == ("XYZ", "XYZ")
    with pytest.raises(ValueError, match="permutation of 'XYZ'"):
        write_bvh(m, tmp_path / "o.bvh", order="XYX")


def test_written_file_is_standard_bvh(tmp_path):
    m = parse_bvh(BASE)
    text = write_bvh(m, tmp_path / "w.bvh", order="ZYX").read_text()
    lines = text.splitlines()
    assert lines[:3] == ["HIERARCHY", "ROOT Hips", "{"]
    assert lines[4].strip() == "CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation"
    assert "\tEnd Site" in text and "MOTION" in lines and "Frames: 2" in lines and "Frame Time: 0.03333333333" in lines
    # a leaf without End Site gets a short default one, continuing its bone
    leafy = Skeleton(("a", "b"), (-1, 0), np.array([[0.0, 0, 0], [0, 2, 0]]))
    mo = Motion(np.tile([1.0, 0, 0, 0], (1, 2, 1)), np.zeros((1, 3)), leafy, 30.0)
    assert read_bvh(write_bvh(mo, tmp_path / "leaf.bvh")).skeleton.end_sites[1].tolist() == [0.0, 0.5, 0.0]


@pytest.mark.parametrize("order", ORDERS)
def test_round_trip_each_order_on_canonical_skeleton(order, tmp_path):
    rng = np.random.default_rng(7)
    q = rng.normal(size=(5, 21, 4))
    m = Motion(q / np.linalg.norm(q, axis=-1, keepdims=True), rng.normal(size=(5, 3)), Skeleton.canonical(), 30.0)
    again = read_bvh(write_bvh(m, tmp_path / "c.bvh", order=order))
    assert again.skeleton.names == m.skeleton.names and again.meta["channel_orders"] == (order,) * 21
    assert np.abs(again.positions() - m.positions()).max() < 1e-7
    # rotations equal up to sign; End Sites kept
    assert np.abs(np.abs((again.rotations * m.rotations).sum(-1)) - 1).max() < 1e-9
    assert all(np.allclose(again.skeleton.end_sites[j], v) for j, v in m.skeleton.end_sites.items())


@st.composite
def random_motions(draw):
    J = draw(st.integers(1, 7))
    T = draw(st.integers(1, 3))
    parents = [-1] + [draw(st.integers(0, j - 1)) for j in range(1, J)]
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    q = rng.normal(size=(T, J, 4))
    if draw(st.booleans()):  # gimbal lock: middle angle of +-90 degrees in the written order
        order = draw(st.sampled_from(ORDERS))
        angles = rng.uniform(-180, 180, (T, J, 3))
        angles[..., 1] = draw(st.sampled_from([90.0, -90.0]))
        q = Rotation.from_euler(order, angles.reshape(-1, 3), degrees=True).as_quat()[:, [3, 0, 1, 2]]
        q = q.reshape(T, J, 4)
    else:
        order = draw(st.one_of(st.sampled_from(ORDERS), st.lists(st.sampled_from(ORDERS), min_size=J, max_size=J)))
    offsets = rng.uniform(-10, 10, (J, 3))
    skeleton = Skeleton(tuple(f"j{j}" for j in range(J)), tuple(parents), offsets)
    motion = Motion(q / np.linalg.norm(q, axis=-1, keepdims=True), rng.uniform(-100, 100, (T, 3)), skeleton,
                    draw(st.sampled_from([24.0, 30.0, 60.0, 120.0])))
    return motion, order


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(random_motions())
def test_write_read_round_trip_property(case):
    motion, order = case
    with tempfile.TemporaryDirectory() as tmp:
        again = read_bvh(write_bvh(motion, Path(tmp) / "m.bvh", order=order))
    # BVH stores joints depth-first: the file's order is a permutation of ours with the same tree
    perm = [again.skeleton.index(n) for n in motion.skeleton.names]
    assert [perm.index(p) if p >= 0 else -1 for p in np.array(again.skeleton.parents)[perm]] == \
        list(motion.skeleton.parents)
    assert again.fps == motion.fps
    want = [order] * motion.skeleton.num_joints if isinstance(order, str) else order
    assert [again.meta["channel_orders"][j] for j in perm] == list(want)
    assert np.abs(again.positions()[:, perm] - motion.positions()).max() < 1e-5


# ---------------------------------------------------------------------------
# Fuzzing: mutated CMU text raises BVHError or reads into a valid Motion, nothing else
# ---------------------------------------------------------------------------

JUNK = ["", "abc", "nan", "inf", "1e999", "-", "1.2.3", "{", "}", "JOINT", "End", "OFFSET", "CHANNELS", "MOTION",
        "Frames:", "0", "-1", "7", "99999999999", "1e-320", "Xrotation", "é", "\x00", "1_0", "٣", "²", "ROOT Hips"]


@pytest.fixture(scope="module")
def cmu_head_text(cmu_bvh_path) -> str:
    """The CMU file's hierarchy and its first 20 frames (fast enough to fuzz 200 times)."""
    lines = cmu_bvh_path.read_text().splitlines()
    motion = lines.index("MOTION")
    return "\n".join(lines[: motion + 1] + ["Frames: 20"] + lines[motion + 2: motion + 23]) + "\n"


mutations = st.lists(st.tuples(st.sampled_from(["delete", "duplicate", "swap", "junk", "truncate"]),
                               st.integers(0, 10**6), st.integers(0, 10**6), st.sampled_from(JUNK)),
                     min_size=1, max_size=3)


def _mutate(text: str, ops) -> str:
    for kind, a, b, junk in ops:
        lines = text.split("\n")
        i, k = a % len(lines), b % len(lines)
        if kind == "delete":
            del lines[i]
        elif kind == "duplicate":
            lines.insert(i, lines[i])
        elif kind == "swap":
            lines[i], lines[k] = lines[k], lines[i]
        elif kind == "junk":
            toks = lines[i].split() or [""]
            toks[b % len(toks)] = junk
            lines[i] = " ".join(toks)
        else:
            text = text[: a % (len(text) + 1)]
            continue
        text = "\n".join(lines)
    return text


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                    HealthCheck.function_scoped_fixture])
@given(ops=mutations)
def test_fuzzed_cmu_text_raises_only_bvh_error(cmu_head_text, ops):
    text = _mutate(cmu_head_text, ops)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.bvh"
        path.write_text(text, encoding="utf-8")
        try:
            m = read_bvh(path, scale=CMU_SCALE)
        except BVHError as err:
            assert str(err).startswith(f"line {err.line}: ") and err.line >= 1
            return
    pos = m.positions()
    assert np.isfinite(pos).all() and pos.shape == (len(m), m.skeleton.num_joints, 3)
    assert np.allclose(np.linalg.norm(m.rotations, axis=-1), 1.0)


# ---------------------------------------------------------------------------
# Inputs the reader and the writer must agree on
# ---------------------------------------------------------------------------

def test_write_refuses_what_read_would_reject(tmp_path):
    m = parse_bvh(BASE)
    m.rotations[1, 1] = np.nan  # an in-place edit after the Motion was checked
    with pytest.raises(ValueError, match="rotations contain NaN or inf; read_bvh would reject"):
        write_bvh(m, tmp_path / "nan.bvh")
    m = parse_bvh(BASE)
    m.rotations[0, 0] *= 2.0
    with pytest.raises(ValueError, match="unit quaternions"):
        write_bvh(m, tmp_path / "long.bvh")
    for scale in (float("nan"), 0.0, -1.0, float("inf")):
        with pytest.raises(ValueError, match="scale must be a positive finite number"):
            write_bvh(parse_bvh(BASE), tmp_path / "s.bvh", scale=scale)
    m = parse_bvh(BASE)
    m.skeleton.end_sites[1][1] = np.inf
    with pytest.raises(ValueError, match="End Site offsets contain NaN or inf"):
        write_bvh(m, tmp_path / "end.bvh")
    m = parse_bvh(BASE)
    m.root_positions[0, 0] = 1e308
    with pytest.raises(ValueError, match="root_positions \\(times scale 10\\) contain NaN or inf"):
        write_bvh(m, tmp_path / "big.bvh", scale=10)
    assert list(tmp_path.iterdir()) == []


def test_write_names_a_missing_folder(tmp_path):
    with pytest.raises(FileNotFoundError, match=f"folder {tmp_path / 'no' / 'such'} does not exist"):
        write_bvh(parse_bvh(BASE), tmp_path / "no" / "such" / "m.bvh")


def test_deep_hierarchy_reads_and_writes(tmp_path):
    J = 1000
    skeleton = Skeleton(tuple(f"j{j}" for j in range(J)), (-1, *range(J - 1)), np.tile([0.0, 0.01, 0.0], (J, 1)))
    m = Motion(np.tile([1.0, 0, 0, 0], (2, J, 1)), np.zeros((2, 3)), skeleton, 30.0)
    again = read_bvh(write_bvh(m, tmp_path / "deep.bvh"))
    assert again.skeleton.parents == skeleton.parents
    np.testing.assert_allclose(again.positions(), m.positions(), atol=1e-9)


@pytest.mark.parametrize("name", ["{", "}", "a{b", "Hip}"])
def test_reader_and_writer_agree_on_joint_names(name, tmp_path):
    with pytest.raises(BVHError, match=f"^line 6: joint name {name!r} contains a brace"):
        parse_bvh(_edit(BASE, {6: f"JOINT {name}"}))
    m = Motion(np.tile([1.0, 0, 0, 0], (1, 2, 1)), np.zeros((1, 3)),
               Skeleton(("root", name), (-1, 0), np.zeros((2, 3))), 30.0)
    with pytest.raises(ValueError, match="cannot be written to BVH"):
        write_bvh(m, tmp_path / "n.bvh")
    ok = Motion(m.rotations, m.root_positions, Skeleton(("root", "é.x:1"), (-1, 0), np.zeros((2, 3))), 30.0)
    assert read_bvh(write_bvh(ok, tmp_path / "ok.bvh")).skeleton.names == ("root", "é.x:1")


def test_byte_order_mark_and_zero_frames(tmp_path):
    (tmp_path / "bom.bvh").write_bytes(b"\xef\xbb\xbf" + BASE.encode())
    np.testing.assert_allclose(read_bvh(tmp_path / "bom.bvh").positions(), parse_bvh(BASE).positions())
    empty = parse_bvh(_edit(BASE, {17: "Frames: 0", 19: "", 20: ""}))
    assert len(empty) == 0 and empty.duration == 0.0 and empty.positions().shape == (0, 2, 3)
    assert len(empty.resample(60.0)) == 0
    again = read_bvh(write_bvh(empty, tmp_path / "empty.bvh"))
    assert len(again) == 0 and again.skeleton.names == ("Hips", "Chest")
    assert parse_bvh(BASE)[:1].duration == 0.0 and parse_bvh(BASE).duration == pytest.approx(1 / 30)


def test_site_sample_creates_the_folder_and_replaces_only_its_own_files(tmp_path):
    m = parse_bvh(BASE)
    site = tmp_path / "site"
    path = write_site_sample(m, "00_walk", site=site)
    assert path == site / "00_walk.bvh" and np.allclose(read_bvh(path).positions(), m.positions())
    assert (site / "00_walk.bvh.sha256").is_file()
    again = write_site_sample(m[:1], "00_walk.bvh", site=site)  # its own earlier sample: replaced
    assert again == path and len(read_bvh(path)) == 1
    path.write_text(path.read_text().replace("Frames: 1", "Frames: 1 "))  # edited by hand since
    with pytest.raises(FileExistsError, match="not a sample this function wrote"):
        write_site_sample(m, "00_walk", site=site)
    (site / "mine.bvh").write_text("a student's own file")
    with pytest.raises(FileExistsError, match="mine.bvh exists"):
        write_site_sample(m, "mine", site=site)
    assert (site / "mine.bvh").read_text() == "a student's own file"
    for bad in ("../up", "a/b", "", " x"):
        with pytest.raises(ValueError, match="must be letters, digits"):
            write_site_sample(m, bad, site=site)
