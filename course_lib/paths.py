"""Where the course's files are: the repository, its checkpoints/ folder and its studies/ folder.

A clone of the repository needs no setting.  A project that installs course_lib apart from the repository
(``pip install .`` into another environment) finds the pretrained weights through one environment variable,
``COURSE_CHECKPOINTS`` (the repository's checkpoints/ folder, or a copy of it with its MANIFEST.json); without it,
loading a pretrained model raises an error that names the variable.  Reading the variable is all this module does.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["CHECKPOINTS", "CHECKPOINTS_ENV", "REPO_ROOT", "missing_checkpoints_hint"]

REPO_ROOT = Path(__file__).resolve().parents[1]  # the clone's root (for an installed package: site-packages)
CHECKPOINTS_ENV = "COURSE_CHECKPOINTS"
CHECKPOINTS = Path(os.environ.get(CHECKPOINTS_ENV) or REPO_ROOT / "checkpoints")


def missing_checkpoints_hint(path: str | os.PathLike) -> str:
    """What to say when a checkpoint is missing: a folder that does not exist means the package runs without its
    repository, so the message names the variable that points at the weights."""
    folder = Path(path).parent
    if folder.is_dir():
        return f"{path} not found (train it with the command in {folder / 'MANIFEST.json'}, or restore it from git)"
    return (f"{path} not found: there is no checkpoints folder at {folder}. course_lib installed apart from the "
            f"course's repository finds the pretrained weights through {CHECKPOINTS_ENV}: set it to the repository's "
            "checkpoints/ folder")
