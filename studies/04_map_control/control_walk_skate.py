"""Lesson 04 side experiment (issue 16): the walking designs' foot skate over seeds 0-2, against eq. (18)'s weight
in eq. (19) (``DesignConfig.contact_weight``; 1 is the shipped sum) on the 5 walking curves. Per design: distance to
the curve, end distance, foot skate, and where the skate comes from (`evaluation.contacts.skate_sources` with the
RNN's bits and the design's low-toe rule).

    OMP_NUM_THREADS=1 python studies/04_map_control/control_walk_skate.py --out studies/04_map_control/control_walk_skate_results.json  # ~10 min a weight
    OMP_NUM_THREADS=1 python studies/04_map_control/control_walk_skate.py --out studies/04_map_control/control_walk_skate_results.json --weights 2

A weight already in --out is kept, not re-measured (the second command adds weight 2 to the first's 4 and 16).

Writes nothing to checkpoints/.  Question: on the mean of three seeds every walk skated over 2x lesson 03's refined
motion (0.094-0.142 m/s against 0.090 allowed) while every run stayed under; is the stance/low-toe term too weak
against the prior and the curve at walking pace, and what does a stronger one cost the curve?
"""

import argparse
import json
from pathlib import Path

import torch
from control_contact_height import measured  # the script's own folder is on sys.path

from course_lib.control import DesignConfig, design_motion
from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import CHECKPOINTS, rounded
from course_lib.results import provenance

COMMAND = "OMP_NUM_THREADS=1 python studies/04_map_control/control_walk_skate.py --out studies/04_map_control/control_walk_skate_results.json"
SEEDS = (0, 1, 2)


def case(task):
    """(curve, seed, weight) -> (key, measures)."""
    name, seed, weight = task
    torch.set_num_threads(1)
    c = C.curve(name)
    m = design_motion(c, C.seconds_for(c, "walk"), "walk", seed=seed, config=DesignConfig(contact_weight=weight,
                                                                                                 plant=False))
    return f"{name}/walk | weight {weight:g} | seed {seed}", measured(m, c)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--weights", type=float, nargs="+", default=[4.0, 16.0])
    parser.add_argument("--workers", type=int, default=C.WORKERS)
    args = parser.parse_args(argv)
    out_path = Path(args.out)
    kept = json.loads(out_path.read_text()) if out_path.exists() else {"weights": [], "rows": {}}
    weights = sorted(set(kept["weights"]) | set(args.weights))
    tasks = [(n, s, w) for w in args.weights if w not in kept["weights"] for n in C.CURVES for s in SEEDS]
    rows = dict(kept["rows"])  # weights measured by an earlier run are kept, not re-measured
    for key, row in C.parallel_map(case, tasks, args.workers):
        rows[key] = rounded(row, 4)
        print(key, {k: round(v, 3) for k, v in row.items() if isinstance(v, float)}, flush=True)
    run = f"{COMMAND} --weights {' '.join(f'{w:g}' for w in args.weights)}"
    commands = kept.get("commands", [kept["command"] + " --weights 4 16"] if "command" in kept else [])
    out = {"commands": commands + [run], "seeds": list(SEEDS), "weights": weights, "rows": rows}
    # each run's provenance (the weights it added); the designs ran in worker processes: the files the prior
    # loads there (design.default_prior)
    out["provenance"] = kept.get("provenance", []) + [provenance(checkpoints=[CHECKPOINTS / "gmm_rnn.pt", CHECKPOINTS / "gmm_rnn_stats.npz"])]
    with open(args.out, "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
