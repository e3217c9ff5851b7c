"""Lesson 06 known answer: are the FID and C2ST blind to frame-to-frame noise at the level of MoGlow's samples?

    OMP_NUM_THREADS=1 python studies/06_moglow/moglow_noise_blind.py --out studies/06_moglow/moglow_noise_blind_results.json  # ~9 min

The held-out mocap with Gaussian noise on the standardised pose features (the space MoGlow samples in; the controls
and root path untouched), independent over frames, and either independent over features or correlated like the
training poses (the same total variance).  Scored by lesson 06's protocol (`experiments.moglow.noisy_mocap`: the same
halves, classifier and decoding as `quality`) at several noise levels, means over generation seeds 0-2, beside the
shipped MoGlow's recorded row.  Writes nothing to checkpoints/.
"""

import argparse
import json
import sys
import time

import numpy as np
import torch

from course_lib.experiments import moglow as E
from course_lib.results import provenance, rounded

COMMAND = "OMP_NUM_THREADS=1 python studies/06_moglow/moglow_noise_blind.py --out studies/06_moglow/moglow_noise_blind_results.json"
SDS = (0.0, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--seeds", type=int, default=E.EVAL_SEEDS)
    args = parser.parse_args()
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    data = E.load_data("full")
    out = {"command": COMMAND, "generation_seeds": list(range(args.seeds)), "noise_sd": list(SDS)}
    for kind, shaped in (("independent", False), ("shaped", True)):
        runs = [E.noisy_mocap(data, SDS, s, shaped=shaped) for s in range(args.seeds)]
        keys = runs[0][SDS[0]].keys()
        out[kind] = {str(sd): {k: float(np.mean([r[sd][k] for r in runs])) for k in keys} for sd in SDS}
        out[kind + "_sd"] = {str(sd): {k: float(np.std([r[sd][k] for r in runs])) for k in keys} for sd in SDS}
        for sd, r in out[kind].items():
            print(kind, sd, {k: round(v, 3) for k, v in r.items()}, file=sys.stderr, flush=True)
    out.update({"moglow_recorded": E.recorded_results()["quality"]["moglow"], "seconds": time.perf_counter() - t0})
    out = {**out, **provenance()}  # the command run (replaces COMMAND), the commit, the checkpoints' sha256
    with open(args.out, "w") as f:
        json.dump(rounded(out, 5), f, indent=1)


if __name__ == "__main__":
    main()
