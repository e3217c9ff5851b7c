"""The checkpoint manifest: which file in checkpoints/ is which, with its sha256 and the command that made it.

``checkpoints/MANIFEST.json`` maps a name (the file's path relative to the manifest, without suffix) to an
entry: file, sha256, bytes, command, course_lib version, and for a model its config, class and training
environment: provenance only (what a training or evaluation measured is in ``results/``, `course_lib.results`).
Every file
the course loads from checkpoints/ (weights and normalisation statistics) is verified here before it is read:
its sha256 must match its entry or, for a copy elsewhere that no manifest lists, its ``.sha256`` sidecar.

`course_lib.training` writes model entries (`save_checkpoint`); `record_file` writes the entry of any other
file (the statistics a model was trained with).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from pathlib import Path

from course_lib import __version__
from course_lib.checksums import is_sha256, read_sidecar, sha256_file, sidecar_path, write_sidecar
from course_lib.paths import CHECKPOINTS

__all__ = ["entry_name", "expected_sha256", "manifest_path", "read_manifest", "record_file", "update_manifest",
           "verify_file"]


def manifest_path(path: Path, manifest: str | os.PathLike | None) -> Path:
    return Path(manifest) if manifest is not None else path.parent / "MANIFEST.json"


def entry_name(path: Path, manifest_path: Path) -> str:
    """The manifest key of a checkpoint: its path relative to the manifest's folder, without suffix."""
    try:
        rel = path.resolve().relative_to(manifest_path.resolve().parent)
    except ValueError:
        rel = Path(path.name)
    return rel.with_suffix("").as_posix()


@contextlib.contextmanager
def locked(path: Path, kind: str):
    """An exclusive lock for a read-modify-write of ``path`` (several processes may write at once).  The lock file
    lives in the temp dir so that no stray file appears next to the checkpoints or results."""
    key = hashlib.sha256(str(Path(path).resolve()).encode()).hexdigest()[:16]
    with open(Path(tempfile.gettempdir()) / f"course_lib_{kind}_{key}.lock", "w") as lock:
        try:
            import fcntl

            fcntl.flock(lock, fcntl.LOCK_EX)
        except ImportError:  # Windows: no advisory locks; single-writer use is fine
            pass
        yield


def replace_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename: a reader never sees half a file."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def update_manifest(manifest_path: Path, name: str, entry: dict) -> None:
    """Read-modify-write MANIFEST.json under an exclusive lock: set the entry ``name``."""
    manifest_path.parent.mkdir(parents=True, exist_ok=True)
    with locked(manifest_path, "manifest"):
        table = json.loads(manifest_path.read_text()) if manifest_path.exists() else {}
        table[name] = entry
        replace_text(manifest_path, json.dumps(dict(sorted(table.items())), indent=2) + "\n")


def read_manifest(mpath: Path) -> dict:
    """MANIFEST.json -> {name: entry}; a malformed file is a ValueError that says so."""
    try:
        table = json.loads(mpath.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ValueError(f"{mpath} is not valid JSON ({err}); restore it (git checkout -- {mpath}) or rebuild "
                         "its checkpoints with the commands it listed") from None
    if not isinstance(table, dict) or not all(isinstance(e, dict) for e in table.values()):
        raise ValueError(f"{mpath} is malformed: expected an object of checkpoint entries; restore it "
                         f"(git checkout -- {mpath})")
    return table


def expected_sha256(path: Path, mpath: Path) -> tuple[str, str]:
    """-> (sha256 the file must have, what to run if it does not): the manifest's entry, else the sidecar."""
    name = entry_name(path, mpath)
    entry = read_manifest(mpath).get(name) if mpath.exists() else None
    if entry is not None:
        command = entry.get("command", "the command that made it")
        if not is_sha256(entry.get("sha256")):
            raise ValueError(f"{mpath}: the entry {name!r} has no valid sha256, so {path} cannot be verified; "
                             f"rebuild it with: {command}")
        return entry["sha256"], f"Rebuild it with: {command}"
    side = read_sidecar(path)
    if side is not None:
        return side, f"Restore the file together with its sidecar {sidecar_path(path).name}, or rebuild it."
    raise ValueError(
        f"cannot verify {path}: {mpath} {'has no entry ' + repr(name) if mpath.exists() else 'does not exist'} and "
        f"there is no sidecar {sidecar_path(path)}. Copy the checkpoint with its .sha256 sidecar (save_checkpoint "
        "writes one). If you trust this file, record its hash with course_lib.checksums.write_sidecar(path), "
        "or load it with verify=False.")


VERIFIED: dict[str, str] = {}  # every file verified in this process -> its sha256 (what a study records it used)


def checkpoints_manifest(checkpoints: str | os.PathLike | None = None) -> dict:
    """{name: entry} of the course's checkpoints (default folder: `paths.CHECKPOINTS`): file, sha256, config,
    command, the environment it was trained on.  What a lesson reads to show a model's provenance."""
    return read_manifest(Path(checkpoints or CHECKPOINTS) / "MANIFEST.json")


def verify_file(path: str | os.PathLike, manifest: str | os.PathLike | None = None) -> Path:
    """Raise ValueError unless ``path``'s sha256 matches its manifest entry (default manifest: MANIFEST.json
    beside it) or, where no manifest lists it, its sidecar; the message says how to proceed.  Returns the path."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path} not found")
    expected, fix = expected_sha256(path, manifest_path(path, manifest))
    actual = sha256_file(path)
    if actual != expected:
        raise ValueError(f"sha256 mismatch for {path}: expected {expected[:12]}..., file {actual[:12]}...; "
                         f"the file is corrupt or stale. {fix}")
    VERIFIED[str(path.resolve())] = actual
    return path


def record_file(path: str | os.PathLike, *, command: str, manifest: str | os.PathLike | None = None) -> dict:
    """Record a file that is not a model (e.g. the normalisation statistics a model was trained with) in the
    manifest beside it, with its sha256 and the command that made it, and write its sidecar.  Returns the entry."""
    path = Path(path)
    if not command or not isinstance(command, str):
        raise ValueError("record_file: command must be the shell command that reproduces this file")
    write_sidecar(path)
    mpath = manifest_path(path, manifest)
    entry = {"file": os.path.relpath(path.resolve(), mpath.resolve().parent).replace(os.sep, "/"),
             "sha256": sha256_file(path), "bytes": path.stat().st_size, "command": command,
             "course_lib_version": __version__}
    update_manifest(mpath, entry_name(path, mpath), entry)
    return entry
