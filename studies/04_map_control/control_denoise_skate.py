"""Lesson 04 side experiment (issue 16): where does the denoised motion's foot skate come from?  The shipped filter
lowers the input's 1.456 m/s to about 0.09, still ~12x the clean motion's 0.008, and a 10x or 100x stronger contact
term does not lower it (studies/04_map_control/control_denoise_start.py).  The skate measure (evaluation.foot_skate) counts every
frame pair on which a toe is below 5 cm, moving or not.  Split those pairs of the filtered motion by the clean motion:

- the clean toe is planted (clean stance: contact bit on) -> the filter slides a foot that should stand;
- the clean toe is in the air or lifting (clean bit off)  -> the filter's toe is low where the clean one is moving;

and, for each, their share of the skate sum (speed x pairs) and whether eq. (18)'s stance bit (the input's, which
the filter holds) is on there.  The same 8 held-out clips and noise seeds as ``experiments.control.denoise_eval``.

    python studies/04_map_control/control_denoise_skate.py --out studies/04_map_control/control_denoise_skate_results.json   # ~1 min, one core
"""

import argparse
import json

import numpy as np
import torch

from course_lib.control import denoise
from course_lib.datasets import noisy_copies
from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import rounded
from course_lib.motion import CONTACT_HEIGHT
from course_lib.results import provenance

TOES = ("LeftToeBase", "RightToeBase")


def skate_pairs(m) -> tuple[np.ndarray, np.ndarray]:
    """motion -> (low (T-1, 2) bool: the toe below the skate height on both frames, speed (T-1, 2) m/s), exactly
    as evaluation.foot_skate counts them."""
    idx = [m.skeleton.index(n) for n in TOES]
    f = m.positions()[:, idx]  # (T, 2, 3)
    low = f[..., 1] < CONTACT_HEIGHT["ToeBase"]
    return low[1:] & low[:-1], np.linalg.norm(np.diff(f[..., [0, 2]], axis=0), axis=-1) * m.fps


def split(out, clean, noisy) -> dict:
    low, v = skate_pairs(out)
    clean_bits = clean.contacts()[1:].astype(bool)  # (T-1, 2): the clean motion planted there
    input_bits = noisy.contacts()[1:].astype(bool)  # eq. (18)'s bits (the filter holds the input's)
    rows = {}
    for name, mask in (("clean stance", clean_bits), ("clean swing", ~clean_bits)):
        sel = low & mask
        rows[name] = {"pairs": int(sel.sum()), "speed_sum": float(v[sel].sum()),
                      "mean_speed_m_s": float(v[sel].mean()) if sel.any() else 0.0,
                      "input_bit_on": int((sel & input_bits).sum())}
    rows["all"] = {"pairs": int(low.sum()), "speed_sum": float(v[low].sum())}
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    clean = C.denoise_clips()  # as denoise_eval
    noisy = noisy_copies(clean, 1)
    per = [split(denoise(n, seed=0), c, n) for n, c in zip(noisy, clean, strict=True)]
    clean_self = [split(c, c, n) for n, c in zip(noisy, clean, strict=True)]
    res = {"command": f"python studies/04_map_control/control_denoise_skate.py --out {args.out}", "clips": len(clean)}
    for label, rows in (("filtered", per), ("clean", clean_self)):
        tot = {k: {s: sum(r[k][s] for r in rows) for s in rows[0][k]} for k in rows[0]}
        all_sum = max(tot["all"]["speed_sum"], 1e-12)
        for k in ("clean stance", "clean swing"):
            t = tot[k]
            t["mean_speed_m_s"] = t["speed_sum"] / max(t["pairs"], 1)
            t["share_of_skate"] = t["speed_sum"] / all_sum
        tot["all"]["mean_speed_m_s"] = tot["all"]["speed_sum"] / max(tot["all"]["pairs"], 1)
        res[label] = tot
        print(label, json.dumps(rounded(tot, 4)), flush=True)
    res = {**res, **provenance()}  # the command run, the commit, the checkpoints' sha256
    with open(args.out, "w") as f:
        f.write(json.dumps(rounded(res), indent=1) + "\n")


if __name__ == "__main__":
    main()
