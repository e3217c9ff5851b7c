"""Retrain every checkpoint with the command recorded for it in checkpoints/MANIFEST.json, then rerun the lessons
that train nothing (their command is in results/<name>.json).

Usage: python tools/reproduce.py [--manifest checkpoints/MANIFEST.json] [--only NAME ...] [--dry-run]

The manifest is a JSON dict name -> entry, or a list of entries; each entry has a "command"
(a shell command run from the repository root, e.g. "python -m course_lib.... --out checkpoints/x.pt").
`python` in a command is this interpreter's (the venv's): its folder is put first on PATH.
`make reproduce` runs this with COURSE_MODE=full.  Commands run in manifest order; the first
failure stops the run (exit status 1) unless --keep-going.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path


def read_manifest(path: Path) -> list[tuple[str, str]]:
    """(name, command) for each entry of the manifest, in order; ValueError naming a bad entry."""
    data = json.loads(path.read_text(encoding="utf-8"))
    if isinstance(data, dict):
        items = list(data.items())
    elif isinstance(data, list):
        items = [(str(e.get("name", i)) if isinstance(e, dict) else str(i), e) for i, e in enumerate(data)]
    else:
        raise ValueError(f"{path}: expected a JSON dict or list of entries, got {type(data).__name__}")
    jobs = []
    for name, entry in items:
        command = entry.get("command") if isinstance(entry, dict) else None
        if not isinstance(command, str) or not command.strip():
            raise ValueError(f"{path}: entry {name!r} has no 'command' string")
        jobs.append((name, command))
    return jobs


def results_jobs(results: Path) -> list[tuple[str, str]]:
    """(name, command) of each lesson results file in `results` (results/<name>.json with a "command"): a lesson
    that trains nothing (lesson 04's control) has no manifest entry, only its results file."""
    jobs = []
    for path in sorted(results.glob("*.json")) if results.is_dir() else []:
        command = json.loads(path.read_text(encoding="utf-8")).get("command")
        if isinstance(command, str) and command.strip():
            jobs.append((path.stem, command))
    return jobs


def distinct_commands(jobs: list[tuple[str, str]]) -> list[tuple[str, str]]:
    """One job per distinct command, in first-seen order, named by every entry it rebuilds
    ("a, b": one `python -m course_lib.reproduce gmm_rnn` writes the RNN and all six refiners)."""
    names: dict[str, list[str]] = {}
    for name, command in jobs:
        names.setdefault(command, []).append(name)
    return [(", ".join(n), command) for command, n in names.items()]


def run_jobs(jobs: list[tuple[str, str]], root: Path, *, keep_going: bool = False) -> list[str]:
    """Run each command from `root` with this interpreter's bin folder first on PATH; names that failed."""
    env = dict(os.environ, PATH=os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "")]))
    failed = []
    for name, command in jobs:
        print(f"reproduce: [{name}] $ {command}", flush=True)
        start = time.perf_counter()
        status = subprocess.run(command, shell=True, cwd=root, env=env).returncode
        print(f"reproduce: [{name}] exit {status} after {time.perf_counter() - start:.1f} s", flush=True)
        if status != 0:
            failed.append(name)
            if not keep_going:
                break
    return failed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--manifest", type=Path, default=Path("checkpoints/MANIFEST.json"))
    parser.add_argument("--root", type=Path, default=None, help="folder the commands run in (default: manifest/..)")
    parser.add_argument("--only", nargs="+", default=None, metavar="NAME", help="run only these entries")
    parser.add_argument("--dry-run", action="store_true", help="print the commands without running them")
    parser.add_argument("--keep-going", action="store_true", help="run the remaining commands after a failure")
    args = parser.parse_args(argv)
    if not args.manifest.exists():
        print(f"reproduce: {args.manifest} does not exist: no checkpoints to reproduce")
        return 0
    jobs = read_manifest(args.manifest)
    known = {command for _, command in jobs}
    jobs += [(name, command) for name, command in results_jobs(args.manifest.resolve().parent.parent / "results")
             if command not in known]
    if args.only:
        unknown = sorted(set(args.only) - {name for name, _ in jobs})
        if unknown:
            parser.error(f"--only: no manifest entries named {', '.join(unknown)}")
        jobs = [(name, command) for name, command in jobs if name in args.only]
    jobs = distinct_commands(jobs)
    if args.dry_run:
        for name, command in jobs:
            print(f"reproduce: [{name}] $ {command}")
        return 0
    root = args.root if args.root is not None else args.manifest.resolve().parent.parent
    failed = run_jobs(jobs, root, keep_going=args.keep_going)
    print(f"reproduce: {len(jobs)} commands, {len(failed)} failed" + (f": {', '.join(failed)}" if failed else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
