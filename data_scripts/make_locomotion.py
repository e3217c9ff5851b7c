"""Generate the locomotion dataset of papers A (Habibie), B (Wang/Chai) and D (MoGlow).

Random control programs (idle, walk, jog, run, side-steps, backwards, turns, speed and gait
changes) drive the procedural generator of course_lib.synthetic; clips of --duration seconds
are generated at 120 fps and stored at --fps.  Writes <out> and a data card beside it
(<stem>.card.json, <stem>.card.md).  The same arguments give the same bytes.

    python data_scripts/make_locomotion.py                       # data/locomotion.npz, 1800 clips
    python data_scripts/make_locomotion.py --clips 40 --out /tmp/loco.npz --force
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
    ap.add_argument("--clips", type=int, default=1800, help="number of clips (default 1800)")
    ap.add_argument("--subjects", type=int, default=None, help="number of subjects (default clips/40, 8..60)")
    ap.add_argument("--duration", type=float, default=4.0, help="seconds per clip (default 4)")
    ap.add_argument("--fps", type=float, default=60.0, help="stored frame rate (default 60; generated at 120)")
    ap.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    ap.add_argument("--out", type=Path, default=D.DATA_DIR / "locomotion.npz", help="output .npz")
    ap.add_argument("--workers", type=int, default=2, help="processes (default 2; output does not depend on it)")
    ap.add_argument("--force", action="store_true", help="replace an existing output file")
    args = ap.parse_args(argv)
    try:  # the .npz and its two card files, before any work (nothing existing is replaced without --force)
        D.check_outputs(D.dataset_paths(args.out), overwrite=args.force, who=Path(__file__).name)
    except (FileExistsError, ValueError) as err:
        ap.error(str(err))
    if args.clips < 1 or not 0 < args.fps < math.inf or not 0 < args.duration < math.inf:
        ap.error(f"--clips, --fps and --duration must be positive finite numbers, got {args.clips}, {args.fps}, "
                 f"{args.duration}")
    if args.clips * args.duration > D.MAX_GENERATED_SECONDS:
        ap.error(f"--clips {args.clips} x --duration {args.duration:g} s = {args.clips * args.duration:.3g} s "
                 f"of motion: more than the {D.MAX_GENERATED_SECONDS:g} s (about "
                 f"{D.MAX_GENERATED_SECONDS / 7200:g}x the full set) that fit in memory; ask for fewer clips")
    if args.subjects is not None and args.subjects < 1:
        ap.error(f"--subjects must be at least 1 (or left out for the default), got {args.subjects}")
    t0 = time.time()
    motions = D.generate_locomotion_set(args.clips, args.seed, args.fps, args.duration, args.subjects,
                                      workers=args.workers, progress=True)
    params = dict(kind="locomotion", seed=args.seed, clips=args.clips, subjects=args.subjects,
                  duration=args.duration, fps=args.fps, schema_version=D.SCHEMA_VERSION)
    command = shlex.join(["python", "data_scripts/make_locomotion.py", *(sys.argv[1:] if argv is None else argv)])
    card = D.data_card(motions, name="locomotion", seed=args.seed, command=command,
                     description="Procedural locomotion driven by smooth random control programs "
                                 "(course_lib.synthetic.generate_locomotion); action = dominant gait of the clip.")
    D.write_dataset(motions, args.out, card=card, meta=params, overwrite=args.force)
    print(f"wrote {args.out} ({len(motions)} clips, {card['frames']} frames) in {time.time() - t0:.1f} s")


if __name__ == "__main__":
    main()
