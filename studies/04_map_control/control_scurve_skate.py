"""Lesson 04 side experiment (issue 16): where the running S-curve's foot skate comes from (seed 0, the recorded
design settings).  The recorded design skates 0.079 m/s, just over the 2x limit of lesson 03's refined motion.
This designs it again without planting, plants it (`planting.plant_legs`), and splits the skate measure
(`evaluation.foot_skate_at_floor`: the mean floor speed of toes below 5 cm on both frames of a pair) pair by pair: how many
pairs, the fastest ones, the share of the skate that the fastest pair alone makes, and where that pair is (its
frames, toe and toe heights).

    OMP_NUM_THREADS=1 python studies/04_map_control/control_scurve_skate.py --out studies/04_map_control/control_scurve_skate_results.json   # ~1.5 min

Writes nothing to checkpoints/.
"""

import argparse
import json
from dataclasses import replace

import numpy as np
import torch

from course_lib.control import design_motion
from course_lib.control.design import default_prior
from course_lib.control.planting import plant_legs
from course_lib.evaluation import foot_skate_at_floor
from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import rounded
from course_lib.models.contact_cleanup import leg_columns
from course_lib.motion import CONTACT_HEIGHT
from course_lib.results import provenance


def pairs(m) -> dict:
    """The skate measure's toe pairs: both frames below the toe's contact height; their floor speeds."""
    toes = list(m.skeleton.feet[1::2])
    p = m.positions()[:, toes]  # (T, 2, 3)
    h = CONTACT_HEIGHT["ToeBase"]
    low = (p[1:, :, 1] < h) & (p[:-1, :, 1] < h)
    v = np.linalg.norm(p[1:, :, [0, 2]] - p[:-1, :, [0, 2]], axis=-1) * m.fps
    fast = np.sort(v[low])[::-1]
    t, k = np.unravel_index(np.argmax(np.where(low, v, -1.0)), v.shape)  # the fastest pair: frames t, t + 1
    return {"foot_skate_m_s": float(foot_skate_at_floor([m])), "low_pairs": int(low.sum()),
            "fastest_pair": {"frames": [int(t), int(t) + 1], "toe": ["left", "right"][k],
                             "toe_heights_m": p[t:t + 2, k, 1].tolist(),
                             "toe_heights_around_m": p[max(t - 3, 0):t + 5, k, 1].tolist()},
            "fastest_pairs_m_s": fast[:5].tolist(), "fastest_pair_share_of_skate": float(fast[0] / fast.sum()),
            "skate_without_the_fastest_pair_m_s": float(fast[1:].mean())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    c = C.curve("s_curve")
    m = design_motion(c, C.seconds_for(c, "run"), "run", seed=0, config=replace(C._config("ours"), plant=False))
    planted = plant_legs(m, leg_columns(m.skeleton, default_prior().fixed))
    out = {"command": f"OMP_NUM_THREADS=1 python studies/04_map_control/control_scurve_skate.py --out {args.out}",
           "case": "s_curve/run/ours, seed 0", "unplanted": pairs(m), "planted": pairs(planted),
           "planted_design": C.measure_design(planted, c)}
    out = {**out, **provenance()}  # the command run, the commit, the checkpoints' sha256
    print(json.dumps(rounded(out, 4), indent=1))
    with open(args.out, "w") as f:
        f.write(json.dumps(rounded(out, 4), indent=1) + "\n")


if __name__ == "__main__":
    main()
