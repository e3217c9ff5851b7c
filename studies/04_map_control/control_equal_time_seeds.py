"""Lesson 04 side experiment (issue 16): PSO + L-BFGS against L-BFGS alone and sampling alone at equal wall time,
over three seeds instead of one.

The recorded equal-time comparison (`experiments.control.equal_time_eval`, seed 0) found L-BFGS alone 6 mm closer
than ours on the walking S-curve, while over three seeds at the default budgets ours is the closer there.  This runs
the same comparison for seeds 1 and 2: ours' rows and the default-budget timings are the seeds' rows of
studies/04_map_control/control_baseline_seeds_results.json (the same motions, timed with the other worker busy, as recorded), the
baselines are run again at budgets scaled by ours' time over theirs; seed 0 is the recorded run's.  It prints each
method's mean distance, end and seconds per seed and on the mean of the seeds.

    OMP_NUM_THREADS=1 python studies/04_map_control/control_equal_time_seeds.py --out studies/04_map_control/control_equal_time_seeds_results.json

Writes nothing to checkpoints/.
"""

import argparse
import json
from pathlib import Path

import numpy as np

from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import CHECKPOINTS, rounded
from course_lib.results import provenance

SEEDS_FILE = Path(__file__).with_name("control_baseline_seeds_results.json")
METHODS = ("ours", "lbfgs", "best_of_n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--workers", type=int, default=C.WORKERS)
    args = parser.parse_args()
    recorded = C.recorded_results(CHECKPOINTS)["equal_time"]
    seeds_rows = json.loads(SEEDS_FILE.read_text())["rows"]
    per_seed = {0: recorded}
    for seed in (1, 2):
        offline = {k.rsplit("/seed ", 1)[0]: v for k, v in seeds_rows.items() if k.endswith(f"/seed {seed}")}
        per_seed[seed] = C.equal_time_eval(seed, offline=offline, workers=args.workers, progress=None)
        for case, row in per_seed[seed].items():
            print(f"seed {seed} {case}", {m: round(r["mean_root_to_curve_m"], 3) for m, r in row.items()}, flush=True)
    summary = {}
    for case in recorded:
        summary[case] = {m: {k: float(np.mean([per_seed[s][case][m][k] for s in per_seed]))
                             for k in ("mean_root_to_curve_m", "end_distance_m", "seconds")} for m in METHODS}
        summary[case]["closest"] = min(METHODS, key=lambda m: summary[case][m]["mean_root_to_curve_m"])
        print(case, summary[case], flush=True)
    out = {"command": f"OMP_NUM_THREADS=1 python studies/04_map_control/control_equal_time_seeds.py --out {args.out}",
           "seed_0": "the recorded run's equal_time rows (results/control.json)",
           "per_seed": {str(s): v for s, v in per_seed.items()}, "summary": summary}
    # the designs ran in worker processes: the files the prior loads there (design.default_prior)
    out = {**out, **provenance(checkpoints=[CHECKPOINTS / "gmm_rnn.pt", CHECKPOINTS / "gmm_rnn_stats.npz"])}
    with open(args.out, "w") as f:
        f.write(json.dumps(rounded(out, 4), indent=1) + "\n")


if __name__ == "__main__":
    main()
