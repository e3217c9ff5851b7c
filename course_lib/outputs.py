"""The one rule for every command and function of the course that writes files.

A writer writes only the paths it was given and their documented companions (a dataset's
``<stem>.card.json`` and ``<stem>.card.md``, a benchmark's ``.md`` beside its ``.json``).  Before any
work starts it checks all of them at once:

- none of them is one of its inputs, or an input's companion (``--force`` does not change this);
- none of them exists, unless the caller asked to replace it (``overwrite=True``, scripts: ``--force``).

So a mistyped ``--out`` fails in the first second, naming the file, and nothing a user made is lost.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path


def _same(a: Path, b: Path) -> bool:
    if a.resolve() == b.resolve():
        return True
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_outputs(outputs: Iterable[str | os.PathLike], *, overwrite: bool = False,
                  inputs: Iterable[str | os.PathLike] = (), who: str = "write") -> list[Path]:
    """Raise before writing when an output is an input or already exists; returns the outputs as Paths.

    outputs: every path the writer will create, companions included.  inputs: every path it reads (and
    their companions).  overwrite: replace existing outputs (never inputs).  who: the command or
    function named in the message."""
    outs, ins = [Path(p) for p in outputs], [Path(p) for p in inputs]
    for out in outs:
        for src in ins:
            if _same(out, src):
                raise FileExistsError(f"{who}: {out} is the input file {src}; choose another output path "
                                      "(--force / overwrite=True never replaces an input)")
    if len({p.resolve() for p in outs}) < len(outs):
        raise ValueError(f"{who}: two outputs are the same file: {', '.join(map(str, outs))}")
    if not overwrite:
        existing = [str(p) for p in outs if p.exists()]
        if existing:
            raise FileExistsError(f"{who}: {' and '.join(existing)} exists; pass overwrite=True (scripts: --force) "
                                  "to replace it, or choose another output path")
    return outs
