"""Lesson 04 side experiment (issue 16): does a looser root data term lower the denoised motion's foot skate?

tools/control_denoise_clamp.py found that the denoised root's positions alone (clean rotations everywhere) skate
0.052 m/s, half the denoised motion's, and that the denoised root's error to the clean root changes by 3.6 mm a frame:
the filter keeps most of make_noisy's 5-mm root noise.  Eq. (25)'s sigma_root (1 cm) holds the root to the noisy
input, and the prior's sigma floor (``prior_min_std`` = 0.3 of the data's sd) lets its velocity move that much.  This
tool scores sigma_root 1 (shipped), 2, 4 and 8 cm on the *tuning* clips (held-out clips 4-7 of each gait) with the
measures of tools/control_denoise_contact.py, picks the lowest skate whose mean joint error is at most 5 % above the
shipped setting's, and reports the shipped and the picked setting on the scored clips (0-3, denoise_eval's).

    python tools/control_denoise_root.py --out tools/control_denoise_root_results.json   # ~4 min, one core
"""

import argparse
import json

import numpy as np
import torch
from control_denoise_contact import scores  # tools/ is the script's directory

from course_lib.control.denoise import DenoiseConfig
from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import rounded

SIGMA_ROOT = (0.01, 0.02, 0.04, 0.08)  # m


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    tuning, scored = C.denoise_clips(first=4), C.denoise_clips(first=0)
    results = {"command": "python tools/control_denoise_root.py --out tools/control_denoise_root_results.json",
               "clips_per_set": 8, "tuning": {}, "scored": {}}
    for s in SIGMA_ROOT:
        results["tuning"][f"sigma_root={s}"] = r = scores(tuning, DenoiseConfig(sigma_root=s))
        print("tuning", s, {k: round(v, 4) for k, v in r.items()}, flush=True)
    rows = results["tuning"]
    limit = 1.05 * rows[f"sigma_root={SIGMA_ROOT[0]}"]["mean_joint_error_m"]
    picked = min(SIGMA_ROOT, key=lambda s: rows[f"sigma_root={s}"]["foot_skate_m_s"]
                 if rows[f"sigma_root={s}"]["mean_joint_error_m"] <= limit else np.inf)
    results["picked_on_tuning"] = f"sigma_root={picked}"
    for s in dict.fromkeys((SIGMA_ROOT[0], picked)):
        results["scored"][f"sigma_root={s}"] = r = scores(scored, DenoiseConfig(sigma_root=s))
        print("scored", s, {k: round(v, 4) for k, v in r.items()}, flush=True)
    with open(args.out, "w") as f:
        json.dump(rounded(results), f, indent=1)
    print("picked on the tuning clips (lowest skate, joint error at most 5 % above the shipped):", picked)


if __name__ == "__main__":
    main()
