"""Generate the labelled actions dataset of paper C (Ghorbani et al. 2020).

Every subject performs every action (walk, jog, jump, lift) in both styles (A, B: the
analogue of the paper's gender attribute), one clip each, generated at 120 fps by
course_lib.synthetic.generate_action and stored at --fps.  Writes <out> and a data card beside
it (<stem>.card.json, <stem>.card.md).  The same arguments give the same bytes.

    python data_scripts/make_actions.py                          # data/actions.npz, 40 subjects, 320 clips
    python data_scripts/make_actions.py --subjects 2 --out /tmp/actions.npz --force
"""

import argparse
import math
import shlex
import sys
import time
from pathlib import Path

from course_lib import datasets as D


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--subjects", type=int, default=40, help="number of subjects (default 40)")
    ap.add_argument("--fps", type=float, default=60.0, help="stored frame rate (default 60; generated at 120)")
    ap.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    ap.add_argument("--out", type=Path, default=D.DATA_DIR / "actions.npz", help="output .npz")
    ap.add_argument("--workers", type=int, default=2, help="processes (default 2; output does not depend on it)")
    ap.add_argument("--force", action="store_true", help="replace an existing output file")
    args = ap.parse_args(argv)
    try:  # the .npz and its two card files, before any work (nothing existing is replaced without --force)
        D.check_outputs(D.dataset_paths(args.out), overwrite=args.force, who=Path(__file__).name)
    except (FileExistsError, ValueError) as err:
        ap.error(str(err))
    if not 1 <= args.subjects <= D.MAX_ACTION_SUBJECTS or not 0 < args.fps < math.inf:
        ap.error(f"--subjects must be 1..{D.MAX_ACTION_SUBJECTS} and --fps a positive finite number, "
                 f"got {args.subjects}, {args.fps}")
    t0 = time.time()
    motions = D.generate_actions_set(args.subjects, args.seed, args.fps, workers=args.workers, progress=True)
    params = dict(kind="actions", seed=args.seed, subjects=args.subjects, actions=list(D.ACTIONS),
                  styles=list(D.STYLES), fps=args.fps, schema_version=D.SCHEMA_VERSION)
    command = shlex.join(["python", "data_scripts/make_actions.py", *(sys.argv[1:] if argv is None else argv)])
    card = D.data_card(motions, name="actions", seed=args.seed, command=command,
                     description=f"Non-periodic labelled actions {', '.join(D.ACTIONS)} in styles "
                                 f"{', '.join(D.STYLES)}, one clip per subject, action and style "
                                 "(course_lib.synthetic.generate_action).")
    D.write_dataset(motions, args.out, card=card, meta=params, overwrite=args.force)
    print(f"wrote {args.out} ({len(motions)} clips, {card['frames']} frames) in {time.time() - t0:.1f} s")


if __name__ == "__main__":
    main()
