"""Lesson 04 side experiment (issue 16): is the denoised motion's foot skate in the energy's minimum, or in the search?

Known answers first: a filter given the clean motion should give it back, with the clean motion's skate.  The shipped
filter (DenoiseConfig(), without its planting step unless --plant: the MAP estimate alone) is run on the 8 scored held-out clips of ``experiments.control.denoise_eval`` with

- the clean motion as the input (from the usual 4-Hz low-pass start, and from the clean motion itself);
- the noisy input (make_noisy's noise, seed 1) from the clean motion as the start;
- each of those again with eq. (19)'s prior term off (``weights={"prior": 0}``: eq. 25's data term and eq. 18 only),
- the clean input from the clean start with eq. (18) off, and with eq. (18) and the prior off (eq. 25 alone: its
  minimum is the input itself, the tool's own known answer),

and each row reports the mean joint error to the clean motion, its max, foot skate (each clip's, averaged, as
denoise_eval) and contact agreement.  If the filter slides clean feet from a clean start, its energy's minimum skates;
if it does so only with the prior on, the prior is what pulls the feet.

    python studies/04_map_control/control_denoise_prior.py --out studies/04_map_control/control_denoise_prior_results.json   # ~6 min, one core
"""

import argparse
import json

import numpy as np
import torch
from control_denoise_contact import mean_scores  # the script's own folder is on sys.path

from course_lib.control.denoise import DenoiseConfig
from course_lib.datasets import noisy_copies
from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import rounded
from course_lib.results import provenance


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--plant", action="store_true",
                        help="plant the toes after the MAP estimate (DenoiseConfig.plant); default: the estimate alone")
    args = parser.parse_args()
    torch.set_num_threads(1)
    clean = C.denoise_clips()
    noisy = noisy_copies(clean, 1)
    rows = {"clean motion itself (no filter)": {k: float(np.mean([C._denoise_scores(c, c)[k] for c in clean]))
                                                for k in C._denoise_scores(clean[0], clean[0])}}
    for prior_on in (True, False):
        config = DenoiseConfig(plant=args.plant) if prior_on else DenoiseConfig(weights={"prior": 0.0}, plant=args.plant)
        tag = "" if prior_on else ", prior off"
        for name, inputs, starts in (("clean input, low-pass start", clean, None),
                                     ("clean input, clean start", clean, clean),
                                     ("noisy input, low-pass start", noisy, None),
                                     ("noisy input, clean start", noisy, clean)):
            rows[name + tag] = r = mean_scores(inputs, clean, config, starts)
            print(f"{name + tag:40s}", {k: round(v, 4) for k, v in r.items()}, flush=True)
    for tag, weights in ((", contact off", {"contact": 0.0}),
                         (", prior and contact off", {"prior": 0.0, "contact": 0.0})):
        rows["clean input, clean start" + tag] = r = mean_scores(clean, clean, DenoiseConfig(weights=weights, plant=args.plant), clean)
        print(f"{'clean input, clean start' + tag:40s}", {k: round(v, 4) for k, v in r.items()}, flush=True)
    out = {"command": "python studies/04_map_control/control_denoise_prior.py --out studies/04_map_control/control_denoise_prior_results.json",
           "clips": len(clean), "planted": args.plant, "rows": rows}
    out = {**out, **provenance()}  # the command run, the commit, the checkpoints' sha256
    with open(args.out, "w") as f:
        json.dump(rounded(out), f, indent=1)


if __name__ == "__main__":
    main()
