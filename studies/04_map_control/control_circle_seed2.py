"""Lesson 04 side experiment (issue 16): why does the walking circle fail on seed 2 (0.265 m from the curve, the end
missed by 1.64 m), the one run of ours in 30 (studies/04_map_control/control_baseline_seeds.py) that misses the distance limit or
the end?

Designs the walking circle with the recorded run's settings (experiments.control.offline_case, method "ours") for
seeds 0, 1 and 2 and prints, window by window (34 frames, 17 kept): the control energy after the search, whether the
retry rule searched the window again, the total energy, and the root's distance to the curve over the kept frames;
then which window first goes wrong on seed 2 and its energy terms.

    python studies/04_map_control/control_circle_seed2.py --out studies/04_map_control/control_circle_seed2_results.json   # ~4 min, one core
"""

import argparse
import json

import torch

from course_lib.control import DesignConfig
from course_lib.control.energy import nearest_on_polyline
from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import rounded
from course_lib.results import provenance


def windows(seed: int) -> dict:
    m, sec = C.offline_case("circle_r2", "walk", "ours", seed)
    c = C.curve("circle_r2")
    _, dist = nearest_on_polyline(torch.from_numpy(m.root_positions[:, [0, 2]]), torch.from_numpy(c))  # (T,) m
    hop = DesignConfig().hop  # the frames each window keeps, after the two start frames
    rows = []
    for i, h in enumerate(m.meta["design"]["windows"]):
        kept = dist[2 + hop * i:2 + hop * (i + 1)].numpy()
        rows.append({"window": i, "control": h["terms"]["control"], "total": h["terms"]["total"],
                     "terms": h["terms"], "retried": bool(h.get("retried", False)),
                     "mean_distance_m": float(kept.mean()), "max_distance_m": float(kept.max())})
    return {"seconds": sec, **C.measure_design(m, c), "windows": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    out = {"command": "python studies/04_map_control/control_circle_seed2.py --out studies/04_map_control/control_circle_seed2_results.json"}
    for seed in (0, 1, 2):
        out[f"seed {seed}"] = r = windows(seed)
        print(f"seed {seed}: mean {r['mean_root_to_curve_m']:.3f} m, end {r['end_distance_m']:.2f} m, "
              f"{r['seconds']:.0f} s", flush=True)
        for w in r["windows"]:
            print(f"  window {w['window']:2d}: control {w['control']:8.1f} total {w['total']:9.1f} "
                  f"retried {str(w['retried']):5s} distance mean {w['mean_distance_m']:.3f} max "
                  f"{w['max_distance_m']:.3f} m", flush=True)
    out = {**out, **provenance()}  # the command run, the commit, the checkpoints' sha256
    with open(args.out, "w") as f:
        json.dump(rounded(out), f, indent=1)


if __name__ == "__main__":
    main()
