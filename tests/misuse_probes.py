"""The course's library and commands under misuse: a probe set tried as a careful new user and a hostile
tester would, each case with the outcome it must give.

    python tests/misuse_probes.py [--out FILE.md]     # the table and the counts per outcome class

Every case runs in a fresh temporary folder (the data scripts on small files made there, never on data/).
Its outcome falls in one of five classes:

- ``clear error``: it raised, and the message names the problem (the word in ``names``);
- ``fine``: an input the library handles, with the right answer (the case checks the value);
- ``unhelpful``: it raised, but the message does not name the problem (or a valid input raised);
- ``wrong answer``: it returned where it should have refused;
- ``data loss``: a file that existed before the case changed or vanished although the case did not ask to
  replace it (every case's folder is hashed before and after).

tests/test_misuse_probes.py runs every case and requires ``clear error`` or ``fine`` as written beside it.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import io
import json
import math
import os
import subprocess
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CLASSES = ("clear error", "fine", "unhelpful", "wrong answer", "data loss")


@dataclass(frozen=True)
class Case:
    area: str
    what: str
    run: Callable[[Path], str]  # tmp folder -> a description of a correct result; raises for an error
    expect: str  # the exception class expected, or "handled"
    names: str  # a word the message (or the description) must contain
    may_change: tuple[str, ...] = ()  # files in the case's folder it is asked to replace (relative names)


# ---------------------------------------------------------------- helpers

_PROTECTED: dict[Path, str] = {}  # files a case made before the call under test -> their sha256


def _protect(*paths: Path) -> None:
    """Record files the user 'made': the call under test may not change or remove them (unless may_change)."""
    for path in paths:
        _PROTECTED[Path(path)] = hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _walk(frames: int = 12):
    from course_lib.motion import Motion
    from course_lib.skeleton import Skeleton

    skel = Skeleton.canonical()
    rot = np.zeros((frames, skel.num_joints, 4))
    rot[..., 0] = 1.0
    root = np.zeros((frames, 3))
    root[:, 1] = 0.95
    root[:, 2] = np.linspace(0, 0.5, frames)
    return Motion(rot, root, skel, 30.0)


def _bvh_text(root_offset: str = "0 0 0", frames: str = "2", body: str | None = None, name: str = "Hips") -> str:
    rows = body if body is not None else "0 0 0 0 0 0 0 0 0\n1 2 3 0 0 0 0 0 0\n"
    return (f"HIERARCHY\nROOT {name}\n{{\n  OFFSET {root_offset}\n"
            "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
            "  JOINT Spine\n  {\n    OFFSET 0 1 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n"
            "    End Site\n    {\n      OFFSET 0 1 0\n    }\n  }\n}\n"
            f"MOTION\nFrames: {frames}\nFrame Time: 0.0333333\n{rows}")


def _read(tmp: Path, text: str | bytes):
    from course_lib.bvh import read_bvh

    path = tmp / "in.bvh"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    return read_bvh(path)


def _script(tmp: Path, name: str, *args: str) -> str:
    """Run a data script's main() in this process (as `python data_scripts/<name> ...` would, from ``tmp``); the
    last stderr line is the message of a refusal (argparse's exit status 2)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(name.removesuffix(".py"), ROOT / "data_scripts" / name)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    err, out = io.StringIO(), io.StringIO()
    cwd = os.getcwd()
    os.chdir(tmp)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            module.main(list(args))
    except SystemExit as stop:
        last = (err.getvalue().strip().splitlines() or ["(no message)"])[-1]
        raise _ScriptError(f"SystemExit (exit {stop.code}): {last}") from None
    finally:
        os.chdir(cwd)
    lines = out.getvalue().strip().splitlines()
    return f"exit 0: {lines[-1] if lines else ''}"


class _ScriptError(Exception):
    pass


def _clean_file(tmp: Path) -> Path:
    from course_lib.datasets import save_motions

    path = tmp / "clean.npz"
    save_motions([_walk(30), _walk(30)], path)
    _protect(path)
    return path


def _checkpoint(tmp: Path) -> Path:
    from course_lib.models.vae import PoseVae, VaeConfig
    from course_lib.training import save_checkpoint

    path = tmp / "vae.pt"
    config = VaeConfig(x_dim=6, hidden=8)
    save_checkpoint(PoseVae(config), config, path, command="python tests/misuse_probes.py")
    return path


def _load(path: Path, **kw):
    from course_lib.models.vae import PoseVae, VaeConfig
    from course_lib.training import load_checkpoint

    load_checkpoint(path, PoseVae, VaeConfig, **kw)
    return "loaded"


# ---------------------------------------------------------------- the cases

def _bvh_root_offset(tmp):
    m = _read(tmp, _bvh_text(root_offset="0 36 0"))
    y = float(m.root_positions[1, 1])
    if abs(y - 2.0) > 1e-9:
        raise AssertionError(f"root placed at y={y}, not by its channels (2)")
    return "handled: the root is placed by its position channels (y = 2 at frame 1), the OFFSET kept as rest"


def _written_root_offset(tmp):
    from course_lib.bvh import read_bvh, write_bvh

    m = _read(tmp, _bvh_text(root_offset="0 36 0"))
    back = read_bvh(write_bvh(m, tmp / "out.bvh"))
    err = float(np.abs(back.root_positions - m.root_positions).max())
    if err > 1e-6:
        raise AssertionError(f"round trip moved the root by {err}")
    return f"handled: written and read back, the root moves by {err:.1e}"


def _renamed_checkpoint(tmp):
    path = _checkpoint(tmp)
    renamed = path.with_name("copy.pt")
    renamed.write_bytes(path.read_bytes())  # without its sidecar
    return _load(renamed)


def _corrupt_with_sidecar(tmp):
    path = _checkpoint(tmp)
    data = bytearray(path.read_bytes())
    data[-10] ^= 0xFF
    path.write_bytes(bytes(data))
    return _load(path)


def _manifest_without_sha(tmp):
    path = _checkpoint(tmp)
    (tmp / "MANIFEST.json").write_text(json.dumps({"vae": {"command": "python -m course_lib.reproduce vae"}}))
    return _load(path)


def _malformed_manifest(tmp):
    path = _checkpoint(tmp)
    (tmp / "MANIFEST.json").write_text("{ not json")
    return _load(path)


def _corrupt_classifier(tmp):
    from course_lib.evaluation import load_classifier
    from course_lib.evaluation.classifiers import checkpoint_path

    copy = tmp / "action.pt"
    data = bytearray(checkpoint_path("action").read_bytes())
    data[-10] ^= 0xFF
    copy.write_bytes(bytes(data))
    load_classifier("action", path=copy)
    return "loaded"


def _torch(values):
    import torch

    return torch.tensor(values, dtype=torch.float64)


def _zero_quat(tmp):
    from course_lib.rotations import quat_to_matrix

    quat_to_matrix(_torch([0.0, 0.0, 0.0, 0.0]))
    return "a matrix"


def _non_unit_quat(tmp):
    from course_lib.rotations import quat_to_matrix

    quat_to_matrix(_torch([1.0, 1.0, 0.0, 0.0]))
    return "a matrix"


def _doubled_fk(tmp):
    import torch

    from course_lib.skeleton import Skeleton, forward_kinematics

    skel = Skeleton.canonical()
    q = torch.zeros(1, skel.num_joints, 4, dtype=torch.float64)
    q[..., 0] = 2.0
    forward_kinematics(q, torch.zeros(1, 3, dtype=torch.float64), torch.as_tensor(skel.offsets), skel.parents)
    return "positions"


def _numpy_fk(tmp):
    from course_lib.skeleton import forward_kinematics

    m = _walk(3)
    pos, _ = forward_kinematics(m.rotations, m.root_positions, m.skeleton.offsets, m.skeleton.parents)
    return f"handled: numpy in, positions {tuple(pos.shape)} out"


def _zero_axis(tmp):
    from course_lib.rotations import axis_angle_to_quat

    axis_angle_to_quat(_torch([0.0, 0.0, 0.0]), 0.5)
    return "a quaternion"


def _reflection(tmp):
    from course_lib.rotations import matrix_to_quat

    matrix_to_quat(_torch([[-1.0, 0, 0], [0, 1, 0], [0, 0, 1]]))
    return "a quaternion"


def _noisy_over_input(tmp):
    clean = _clean_file(tmp)
    before = clean.read_bytes()
    try:
        return _script(tmp, "make_noisy.py", "--input", str(clean), "--out", str(clean), "--force")
    finally:
        if clean.read_bytes() != before:
            raise AssertionError("make_noisy changed its input")


def _noisy_clips(n):
    def case(tmp):
        clean = _clean_file(tmp)
        return _script(tmp, "make_noisy.py", "--input", str(clean), "--out", str(tmp / "noisy.npz"), "--clips", n)
    return case


def _locomotion(*args):
    def case(tmp):
        return _script(tmp, "make_locomotion.py", "--clips", "2", "--out", str(tmp / "loco.npz"), *args)
    return case


def _write_nan_after_edit(tmp):
    from course_lib.bvh import write_bvh

    m = _walk()
    m.rotations[3, 2, 0] = math.nan
    write_bvh(m, tmp / "out.bvh")
    return "written"


def _write_scale_nan(tmp):
    from course_lib.bvh import write_bvh

    write_bvh(_walk(), tmp / "out.bvh", scale=math.nan)
    return "written"


def _write_inf_end_site(tmp):
    import dataclasses

    from course_lib.bvh import write_bvh

    m = _walk()
    skel = m.skeleton
    ends = {k: np.array([np.inf, 0, 0]) for k in list(skel.end_sites)[:1]}
    m.skeleton = dataclasses.replace(skel, end_sites={**skel.end_sites, **ends})
    write_bvh(m, tmp / "out.bvh")
    return "written"


def _write_missing_folder(tmp):
    from course_lib.bvh import write_bvh

    write_bvh(_walk(), tmp / "no_such_folder" / "out.bvh")
    return "written"


def _deep_hierarchy(tmp):
    from course_lib.bvh import read_bvh, write_bvh

    depth = 1000
    text = ("HIERARCHY\nROOT J0\n{\n OFFSET 0 0 0\n"
            " CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n")
    for i in range(1, depth):
        text += f"JOINT J{i}\n{{\n OFFSET 0 0.01 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n"
    text += "End Site\n{\n OFFSET 0 0.01 0\n}\n" + "}\n" * depth
    text += "MOTION\nFrames: 1\nFrame Time: 0.0333\n" + " ".join(["0"] * (3 + 3 * depth)) + "\n"
    m = _read(tmp, text)
    back = read_bvh(write_bvh(m, tmp / "out.bvh"))
    return f"handled: {back.skeleton.num_joints} joints read, written and read back"


def _brace_name(tmp):
    _read(tmp, _bvh_text(name="{"))
    return "read"


def _bom(tmp):
    m = _read(tmp, b"\xef\xbb\xbf" + _bvh_text().encode())
    return f"handled: read ({m.num_frames} frames)"


def _zero_frames(tmp):
    m = _read(tmp, _bvh_text(frames="0", body=""))
    return f"handled: {m.num_frames} frames, duration {m.duration:.1f} s"


def _malformed_line(tmp):
    _read(tmp, _bvh_text(body="0 0 0 0 0 0 0 0 0\n1 2 x 0 0 0 0 0 0\n"))
    return "read"


def _empty_npz(tmp):
    from course_lib.datasets import load_motions

    (tmp / "empty.npz").write_bytes(b"")
    load_motions(tmp / "empty.npz")
    return "loaded"


def _npy(tmp):
    from course_lib.datasets import load_motions

    np.save(tmp / "x.npy", np.zeros(3))
    load_motions(tmp / "x.npy")
    return "loaded"


def _dataset_mode(tmp):
    from course_lib.datasets import load_dataset

    load_dataset("locomotion", mode="fast", data_dir=tmp)
    return "loaded"


CASES = [
    Case("BVH", "root with a non-zero OFFSET (0 36 0) and position channels", _bvh_root_offset, "handled", "channels"),
    Case("BVH", "the same motion written by write_bvh and read back", _written_root_offset, "handled", "read back"),
    Case("checkpoint", "a renamed copy without manifest entry or sidecar", _renamed_checkpoint, "ValueError",
         "cannot verify"),
    Case("checkpoint", "corrupted bytes, with its sidecar", _corrupt_with_sidecar, "ValueError", "sha256 mismatch"),
    Case("checkpoint", "a manifest entry without sha256", _manifest_without_sha, "ValueError", "no valid sha256"),
    Case("checkpoint", "a malformed MANIFEST.json", _malformed_manifest, "ValueError", "not valid JSON"),
    Case("checkpoint", "load_classifier(path=...) of a corrupted copy", _corrupt_classifier, "ValueError",
         "cannot verify"),
    Case("rotations", "quat_to_matrix of a zero quaternion", _zero_quat, "ValueError", "zero"),
    Case("rotations", "quat_to_matrix of (1, 1, 0, 0)", _non_unit_quat, "ValueError", "unit"),
    Case("rotations", "forward_kinematics with doubled quaternions", _doubled_fk, "ValueError", "unit"),
    Case("rotations", "numpy arrays (motion.rotations) into forward_kinematics", _numpy_fk, "handled", "numpy"),
    Case("rotations", "axis_angle_to_quat with a zero axis", _zero_axis, "ValueError", "axis"),
    Case("rotations", "matrix_to_quat of a reflection", _reflection, "ValueError", "reflection"),
    Case("data scripts", "make_noisy.py --out equal to --input, with --force", _noisy_over_input, "_ScriptError",
         "input"),
    Case("data scripts", "make_noisy.py --clips -1", _noisy_clips("-1"), "_ScriptError", "--clips"),
    Case("data scripts", "make_noisy.py --clips 0", _noisy_clips("0"), "_ScriptError", "--clips"),
    Case("data scripts", "make_locomotion.py --subjects 0", _locomotion("--subjects", "0"), "_ScriptError",
         "--subjects"),
    Case("data scripts", "make_locomotion.py --subjects -2", _locomotion("--subjects", "-2"), "_ScriptError",
         "--subjects"),
    Case("data scripts", "make_locomotion.py --duration nan", _locomotion("--duration", "nan"), "_ScriptError",
         "--duration"),
    Case("write_bvh", "NaN rotations after an in-place edit", _write_nan_after_edit, "ValueError", "NaN"),
    Case("write_bvh", "scale=nan", _write_scale_nan, "ValueError", "scale"),
    Case("write_bvh", "an infinite End Site offset", _write_inf_end_site, "ValueError", "End Site"),
    Case("write_bvh", "a missing folder", _write_missing_folder, "FileNotFoundError", "no_such_folder"),
    Case("BVH", "a hierarchy 1,000 joints deep", _deep_hierarchy, "handled", "1000 joints"),
    Case("BVH", "a joint named '{'", _brace_name, "BVHError", "name"),
    Case("BVH", "a UTF-8 byte-order mark", _bom, "handled", "read"),
    Case("BVH", "Frames: 0", _zero_frames, "handled", "duration 0.0"),
    Case("BVH", "a malformed number in a frame line", _malformed_line, "BVHError", "line"),
    Case("datasets", "load_motions of a 0-byte file", _empty_npz, "ValueError", "empty.npz"),
    Case("datasets", "load_motions of a .npy file", _npy, "ValueError", "x.npy"),
    Case("datasets", "load_dataset(mode='fast')", _dataset_mode, "ValueError", "fast"),
]


# ---------------------------------------------------------------- generated probes (issue: misuse classes)
# Known answers: _walk(T) stands on its toes (1.5 cm above the floor) and glides 0.5 m along +Z over T frames at
# 30 fps, so its toes slide at 0.5 / (T - 1) * 30 m/s (foot skate), its joints move in straight lines (jitter 0)
# and nothing goes below the floor (penetration 0).

def _card(name: str) -> dict:
    from course_lib.datasets import data_card

    return data_card([_walk(4)], name=name, seed=0, command="python tests/misuse_probes.py", description="probe")


def _last_line(stream: io.StringIO) -> str:
    return (stream.getvalue().strip().splitlines() or ["(no message)"])[-1]


def _speed(frames: int) -> float:
    return 0.5 / (frames - 1) * 30


def _other_skeleton_walk(frames: int = 12):
    """A 2-joint skeleton's motion (not the canonical 21 joints)."""
    from course_lib.motion import Motion
    from course_lib.skeleton import Skeleton

    skel = Skeleton(names=["Hips", "Spine"], parents=[-1, 0], offsets=np.array([[0, 0, 0], [0, 0.1, 0]]))
    rot = np.zeros((frames, 2, 4))
    rot[..., 0] = 1.0
    return Motion(rot, np.zeros((frames, 3)), skel, 30.0)


def _at(fps: float, frames: int = 12):
    import dataclasses

    return dataclasses.replace(_walk(frames), fps=fps)


def _nan_root_after(frames: int = 12):
    m = _walk(frames)
    m.root_positions[2, 1] = math.nan
    return m


def _positions(frames: int = 12) -> np.ndarray:
    return _walk(frames).positions()[None]  # (1, T, 21, 3)


def _measure(fn_name: str, *args, **kw):
    from course_lib.evaluation import metrics

    return getattr(metrics, fn_name)(*args, **kw)


def _value_case(fn_name: str, make, expected: float, tol: float = 1e-6, **kw):
    def case(tmp):
        value = _measure(fn_name, make(), **kw)
        if not (math.isfinite(value) and abs(value - expected) <= tol * max(1.0, abs(expected))):
            raise AssertionError(f"{fn_name} gave {value}, the known answer is {expected}")
        return f"handled: {fn_name} = {value:.6g} (known answer {expected:.6g})"
    return case


def _call_case(fn_name: str, make, **kw):
    def case(tmp):
        value = _measure(fn_name, make(), **kw)
        return f"returned {value!r}"
    return case


_FPS_MEASURES = ("foot_skate", "jitter", "root_jerk_split")
_MEASURES = ("foot_skate", "jitter", "root_jerk_split", "ground_penetration", "bone_length_violation")
_MIN_FRAMES = {"foot_skate": 2, "jitter": 4, "root_jerk_split": 4, "ground_penetration": 1,
               "bone_length_violation": 1}


def _measure_cases() -> list[Case]:
    cases = []
    for fn in _MEASURES:
        takes_fps = fn in _FPS_MEASURES
        add = cases.append
        add(Case("measures", f"{fn}([]) (no clips)", _call_case(fn, lambda: []), "ValueError", "no clips"))
        add(Case("measures", f"{fn} of a 0-frame clip", _call_case(fn, lambda: [_walk(12)[0:0]]), "ValueError",
                 "0 frames"))
        short = _MIN_FRAMES[fn] - 1
        if short >= 1:
            add(Case("measures", f"{fn} of a {short}-frame clip (below its shortest, {_MIN_FRAMES[fn]})",
                     _call_case(fn, lambda s=short: [_walk(12)[0:s]]), "ValueError", "needs at least"))
        if fn == "bone_length_violation":  # bones need no frame rate, and each Motion brings its own skeleton
            add(Case("measures", f"{fn} of clips at 30 and 60 fps", _value_case(fn, lambda: [_walk(12), _at(60.0)],
                     0.0, tol=1e-9), "handled", "known answer"))
        else:
            add(Case("measures", f"{fn} of clips at 30 and 60 fps", _call_case(fn, lambda: [_walk(12), _at(60.0)]),
                     "ValueError", "fps"))
            add(Case("measures", f"{fn} of a 21-joint and a 2-joint clip",
                     _call_case(fn, lambda: [_walk(12), _other_skeleton_walk()]), "ValueError", "joints"))
        add(Case("measures", f"{fn} of positions with a NaN", _call_case(fn, lambda: np.where(
            np.arange(21)[None, None, :, None] == 3, np.nan, _positions()), **({"fps": 30} if takes_fps else {})),
            "ValueError", "NaN"))
        add(Case("measures", f"{fn} of positions with an inf", _call_case(fn, lambda: _positions() * np.inf,
                 **({"fps": 30} if takes_fps else {})), "ValueError", "inf"))
        add(Case("measures", f"{fn} of (1, T, 20, 3) positions (20 joints)", _call_case(fn, lambda: _positions()[
            :, :, :20], **({"fps": 30} if takes_fps else {})), "ValueError", "21 joints"))
        add(Case("measures", f"{fn} of (1, T, 21, 2) positions", _call_case(fn, lambda: _positions()[..., :2],
                 **({"fps": 30} if takes_fps else {})), "ValueError", "(N, T, J, 3)"))
        add(Case("measures", f"{fn} of a Motion whose root got a NaN after it was made",
                 _call_case(fn, lambda: [_nan_root_after()]), "ValueError", "NaN"))
        add(Case("measures", f"{fn} of a list mixing a Motion and an array",
                 _call_case(fn, lambda: [_walk(12), _positions()[0]]), "ValueError", "mixing"))
        add(Case("measures", f"{fn} of a string", _call_case(fn, lambda: "walk.bvh"), "ValueError",
                 "expected a numeric array"))
        if takes_fps:
            add(Case("measures", f"{fn}(Motions at 30 fps, fps=120)", _call_case(fn, lambda: [_walk(12)], fps=120),
                     "ValueError", "leave fps out"))
            add(Case("measures", f"{fn}(positions) without fps", _call_case(fn, _positions), "ValueError",
                     "give fps"))
            for bad in (0, -30, math.inf, math.nan, "30"):
                add(Case("measures", f"{fn}(positions, fps={bad!r})", _call_case(fn, _positions, fps=bad),
                         "ValueError", "fps must be positive"))
    # known answers: the measures on valid input give the right number
    cases += [
        Case("measures", "foot_skate of the gliding walk (Motion)", _value_case("foot_skate", lambda: [_walk(12)],
             _speed(12)), "handled", "known answer"),
        Case("measures", "foot_skate of the same positions with fps=30", _value_case(
            "foot_skate", _positions, _speed(12), fps=30), "handled", "known answer"),
        Case("measures", "foot_skate of the walk taken every 2nd frame (m[::2], 15 fps)", _value_case(
            "foot_skate", lambda: [_walk(13)[::2]], _speed(13)), "handled", "known answer"),
        Case("measures", "foot_skate of a 2-frame clip", _value_case("foot_skate", lambda: [_walk(12)[0:2]],
             _speed(12)), "handled", "known answer"),
        Case("measures", "foot_skate with numpy-integer fps", _value_case("foot_skate", _positions, _speed(12),
             fps=np.int64(30)), "handled", "known answer"),
        Case("measures", "jitter of straight-line motion", _value_case("jitter", lambda: [_walk(12)], 0.0,
             tol=1e-6), "handled", "known answer"),
        Case("measures", "ground_penetration of a 1-frame clip", _value_case("ground_penetration",
             lambda: [_walk(12)[0]], 0.0), "handled", "known answer"),
        Case("measures", "bone_length_violation of FK positions", _value_case(
            "bone_length_violation", lambda: [_walk(12)], 0.0, tol=1e-9), "handled", "known answer"),
        Case("measures", "bone_length_violation of clips on two skeletons (each its own bones)", _value_case(
            "bone_length_violation", lambda: [_walk(12), _other_skeleton_walk()], 0.0, tol=1e-9), "handled",
            "known answer"),
        Case("measures", "speed_error(Motions at 30 fps, 1.0, fps=120)", _call_case(
            "speed_error", lambda: [_walk(12)], target_speed=1.0, fps=120), "ValueError", "leave fps out"),
        Case("measures", "speed_error of the glide against its own speed", _value_case(
            "speed_error", lambda: [_walk(12)], 0.0, tol=1e-9, target_speed=_speed(12)), "handled", "known answer"),
        Case("measures", "speed_error of a 1-frame clip", _call_case("speed_error", lambda: [_walk(12)[0]],
             target_speed=1.0), "ValueError", "needs at least 2"),
    ]
    return cases


# --- Motion: frame rates, indexing, shapes

def _motion_with(**kw):
    def case(tmp):
        from course_lib.motion import Motion

        m = _walk(6)
        args = dict(rotations=m.rotations, root_positions=m.root_positions, skeleton=m.skeleton, fps=30.0)
        args.update(kw)
        Motion(**args)
        return "made"
    return case


def _index(index, check=None):
    def case(tmp):
        m = _walk(10)
        sub = m[index]
        if check is None:
            return f"returned {len(sub)} frames"
        return check(m, sub)
    return case


def _expect_frames(n, fps):
    def check(m, sub):
        if len(sub) != n or sub.fps != fps:
            raise AssertionError(f"{len(sub)} frames at {sub.fps} fps, expected {n} at {fps}")
        return f"handled: {n} frames at {fps:g} fps"
    return check


def _resample(fps):
    def case(tmp):
        _walk(10).resample(fps)
        return "resampled"
    return case


def _fk_after(edit):
    def case(tmp):
        m = _walk(6)
        edit(m)
        m.positions()
        return "positions"
    return case


def _contacts_after_nan(tmp):
    m = _walk(6)
    m.root_positions[:, 0] = math.inf
    m.contacts()
    return "contacts"


def _motion_cases() -> list[Case]:
    rows = []
    for bad in (math.inf, -math.inf, math.nan, 0.0, -30.0, "30", None, True):
        rows.append(Case("Motion", f"Motion(fps={bad!r})", _motion_with(fps=bad), "ValueError",
                         "fps must be positive"))
    rows += [
        Case("Motion", "Motion(skeleton=None)", _motion_with(skeleton=None), "TypeError", "skeleton must be"),
        Case("Motion", "Motion(skeleton='canonical')", _motion_with(skeleton="canonical"), "TypeError",
             "skeleton must be"),
        Case("Motion", "rotations (6, 20, 4) for 21 joints", _motion_with(rotations=np.ones((6, 20, 4)) / 2),
             "ValueError", "(T, 21, 4)"),
        Case("Motion", "root_positions (5, 3) for 6 frames", _motion_with(root_positions=np.zeros((5, 3))),
             "ValueError", "root_positions must be (6, 3)"),
        Case("Motion", "root_positions with a NaN", _motion_with(root_positions=np.full((6, 3), np.nan)),
             "ValueError", "NaN"),
        Case("Motion", "zero quaternions", _motion_with(rotations=np.zeros((6, 21, 4))), "ValueError", "unit"),
        Case("Motion", "m[100] on 10 frames", _index(100), "IndexError", "out of range"),
        Case("Motion", "m[-11] on 10 frames", _index(-11), "IndexError", "out of range"),
        Case("Motion", "m[10] on 10 frames", _index(10), "IndexError", "out of range"),
        Case("Motion", "m[-1]", _index(-1, _expect_frames(1, 30.0)), "handled", "1 frames"),
        Case("Motion", "m[np.int64(3)]", _index(np.int64(3), _expect_frames(1, 30.0)), "handled", "1 frames"),
        Case("Motion", "m[::2] keeps real time (15 fps)", _index(slice(None, None, 2), _expect_frames(5, 15.0)),
             "handled", "15 fps"),
        Case("Motion", "m[::-1] (played backwards at 30 fps)", _index(slice(None, None, -1),
             _expect_frames(10, 30.0)), "handled", "30 fps"),
        Case("Motion", "m[2:5]", _index(slice(2, 5), _expect_frames(3, 30.0)), "handled", "3 frames"),
        Case("Motion", "m[::0]", _index(slice(None, None, 0)), "ValueError", "step"),
        Case("Motion", "m[::1.5]", _index(slice(None, None, 1.5)), "ValueError", "step"),
        Case("Motion", "m[[1, 5, 6]] (uneven frame times)", _index([1, 5, 6]), "TypeError", "integer or a slice"),
        Case("Motion", "m[2.0]", _index(2.0), "TypeError", "integer or a slice"),
        Case("Motion", "m[True]", _index(True), "TypeError", "integer or a slice"),
        Case("Motion", "resample(0)", _resample(0), "ValueError", "fps must be positive"),
        Case("Motion", "resample(inf)", _resample(math.inf), "ValueError", "fps must be positive"),
        Case("Motion", "resample(nan)", _resample(math.nan), "ValueError", "fps must be positive"),
        Case("Motion", "positions() after a NaN written into root_positions", _fk_after(
            lambda m: m.root_positions.__setitem__((1, 0), math.nan)), "ValueError", "NaN"),
        Case("Motion", "positions() after a NaN written into rotations", _fk_after(
            lambda m: m.rotations.__setitem__((1, 3, 0), math.nan)), "ValueError", "NaN"),
        Case("Motion", "contacts() after an inf written into root_positions", _contacts_after_nan, "ValueError",
             "inf"),
    ]
    return rows


# --- writers: nothing a user made is lost

def _write(path: Path, text: str = "the user's own file\n") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    _protect(path)
    return path


def _locomotion_over_card(tmp):
    _write(tmp / "d" / "walks.card.md")
    return _script(tmp, "make_locomotion.py", "--clips", "2", "--subjects", "1", "--duration", "1",
                   "--workers", "1", "--out", str(tmp / "d" / "walks.npz"))


def _locomotion_over_card_json(tmp):
    _write(tmp / "walks.card.json", "{}")
    return _script(tmp, "make_locomotion.py", "--clips", "2", "--out", str(tmp / "walks.npz"))


def _actions_over_card(tmp):
    _write(tmp / "acts.card.md")
    return _script(tmp, "make_actions.py", "--subjects", "1", "--out", str(tmp / "acts.npz"))


def _locomotion_over_npz(tmp):
    _write(tmp / "walks.npz")
    return _script(tmp, "make_locomotion.py", "--clips", "2", "--out", str(tmp / "walks.npz"))


def _locomotion_huge(tmp):
    return _script(tmp, "make_locomotion.py", "--clips", "1000000000", "--out", str(tmp / "big.npz"))


def _actions_zero(tmp):
    return _script(tmp, "make_actions.py", "--subjects", "0", "--out", str(tmp / "a.npz"))


def _actions_fps_inf(tmp):
    return _script(tmp, "make_actions.py", "--fps", "inf", "--out", str(tmp / "a.npz"))


def _noisy_upper_case(tmp):
    from course_lib.datasets import write_dataset

    clean = tmp / "clean.npz"
    write_dataset([_walk(30), _walk(30)], clean, card=_card("clean"))
    _protect(*tmp.iterdir())
    return _script(tmp, "make_noisy.py", "--input", str(clean), "--out", str(tmp / "clean.NPZ"), "--force")


def _noisy_text_input(tmp):
    _write(tmp / "notes.txt", "a student's notes\n")
    return _script(tmp, "make_noisy.py", "--input", str(tmp / "notes.txt"), "--out", str(tmp / "n.npz"))


def _noisy_over_card(tmp):
    clean = _clean_file(tmp)
    _write(tmp / "noisy.card.json", "{}")
    return _script(tmp, "make_noisy.py", "--input", str(clean), "--out", str(tmp / "noisy.npz"))


def _run_main(main, argv) -> str:
    """Call a command's main(argv); argparse's refusal (SystemExit) becomes _ScriptError with its message."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            main(list(argv))
        except SystemExit as stop:
            raise _ScriptError(f"SystemExit (exit {stop.code}): {_last_line(err)}") from None
    return "ran"


def _benchmark(*args):
    def case(tmp):
        from course_lib import benchmark

        return _run_main(benchmark.main, args)
    return case


def _benchmark_md(tmp):
    _write(tmp / "results.md")
    return _benchmark("--ci", "--out", str(tmp / "results.md"))(tmp)


def _benchmark_companion(tmp):
    _write(tmp / "summary.md")
    return _benchmark("--ci", "--out", str(tmp / "summary.json"))(tmp)


def _benchmark_existing(tmp):
    _write(tmp / "summary.json", "{}")
    return _benchmark("--ci", "--out", str(tmp / "summary.json"))(tmp)


def _student_tool():
    import importlib.util

    spec = importlib.util.spec_from_file_location("student_copies", ROOT / "tools" / "student_copies.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _lesson_with_exercise(folder: Path) -> Path:
    import nbformat

    nb = nbformat.v4.new_notebook()
    setup = nbformat.v4.new_code_cell("x = 1", metadata={"nbgrader": {
        "grade": False, "grade_id": "exercises-setup", "locked": True, "schema_version": 3, "solution": False,
        "task": False}})
    sol = nbformat.v4.new_code_cell("y = 0\n### BEGIN SOLUTION\ny = 2\n### END SOLUTION", metadata={"nbgrader": {
        "grade": False, "grade_id": "ex1", "locked": False, "schema_version": 3, "solution": True, "task": False}})
    check = nbformat.v4.new_code_cell("assert y == 2", metadata={"nbgrader": {
        "grade": True, "grade_id": "ex1-check", "locked": True, "points": 1, "schema_version": 3,
        "solution": False, "task": False}})
    nb.cells = [nbformat.v4.new_markdown_cell("## Exercises"), setup, sol, check]
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "01_lesson.ipynb"
    nbformat.write(nb, path)
    _protect(path)
    return path


def _student(*args):
    def run(tmp):
        return _run_main(_student_tool().main, args)
    return run


def _student_into_source(tmp):
    _lesson_with_exercise(tmp / "lessons")
    return _student("--notebooks", str(tmp / "lessons"), "--out", str(tmp / "lessons"), "--force")(tmp)


def _student_into_source_dot(tmp):
    _lesson_with_exercise(tmp / "lessons")
    return _student("--notebooks", str(tmp / "lessons"), "--out", str(tmp / "lessons" / "."), "--force")(tmp)


def _student_keeps_answers(tmp):
    _lesson_with_exercise(tmp / "lessons")
    answers = _write(tmp / "student" / "01_lesson.ipynb", "{\"my\": \"answers\"}")
    _student("--notebooks", str(tmp / "lessons"), "--out", str(tmp / "student"))(tmp)
    if answers.read_text() != "{\"my\": \"answers\"}":
        raise AssertionError("answers replaced without --force")
    return "handled: the copy holding answers is kept"


def _student_force_backs_up(tmp):
    _lesson_with_exercise(tmp / "lessons")
    _write(tmp / "student" / "01_lesson.ipynb", "{\"my\": \"answers\"}")
    _student("--notebooks", str(tmp / "lessons"), "--out", str(tmp / "student"), "--force")(tmp)
    backups = list((tmp / "student" / "backups").glob("*/01_lesson.ipynb"))
    if len(backups) != 1 or backups[0].read_text() != "{\"my\": \"answers\"}":
        raise AssertionError(f"no backup of the answers: {backups}")
    return "handled: --force kept the answers in a timestamped backup"


def _make_clean_keeps_student(tmp):
    proc = subprocess.run(["make", "-n", "clean"], cwd=ROOT, capture_output=True, text=True, timeout=60)
    removed = [w for line in proc.stdout.splitlines() if line.startswith("rm ") for w in line.split()]
    if "student" in removed or "student/" in removed:
        raise AssertionError(f"make clean removes student/: {proc.stdout}")
    return "handled: make clean removes " + " ".join(w for w in removed if not w.startswith("-") and w != "rm")


def _npz_over(tmp):
    from course_lib.datasets import write_npz

    _write(tmp / "x.npz")
    write_npz({"a": np.zeros(2)}, tmp / "x.npz")
    return "written"


def _save_motions_over(tmp):
    from course_lib.datasets import save_motions

    _write(tmp / "mine.npz")
    save_motions([_walk(4)], tmp / "mine.npz")
    return "written"


def _dataset_over_card(tmp):
    from course_lib.datasets import write_dataset

    _write(tmp / "set.card.md")
    write_dataset([_walk(4)], tmp / "set.npz", card=_card("set"))
    return "written"


def _dataset_over_input(tmp):
    from course_lib.datasets import dataset_paths, write_dataset

    _clean_file(tmp)
    write_dataset([_walk(4)], tmp / "clean.npz", card={}, overwrite=True, inputs=dataset_paths(tmp / "clean.npz"))
    return "written"


def _dataset_force(tmp):
    from course_lib.datasets import load_motions, write_dataset

    _write(tmp / "set.npz")
    _write(tmp / "set.card.md")
    write_dataset([_walk(4)], tmp / "set.npz", card=_card("set"),
                  overwrite=True)
    return f"handled: replaced as asked ({len(load_motions(tmp / 'set.npz'))} clip)"


def _bvh_over(tmp):
    from course_lib.bvh import write_bvh

    _write(tmp / "take.bvh")
    write_bvh(_walk(4), tmp / "take.bvh")
    return "written"


def _checkpoint_over(tmp):
    from course_lib.models.vae import PoseVae, VaeConfig
    from course_lib.training import save_checkpoint

    _write(tmp / "vae.pt")
    config = VaeConfig(x_dim=6, hidden=8)
    save_checkpoint(PoseVae(config), config, tmp / "vae.pt", command="python tests/misuse_probes.py")
    return "written"


def _video_over(kind):
    def case(tmp):
        from course_lib import render

        _write(tmp / f"clip.{kind}")
        frames = np.zeros((2, 16, 16, 3), np.uint8)
        render.write_mp4(frames, 5, tmp / "clip.mp4") if kind == "mp4" else render._write_gif(
            frames, 5, tmp / "clip.gif")
        return "written"
    return case


def _stick_over(tmp):
    from course_lib import render

    _write(tmp / "stick.mp4")
    render.stick_mp4(_walk(4), tmp / "stick.mp4")
    return "written"


def _still_over(tmp):
    from course_lib import render

    _write(tmp / "frame.png")
    render.render_still(_walk(4), tmp / "frame.png", size=(32, 32))
    return "written"


def _stats_tampered(tmp):
    from course_lib.datasets import WindowDataset, load_stats

    ds = WindowDataset([_walk(40), _walk(40)], "positions_control", 10, fps=30.0)
    path = ds.save_stats(tmp / "stats.npz")
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["mean"] = arrays["mean"] + 0.1
    arrays["std"] = arrays["std"] * 3
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    load_stats(path)
    return "loaded"


def _stats_shipped(tmp):
    from course_lib.datasets import load_stats

    names = []
    for name in ("gmm_rnn_stats", "moglow_stats", "vae_lstm_stats"):
        load_stats(ROOT / "checkpoints" / f"{name}.npz")
        names.append(name)
    manifest = json.loads((ROOT / "checkpoints" / "MANIFEST.json").read_text())
    files = {e.get("file") for e in manifest.values()}
    missing = sorted(p.name for p in (ROOT / "checkpoints").iterdir()
                     if p.suffix in (".pt", ".npz") and p.name not in files)
    if missing:
        raise AssertionError(f"not in the manifest: {missing}")
    return f"handled: every checkpoint file is in the manifest; {', '.join(names)} verified and loaded"


def _stats_copied_without_sidecar(tmp):
    from course_lib.datasets import load_stats

    (tmp / "stats.npz").write_bytes((ROOT / "checkpoints" / "gmm_rnn_stats.npz").read_bytes())
    load_stats(tmp / "stats.npz")
    return "loaded"


def _online(speed, direction=0.0):
    def case(tmp):
        from course_lib.control.online import OnlineController

        controller = OnlineController("walk", seed=0)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            batches = [controller.step(speed, direction) for _ in range(4)]
        root = np.concatenate([b.root_positions for b in batches])[:, [0, 2]]
        fastest = float(np.linalg.norm(np.diff(root, axis=0), axis=-1).max() * batches[0].fps)
        said = " / ".join(str(w.message) for w in caught)
        if fastest > 10 or abs(controller.heading - direction) > 0.5 or "outside the training data" not in said:
            raise AssertionError(f"fastest frame {fastest:.1f} m/s, heading {controller.heading:.2f}; warned: {said}")
        return f"handled: warned ({said[:60]}...), fastest frame {fastest:.1f} m/s, heading {controller.heading:.2f}"
    return case


def _online_bad(speed, direction=0.0):
    def case(tmp):
        from course_lib.control.online import OnlineController

        OnlineController("walk", seed=0).step(speed, direction)
        return "stepped"
    return case


def _load_model(lesson, name):
    def case(tmp):
        import importlib

        importlib.import_module(f"course_lib.experiments.{lesson}").load_model(name)
        return "loaded"
    return case


def _reproduce(*args, manifest: bool = True):
    def case(tmp):
        import shutil

        from course_lib import reproduce

        if manifest:
            shutil.copy(ROOT / "checkpoints" / "MANIFEST.json", tmp / "MANIFEST.json")
        _write(tmp / "mine.json", "{}")
        return _run_main(reproduce.main, [a.replace("<tmp>", str(tmp)) for a in args])
    return case


def _moglow_command(forward, yaw_rate=0.0):
    def case(tmp):
        from course_lib.experiments import moglow as E

        data = E.load_data("ci", 0)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            c = E.constant_control(data, 1, 3, forward, 0.0, yaw_rate)
        raw = c[0, 0].double().numpy() * data.stats[1][63:] + data.stats[0][63:]
        low, high = data.control_range()
        said = " / ".join(str(w.message) for w in caught)
        if not ((raw >= low - 1e-6).all() and (raw <= high + 1e-6).all() and "outside the training data" in said):
            raise AssertionError(f"control {raw} outside {low}..{high}; warned: {said!r}")
        return f"handled: warned ({said[:70]}...), clamped to {raw[0]:.2f} m/s forward, {raw[2]:.2f} rad/s"
    return case


def _hvrnn_attribute(attribute):
    def case(tmp):
        from course_lib.experiments import hvrnn as H

        H.generate(H.load_model("hvrnn_proposed"), n_per=1, frames=10, attribute=attribute)
        return "generated"
    return case


def _fid_mixed_joints(tmp):
    from course_lib.evaluation import fid

    fid([_walk(40)] * 3, [_walk(40), _walk(40), _other_skeleton_walk(40)])
    return "a distance"


def _writer_cases() -> list[Case]:
    return [
        Case("writers", "make_locomotion --out d/walks.npz beside the user's d/walks.card.md", _locomotion_over_card,
             "_ScriptError", "walks.card.md"),
        Case("writers", "make_locomotion --out walks.npz beside the user's walks.card.json",
             _locomotion_over_card_json, "_ScriptError", "walks.card.json"),
        Case("writers", "make_locomotion --out over an existing file", _locomotion_over_npz, "_ScriptError",
             "--force"),
        Case("writers", "make_locomotion --clips 1000000000", _locomotion_huge, "_ScriptError", "fewer clips"),
        Case("writers", "make_actions --out acts.npz beside the user's acts.card.md", _actions_over_card,
             "_ScriptError", "acts.card.md"),
        Case("writers", "make_actions --subjects 0", _actions_zero, "_ScriptError", "--subjects"),
        Case("writers", "make_actions --fps inf", _actions_fps_inf, "_ScriptError", "--fps"),
        Case("writers", "make_noisy --input clean.npz --out clean.NPZ --force (same card files)",
             _noisy_upper_case, "_ScriptError", "is the input file"),
        Case("writers", "make_noisy --input notes.txt", _noisy_text_input, "_ScriptError", "not a .npz"),
        Case("writers", "make_noisy --out noisy.npz beside the user's noisy.card.json", _noisy_over_card,
             "_ScriptError", "noisy.card.json"),
        Case("writers", "benchmark --out results.md", _benchmark_md, "_ScriptError", ".json"),
        Case("writers", "benchmark --out summary.json beside the user's summary.md", _benchmark_companion,
             "_ScriptError", "summary.md"),
        Case("writers", "benchmark --out over an existing results file", _benchmark_existing, "_ScriptError",
             "--force"),
        Case("writers", "student_copies --notebooks X --out X --force", _student_into_source, "_ScriptError",
             "is the --notebooks folder"),
        Case("writers", "student_copies --notebooks X --out X/. --force", _student_into_source_dot,
             "_ScriptError", "is the --notebooks folder"),
        Case("writers", "student_copies over a copy holding answers (no --force)", _student_keeps_answers,
             "handled", "kept"),
        Case("writers", "student_copies --force over a copy holding answers", _student_force_backs_up, "handled",
             "backup", may_change=("student/01_lesson.ipynb",)),
        Case("writers", "make clean (what it removes)", _make_clean_keeps_student, "handled", "make clean removes"),
        Case("writers", "write_npz over an existing file", _npz_over, "FileExistsError", "overwrite=True"),
        Case("writers", "save_motions over an existing file", _save_motions_over, "FileExistsError",
             "overwrite=True"),
        Case("writers", "write_dataset beside the user's set.card.md", _dataset_over_card, "FileExistsError",
             "set.card.md"),
        Case("writers", "write_dataset onto its own input, overwrite=True", _dataset_over_input,
             "FileExistsError", "is the input file"),
        Case("writers", "write_dataset over its files with overwrite=True", _dataset_force, "handled",
             "replaced as asked", may_change=("set.npz", "set.card.md")),
        Case("writers", "write_bvh over an existing file", _bvh_over, "FileExistsError", "overwrite"),
        Case("writers", "save_checkpoint over an existing file", _checkpoint_over, "FileExistsError", "overwrite"),
        Case("writers", "write_mp4 over an existing file", _video_over("mp4"), "FileExistsError", "overwrite=True"),
        Case("writers", "a GIF over an existing file", _video_over("gif"), "FileExistsError", "overwrite=True"),
        Case("writers", "stick_mp4 over an existing file", _stick_over, "FileExistsError", "overwrite=True"),
        Case("writers", "render_still over an existing picture", _still_over, "FileExistsError", "overwrite=True"),
        Case("verified inputs", "normalisation stats with a shifted mean and tripled std", _stats_tampered,
             "ValueError", "sha256 mismatch"),
        Case("verified inputs", "the shipped checkpoints and stats", _stats_shipped, "handled", "manifest"),
        Case("verified inputs", "a stats file copied without its sidecar", _stats_copied_without_sidecar,
             "ValueError", "cannot verify"),
        Case("controllers", "OnlineController.step(100.0, 0)", _online(100.0), "handled", "warned"),
        Case("controllers", "MoGlow constant_control(forward=100 m/s)", _moglow_command(100.0), "handled", "warned"),
        Case("controllers", "MoGlow constant_control(yaw_rate=-50 rad/s)", _moglow_command(1.0, -50.0), "handled",
             "warned"),
        Case("controllers", "MoGlow constant_control(forward=nan)", _moglow_command(math.nan), "ValueError",
             "must be finite"),
        Case("controllers", "hvrnn.generate(attribute=('fly', 'x'))", _hvrnn_attribute(("fly", "x")), "ValueError",
             "action one of"),
        Case("controllers", "OnlineController.step(nan, 0)", _online_bad(math.nan), "ValueError", "finite speed"),
        Case("controllers", "OnlineController.step(-1, 0)", _online_bad(-1.0), "ValueError", "speed >= 0"),
        Case("controllers", "OnlineController.step(1, inf)", _online_bad(1.0, math.inf), "ValueError",
             "finite direction"),
        Case("commands", "vae_lstm.load_model('vae')", _load_model("vae_lstm", "vae"), "KeyError", "choose one of"),
        Case("commands", "hvrnn.load_model('VAE')", _load_model("hvrnn", "VAE"), "KeyError", "choose one of"),
        Case("commands", "moglow.load_model('glow')", _load_model("moglow", "glow"), "KeyError", "choose one of"),
        Case("commands", "reproduce moglow --eval-only with its checkpoints missing", _reproduce(
            "moglow", "--eval-only", "--checkpoints", "<tmp>"), "_ScriptError", "moglow.pt"),
        Case("commands", "reproduce hvrnn --eval-only on a folder without a manifest", _reproduce(
            "hvrnn", "--eval-only", "--checkpoints", "<tmp>", manifest=False), "_ScriptError", "MANIFEST.json"),
        Case("commands", "reproduce control --out over the user's file", _reproduce(
            "control", "--eval-only", "--out", "<tmp>/mine.json"), "_ScriptError", "mine.json"),
        Case("commands", "reproduce vae_lstm --threads 0", _reproduce("vae_lstm", "--threads", "0"), "_ScriptError",
             "--threads"),
        Case("measures", "fid of 21-joint clips against a 2-joint one", _fid_mixed_joints, "ValueError",
             "clip 2 has 2 joints"),
    ]


CASES = CASES + _measure_cases() + _motion_cases() + _writer_cases()


# ---------------------------------------------------------------- running and classifying

def outcome(case: Case) -> tuple[str, str]:
    """-> (exception class or "handled", message or description), run in a fresh temporary folder (named <tmp>
    in the message).  A case that changed or removed a file the user made (see `_protect`) that it was not asked
    to replace gives ("DataLoss", ...)."""
    _PROTECTED.clear()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        try:
            kind, message = "handled", case.run(folder)
        except Exception as err:  # noqa: BLE001 - the outcome is what we report
            kind, message = type(err).__name__, str(err)
        lost = [path.relative_to(folder).as_posix() for path, digest in _PROTECTED.items()
                if path.relative_to(folder).as_posix() not in case.may_change
                and (not path.exists() or hashlib.sha256(path.read_bytes()).hexdigest() != digest)]
    message = message.replace(str(folder.resolve()), "<tmp>").replace(tmp, "<tmp>")
    if lost:
        return "DataLoss", f"changed or removed: {', '.join(lost)} ({message})"
    return kind, message


def classify(case: Case, kind: str, message: str) -> str:
    """One of CLASSES."""
    if kind == "DataLoss":
        return "data loss"
    if kind == "handled":
        return "fine" if case.expect == "handled" and case.names in message else "wrong answer"
    if case.expect != "handled" and kind == case.expect and case.names in message and "Traceback" not in message:
        return "clear error"
    return "unhelpful"


def table(rows: list[tuple[Case, str, str]]) -> str:
    lines = ["| area | input | class | outcome now |", "|---|---|---|---|"]
    for case, kind, message in rows:
        shown = message if kind == "handled" else f"`{'refused' if kind == '_ScriptError' else kind}`: {message}"
        lines.append(f"| {case.area} | {case.what} | {classify(case, kind, message)} | "
                     f"{shown.replace('|', '/')[:300]} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, help="also write the table to this new markdown file")
    args = parser.parse_args(argv)
    if args.out and args.out.exists():
        parser.error(f"--out {args.out} exists; choose a new file")
    os.environ.setdefault("COURSE_MODE", "ci")
    rows = [(case, *outcome(case)) for case in CASES]
    text = table(rows)
    print(text)
    counts = {c: 0 for c in CLASSES}
    for case, kind, message in rows:
        counts[classify(case, kind, message)] += 1
    print(f"{len(rows)} probes: " + ", ".join(f"{n} {c}" for c, n in counts.items()))
    if args.out:
        args.out.write_text(text)
    return 0 if counts["unhelpful"] == counts["wrong answer"] == counts["data loss"] == 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
