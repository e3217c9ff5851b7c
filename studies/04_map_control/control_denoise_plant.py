"""Lesson 04 side experiment (issue 16): does eq. (18) solved as a near-hard constraint after the MAP filter bring the
denoised motion's foot skate within 2x the clean motion's, and at what price in joint error?

studies/04_map_control/control_denoise_prior.py measured that the energy's own minimum, started at the clean motion, already skates
about 3x the clean motion: eq. (18)'s sigma_con of 3 cm per frame and the prior's floored sigmas cannot resolve the
half millimetre a frame a planted toe may move.  Lesson 03 has the sharp version of the same term,
`contact_cleanup.plant_feet`: every flagged toe held still (sigma_slide 3 mm) and on the floor, by L-BFGS on the root
and the leg angles, each held near its value.  This tool runs the shipped filter, then plant_feet on its output with its
contact bits (lesson 03's GAN2 + contacts columns, `gmm_rnn.contact_columns`, each clip on its own skeleton), on the
tuning clips (held-out clips 4-7 of each gait) and the scored clips (0-3, denoise_eval's), and reports both with and
without the planting: mean and max joint error to the clean motion, foot skate (and the clean clips'), contact
agreement.  Nothing is picked: the one setting is lesson 03's.

    python studies/04_map_control/control_denoise_plant.py --out /tmp/control_denoise_plant_results.json   # ~6 min, one core
"""

import argparse
import json
import time

import numpy as np
import torch

from course_lib.control import DenoiseConfig, denoise
from course_lib.datasets import load_stats, noisy_copies
from course_lib.evaluation import foot_skate
from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import CHECKPOINTS, contact_columns, rounded
from course_lib.models.contact_cleanup import plant_feet
from course_lib.representations import decode_state_features, encode_state_features, root_start
from course_lib.results import provenance


def planted(m, columns=None):
    """A denoised Motion -> the same with its flagged toes held still and on the floor (plant_feet) by moving
    ``columns`` (None: lesson 03's, the root and the legs, `gmm_rnn.contact_columns`)."""
    f = encode_state_features(m)
    if columns is None:
        columns = contact_columns(load_stats(CHECKPOINTS / "gmm_rnn_stats.npz", "state_features"), m.skeleton)
    g = plant_feet(f[None], m.skeleton, columns, offsets=m.skeleton.offsets[None])[0]
    return decode_state_features(g, m.skeleton, m.fps, root_start(m))


def score_set(clips: list, seed: int = 0) -> dict:
    noisy = noisy_copies(clips, seed + 1)
    t0 = time.perf_counter()
    out = [denoise(n, seed=seed, config=DenoiseConfig(plant=False)) for n in noisy]  # the MAP estimate alone
    t1 = time.perf_counter()
    plant = [planted(m) for m in out]
    t2 = time.perf_counter()
    rows = {"denoised": [C._denoise_scores(m, c) for m, c in zip(out, clips, strict=True)],
            "denoised + plant_feet": [C._denoise_scores(m, c) for m, c in zip(plant, clips, strict=True)],
            "noisy": [C._denoise_scores(m, c) for m, c in zip(noisy, clips, strict=True)]}
    res = {k: {s: float(np.mean([r[s] for r in v])) for s in v[0]} for k, v in rows.items()}
    res["clean_foot_skate_m_s"] = float(foot_skate(clips))
    res["seconds"] = {"denoise": t1 - t0, "plant_feet": t2 - t1}
    return res


def tuning_and_scored(score_set, command: str, description: str, **rounding) -> None:
    """A tool's main: --out; score_set(clips) on the tuning clips (held-out 4-7 of each gait) and the scored ones (0-3),
    printed and written to --out with the command, rounded (``rounding``: rounded()'s keywords)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    results = {"command": command}
    for name, first in (("tuning", 4), ("scored", 0)):
        results[name] = r = score_set(C.denoise_clips(first=first))
        print(name, json.dumps(rounded(r, **rounding)), flush=True)
    results = {**results, **provenance()}  # the command run (replaces ``command``), commit, checkpoints' sha256
    with open(args.out, "w") as f:
        json.dump(rounded(results, **rounding), f, indent=1)


def main() -> None:
    tuning_and_scored(score_set, "python studies/04_map_control/control_denoise_plant.py --out /tmp/control_denoise_plant_results.json",
                      __doc__.splitlines()[0])


if __name__ == "__main__":
    main()
