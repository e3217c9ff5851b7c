"""Noisy copies of a clean dataset, for the denoising lessons (paper B).

Reads a clean file written by make_locomotion.py or make_actions.py, adds the noise model of
course_lib.synthetic.add_noise (jitter, spikes/outliers, dropped frames) to each clip and
writes the noisy clips to <out>.  The clean file stays beside it: the output records its name
and sha256, and each noisy clip's meta["clean_index"]; course_lib.datasets.load_noisy_pairs
returns matching (noisy, clean) lists.  The same arguments give the same bytes.

    python data_scripts/make_noisy.py                            # data/locomotion.npz -> data/locomotion_noisy.npz
    python data_scripts/make_noisy.py --input data/actions.npz --out data/actions_noisy.npz
"""

import argparse
import math
import os
import shlex
import sys
import time
from pathlib import Path

from course_lib import datasets as D


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--input", type=Path, default=D.DATA_DIR / "locomotion.npz", help="clean .npz")
    ap.add_argument("--out", type=Path, default=None, help="output .npz (default <input stem>_noisy.npz)")
    ap.add_argument("--clips", type=int, default=None, help="use only the first N clean clips (default all)")
    ap.add_argument("--fps", type=float, default=None, help="resample the clean clips first (default: keep)")
    ap.add_argument("--seed", type=int, default=1, help="random seed of the noise (default 1)")
    ap.add_argument("--force", action="store_true", help="replace an existing output file")
    args = ap.parse_args(argv)
    out = args.out or args.input.with_name(args.input.stem + "_noisy.npz")
    # the .npz and its card files: never the clean input's (whatever --force says), nor existing ones without --force
    try:
        D.check_outputs(D.dataset_paths(out), overwrite=args.force, inputs=D.dataset_paths(args.input),
                        who=Path(__file__).name)
    except (FileExistsError, ValueError) as err:
        ap.error(str(err))
    if not args.input.exists():
        ap.error(f"{args.input} does not exist; make it first (make_locomotion.py or make_actions.py)")
    if args.clips is not None and args.clips < 1:
        ap.error(f"--clips must be at least 1 (or left out for all clips), got {args.clips}")
    if args.fps is not None and not 0 < args.fps < math.inf:
        ap.error(f"--fps must be a positive finite number, got {args.fps}")
    t0 = time.time()
    try:  # a file that is not a motion set is refused with its reason, not a traceback
        motions = D.load_motions(args.input)
    except ValueError as err:
        ap.error(f"--input: {err}")
    if args.clips is not None and args.clips > len(motions):
        ap.error(f"--clips {args.clips}: {args.input} holds only {len(motions)} clips")
    clean = D.resample_clips(motions[:args.clips], args.fps)
    noisy = D.noisy_copies(clean, args.seed, progress=True)
    params = dict(kind="noisy", seed=args.seed, clips=len(noisy), fps=args.fps, schema_version=D.SCHEMA_VERSION,
                  clean_file=os.path.relpath(args.input.resolve(), out.resolve().parent),
                  clean_sha256=D.file_sha256(args.input))
    command = shlex.join(["python", "data_scripts/make_noisy.py", *(sys.argv[1:] if argv is None else argv)])
    card = D.data_card(noisy, name=out.stem, seed=args.seed, command=command,
                     description=f"Noisy copies (course_lib.synthetic.add_noise) of the first {len(noisy)} clips of "
                                 f"{args.input.name}; pairs: course_lib.datasets.load_noisy_pairs.")
    D.write_dataset(noisy, out, card=card, meta=params, overwrite=args.force, inputs=D.dataset_paths(args.input))
    print(f"wrote {out} ({len(noisy)} clips) in {time.time() - t0:.1f} s")


if __name__ == "__main__":
    main()
