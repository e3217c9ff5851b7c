"""Results for JSON: every experiment and study records its numbers rounded the same way; the lessons' recorded
results live in ``results/<name>.json``, and the lessons read the studies' results through one function.

`rounded` is used by the lessons' experiment modules (course_lib/experiments/), the benchmark and the studies in
studies/ before they write a result to a JSON file, so that a re-run on another CPU changes a recorded number
only where it changes in its sixth decimal (or the ``digits`` asked).

The lessons' results (DESIGN.md, "Layout"): one file per reproduction command, ``results/<name>.json`` for
``python -m course_lib.reproduce NAME``, ``{"command": ..., "checkpoints": {entry: metrics}, ...}``: what each
checkpoint's training recorded (its curves, seconds, the evaluation a lesson stores with its main model) under
the checkpoint's manifest name, and whatever else the lesson records (lesson 04's "results").  The manifest
(`course_lib.manifest`) keeps provenance only.  `results_file` says where a lesson's file is: the repository's
``results/`` for its own ``checkpoints/``, ``<folder>/results/`` for any other checkpoint folder (a scratch
copy, a test's tmp folder), so that work there never touches the shipped results.  `read_results`,
`update_results`, `checkpoint_metrics` and `record_checkpoint_metrics` read and write them (the last two for a
checkpoint file, through its manifest entry: `training.save_checkpoint` / `record_metrics` / `recorded_metrics`
call them).

`study_result(name)` reads ``studies/<lesson>/<name>.json`` (each study's result, beside the script that wrote it);
`provenance` is what a study records about itself: its command, the commit and the checkpoints' sha256.
"""

from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from course_lib.checksums import sha256_file
from course_lib.manifest import VERIFIED, entry_name, locked, manifest_path, read_manifest, replace_text
from course_lib.paths import CHECKPOINTS, REPO_ROOT

__all__ = ["checkpoint_metrics", "git_commit", "provenance", "read_results", "record_checkpoint_metrics", "recorded",
           "results_file", "results_folder", "results_name", "rounded", "studies_folder", "study_result",
           "update_results", "write_study_result"]

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


def git_commit(root: Path) -> str:
    """The commit of the git checkout at ``root``, with "+changes" when tracked files differ from it (a change to
    a study's result JSON does not count: it is another study's output, not an input of this run)."""
    def git(*args):
        try:
            return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, timeout=30).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return ""

    commit = git("rev-parse", "HEAD") or "unknown (not a git checkout)"
    if commit[:1] != "u" and git("status", "--porcelain", "--untracked-files=no", "--", ".",
                                 ":(exclude)studies/*/*.json"):
        commit += "+changes"
    return commit


def provenance(checkpoints=None, argv=None) -> dict:
    """What a study records about itself, to merge into the JSON it writes (``{**result, **provenance()}``): the
    command that ran it (``argv``, default sys.argv), the repository's commit (`git_commit`) and the sha256 of
    each checkpoint file it used: ``checkpoints`` (paths), default every file this process loaded through a
    verified load (`manifest.VERIFIED`: checkpoints and their statistics)."""
    root = Path(__file__).resolve().parents[1]
    commit = git_commit(root)
    argv = list(sys.argv if argv is None else argv)
    script = Path(argv[0]) if argv else Path("?")
    if script.is_absolute() and root in script.parents:
        argv[0] = str(script.relative_to(root))
    used = ({Path(p).name: sha256_file(p) for p in checkpoints} if checkpoints is not None
            else {Path(p).name: digest for p, digest in sorted(VERIFIED.items())})
    return {"command": shlex.join(["python", *argv]), "commit": commit, "checkpoints_sha256": used}


def rounded(d, digits: int = 6):
    """Results for JSON: floats rounded to ``digits`` decimals inside nested dicts/lists/tuples, keys as str."""
    if isinstance(d, dict):
        return {str(k): rounded(v, digits) for k, v in d.items()}
    if isinstance(d, (list, tuple)):
        return [rounded(v, digits) for v in d]
    return round(float(d), digits) if isinstance(d, (float, np.floating)) else d



def write_study_result(path: str | os.PathLike, result: dict, digits: int = 6, checkpoints=None) -> Path:
    """A study's result JSON: ``result`` with its `provenance` (command, commit, checkpoints' sha256), floats
    `rounded` to ``digits``, written to ``path`` with a final newline.  Returns the path."""
    path = Path(path)
    record = rounded({**result, **provenance(checkpoints)}, digits)
    path.write_text(json.dumps(record, indent=1, default=float) + "\n")
    return path

# ----------------------------------------------------------------------------- the lessons' results files

_ROOT = REPO_ROOT
REPRODUCE = "python -m course_lib.reproduce"


def results_folder(checkpoints: str | os.PathLike) -> Path:
    """Where the results of the checkpoints in ``checkpoints`` go: the repository's results/ for its own
    checkpoints/ folder, ``<checkpoints>/results/`` for any other folder (tests and scratch copies stay apart)."""
    checkpoints = Path(checkpoints)
    if checkpoints.resolve() == (_ROOT / "checkpoints").resolve():
        return _ROOT / "results"
    return checkpoints / "results"


def results_file(name: str, checkpoints: str | os.PathLike = CHECKPOINTS) -> Path:
    """The results file of reproduction ``name`` (or of a checkpoint without one) for ``checkpoints``."""
    if not name or "/" in name or name.startswith("."):
        raise ValueError(f"results_file: {name!r} is not a results name (a lesson command's name, e.g. 'gmm_rnn')")
    return results_folder(checkpoints) / f"{name}.json"


