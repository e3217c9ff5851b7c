"""Results for JSON: every experiment and study records its numbers rounded the same way, and the lessons read
the studies' results through one function.

`rounded` is used by the lessons' experiment modules (course_lib/experiments/), the benchmark and the studies in
studies/ before they write a result to the manifest or a JSON file, so that a re-run on another CPU changes a
recorded number only where it changes in its sixth decimal (or the ``digits`` asked).

`study_result(name)` reads ``studies/<lesson>/<name>.json`` (each study's result, beside the script that wrote it);
`provenance` is what a study records about itself: its command, the commit and the checkpoints' sha256.
"""

from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np

from course_lib.checksums import sha256_file

__all__ = ["provenance", "rounded", "studies_folder", "study_result"]

STUDIES_ENV = "COURSE_STUDIES"  # where studies/ is, for a course_lib installed apart from its repository


def studies_folder() -> Path:
    """The repository's studies/ folder (or $COURSE_STUDIES); FileNotFoundError that says how to point at it."""
    folder = Path(os.environ.get(STUDIES_ENV) or Path(__file__).resolve().parents[1] / "studies")
    if not folder.is_dir():
        raise FileNotFoundError(f"no studies folder at {folder}: the studies ship with the course's repository, not "
                                f"with the installed package; set {STUDIES_ENV} to the repository's studies/ folder")
    return folder


def study_result(name: str) -> dict:
    """The result of the study ``name`` (its JSON's file name, with or without .json), from studies/<lesson>/."""
    file = name if name.endswith(".json") else f"{name}.json"
    found = sorted(studies_folder().glob(f"*/{file}"))
    if len(found) != 1:
        raise FileNotFoundError(f"study {name!r}: {len(found)} files named {file} in {studies_folder()}/*/ "
                                "(expected exactly one; the index is studies/README.md)")
    return json.loads(found[0].read_text())


def provenance(checkpoints=(), argv=None) -> dict:
    """What a study records about itself: the command that reran it (``argv``, default sys.argv), the repository's
    commit (with "+changes" when the work tree differs from it) and the sha256 of each checkpoint file it used."""
    root = Path(__file__).resolve().parents[1]

    def git(*args):
        try:
            return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, timeout=30).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return ""

    commit = git("rev-parse", "HEAD") or "unknown (not a git checkout)"
    if commit[:1] != "u" and git("status", "--porcelain", "--untracked-files=no"):
        commit += "+changes"
    argv = list(sys.argv if argv is None else argv)
    script = Path(argv[0]) if argv else Path("?")
    if script.is_absolute() and root in script.parents:
        argv[0] = str(script.relative_to(root))
    return {"command": shlex.join(["python", *argv]), "commit": commit,
            "checkpoints_sha256": {Path(p).name: sha256_file(p) for p in checkpoints}}


def rounded(d, digits: int = 6):
    """Results for JSON: floats rounded to ``digits`` decimals inside nested dicts/lists/tuples, keys as str."""
    if isinstance(d, dict):
        return {str(k): rounded(v, digits) for k, v in d.items()}
    if isinstance(d, (list, tuple)):
        return [rounded(v, digits) for v in d]
    return round(float(d), digits) if isinstance(d, (float, np.floating)) else d
