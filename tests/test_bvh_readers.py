"""course_lib.bvh against the BVH readers students use: Blender's own importer and bvhio (PyPI).

Every test file (the real CMU walk, the crafted mixed-order file, and cmu_07_01_root_offset.bvh:
frames 100-139 of the CMU walk with the root OFFSET set to (10, 36, -5), position channels kept)
is read by course_lib, Blender and bvhio, and so is a file written by `write_bvh` from each of
them; world joint positions must agree on every frame within 1e-4 of the motion's extent.
Blender is not optional: CI (.ci/run) installs Debian's `blender` package, and without it these
tests fail with a message saying so.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import bvhio
import numpy as np
import pytest

from course_lib.bvh import read_bvh, write_bvh
from course_lib.motion import Motion

pytestmark = pytest.mark.slow  # make test-slow: one Blender process per module

HERE = Path(__file__).resolve().parent
DATA = HERE / "data"
ROOT_OFFSET_FILE = DATA / "cmu_07_01_root_offset.bvh"
TOL = 1e-4  # max position difference / the motion's extent


@pytest.fixture(scope="module")
def cases(cmu_bvh_path, tmp_path_factory) -> dict[str, tuple[Path, Motion]]:
    """name -> (file, the Motion course_lib says it holds): each test file as read_bvh reads it, and a
    file write_bvh made from that Motion (the Motion written is the reference for the file)."""
    out = tmp_path_factory.mktemp("written")
    sources = {"cmu_walk": (cmu_bvh_path, "XYZ"), "crafted": (DATA / "crafted_mixed_orders.bvh", None),
               "root_offset": (ROOT_OFFSET_FILE, "YZX")}
    result = {}
    for name, (path, order) in sources.items():
        motion = read_bvh(path)
        result[f"read {name}"] = (path, motion)
        written = write_bvh(motion, out / f"{name}.bvh", order=order or motion.meta["channel_orders"])
        result[f"write {name}"] = (written, motion)
    return result


def _blender() -> str:
    exe = shutil.which("blender")
    if exe is None:
        pytest.fail("Blender is not on PATH: these tests compare course_lib with Blender's own BVH importer. "
                    "Install Debian's package (sudo apt-get install blender); .ci/run installs it.")
    return exe


@pytest.fixture(scope="module")
def blender_positions(cases, tmp_path_factory) -> dict[str, dict]:
    """Blender's world bone-head positions of every case's file, from one Blender process."""
    out = tmp_path_factory.mktemp("blender") / "positions.json"
    paths = [str(p) for p, _ in cases.values()]
    cmd = [_blender(), "-b", "--factory-startup", "-noaudio", "--python", str(HERE / "blender_bvh_positions.py"),
           "--", str(out), *paths]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    if run.returncode != 0 or not out.exists():
        pytest.fail(f"Blender's BVH import failed (exit {run.returncode}):\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}")
    return json.loads(out.read_text())


def _relative_error(motion: Motion, names: list[str], positions: np.ndarray) -> float:
    """Max |course_lib - other| over frames and joints, divided by the extent of course_lib's positions."""
    ours = motion.positions()  # (T, J, 3)
    assert sorted(names) == sorted(motion.skeleton.names)
    assert positions.shape == (len(motion), len(names), 3)
    ours = ours[:, [motion.skeleton.index(n) for n in names]]
    extent = np.ptp(ours.reshape(-1, 3), axis=0).max()
    return float(np.abs(ours - positions).max() / extent)


CASE_NAMES = [f"{kind} {name}" for name in ("cmu_walk", "crafted", "root_offset") for kind in ("read", "write")]


@pytest.mark.parametrize("case", CASE_NAMES)
def test_blender_importer_agrees(case, cases, blender_positions):
    path, motion = cases[case]
    got = blender_positions[str(path)]
    err = _relative_error(motion, got["names"], np.array(got["positions"]))
    print(f"Blender vs course_lib, {case}: max error / extent = {err:.2e}")
    assert err < TOL


def _bvhio_positions(path: Path) -> tuple[list[str], np.ndarray]:
    root = bvhio.readAsHierarchy(str(path))
    joints = [j for j, _, _ in root.layout()]
    frames = []
    for t in range(len(root.Keyframes)):
        root.loadPose(t)
        frames.append([list(j.PositionWorld) for j in joints])
    return [j.Name for j in joints], np.array(frames)


@pytest.mark.parametrize("case", CASE_NAMES)
def test_bvhio_agrees(case, cases):
    path, motion = cases[case]
    names, positions = _bvhio_positions(path)
    err = _relative_error(motion, names, positions)
    print(f"bvhio vs course_lib, {case}: max error / extent = {err:.2e}")
    assert err < TOL


def test_root_offset_is_not_added_to_the_position_channels(cmu_bvh_path):
    """The non-zero root OFFSET moves the rest pose only: the motion equals the CMU frames it was cut from."""
    cut = read_bvh(ROOT_OFFSET_FILE)
    np.testing.assert_allclose(cut.skeleton.offsets[0], [10.0, 36.0, -5.0])
    np.testing.assert_allclose(cut.positions(), read_bvh(cmu_bvh_path)[100:140].positions(), atol=1e-12)
    assert np.ptp(cut.positions()[..., 1]) < 36  # not floating 36 units above the CMU clip
