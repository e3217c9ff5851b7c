"""BVH motion files: read any BVH, write standard BVH, map a CMU skeleton onto the canonical 21 joints.

BVH (Biovision Hierarchy) holds a HIERARCHY (a tree of joints: OFFSET from the
parent, CHANNELS listing which values each frame carries, End Sites) and a
MOTION block (Frames:, Frame Time:, one line of channel values per frame).

Conventions used here (and by Blender, MotionBuilder and the CMU conversions):
- rotation channels are intrinsic Euler angles in degrees, applied in channel
  order: ``Zrotation Yrotation Xrotation`` means R = Rz @ Ry @ Rx; this is
  `course_lib.rotations.euler_to_quat(angles, "ZYX")`;
- a joint with position channels is placed by them alone, relative to its
  parent (the root: its world position); its OFFSET is not added.  A joint
  without position channels sits at its OFFSET.  This is what Blender's
  importer and bvhio do (and PyMO for the root; PyMO adds a non-root joint's
  channels to its OFFSET); an axis without a channel is 0, as in Blender.
  The root's OFFSET is kept as ``skeleton.offsets[0]`` (the rest position
  Blender shows) and written back; `Motion.root_positions` are the channels;
- ``scale`` multiplies offsets and positions (CMU files are in inches / 0.45:
  ``scale=0.056444`` gives metres).

Choices (documented, tested):
- Position channels on a non-root joint replace its OFFSET when their values are
  the same on every frame (exporters that write 6 channels on every joint write
  the OFFSET there); a `Motion` has fixed bone offsets, so values that change over
  time raise `BVHError` ("translation channels on non-root joints are not supported").
- Joint names are one word without braces (`valid_joint_name`), for reader and writer alike.
- A UTF-8 byte-order mark is skipped; ``Frames: 0`` gives an empty Motion.
- A joint has 0 or 3 rotation channels (X, Y, Z once each, any of the 6 orders);
  position channels may come before, after or between them.
- End Sites become `Skeleton.end_sites` (one per joint; a second one is ignored).
- Frame rate = 1 / Frame Time, snapped to the nearest integer when within 0.01 %
  (files print .0083333 for 120 fps).

Taught in notebooks/00_skeletons_and_rotations.ipynb.
"""

from __future__ import annotations

import os
import re
import tempfile
import warnings
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
import torch

from course_lib.checksums import read_sidecar, sha256_file, write_sidecar
from course_lib.motion import Motion
from course_lib.rotations import euler_to_quat, quat_conjugate, quat_mul, quat_rotate, quat_to_euler
from course_lib.skeleton import CANONICAL_JOINTS, CANONICAL_PARENTS, Skeleton, forward_kinematics

CMU_SCALE = 0.056444  # CMU BVH length unit -> metres
SITE_DIR = Path(__file__).resolve().parents[1] / "site"  # the course site `make course` builds, beside its lessons
CMU_SAMPLE = "cmu_07_01_walk.bvh"  # the course's real clip, shipped in course_lib/data/ (data card: README.md there)


def cmu_sample_path() -> Path:
    """Path of the course's real CMU walk, ``course_lib/data/cmu_07_01_walk.bvh``: package data, so it is
    there in a plain clone and in a non-editable install alike (its source and terms: course_lib/data/README.md)."""
    path = Path(str(resources.files("course_lib") / "data" / CMU_SAMPLE))
    if not path.is_file():
        raise FileNotFoundError(f"the packaged CMU clip {path} is missing (a broken install of course_lib?)")
    return path


_POSITION = ("Xposition", "Yposition", "Zposition")
_ROTATION = ("Xrotation", "Yrotation", "Zrotation")
_NUMBER = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")
_NUMBER_CHARS = re.compile(r"[0-9eE+\-.]*")


def valid_joint_name(name: str) -> bool:
    """A BVH joint name is one non-empty word without braces (both the reader and the writer enforce it)."""
    return isinstance(name, str) and bool(name) and not any(ch.isspace() or ch in "{}" for ch in name)


class BVHError(ValueError):
    """A malformed BVH file; the message starts with the line number ("line 12: ...")."""

    def __init__(self, line: int, problem: str):
        self.line = line
        super().__init__(f"line {line}: {problem}")


# ---------------------------------------------------------------------------
# Reading
# ---------------------------------------------------------------------------

@dataclass
class _Joint:
    name: str
    parent: int
    line: int
    offset: np.ndarray | None = None
    channels: tuple[str, ...] | None = None
    channels_line: int = 0
    end_site: np.ndarray | None = None
    children: list[int] = field(default_factory=list)