def results_name(command: str | None, entry: str) -> str:
    """Which results file a checkpoint's metrics go to: NAME of its command ``python -m course_lib.reproduce NAME``,
    else the checkpoint's own manifest name ``entry`` (its last path component)."""
    words = _reproduce_words(command)
    return words[3] if words else entry.rsplit("/", 1)[-1]


def _reproduce_words(command: str | None) -> list[str]:
    """The words of ``python -m course_lib.reproduce NAME ...``; [] for any other command."""
    try:
        words = shlex.split(command or "")
    except ValueError:
        return []
    return words if words[:3] == REPRODUCE.split() and len(words) > 3 else []


def _command_of(name: str) -> str:
    return f"{REPRODUCE} {name}"


def read_results(name: str, checkpoints: str | os.PathLike = CHECKPOINTS) -> dict:
    """The results file of ``name`` as a dict; FileNotFoundError (naming the command that writes it) when absent,
    ValueError when it is not a JSON object."""
    file = results_file(name, checkpoints)
    if not file.is_file():
        raise FileNotFoundError(f"{file} not found: it is written by the reproduction command ({_command_of(name)} "
                                "for a lesson) when it trains or records its evaluation")
    try:
        data = json.loads(file.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ValueError(f"{file} is not valid JSON ({err}); restore it (git checkout -- {file}) or rerun "
                         f"{_command_of(name)}") from None
    if not isinstance(data, dict) or not isinstance(data.get("checkpoints", {}), dict):
        raise ValueError(f"{file} is malformed: expected an object with a 'checkpoints' object")
    return data


def recorded(name: str, *keys: str, checkpoints: str | os.PathLike = CHECKPOINTS):
    """``read_results(name)[keys[0]][keys[1]]...``; a missing key is a KeyError that names the file and the
    command that records it."""
    value = read_results(name, checkpoints)
    for i, key in enumerate(keys):
        if not isinstance(value, dict) or key not in value:
            raise KeyError(f"{results_file(name, checkpoints)} has no {'/'.join(keys[:i + 1])}: record it with "
                           f"{_command_of(name)}")
        value = value[key]
    return value


def _dumps(x, level: int = 0) -> str:
    """JSON with one space of indent per level, a list of plain values (a training curve) on one line."""
    if isinstance(x, dict) and x:
        pad = " " * (level + 1)
        items = ",\n".join(f"{pad}{json.dumps(k)}: {_dumps(v, level + 1)}" for k, v in x.items())
        return "{\n" + items + "\n" + " " * level + "}"
    if isinstance(x, list) and any(isinstance(v, (dict, list)) for v in x):
        pad = " " * (level + 1)
        return "[\n" + ",\n".join(pad + _dumps(v, level + 1) for v in x) + "\n" + " " * level + "]"
    return json.dumps(x)


def update_results(name: str, change: Callable[[dict], None],
                   checkpoints: str | os.PathLike = CHECKPOINTS, *, command: str | None = None) -> dict:
    """Read-modify-write the results file of ``name`` under an exclusive lock: ``change(data)`` edits the dict in
    place ({"command", "checkpoints": {}} for a new file; ``command`` defaults to the lesson's reproduction command).
    Returns what was written."""
    file = results_file(name, checkpoints)
    file.parent.mkdir(parents=True, exist_ok=True)
    with locked(file, "results"):
        data = read_results(name, checkpoints) if file.exists() else {}
        data = {"command": None, "checkpoints": {}, **data}  # these two first in a new file
        data["command"] = command or data["command"] or _command_of(name)
        change(data)
        data["checkpoints"] = dict(sorted(data["checkpoints"].items()))
        data = json.loads(json.dumps(data))  # plain JSON values (str keys), as a reader will see them
        replace_text(file, _dumps(data) + "\n")
    return data


def _checkpoint_key(path: str | os.PathLike, manifest: str | os.PathLike | None) -> tuple[str, str, Path, dict]:
    """A checkpoint file -> (results name, manifest name, checkpoint folder, manifest entry); KeyError without one."""
    path = Path(path)
    mpath = manifest_path(path, manifest)
    name = entry_name(path, mpath)
    table = read_manifest(mpath) if mpath.exists() else {}
    if name not in table:
        raise KeyError(f"{mpath} has no entry {name!r}; build it with the lesson's reproduction command")
    entry = table[name]
    return results_name(entry.get("command"), name), name, mpath.parent, entry


def checkpoint_metrics(path: str | os.PathLike, manifest: str | os.PathLike | None = None) -> dict:
    """What a checkpoint's training (and its lesson's evaluation) recorded about it: its entry in its results file
    ({} when nothing was recorded).  KeyError when the manifest does not list the checkpoint."""
    lesson, name, folder, _ = _checkpoint_key(path, manifest)
    if not results_file(lesson, folder).is_file():
        return {}
    return read_results(lesson, folder)["checkpoints"].get(name, {})


def record_checkpoint_metrics(path: str | os.PathLike, metrics: dict | None, *,
                              manifest: str | os.PathLike | None = None, merge: bool = False) -> dict:
    """Store a checkpoint's metrics in its results file: replace its entry (``merge=False``: a fresh training;
    None drops a stale one) or merge ``metrics`` into it.  The checkpoint must have a manifest entry.  Returns
    the checkpoint's metrics as stored."""
    lesson, name, folder, entry = _checkpoint_key(path, manifest)
    if metrics is None and not merge and not results_file(lesson, folder).is_file():
        return {}
    command = None if _reproduce_words(entry.get("command")) else entry.get("command")  # a lesson's: its NAME's

    def change(data):
        if metrics is None and not merge:
            data["checkpoints"].pop(name, None)
        else:
            data["checkpoints"][name] = {**(data["checkpoints"].get(name, {}) if merge else {}), **(metrics or {})}

    return update_results(lesson, change, folder, command=command)["checkpoints"].get(name, {})
