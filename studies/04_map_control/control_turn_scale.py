"""Lesson 04 side experiment (issue 16): is the turn rate the cause of greedy steering's wins on the running curves?

Greedy steering is closer than ours, on the mean of three seeds, on exactly the three running curves that ask a turn
faster than 99 % of the training runs' frames (`experiments.control.curve_heading_rate` against `heading_rates`;
lesson 04 section 4).  Here the running S-curve and U-turn are scaled up by ``--scale`` (1.6: the S-curve then asks
about 81 deg/s at the running pace, the U-turn about 100, under the runs' 99th percentile), with the same pace, and
ours and greedy steering run on seeds 0-2 exactly as the recorded rows (`experiments.control._offline_row`, planted).
If the turn rate is the cause, ours should be the closer on the scaled curves.

    OMP_NUM_THREADS=1 python studies/04_map_control/control_turn_scale.py --out studies/04_map_control/control_turn_scale_results.json  # ~10 min

Writes nothing to checkpoints/.
"""

import argparse
import json

import numpy as np

from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import CHECKPOINTS, rounded
from course_lib.results import provenance

CASES = ("s_curve", "u_turn")
BASE_CURVE = C.curve
SEEDS = (0, 1, 2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--scale", type=float, default=1.6)
    parser.add_argument("--workers", type=int, default=C.WORKERS)
    args = parser.parse_args()
    scaled = {n: BASE_CURVE(n) * args.scale for n in CASES}
    tasks = [(n, "run", m, s, args.scale) for n in CASES for m in ("ours", "greedy") for s in SEEDS]
    rows = {}
    for t, (key, row) in zip(tasks, C.parallel_map(_row, tasks, args.workers), strict=True):
        rows[f"{key}/seed {t[3]}"] = {k: v for k, v in row.items() if k != "root_xz"}
        print(f"{key}/seed {t[3]}", {k: round(v, 3) for k, v in rows[f'{key}/seed {t[3]}'].items()}, flush=True)
    summary = {}
    for n in CASES:
        asked = C.curve_heading_rate(scaled[n], C.PACE["run"])
        d = {m: float(np.mean([rows[f"{n}/run/{m}/seed {s}"]["mean_root_to_curve_m"] for s in SEEDS]))
             for m in ("ours", "greedy")}
        summary[n] = {"asks_deg_s": asked, "mean_distance_m": d, "closer": min(d, key=d.get)}
        print(n, "scaled", args.scale, summary[n], flush=True)
    out = {"command": f"OMP_NUM_THREADS=1 python studies/04_map_control/control_turn_scale.py --out {args.out} --scale {args.scale:g}",
           "scale": args.scale, "seeds": list(SEEDS), "rows": rows, "summary": summary}
    # the command above is the script's own (it spells out --scale, which the argv may leave out); the designs
    # ran in worker processes: the files the prior loads there (design.default_prior)
    prov = provenance(checkpoints=[CHECKPOINTS / "gmm_rnn.pt", CHECKPOINTS / "gmm_rnn_stats.npz"])
    out = {**out, "commit": prov["commit"], "checkpoints_sha256": prov["checkpoints_sha256"]}
    with open(args.out, "w") as f:
        json.dump(rounded(out, 4), f, indent=1)
        f.write("\n")


def _row(task):
    """One (curve, gait, method, seed, scale) case on the scaled curve, in a worker process."""
    name, gait, method, seed, scale = task
    C.curve = lambda n: BASE_CURVE(n) * scale if n == name else BASE_CURVE(n)  # noqa: E731 (read by _offline_row)
    try:
        return C._offline_row((name, gait, method, seed, 1.0))
    finally:
        C.curve = BASE_CURVE


if __name__ == "__main__":
    main()