def _number(tok: str, line: int, what: str) -> float:
    if not _NUMBER.fullmatch(tok):
        raise BVHError(line, f"{what}: {tok!r} is not a number")
    value = float(tok)
    if not np.isfinite(value):
        raise BVHError(line, f"{what}: {tok!r} is too large to be a finite number")
    return value


def _offset(toks: list[str], line: int) -> np.ndarray:
    if len(toks) != 4:
        raise BVHError(line, f"OFFSET needs 3 numbers, got {len(toks) - 1}")
    return np.array([_number(t, line, "OFFSET") for t in toks[1:]])


def _channels(toks: list[str], line: int) -> tuple[str, ...]:
    if len(toks) < 2 or not re.fullmatch(r"[0-9]+", toks[1]):
        raise BVHError(line, f"CHANNELS needs a count then channel names, got {' '.join(toks[1:2])!r}")
    names = tuple(toks[2:])
    if int(toks[1]) != len(names):
        raise BVHError(line, f"CHANNELS says {toks[1]} channels but lists {len(names)}")
    bad = [c for c in names if c not in _POSITION + _ROTATION]
    if bad:
        raise BVHError(line, f"unknown channel name {bad[0]!r}; expected one of {', '.join(_POSITION + _ROTATION)}")
    if len(set(names)) != len(names):
        raise BVHError(line, "a channel is listed twice")
    n_rot = sum(c in _ROTATION for c in names)
    if n_rot not in (0, 3):
        raise BVHError(line, f"a joint needs 0 or 3 rotation channels (X, Y, Z), got {n_rot}")
    return names


class _HierarchyParser:
    """Line-based parser of the HIERARCHY block; one statement per line."""

    def __init__(self, lines: list[tuple[int, list[str]]]):
        self.lines = lines  # (line number, tokens) of the non-blank lines
        self.pos = 0
        self.joints: list[_Joint] = []
        self.site_owner, self.site_offset = -1, None  # the End Site being read

    def next(self, expect: str) -> tuple[int, list[str]]:
        if self.pos >= len(self.lines):
            last = self.lines[-1][0] + 1 if self.lines else 1
            raise BVHError(last, f"file ends where {expect} was expected")
        self.pos += 1
        return self.lines[self.pos - 1]

    def brace(self, owner: str) -> None:
        line, toks = self.next(f"'{{' opening {owner}")
        if toks != ["{"]:
            raise BVHError(line, f"expected '{{' opening {owner}, got {' '.join(toks)!r}")

    def parse(self) -> list[_Joint]:
        line, toks = self.next("HIERARCHY")
        if toks != ["HIERARCHY"]:
            raise BVHError(line, f"a BVH file starts with HIERARCHY, got {' '.join(toks)!r}")
        line, toks = self.next("ROOT")
        if toks[0] != "ROOT":
            raise BVHError(line, f"expected ROOT, got {' '.join(toks)!r}")
        self.declare(toks, line, parent=-1)
        stack = [0]  # joint indices whose '{ ... }' is open; -1 = an End Site
        while stack:
            line, toks = self.next(f"'}}' closing {self.owner(stack[-1])}")
            self.statement(line, toks, stack)
        return self.joints

    def owner(self, j: int) -> str:
        return "an End Site" if j < 0 else f"joint {self.joints[j].name!r} (line {self.joints[j].line})"

    def declare(self, toks: list[str], line: int, parent: int) -> int:
        if len(toks) != 2:
            raise BVHError(line, f"{toks[0]} needs exactly one name (no spaces), got {len(toks) - 1} words")
        if not valid_joint_name(toks[1]):
            raise BVHError(line, f"joint name {toks[1]!r} contains a brace; a name is one word without braces")
        if any(j.name == toks[1] for j in self.joints):
            raise BVHError(line, f"joint name {toks[1]!r} is used twice")
        self.joints.append(_Joint(toks[1], parent, line))
        if parent >= 0:
            self.joints[parent].children.append(len(self.joints) - 1)
        self.brace(f"joint {toks[1]!r}")
        return len(self.joints) - 1

    def statement(self, line: int, toks: list[str], stack: list[int]) -> None:
        j = stack[-1]
        key = toks[0]
        if j < 0:  # inside an End Site: only OFFSET, then '}'
            self.end_site_statement(line, toks, stack)
        elif key == "OFFSET":
            if self.joints[j].offset is not None:
                raise BVHError(line, f"second OFFSET for {self.owner(j)}")
            self.joints[j].offset = _offset(toks, line)
        elif key == "CHANNELS":
            if self.joints[j].channels is not None:
                raise BVHError(line, f"second CHANNELS for {self.owner(j)}")
            self.joints[j].channels = _channels(toks, line)
            self.joints[j].channels_line = line
        elif key in ("JOINT", "}") or toks[:1] == ["End"]:
            self.require_header(j, line)
            if key == "}":
                stack.pop()
            elif key == "JOINT":
                stack.append(self.declare(toks, line, parent=j))
            else:
                if len(toks) != 2 or toks[1].lower() != "site":
                    raise BVHError(line, f"expected 'End Site', got {' '.join(toks)!r}")
                self.brace("an End Site")
                stack.append(-1)
                self.site_owner, self.site_offset = j, None
        elif key in ("MOTION", "ROOT", "HIERARCHY"):
            raise BVHError(line, f"unbalanced braces: {key} before the '}}' closing {self.owner(j)}")
        else:
            raise BVHError(line, f"unknown keyword {key!r} in {self.owner(j)}; expected OFFSET, CHANNELS, "
                                 f"JOINT, End Site or '}}'")

    def require_header(self, j: int, line: int) -> None:
        for attr, word in (("offset", "OFFSET"), ("channels", "CHANNELS")):
            if getattr(self.joints[j], attr) is None:
                raise BVHError(line, f"{self.owner(j)} has no {word} before this line")

    def end_site_statement(self, line: int, toks: list[str], stack: list[int]) -> None:
        if toks[0] == "OFFSET" and self.site_offset is None:
            self.site_offset = _offset(toks, line)
        elif toks == ["}"] and self.site_offset is not None:
            stack.pop()
            if self.joints[self.site_owner].end_site is None:
                self.joints[self.site_owner].end_site = self.site_offset
        else:
            want = "'}'" if self.site_offset is not None else "OFFSET"
            raise BVHError(line, f"an End Site holds one OFFSET then '}}'; expected {want}, got {' '.join(toks)!r}")


