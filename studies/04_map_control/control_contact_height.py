"""Lesson 04 side experiment (issue 16), on the shipped widths-256 RNN: offline designs with eq. (18)'s contact
labels as the RNN's contact bits alone (the paper's; ``DesignConfig(contact_height=None)``) against the shipped rule
(a bit, or a toe below 5 cm: foot_skate's height) on the 10 recorded cases (seed 0): distance to the curve, end
distance, foot skate, and where the skate comes from (`evaluation.contacts.skate_sources` with the RNN's bits).

    OMP_NUM_THREADS=1 python studies/04_map_control/control_contact_height.py --out studies/04_map_control/control_contact_height_results.json  # ~5 min

Writes nothing to checkpoints/.  Question: the designs whose skate was over 2x lesson 03's refined motion skated
from low toes whose bit was off; does holding those toes in eq. (18) remove it, and at what cost to the curve?
"""

import argparse
import json

import numpy as np
import torch

from course_lib.control import DesignConfig, design_motion
from course_lib.evaluation.contacts import skate_sources
from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import CHECKPOINTS, rounded
from course_lib.results import provenance

COMMAND = "OMP_NUM_THREADS=1 python studies/04_map_control/control_contact_height.py --out studies/04_map_control/control_contact_height_results.json"
RULES = {"bits only (the paper's labels)": None, "bits or toe below 5 cm (shipped)": DesignConfig().contact_height}


def case(task):
    """(curve, gait, rule) -> (key, measures)."""
    name, gait, rule = task
    torch.set_num_threads(1)
    c = C.curve(name)
    m = design_motion(c, C.seconds_for(c, gait), gait, seed=0, config=DesignConfig(contact_height=RULES[rule],
                                                                                                  plant=False))
    return f"{name}/{gait} | {rule}", measured(m, c)


def measured(m, c) -> dict:
    """A designed motion against its curve (`experiments.control.measure_design`) and where its skate comes from
    (`evaluation.contacts.skate_sources`, with the RNN's own contact bits)."""
    bits = np.asarray(m.meta["contacts_bits"]) > 0.5
    src = skate_sources(m.positions()[None], bits[None], m.skeleton, m.fps)
    return {**C.measure_design(m, c), "skate_from_unflagged": src["skate_from_unflagged"],
            "unflagged_low_speed": src["unflagged_low_speed"]}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--workers", type=int, default=C.WORKERS)
    args = parser.parse_args(argv)
    tasks = [(n, g, r) for n in C.CURVES for g in ("walk", "run") for r in RULES]
    rows = {}
    for key, row in C.parallel_map(case, tasks, args.workers):
        rows[key] = row
        print(key, {k: round(v, 3) for k, v in row.items()}, flush=True)
    out = {"command": COMMAND, "seed": 0, "rows": rounded(rows, 4)}
    # the designs ran in worker processes: the files the prior loads there (design.default_prior)
    out = {**out, **provenance(checkpoints=[CHECKPOINTS / "gmm_rnn.pt", CHECKPOINTS / "gmm_rnn_stats.npz"])}
    with open(args.out, "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
