"""sha256 of files and their sidecars: how course_lib knows a file is the one it wrote.

A sidecar is ``<file>.sha256`` beside the file, in the format of ``sha256sum``
(``<64 hex digits>  <file name>``), so ``sha256sum -c model.pt.sha256`` checks it too.
`training.save_checkpoint` writes one next to every checkpoint (loading verifies it when no
manifest lists the file); `bvh.write_site_sample` writes one next to every sample it puts
into site/, and replaces only a sample whose sidecar still matches.
"""

from __future__ import annotations

import hashlib
import os
import re
from pathlib import Path

_DIGEST = re.compile(r"[0-9a-f]{64}")


def sha256_file(path: str | os.PathLike) -> str:
    """Hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def is_sha256(value) -> bool:
    """A 64-digit lower-case hex string."""
    return isinstance(value, str) and _DIGEST.fullmatch(value) is not None


def sidecar_path(path: str | os.PathLike) -> Path:
    """``<path>.sha256``."""
    path = Path(path)
    return path.with_name(path.name + ".sha256")


def write_sidecar(path: str | os.PathLike) -> Path:
    """Hash `path` and write its sidecar; returns the sidecar's path."""
    path = Path(path)
    side = sidecar_path(path)
    side.write_text(f"{sha256_file(path)}  {path.name}\n", encoding="ascii")
    return side


def read_sidecar(path: str | os.PathLike) -> str | None:
    """The sha256 recorded in `path`'s sidecar; None without a sidecar, ValueError if it is malformed."""
    side = sidecar_path(path)
    if not side.is_file():
        return None
    words = side.read_text(encoding="ascii", errors="replace").split()
    if not words or not is_sha256(words[0]):
        raise ValueError(f"{side} is not a sha256 sidecar (expected '<64 hex digits>  {Path(path).name}'); "
                         f"delete it, or rewrite it with course_lib.checksums.write_sidecar({str(path)!r})")
    return words[0]