def _motion_header(lines: list[tuple[int, list[str]]], pos: int) -> tuple[int, float, int]:
    """-> (frame count, frame time, index of the first frame line)."""
    def get(i: int, what: str) -> tuple[int, list[str]]:
        if i >= len(lines):
            raise BVHError(lines[-1][0] + 1, f"file ends where {what} was expected")
        return lines[i]

    line, toks = get(pos, "MOTION")
    if toks != ["MOTION"]:
        why = {"}": "unbalanced braces: '}' after the ROOT joint was closed",
               "ROOT": "only one ROOT is supported"}.get(toks[0], "expected MOTION after the hierarchy")
        raise BVHError(line, f"{why}, got {' '.join(toks)!r}")
    line, toks = get(pos + 1, "'Frames: N'")
    text = " ".join(toks)
    m = re.fullmatch(r"Frames\s*:\s*([0-9]+)", text)
    if not m:
        raise BVHError(line, f"expected 'Frames: N' with N a whole number >= 0, got {text!r}")
    frames = int(m.group(1))
    line, toks = get(pos + 2, "'Frame Time: seconds'")
    text = " ".join(toks)
    m = re.fullmatch(r"Frame\s+Time\s*:\s*(\S+)", text)
    if not m or not _NUMBER.fullmatch(m.group(1)) or not 1e-9 <= float(m.group(1)) < 1e9:
        raise BVHError(line, f"expected 'Frame Time: seconds' with a number in [1e-9, 1e9), got {text!r}")
    return frames, float(m.group(1)), pos + 3


def _frame_values(lines: list[tuple[int, list[str]]], start: int, frames: int, n_channels: int,
                  frames_line: int) -> np.ndarray:
    """The frame lines -> (T, C) values; checks the count of lines and of values on each."""
    rows = lines[start:]
    if len(rows) > frames:
        raise BVHError(rows[frames][0], f"more frame lines than 'Frames: {frames}' (line {frames_line}) declares")
    if len(rows) < frames:
        end = rows[-1][0] + 1 if rows else lines[start - 1][0] + 1
        raise BVHError(end, f"truncated MOTION block: file ends after {len(rows)} of the {frames} frames "
                            f"declared on line {frames_line}")
    for line, toks in rows:
        if len(toks) != n_channels:
            raise BVHError(line, f"frame line has {len(toks)} values, the hierarchy has {n_channels} channels")
    flat = [t for _, toks in rows for t in toks]
    try:
        strict = all(_NUMBER_CHARS.fullmatch("".join(toks)) for _, toks in rows)  # numpy also takes '1_0', 'nan'
        values = np.array(flat, dtype=np.float64).reshape(frames, n_channels) if strict else None
    except ValueError:
        values = None
    if values is None or not np.isfinite(values).all():
        for line, toks in rows:
            for t in toks:
                _number(t, line, "frame value")
        raise BVHError(rows[0][0], "a frame value is not a finite number")
    return values


