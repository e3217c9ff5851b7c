"""Lesson 04 side experiment (issue 16): are the two running cases where a baseline is closer to the curve than ours
(the recorded run, seed 0: greedy steering on the running line and S-curve, L-BFGS alone on the running S-curve)
a difference between the methods or the spread of one seed?

Runs ours, L-BFGS alone and greedy steering on those two cases for seeds 0, 1 and 2 (the start frame, the samples
and the noise all change with the seed), with the recorded run's settings and measure (experiments.control's
offline rows), and prints each method's mean root-to-curve distance and foot skate per seed, their mean and sd.

    python tools/control_baseline_seeds.py --out tools/control_baseline_seeds_results.json   # ~5 min, 2 processes
"""

import argparse
import json

import numpy as np

from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import rounded

CASES = (("line", "run"), ("s_curve", "run"))
METHODS = ("ours", "lbfgs", "greedy")
SEEDS = (0, 1, 2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--workers", type=int, default=C.WORKERS)
    args = parser.parse_args()
    tasks = [(name, gait, method, seed, 1.0) for name, gait in CASES for method in METHODS for seed in SEEDS]
    rows = {f"{key}/seed {t[3]}": {k: v for k, v in row.items() if k != "root_xz"}
            for t, (key, row) in zip(tasks, C.parallel_map(C._offline_row, tasks, args.workers), strict=True)}
    summary = {}
    for name, gait in CASES:
        for method in METHODS:
            per = [rows[f"{name}/{gait}/{method}/seed {s}"] for s in SEEDS]
            d = [r["mean_root_to_curve_m"] for r in per]
            summary[f"{name}/{gait}/{method}"] = {
                "mean_root_to_curve_m": d, "mean_distance_mean_m": float(np.mean(d)),
                "mean_distance_sd_m": float(np.std(d, ddof=1)),
                "foot_skate_m_s": [r["foot_skate_m_s"] for r in per],
                "end_distance_m": [r["end_distance_m"] for r in per]}
            s = summary[f"{name}/{gait}/{method}"]
            print(f"{name}/{gait}/{method:7s} distance {np.round(d, 3)} mean {s['mean_distance_mean_m']:.3f} "
                  f"± {s['mean_distance_sd_m']:.3f} m, skate {np.round(s['foot_skate_m_s'], 3)}", flush=True)
    out = {"command": "python tools/control_baseline_seeds.py --out tools/control_baseline_seeds_results.json",
           "seeds": list(SEEDS), "rows": rows, "summary": summary}
    with open(args.out, "w") as f:
        json.dump(rounded(out), f, indent=1)


if __name__ == "__main__":
    main()
