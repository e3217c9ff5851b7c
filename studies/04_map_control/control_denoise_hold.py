"""Lesson 04 side experiment (issue 16): can the denoised feet be held?  The shipped filter's stance bits are the
noisy input's, and the noise makes a planted foot look fast: on the tuning clips they flag 0.11 of the clean
motion's stance frames.  Taken from the low-passed start at a laxer speed threshold (0.6 m/s) they flag 0.90
(``DenoiseConfig(contact_bits="start", stance_speed=0.6)``).  This measures, on the tuning clips (held-out clips
4-7 of each gait, denoise_eval's noise), how well each set of bits matches the clean stances, and what eq. (18)
then does with them: the filtered motion, and the same with lesson 03's contact handling
(contact_cleanup.plant_feet, the same bits) applied after it.  Skate split by evaluation.contacts.skate_sources.

    python studies/04_map_control/control_denoise_hold.py --out studies/04_map_control/control_denoise_hold_results.json   # ~1 min, one core
"""

import argparse
import json

import numpy as np
import torch

from course_lib.control import DenoiseConfig, denoise
from course_lib.control.dropouts import fill_held
from course_lib.control.lowpass import lowpass
from course_lib.datasets import noisy_copies
from course_lib.evaluation.contacts import skate_sources
from course_lib.experiments import control as C
from course_lib.experiments import gmm_rnn as X
from course_lib.models.contact_cleanup import plant_feet
from course_lib.motion import CONTACT_SPEED, foot_contacts
from course_lib.representations import decode_state_features, encode_state_features, root_start
from course_lib.results import provenance

SPEED = 0.6  # m/s, the laxer stance threshold for the low-passed start


def bits_of(m, speed: float = CONTACT_SPEED) -> np.ndarray:
    return foot_contacts(m.positions(), m.skeleton, m.fps, speed=speed)


def recall(bits: np.ndarray, clean_bits: np.ndarray) -> tuple[int, int, int]:
    return int((bits & clean_bits).sum()), int(clean_bits.sum()), int((bits & ~clean_bits).sum())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    clean = C.denoise_clips(first=4)
    noisy = noisy_copies(clean, 1)
    stats = X.load_stats(X._stats_path(X.CHECKPOINTS), "state_features")
    counts = {k: np.zeros(3, int) for k in ("input", "start", f"start at {SPEED} m/s")}
    rows = {"filtered": [], "filtered + plant_feet": []}
    for n, c in zip(noisy, clean, strict=True):
        start = lowpass(fill_held(n), "butter", 4.0)
        cb = bits_of(c)
        held = bits_of(start, SPEED)
        for k, b in zip(counts, (bits_of(n), bits_of(start), held), strict=True):
            counts[k] += recall(b, cb)
        d = denoise(n, config=DenoiseConfig(contact_bits="start", stance_speed=SPEED))
        f = encode_state_features(d)
        f[:, -2:] = held
        g = plant_feet(f[None], d.skeleton, X.contact_columns(stats, d.skeleton),
                       offsets=np.asarray(d.skeleton.offsets)[None])[0]
        p = decode_state_features(g, d.skeleton, d.fps, root_start(d))
        for k, m in (("filtered", d), ("filtered + plant_feet", p)):
            rows[k].append({**C._denoise_scores(m, c), **skate_sources(m.positions()[None], held[None], m.skeleton,
                                                                         m.fps)})
    out = {"command": f"python studies/04_map_control/control_denoise_hold.py --out {args.out}", "clips": len(clean),
           "stance_bits": {k: {"recall_of_clean_stance": float(v[0] / v[1]), "false_frames": int(v[2])}
                           for k, v in counts.items()},
           "config": f"DenoiseConfig(contact_bits='start', stance_speed={SPEED})",
           "results": {k: {q: float(np.nanmean([r[q] for r in v])) for q in v[0]} for k, v in rows.items()}}
    out = {**out, **provenance()}  # the command run, the commit, the checkpoints' sha256
    print(json.dumps(X.rounded(out), indent=1))
    with open(args.out, "w") as f:
        f.write(json.dumps(X.rounded(out), indent=1) + "\n")


if __name__ == "__main__":
    main()