def _split_lines(text: str) -> list[tuple[int, list[str]]]:
    """-> (line number, tokens) of every non-blank line; CRLF, CR, tabs allowed."""
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    return [(i + 1, ln.split()) for i, ln in enumerate(lines) if ln.strip()]


def parse_bvh(text: str, scale: float = 1.0, source_path: str | None = None) -> Motion:
    """BVH text -> Motion on the file's own skeleton (joints in depth-first order); see `read_bvh`."""
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"parse_bvh: scale must be a positive number, got {scale}")
    lines = _split_lines(text.removeprefix("\ufeff"))  # a UTF-8 byte-order mark is not content
    parser = _HierarchyParser(lines)
    joints = parser.parse()
    frames, frame_time, start = _motion_header(lines, parser.pos)
    n_channels = sum(len(j.channels) for j in joints)
    values = _frame_values(lines, start, frames, n_channels, lines[start - 2][0])
    return _to_motion(joints, values, frame_time, scale, source_path)


def _split_channels(joints: list[_Joint], values: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(T, C) -> root positions (T, 3) (file units), per-joint angles (T, J, 3) degrees, rotation orders.

    A joint with position channels is placed by them, not OFFSET + them (Blender, bvhio); the root
    without any sits at its OFFSET.  Constant non-root channels replace that joint's OFFSET.
    """
    T, J = values.shape[0], len(joints)
    root_pos = np.broadcast_to(joints[0].offset, (T, 3)).copy()
    angles, orders, col = np.zeros((T, J, 3)), [], 0
    for j, joint in enumerate(joints):
        rot = [c for c in joint.channels if c in _ROTATION]
        orders.append("".join(c[0] for c in rot))
        pos = np.zeros((T, 3))
        for c in joint.channels:
            if c in _POSITION:
                pos[:, _POSITION.index(c)] = values[:, col]
            else:
                angles[:, j, rot.index(c)] = values[:, col]
            col += 1
        if len(rot) == len(joint.channels):
            continue
        if j == 0:
            root_pos = pos
        else:
            joint.offset = _constant_translation(joint, pos)
    return root_pos, angles, orders


def _constant_translation(joint: _Joint, pos: np.ndarray) -> np.ndarray:
    if len(pos) and np.abs(pos - pos[0]).max() > 0:
        raise BVHError(joint.channels_line, f"joint {joint.name!r} has translation channels whose values change "
                                            "over time; translation channels on non-root joints are not supported "
                                            "(a Motion has fixed bone offsets)")
    return pos[0] if len(pos) else joint.offset


def _to_motion(joints: list[_Joint], values: np.ndarray, frame_time: float, scale: float,
               source_path: str | None) -> Motion:
    root_pos, angles, orders = _split_channels(joints, values)
    T, J = angles.shape[:2]
    quats = np.zeros((T, J, 4))
    quats[..., 0] = 1.0
    for order in set(o for o in orders if o):
        js = [j for j, o in enumerate(orders) if o == order]
        # BVH: R = R_{c0}(a0) R_{c1}(a1) R_{c2}(a2) for channel order c0 c1 c2 (intrinsic, degrees)
        quats[:, js] = euler_to_quat(torch.from_numpy(np.radians(angles[:, js])), order).numpy()
    offsets = np.stack([j.offset for j in joints]) * scale
    root = root_pos * scale
    if not (np.isfinite(offsets).all() and np.isfinite(root).all() and np.isfinite(quats).all()):
        raise BVHError(joints[0].line, f"offsets or positions overflow to infinity at scale {scale}")
    ends = {j: jt.end_site * scale for j, jt in enumerate(joints) if jt.end_site is not None}
    skeleton = Skeleton(tuple(j.name for j in joints), tuple(j.parent for j in joints), offsets, ends)
    fps = 1.0 / frame_time
    if abs(fps - round(fps)) < 1e-4 * fps:
        fps = float(round(fps))
    meta = {"channel_orders": tuple(orders), "channels": tuple(j.channels for j in joints),
            "source_path": source_path, "frame_time": frame_time, "scale": scale}
    return Motion(quats, root, skeleton, fps, meta=meta)


def read_bvh(path: str | os.PathLike, scale: float = 1.0) -> Motion:
    """A BVH file -> Motion on the file's own skeleton.

    Joints are in depth-first order of appearance; End Sites become
    `skeleton.end_sites`; each joint's channel order is honoured; lengths are
    multiplied by `scale` (`CMU_SCALE` turns CMU files into metres).  Malformed
    files raise `BVHError` naming the line and the problem.
    meta: channel_orders (J,) e.g. "ZYX" ("" without rotation channels), channels, source_path,
    frame_time, scale.
    """
    data = Path(path).read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise BVHError(data[: err.start].count(b"\n") + 1, "the file is not UTF-8 text") from None
    return parse_bvh(text, scale=scale, source_path=str(path))


# ---------------------------------------------------------------------------
# Writing
# ---------------------------------------------------------------------------

def _default_end_site(skeleton: Skeleton, j: int) -> np.ndarray:
    """A short bone continuing the joint's own bone (a quarter of its length), or 2 cm up."""
    o = skeleton.offsets[j]
    length = np.linalg.norm(o)
    return 0.25 * o if length > 1e-9 else np.array([0.0, 0.02, 0.0])


def _hierarchy_lines(skeleton: Skeleton, orders: list[str], scale: float, fmt: str) -> list[str]:
    """The HIERARCHY block, depth-first; iterative, so a hierarchy thousands of joints deep is fine."""
    out = ["HIERARCHY"]

    def vec(v) -> str:
        return " ".join(fmt % x for x in np.asarray(v) * scale)

    children = [[] for _ in range(skeleton.num_joints)]
    for c, p in enumerate(skeleton.parents[1:], 1):
        children[p].append(c)
    stack: list[tuple[int, int, bool]] = [(0, 0, False)]  # (joint, depth, its children already written)
    while stack:
        j, depth, closing = stack.pop()
        pad = "\t" * depth
        if closing:
            if j in skeleton.end_sites or not children[j]:
                end = skeleton.end_sites.get(j, None)
                end = _default_end_site(skeleton, j) if end is None else end
                out.extend([f"{pad}\tEnd Site", f"{pad}\t{{", f"{pad}\t\tOFFSET {vec(end)}", f"{pad}\t}}"])
            out.append(f"{pad}}}")
            continue
        rot = " ".join(f"{axis}rotation" for axis in orders[j])
        head = "ROOT" if j == 0 else "JOINT"
        channels = f"CHANNELS 6 Xposition Yposition Zposition {rot}" if j == 0 else f"CHANNELS 3 {rot}"
        out.extend([f"{pad}{head} {skeleton.names[j]}", f"{pad}{{", f"{pad}\tOFFSET {vec(skeleton.offsets[j])}",
                    f"{pad}\t{channels}"])
        stack.append((j, depth, True))
        stack.extend((c, depth + 1, False) for c in reversed(children[j]))
    return out


def _depth_first(skeleton: Skeleton) -> list[int]:
    order, stack = [], [0]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(reversed(skeleton.children(j)))
    return order


def _frame_lines(motion: Motion, orders: list[str], scale: float, fmt: str) -> list[str]:
    """-> one line per frame: root position, then each joint's angles, joints depth-first as in the HIERARCHY."""
    T, J = motion.rotations.shape[:2]
    rot = torch.from_numpy(motion.rotations)
    angles = np.zeros((T, J, 3))
    for order in set(orders):
        js = [j for j, o in enumerate(orders) if o == order]
        angles[:, js] = np.degrees(quat_to_euler(rot[:, js], order).numpy())
    root = motion.root_positions * scale  # the root is placed by its channels alone (not OFFSET + channels)
    values = np.concatenate([root, angles[:, _depth_first(motion.skeleton)].reshape(T, 3 * J)], axis=1)  # (T, 3+3J)
    row = " ".join([fmt] * values.shape[1])
    return [row % tuple(v) for v in values]


def _check_orders(order, J: int) -> list[str]:
    orders = [order] * J if isinstance(order, str) else list(order)
    if len(orders) != J:
        raise ValueError(f"write_bvh: {len(orders)} rotation orders for {J} joints")
    for o in orders:
        if not (isinstance(o, str) and len(o) == 3 and sorted(o) == ["X", "Y", "Z"]):
            raise ValueError(f"write_bvh: rotation order must be a permutation of 'XYZ' such as 'ZYX', got {o!r}")
    return orders


def _check_writable(motion: Motion, scale: float) -> None:
    """Refuse what `read_bvh` would reject (the arrays may have been edited in place since the Motion was made)."""
    sk = motion.skeleton
    for name in sk.names:
        if not valid_joint_name(name):
            raise ValueError(f"write_bvh: joint name {name!r} cannot be written to BVH (empty, space or brace)")
    if not (isinstance(scale, (int, float, np.floating)) and np.isfinite(scale) and scale > 0):
        raise ValueError(f"write_bvh: scale must be a positive finite number, got {scale}")
    if not (isinstance(motion.fps, (int, float, np.floating)) and 1e-9 <= 1.0 / motion.fps < 1e9):
        raise ValueError(f"write_bvh: fps must be a positive finite number (1e-9 < fps <= 1e9), got {motion.fps}")
    ends = np.array([v for v in sk.end_sites.values()]).reshape(-1, 3)
    for what, x, s in (("rotations", motion.rotations, 1.0), ("root_positions", motion.root_positions, scale),
                       ("skeleton offsets", sk.offsets, scale), ("End Site offsets", ends, scale)):
        with np.errstate(over="ignore", invalid="ignore"):
            finite = np.isfinite(x * s).all()
        if not finite:
            times = f" (times scale {scale})" if s != 1.0 else ""
            raise ValueError(f"write_bvh: {what}{times} contain NaN or inf; read_bvh would reject the file")
    norms = np.linalg.norm(motion.rotations, axis=-1)
    if norms.size and np.abs(norms - 1).max() > 1e-3:
        raise ValueError(f"write_bvh: rotations must be unit quaternions (norms range {norms.min():.4g}.."
                         f"{norms.max():.4g})")


def write_bvh(motion: Motion, path: str | os.PathLike, order: str | list[str] = "ZYX", overwrite: bool = False,
              scale: float = 1.0, decimals: int = 8) -> Path:
    """Write `motion` as a standard BVH file (read by Blender, MotionBuilder, bvhio...) and return its path.

    Root: 6 channels (X/Y/Z position, then rotations); other joints 3 rotation
    channels; joints in depth-first order (the skeleton's own order when it is
    depth-first, as the canonical one); angles in degrees in `order` (one order,
    or one per joint, e.g. ``motion.meta["channel_orders"]``); End Sites from `skeleton.end_sites`,
    or a short default one on leaf joints without.  Lengths are multiplied by
    `scale` (e.g. ``1 / CMU_SCALE`` for CMU units).  Refuses to replace an
    existing file unless `overwrite`; writes a temporary file then renames it,
    so a reader never sees half a file.  The root's OFFSET is ``skeleton.offsets[0]`` and its
    position channels are `motion.root_positions` (see the module docstring: Blender places the
    root by its channels alone).  Refuses (ValueError) what `read_bvh` would reject: NaN or inf
    values, non-unit rotations, a scale that is not a positive number, joint names with spaces
    or braces.
    """
    path = Path(path)
    orders = _check_orders(order, motion.skeleton.num_joints)
    _check_writable(motion, scale)
    if not path.parent.is_dir():
        raise FileNotFoundError(f"write_bvh: folder {path.parent} does not exist (create it first)")
    if path.exists() and not overwrite:
        raise FileExistsError(f"write_bvh: {path} exists; pass overwrite=True to replace it")
    fmt = f"%.{int(decimals)}f"
    lines = _hierarchy_lines(motion.skeleton, orders, scale, fmt)
    lines += ["MOTION", f"Frames: {len(motion)}", f"Frame Time: {1.0 / motion.fps:.10g}"]
    lines += _frame_lines(motion, orders, scale, fmt)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as f:
            f.write("\n".join(lines) + "\n")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_site_sample(motion: Motion, name: str, site: str | os.PathLike | None = None, **options) -> Path:
    """Write a lesson's sample motion to ``<site>/<name>.bvh`` (default: the repository's site/) and return it.

    For students to open in Blender (File > Import > Motion Capture (.bvh)).  Creates the folder;
    `options` go to `write_bvh`.  A sidecar ``<name>.bvh.sha256`` records what was written, and
    an existing ``<name>.bvh`` is replaced only when its sidecar shows that this function wrote it
    and nobody changed it since: any other file of that name raises FileExistsError.
    name: letters, digits, '_', '-', '.' (no folders).
    """
    name = name.removesuffix(".bvh")
    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]*", name):
        raise ValueError(f"write_site_sample: name {name!r} must be letters, digits, '_', '-', '.' (no folders)")
    folder = Path(site) if site is not None else SITE_DIR
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.bvh"
    if path.exists() or path.is_symlink():
        ours = path.is_file() and not path.is_symlink() and read_sidecar(path) == sha256_file(path)
        if not ours:
            raise FileExistsError(f"write_site_sample: {path} exists and is not a sample this function wrote "
                                  "(or it was changed since); move it away or choose another name")
    write_bvh(motion, path, overwrite=True, **options)
    write_sidecar(path)
    return path


