"""Lesson 04 side experiment: lesson 03's contact handling (contact_cleanup.plant_feet, the RNN's own contact bits)
applied after MAP motion design, on the designs whose skate was furthest above 2x lesson 03's refined motion.

    python studies/04_map_control/control_plant_feet.py --out studies/04_map_control/control_plant_feet_results.json   # ~2 min per case, one core

Writes nothing to checkpoints/.  Question: is the designed motions' skate (issue 16: at most 2x lesson 03's GAN2 +
contacts) what the contact handling removes, and what does it cost in curve following?
"""

import argparse
import time

import numpy as np
import torch

from course_lib.evaluation.contacts import skate_sources
from course_lib.experiments import control as C
from course_lib.experiments import gmm_rnn as X
from course_lib.models.contact_cleanup import plant_feet
from course_lib.representations import decode_state_features, encode_state_features, root_start
from course_lib.results import write_study_result

CASES = (("u_turn", "walk"), ("polyline", "walk"), ("u_turn", "run"), ("line", "walk"))


def planted(motion, stats):
    """The designed motion with its flagged feet held by plant_feet (bits: the RNN's, from motion.meta)."""
    f = encode_state_features(motion)
    f[:, -2:] = np.asarray(motion.meta["contacts_bits"], dtype=float)
    cols = X.contact_columns(stats, motion.skeleton)
    g = plant_feet(f[None], motion.skeleton, cols, offsets=np.asarray(motion.skeleton.offsets)[None])[0]
    return decode_state_features(g, motion.skeleton, motion.fps, root_start(motion))


def sources(motion) -> dict:
    """Where the motion's skate comes from (evaluation.contacts.skate_sources) with the RNN's contact bits."""
    bits = np.asarray(motion.meta["contacts_bits"]) > 0.5
    return skate_sources(motion.positions()[None], bits[None], motion.skeleton, motion.fps)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    stats = X.load_stats(X._stats_path(X.CHECKPOINTS), "state_features")
    out = {"command": f"python studies/04_map_control/control_plant_feet.py --out {args.out}", "cases": {}}
    for name, gait in CASES:
        m, seconds = C.offline_case(name, gait, "ours", seed=0)
        t0 = time.perf_counter()
        p = planted(m, stats)
        c = C.curve(name)
        p.meta["contacts_bits"] = m.meta["contacts_bits"]
        out["cases"][f"{name}, {gait}"] = {"designed": {**C.measure_design(m, c), **sources(m)},
                                           "design_seconds": seconds,
                                           "with_plant_feet": {**C.measure_design(p, c), **sources(p)},
                                           "plant_feet_seconds": time.perf_counter() - t0}
        print(name, gait, {k: {q: round(v[q], 3) for q in ("foot_skate_m_s", "flagged_speed", "unflagged_low_speed",
                                                           "unflagged_low_fraction", "skate_from_unflagged")}
                           for k, v in out["cases"][f"{name}, {gait}"].items() if isinstance(v, dict)}, flush=True)
        write_study_result(args.out, out)  # + command, commit, checkpoints' sha256


if __name__ == "__main__":
    main()
