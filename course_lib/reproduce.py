"""Reproduce a lesson's results from scratch, or re-evaluate them from the shipped checkpoints.

    python -m course_lib.reproduce vae_lstm [--eval-only]  # lesson 02, course_lib/experiments/vae_lstm.py
    python -m course_lib.reproduce gmm_rnn [--eval-only]   # lesson 03, course_lib/experiments/gmm_rnn.py
    python -m course_lib.reproduce hvrnn [--eval-only]     # lesson 05, course_lib/experiments/hvrnn.py
    python -m course_lib.reproduce moglow [--eval-only]    # lesson 06, course_lib/experiments/moglow.py
    python -m course_lib.reproduce control [--eval-only]   # lesson 04, course_lib/experiments/control.py (no training)

Without --eval-only: data, train every model of the lesson (or those named in --only), save the
checkpoints (provenance in checkpoints/MANIFEST.json) and record the results in results/<name>.json; with it:
the results from the shipped checkpoints.  Each lesson registers one entry in ``EXPERIMENTS`` (name ->
(train_fn, eval_fn)).  Nothing runs at import time.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import torch

from course_lib.experiments import control, gmm_rnn, hvrnn, moglow, vae_lstm
from course_lib.manifest import read_manifest
from course_lib.outputs import check_outputs
from course_lib.paths import CHECKPOINTS

ROOT = Path(__file__).resolve().parent.parent


EXPERIMENTS = {name: (getattr(lesson, f"train_{name}"), getattr(lesson, f"eval_{name}"))
               for name, lesson in (("vae_lstm", vae_lstm), ("gmm_rnn", gmm_rnn), ("hvrnn", hvrnn),
                                    ("moglow", moglow), ("control", control))}


def missing_checkpoints(experiment: str, checkpoints: Path) -> list[str]:
    """The files the manifest in `checkpoints` lists as made by this lesson's command that are not there (all of
    them, with the manifest, when the folder has no MANIFEST.json)."""
    manifest = checkpoints / "MANIFEST.json"
    if not manifest.is_file():
        return [str(manifest)]
    command = f"python -m course_lib.reproduce {experiment}"
    files = [e["file"] for e in read_manifest(manifest).values() if e.get("command") == command and e.get("file")]
    return [f for f in files if not (checkpoints / f).is_file()]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m course_lib.reproduce", description=__doc__.split("\n\n")[0])
    parser.add_argument("experiment", choices=sorted(EXPERIMENTS))
    parser.add_argument("--eval-only", action="store_true", help="recompute the tables from checkpoints/")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1, help="torch threads (1 is fastest on a busy CPU)")
    parser.add_argument("--out", type=Path, default=None, help="also write the JSON here")
    parser.add_argument("--only", nargs="*", default=None,
                        help="train only these models (others: checkpoints); control: measure only these parts")
    parser.add_argument("--checkpoints", type=Path, default=CHECKPOINTS, help="checkpoint folder (with MANIFEST.json)")
    parser.add_argument("--record", action="store_true",
                        help="with --eval-only: store the evaluation in results/ as training does (vae_lstm)")
    parser.add_argument("--force", action="store_true", help="replace an existing --out file")
    args = parser.parse_args(argv)
    if args.threads < 1:
        parser.error(f"--threads must be at least 1, got {args.threads}")
    if args.out is not None:
        try:
            check_outputs([args.out], overwrite=args.force, who="course_lib.reproduce")
        except (FileExistsError, ValueError) as err:
            parser.error(str(err))
    if args.eval_only:  # every checkpoint the lesson evaluates must be there before any data work starts
        missing = missing_checkpoints(args.experiment, args.checkpoints)
        if missing:
            parser.error(f"--eval-only {args.experiment}: {', '.join(missing)} not found in {args.checkpoints}; "
                         f"train them with `python -m course_lib.reproduce {args.experiment}` or give --checkpoints")
    torch.set_num_threads(args.threads)
    train_fn, eval_fn = EXPERIMENTS[args.experiment]
    kw = {"seed": args.seed, "checkpoints": args.checkpoints}
    if args.record:
        if not args.eval_only:
            parser.error("--record goes with --eval-only (training records its evaluation anyway)")
        kw["record"] = True
    result = eval_fn(**kw) if args.eval_only else train_fn(**kw, only=args.only)
    text = json.dumps(result, indent=1)
    print(text)
    if args.out:
        args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