# ---------------------------------------------------------------------------
# Mapping a skeleton onto another one with fewer joints (CMU 31 -> canonical 21)
# ---------------------------------------------------------------------------

# canonical joint -> CMU joint.  The spine and neck are shifted by one joint on purpose,
# see `map_to_canonical`: these are the only choices whose joint positions stay exact.
CMU_TO_CANONICAL: dict[str, str] = {
    "Hips": "Hips",
    "LeftUpLeg": "LeftUpLeg", "LeftLeg": "LeftLeg", "LeftFoot": "LeftFoot", "LeftToeBase": "LeftToeBase",
    "RightUpLeg": "RightUpLeg", "RightLeg": "RightLeg", "RightFoot": "RightFoot", "RightToeBase": "RightToeBase",
    "Spine": "LowerBack", "Spine1": "Spine", "Neck": "Neck", "Head": "Neck1",
    "LeftShoulder": "LeftShoulder", "LeftArm": "LeftArm", "LeftForeArm": "LeftForeArm", "LeftHand": "LeftHand",
    "RightShoulder": "RightShoulder", "RightArm": "RightArm", "RightForeArm": "RightForeArm",
    "RightHand": "RightHand",
}
# canonical leaf -> CMU joint whose End Site (rest pose) becomes the leaf's End Site
CMU_END_SITES: dict[str, str] = {
    "Head": "Head", "LeftHand": "LeftHandIndex1", "RightHand": "RightHandIndex1",
    "LeftToeBase": "LeftToeBase", "RightToeBase": "RightToeBase",
}


