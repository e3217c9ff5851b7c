"""Lesson 06 side experiment (issue 17): does longer training, within the 15-minute budget, bring the zero-control
stepping ratio under 0.3, and at what price?  The shipped models train ``E.STEPS`` = 5000 steps (the largest ~11 min);
here all four variants train 6300 steps (the largest ~14 min on one core), the same data, seed and evaluation
(``experiments.moglow.train_moglow``), into a folder of their own; then the ratio over sampling seeds 0-4 as
studies/06_moglow/moglow_zero_control_seeds.py measures it.  Writes nothing to checkpoints/.

    python studies/06_moglow/moglow_longer_training.py --steps 6300 --folder /tmp/mg6300 \\
        --out studies/06_moglow/moglow_longer_training_results.json   # ~50 min on one core
    # --skip-training: score the checkpoints a run left in --folder (its results.json)
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import torch

from course_lib.experiments import moglow as E
from course_lib.results import provenance, rounded

sys.path.insert(0, str(Path(__file__).resolve().parent))
from moglow_zero_control_seeds import stepping_speed  # noqa: E402

SEEDS = tuple(range(5))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=6300)
    parser.add_argument("--folder", type=Path, required=True, help="where the longer-trained checkpoints go")
    parser.add_argument("--out", required=True)
    parser.add_argument("--skip-training", action="store_true", help="score the checkpoints already in --folder")
    args = parser.parse_args()
    torch.set_num_threads(1)
    if args.folder.resolve() == E.CHECKPOINTS.resolve():
        raise SystemExit("--folder must not be checkpoints/ (this experiment does not replace the shipped models)")
    args.folder.mkdir(parents=True, exist_ok=True)
    if args.skip_training:
        results = json.loads((args.folder / "results.json").read_text())
    else:
        results = E.train_moglow(checkpoints=args.folder, steps=args.steps)
        (args.folder / "results.json").write_text(json.dumps({**results, **provenance()}, indent=1) + "\n")
    data = E.load_data("full")
    seeds = {}
    for label, folder in (("longer", args.folder), ("shipped", E.CHECKPOINTS)):
        models = {n: E.load_model(n, folder) for n in ("moglow", "moglow_nodrop")}
        sp = {n: [stepping_speed(m, data, s) for s in SEEDS] for n, m in models.items()}
        ratios = np.array(sp["moglow"]) / np.array(sp["moglow_nodrop"])
        seeds[label] = {"feet_speed": sp, "ratios": ratios.tolist(), "mean": float(ratios.mean()),
                        "max": float(ratios.max())}
        print(label, np.round(ratios, 3).tolist(), flush=True)
    out = {"command": "python " + " ".join(sys.argv), "steps": args.steps, "shipped_steps": E.STEPS,
           "results": results, "seeds": list(SEEDS), "zero_control_ratio_over_seeds": seeds}
    out = {**out, **provenance()}  # the command run, the commit, the checkpoints' sha256
    with open(args.out, "w") as f:
        f.write(json.dumps(rounded(out, 5), indent=1) + "\n")


if __name__ == "__main__":
    main()
