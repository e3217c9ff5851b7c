"""Shared pytest fixtures: where the repository and the real CMU clip (package data) are.

Also defaults the headless-rendering variables (only where unset) so that
`pytest tests/test_render.py` works without an X server, as under `make test`.
These are set before any test module imports pyvista or matplotlib.
"""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]

for _name, _value in {
    "VTK_DEFAULT_OPENGL_WINDOW": "vtkEGLRenderWindow",
    "PYVISTA_OFF_SCREEN": "true",
    "PYVISTA_JUPYTER_BACKEND": "static",
    "MPLBACKEND": "Agg",
}.items():
    os.environ.setdefault(_name, _value)


def load_module(path: Path):
    """A script (tools/*.py, studies/*/*.py, data_scripts/*.py: folders that are not packages) as a module."""
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[path.stem] = module  # dataclasses in the script look their module up there
    spec.loader.exec_module(module)
    return module


def load_study(name: str):
    """studies/<lesson>/<name>.py as a module (``from conftest import load_study``); its folder goes on sys.path,
    as when the script runs, so that it can import a study beside it."""
    found = sorted(REPO_ROOT.glob(f"studies/*/{name}.py"))
    assert len(found) == 1, f"expected one studies/*/{name}.py, found {found}"
    if str(found[0].parent) not in sys.path:
        sys.path.insert(0, str(found[0].parent))
    return load_module(found[0])


@pytest.fixture(scope="session")
def repo_root() -> Path:
    """The repository's root folder (holds pyproject.toml)."""
    return REPO_ROOT


@pytest.fixture(scope="session")
def cmu_bvh_path() -> Path:
    """The real CMU clip course_lib/data/cmu_07_01_walk.bvh, package data in this repository (120 fps, 31 joints)."""
    path = REPO_ROOT / "course_lib" / "data" / "cmu_07_01_walk.bvh"
    if not path.is_file():
        pytest.fail(f"the CMU clip {path} is missing")
    return path