def _source_chain(parents: tuple[int, ...], ancestor: int, j: int) -> list[int]:
    """Joints on the path ancestor -> j (j included, ancestor excluded); raises if not an ancestor."""
    chain = []
    while j != ancestor:
        if j < 0:
            raise ValueError
        chain.append(j)
        j = parents[j]
    return chain[::-1]


def _source_indices(src: Skeleton, names, parents, mapping: dict[str, str]) -> list[int]:
    missing = [n for n in names if n not in mapping]
    if missing:
        raise KeyError(f"retarget_names: the mapping has no source joint for {', '.join(missing)}")
    s = [src.index(mapping[n]) for n in names]
    if len(set(s)) != len(s):
        raise ValueError("retarget_names: two target joints map to the same source joint")
    for c in range(1, len(names)):
        try:
            _source_chain(src.parents, s[parents[c]], s[c])
        except ValueError:
            raise ValueError(f"retarget_names: {names[c]}'s parent {names[parents[c]]} maps to "
                             f"{src.names[s[parents[c]]]}, which is not an ancestor of {src.names[s[c]]}") from None
    return s


def _rest_vector(src: Skeleton, a: int, b: int) -> np.ndarray:
    """Rest-pose vector from source joint a to its descendant b (sum of the offsets between)."""
    return sum((src.offsets[k] for k in _source_chain(src.parents, a, b)), np.zeros(3))


