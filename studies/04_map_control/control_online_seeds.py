"""Lesson 04 side experiment (issue 16): is the online controller's recorded run one draw of a chaotic process?

The recorded run's held share (batches within 10 % of the commanded speed from 1 s after a change) moved between
recordings of the same controller code (0.92 / 0.39 walking / running, then 0.83 / 0.28).  This tool reruns the
recorded scripted run (seed 0) in a fresh process, compares it batch by batch with the recording in results/control.json (the
first batch whose speed differs by more than 1e-4 m/s, and the heading just before it), then runs seeds 1 and 2:
settling times, turn times and held share per seed.

    OMP_NUM_THREADS=1 python studies/04_map_control/control_online_seeds.py --out studies/04_map_control/control_online_seeds_results.json  # ~2 min

Writes nothing to checkpoints/.
"""

import argparse
import json

import torch

from course_lib.experiments import control as C
from course_lib.results import write_study_result

COMMAND = "OMP_NUM_THREADS=1 python studies/04_map_control/control_online_seeds.py --out studies/04_map_control/control_online_seeds_results.json"
SUMMARY = ("speed_settle_s", "turn_s", "speed_held", "frames_per_s")


def divergence(now: dict, recorded: dict, tol: float = 1e-4) -> dict:
    """The first batch whose speed differs by more than tol between two runs -> its index, time, both speeds and
    both headings of the batch before it (None when every batch agrees)."""
    a, b = now["batches"], recorded["batches"]
    first = next((i for i, (x, y) in enumerate(zip(a, b, strict=True)) if abs(x["speed"] - y["speed"]) > tol), None)
    if first is None:
        return {"first_batch": None}
    before = max(first - 1, 0)
    return {"first_batch": first, "t": b[first]["t"], "speed_now": a[first]["speed"],
            "speed_recorded": b[first]["speed"], "heading_before_now": a[before]["heading"],
            "heading_before_recorded": b[before]["heading"]}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    recorded = C.recorded_results()["online"]
    out = {"command": COMMAND, "rerun_seed_0": {}, "seeds": {}}
    for gait in ("walk", "run"):
        again = C.online_run(gait, 0)
        out["rerun_seed_0"][gait] = {"recorded_held": recorded[gait]["speed_held"], "rerun_held": again["speed_held"],
                                     **divergence(again, recorded[gait])}
        out["seeds"][gait] = {"0 (recorded)": {k: recorded[gait][k] for k in SUMMARY}}
        for seed in (1, 2):
            r = C.online_run(gait, seed)
            out["seeds"][gait][str(seed)] = {k: r[k] for k in SUMMARY}
        print(gait, json.dumps(out["rerun_seed_0"][gait]), flush=True)
    write_study_result(args.out, out, 5)  # + command, commit, checkpoints' sha256


if __name__ == "__main__":
    main()
