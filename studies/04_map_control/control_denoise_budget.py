"""Lesson 04 side experiment (issue 16): is the denoised motion's foot skate the L-BFGS budget's?

The shipped filter spends 80 function evaluations per fixed-mixture round (3 rounds).  This tool scores 80 and 240 on
the *tuning* clips (held-out clips 4-7 of each gait, as studies/04_map_control/control_denoise_start.py), with the measures of
studies/04_map_control/control_denoise_contact.py.  If the skate were the search stopping early, 3x the budget would lower it.

    python studies/04_map_control/control_denoise_budget.py --out studies/04_map_control/control_denoise_budget_results.json   # ~2 min, one core
"""

import argparse
import json

import torch
from control_denoise_contact import scores  # the script's own folder is on sys.path

from course_lib.control.denoise import DenoiseConfig
from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import rounded
from course_lib.results import provenance

ITERATIONS = (80, 240)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    tuning = C.denoise_clips(first=4)
    results = {"command": "python studies/04_map_control/control_denoise_budget.py --out studies/04_map_control/control_denoise_budget_results.json",
               "clips": len(tuning), "tuning": {}}
    for n in ITERATIONS:
        results["tuning"][f"iterations={n}"] = r = scores(tuning, DenoiseConfig(iterations=n))
        print("tuning", n, {k: round(v, 4) for k, v in r.items()}, flush=True)
    results = {**results, **provenance()}  # the command run, the commit, the checkpoints' sha256
    with open(args.out, "w") as f:
        json.dump(rounded(results), f, indent=1)


if __name__ == "__main__":
    main()