def _end_sites(src: Skeleton, names, s: list[int], leaves, sources: dict[str, str]) -> dict[int, np.ndarray]:
    ends = {}
    for c in leaves:
        k = src.index(sources.get(names[c], src.names[s[c]]))
        if k in src.end_sites:
            try:
                ends[c] = _rest_vector(src, s[c], k) + src.end_sites[k]
            except ValueError:
                raise ValueError(f"retarget_names: end-site source {src.names[k]} is not below "
                                 f"{src.names[s[c]]}") from None
    return ends


def _fixed_offsets(v: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """v (T, K, 3) offsets seen on each frame, rest (K, 3) -> (K, 3): the rest-pose vector where
    every frame agrees with it (to rounding), else the mean over frames (exact if v is constant)."""
    if not len(v):
        return rest
    agrees = np.abs(v - rest).max(0).max(-1) <= 1e-9 * (1 + np.linalg.norm(rest, axis=-1))  # (K,)
    return np.where(agrees[:, None], rest, v.mean(0))


def retarget_names(motion: Motion, names, parents, mapping: dict[str, str],
                   end_site_sources: dict[str, str] | None = None, tol: float = 1e-5) -> Motion:
    """Motion on a source skeleton -> the same motion on a sub-skeleton `names`/`parents`.

    mapping: target joint -> source joint.  Each target joint keeps its source
    joint's GLOBAL rotation and position; its local rotation is
    r'_c = G_p^-1 G_c (p = its target parent's source joint), its offset is the
    vector v_c(t) = G_p^-1 (x_c - x_p): the rest-pose vector (sum of the offsets between)
    where all frames agree with it, else its average over frames.  Removed joints between
    p and c fold into r'_c; v_c(t) is constant, so FK reproduces the source
    positions exactly, unless a removed joint with a non-zero offset (or whose child
    has one) rotates over time: then no fixed offset can, and the remaining error
    is reported in meta["retarget_max_error"] (a warning above `tol`).
    End Sites of target leaves: the rest-pose position of the End Site of
    end_site_sources[leaf] (default: the leaf's own source joint), if it has one.
    """
    src = motion.skeleton
    s = _source_indices(src, names, parents, mapping)
    rot = torch.from_numpy(motion.rotations)
    x, g = forward_kinematics(rot, torch.from_numpy(motion.root_positions), torch.from_numpy(src.offsets),
                              src.parents)  # (T, J, 3), (T, J, 4)
    xs, gs = x[:, s], g[:, s]  # (T, K, 3), (T, K, 4)
    par = list(parents[1:])
    g_par_inv = quat_conjugate(gs[:, par])  # (T, K-1, 4)
    local = torch.cat([gs[:, :1], quat_mul(g_par_inv, gs[:, 1:])], 1)  # r'_c = G_p^-1 G_c
    v = quat_rotate(g_par_inv, xs[:, 1:] - xs[:, par])  # (T, K-1, 3) offset in the parent's frame
    rest = np.stack([_rest_vector(src, s[p], s[c]) for c, p in enumerate(parents) if c])
    offsets = np.concatenate([src.offsets[s[0]][None] if s[0] == 0 else np.zeros((1, 3)),
                              _fixed_offsets(v.numpy(), rest)])
    leaves = [c for c in range(len(names)) if c not in parents]
    skeleton = Skeleton(tuple(names), tuple(parents), offsets,
                        _end_sites(src, names, s, leaves, end_site_sources or {}))
    meta = {k: v for k, v in motion.meta.items() if k not in ("channel_orders", "channels")}
    out = Motion(local.numpy(), xs[:, 0].numpy(), skeleton, motion.fps, motion.action, motion.style,
                 motion.subject, meta)
    err = float(np.abs(out.positions() - xs.numpy()).max()) if len(motion) else 0.0
    out.meta.update(retarget_max_error=err, retargeted_from=src.names, retarget_mapping=dict(mapping))
    if err > tol:
        warnings.warn(f"retarget_names: joint positions differ from the source by up to {err:.3g} "
                      "(a removed joint with a non-zero offset rotates over time)", stacklevel=2)
    return out


def map_to_canonical(motion: Motion, mapping: dict[str, str] = CMU_TO_CANONICAL,
                     end_site_sources: dict[str, str] = CMU_END_SITES) -> Motion:
    """A 31-joint CMU motion -> the canonical 21 joints (names, parents), with the CMU's own offsets.

    Removed: LHipJoint, RHipJoint (zero offsets, never rotate: no degrees of freedom in
    the CMU ASF), CMU Spine1 (its children sit at its own position), Head (becomes the
    canonical Head's End Site) and the fingers/thumbs (leaves).  Why the spine shifts
    (canonical Spine = CMU LowerBack, Spine1 = Spine, Head = Neck1): both leg offsets
    (not parallel) fix the canonical Hips' rotation to the CMU Hips' one, so the
    canonical Spine's position must be a fixed offset in the Hips' frame; the CMU Spine
    joint is not (LowerBack, at the hips, rotates it), but LowerBack is.  The same
    argument along the neck (CMU Neck at Spine1 rotates Neck1) gives Neck = Neck and
    Head = Neck1.  With this choice every canonical joint lands exactly on its CMU
    joint on every frame (tested, < 1e-5).  Works for any BVH using the CMU names.
    """
    return retarget_names(motion, CANONICAL_JOINTS, CANONICAL_PARENTS, mapping, end_site_sources)
