"""Lesson 04 side experiment (issue 16): is "better than every baseline" a difference between the methods or the
spread of one seed?

The offline rows are one seed's, and they move with numerics alone: after the online-speed changes (FK by rotation
matrices, the same positions to ~1e-16 m) the recorded run's "ours closest to the curve" went from 8 to 6 of 10 cases
with the cases that failed changed.  This tool runs every method on every case (5 curves x walking and running) for
seeds 1 and 2 (the start frame, the samples and the noise all change with the seed), with the recorded run's settings
and measure (experiments.control's offline rows), takes seed 0 from the recorded run (results/control.json,
``control``), and prints each method's mean root-to-curve distance, end distance and foot skate per seed, their mean
and sd, and per case which baselines have a smaller mean distance than ours over the 3 seeds.

    python studies/04_map_control/control_baseline_seeds.py --out studies/04_map_control/control_baseline_seeds_results.json   # ~12 min, 2 processes
"""

import argparse
import json

import numpy as np

from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import CHECKPOINTS, rounded
from course_lib.results import provenance

GAITS = ("walk", "run")
SEEDS = (0, 1, 2)  # seed 0: the recorded run's rows
KEYS = ("mean_root_to_curve_m", "end_distance_m", "foot_skate_m_s")


def summarise(rows: dict, seeds=SEEDS) -> tuple[dict, dict]:
    """{"curve/gait/method/seed s": row} -> (per case and method: each measure per seed, mean and sd;
    per case: the baselines whose mean distance over the seeds is below ours)."""
    summary, beaten = {}, {}
    for name in C.CURVES:
        for gait in GAITS:
            case = f"{name}/{gait}"
            for method in C.METHODS:
                per = [rows[f"{case}/{method}/seed {s}"] for s in seeds]
                summary[f"{case}/{method}"] = s = {k: [r[k] for r in per] for k in KEYS}
                for k in KEYS:
                    s[k + "_mean"], s[k + "_sd"] = float(np.mean(s[k])), float(np.std(s[k], ddof=1))
            ours = summary[f"{case}/ours"]["mean_root_to_curve_m_mean"]
            beaten[case] = [m for m in C.METHODS[1:] if summary[f"{case}/{m}"]["mean_root_to_curve_m_mean"] < ours]
    return summary, beaten


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--workers", type=int, default=C.WORKERS)
    args = parser.parse_args()
    recorded = C.recorded_results(CHECKPOINTS)["offline"]
    rows = {f"{key}/seed 0": {k: v for k, v in row.items() if k != "root_xz"} for key, row in recorded.items()}
    tasks = [(name, gait, method, seed, 1.0) for seed in SEEDS[1:] for name in C.CURVES for gait in GAITS
             for method in C.METHODS]
    for t, (key, row) in zip(tasks, C.parallel_map(C._offline_row, tasks, args.workers), strict=True):
        rows[f"{key}/seed {t[3]}"] = {k: v for k, v in row.items() if k != "root_xz"}
        print(f"{key}/seed {t[3]}", {k: round(row[k], 3) for k in KEYS}, flush=True)
    summary, beaten = summarise(rows)
    for key, s in summary.items():
        print(f"{key:28s} distance {np.round(s['mean_root_to_curve_m'], 3)} -> {s['mean_root_to_curve_m_mean']:.3f} "
              f"± {s['mean_root_to_curve_m_sd']:.3f} m | end {np.round(s['end_distance_m'], 2)} | skate "
              f"{np.round(s['foot_skate_m_s'], 2)}")
    print("baselines closer to the curve than ours on the mean of the seeds:", beaten)
    out = {"command": "python studies/04_map_control/control_baseline_seeds.py --out studies/04_map_control/control_baseline_seeds_results.json",
           "seeds": list(SEEDS), "seed_0": "the recorded run's rows (results/control.json)", "rows": rows,
           "summary": summary, "baselines_closer_on_the_mean": beaten}
    # the designs ran in worker processes: the files the prior loads there (design.default_prior)
    out = {**out, **provenance(checkpoints=[CHECKPOINTS / "gmm_rnn.pt", CHECKPOINTS / "gmm_rnn_stats.npz"])}
    with open(args.out, "w") as f:
        json.dump(rounded(out), f, indent=1)


if __name__ == "__main__":
    main()
