"""Issue 18's table of bad inputs: each input the issue lists, tried as a user would, and what happens now.

    python tools/bad_inputs.py [--out FILE.md]

Every case runs in a fresh temporary folder (the data scripts on copies of a small clean file, never on
data/), and its outcome is the exception it raises (class and message) or, for the inputs that are
handled correctly, what it returns.  `tests/test_bad_inputs.py` runs the same cases and checks that each
gives the outcome written beside it here, so the table cannot drift from the code.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


@dataclass(frozen=True)
class Case:
    area: str
    what: str
    run: Callable[[Path], str]  # tmp folder -> a description of a correct result; raises for an error
    expect: str  # the exception class expected, or "handled"
    names: str  # a word the message (or the description) must contain


# ---------------------------------------------------------------- helpers

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
    """Run a data script; its last stderr line is the message of a refusal (exit status 2)."""
    proc = subprocess.run([sys.executable, str(ROOT / "data_scripts" / name), *args], capture_output=True,
                          text=True, cwd=tmp, timeout=600)
    if proc.returncode == 0:
        return f"exit 0: {proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else ''}"
    last = (proc.stderr.strip().splitlines() or ["(no message)"])[-1]
    kind = "Traceback" if "Traceback" in proc.stderr else "SystemExit"
    raise _ScriptError(f"{kind} (exit {proc.returncode}): {last}")


class _ScriptError(Exception):
    pass


def _clean_file(tmp: Path) -> Path:
    from course_lib.datasets import save_motions

    path = tmp / "clean.npz"
    save_motions([_walk(30), _walk(30)], path)
    return path


def _checkpoint(tmp: Path) -> Path:
    from course_lib.models.vae import PoseVae, VaeConfig
    from course_lib.training import save_checkpoint

    path = tmp / "vae.pt"
    config = VaeConfig(x_dim=6, hidden=8)
    save_checkpoint(PoseVae(config), config, path, command="python tools/bad_inputs.py")
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


def outcome(case: Case) -> tuple[str, str]:
    """-> (exception class or "handled", message or description), run in a fresh temporary folder (named <tmp> in
    the message)."""
    with tempfile.TemporaryDirectory() as tmp:
        try:
            kind, message = "handled", case.run(Path(tmp))
        except Exception as err:  # noqa: BLE001 - the outcome is what we report
            kind, message = type(err).__name__, str(err)
    return kind, message.replace(str(Path(tmp).resolve()), "<tmp>").replace(tmp, "<tmp>")


def table(rows: list[tuple[Case, str, str]]) -> str:
    lines = ["| area | input | outcome now |", "|---|---|---|"]
    for case, kind, message in rows:
        shown = message if kind == "handled" else f"`{'refused' if kind == '_ScriptError' else kind}`: {message}"
        lines.append(f"| {case.area} | {case.what} | {shown.replace('|', '/')[:300]} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, help="also write the table to this markdown file")
    args = parser.parse_args(argv)
    rows = [(case, *outcome(case)) for case in CASES]
    text = table(rows)
    print(text)
    wrong = [case.what for case, kind, message in rows if kind != case.expect or case.names not in message]
    print(f"{len(rows) - len(wrong)} of {len(rows)} inputs give the outcome expected" +
          (f"; not: {wrong}" if wrong else ""))
    if args.out:
        args.out.write_text(text)
    return 1 if wrong else 0


if __name__ == "__main__":
    raise SystemExit(main())
