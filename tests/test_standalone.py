"""The repository works alone: a clone with nothing beside it runs lesson 00 (which reads the real CMU clip),
and a built wheel ships that clip and its data card as package data.

The clone is of the committed HEAD (`git clone` of this checkout), so uncommitted changes are not tested here.
Lesson 00 runs there in CI mode with the clone first on PYTHONPATH, so its kernel imports the clone's course_lib
(checked twice: `course_lib.__file__` in a subprocess, and the BVH sample lesson 00 writes into the clone's site/).
About a minute on two cores.
"""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # make test-slow: a clone, a notebook and a wheel

REPO = Path(__file__).resolve().parents[1]
CLIP = "course_lib/data/cmu_07_01_walk.bvh"
CARD = "course_lib/data/README.md"
LESSON = "notebooks/00_skeletons_and_rotations.ipynb"


@pytest.fixture(scope="module")
def lone_clone(tmp_path_factory) -> Path:
    """A fresh clone of the committed HEAD in an otherwise empty folder."""
    clone = tmp_path_factory.mktemp("alone") / "course"
    done = subprocess.run(["git", "clone", "--quiet", str(REPO), str(clone)], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, f"git clone of {REPO} failed:\n{done.stderr}"
    assert sorted(p.name for p in clone.parent.iterdir()) == ["course"]  # nothing beside it
    return clone


def clone_env(clone: Path) -> dict[str, str]:
    """The environment of `make nbval`, with the clone (and only the clone) on PYTHONPATH."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_") and k != "MPLBACKEND"}
    env.update(PYTHONPATH=str(clone), COURSE_MODE="ci", TQDM_DISABLE="1", OMP_NUM_THREADS="1",
               VTK_DEFAULT_OPENGL_WINDOW="vtkEGLRenderWindow", PYVISTA_OFF_SCREEN="true",
               PYVISTA_JUPYTER_BACKEND="static")
    return env


def test_lesson_00_runs_in_a_clone_with_nothing_beside_it(lone_clone):
    env = clone_env(lone_clone)
    probe = subprocess.run(
        [sys.executable, "-c", "import course_lib; from course_lib.bvh import cmu_sample_path; "
         "print(course_lib.__file__); print(cmu_sample_path())"],
        cwd=lone_clone, env=env, capture_output=True, text=True, timeout=300)
    assert probe.returncode == 0, probe.stderr
    module, clip = (Path(line) for line in probe.stdout.split())
    assert module == lone_clone / "course_lib" / "__init__.py", f"imported {module}, not the clone's course_lib"
    assert clip == lone_clone / CLIP and clip.is_file()

    sample = lone_clone / "site" / "00_cmu_walk.bvh"  # lesson 00 writes it beside course_lib (bvh.SITE_DIR)
    assert not sample.exists()
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:xdist", "-p", "no:cacheprovider", "--nbval-lax",
         "--nbval-current-env", "--nbval-cell-timeout=300", "-q", LESSON],
        cwd=lone_clone, env=env, capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, f"lesson 00 failed in a lone clone:\n{run.stdout[-6000:]}\n{run.stderr[-3000:]}"
    assert sample.is_file(), "the lesson's kernel did not import the clone's course_lib"


def test_wheel_ships_the_clip_and_its_data_card(lone_clone, tmp_path):
    """A non-editable install gets the clip: `pip wheel` of the clone holds it and the card (package data)."""
    built = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--quiet", "-w", str(tmp_path),
         str(lone_clone)], capture_output=True, text=True, timeout=600)
    assert built.returncode == 0, built.stderr[-3000:]
    (wheel,) = tmp_path.glob("course_lib-*.whl")
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
        assert {CLIP, CARD} <= names, sorted(n for n in names if "/data/" in n)
        assert zf.read(CLIP) == (lone_clone / CLIP).read_bytes()
