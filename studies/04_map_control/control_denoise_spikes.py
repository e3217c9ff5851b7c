"""Lesson 04 side experiment (issue 16): are the spikes removed?  With eq. (25)'s Gaussian data term on every
joint, the largest error left after denoising sat at one of make_noisy's spiked frames in 3 of the 8 scored clips
(0.23, 0.35 and 0.30 m, where the input was 0.75, 0.41 and 1.12 m off).  This measures the spike detector of
`control/spikes.py` on its known answers, then the filter with and without it (``DenoiseConfig.spike_angle``).

Detector, on the first 24 held-out clips of each gait (34 clips: the held-out runs are fewer; the scored and the
tuning clips among them), after the dropped frames are interpolated as denoise does:
  * clean clips: how many (frame, joint) pairs it flags (should be none) and the largest deviation it sees;
  * noisy clips: of the spiked frames' joints that the kick moved more than 0.15 rad, how many it flags; how
    many other pairs it flags; the largest kick it misses.

Filter, on the tuning clips (4-7 of each gait) and the scored clips (0-3), spike_angle None (eq. 25 as printed)
and the shipped 0.35: mean and max joint error, the largest error on a spiked frame and elsewhere, skate,
contact agreement (experiments.control._denoise_scores).

    OMP_NUM_THREADS=1 python studies/04_map_control/control_denoise_spikes.py --out studies/04_map_control/control_denoise_spikes_results.json  # ~4 min
"""

import argparse
import json

import numpy as np
import torch

from course_lib.control import DenoiseConfig, denoise
from course_lib.control.dropouts import dropped_mask, fill_held
from course_lib.control.spikes import SPIKE_ANGLE, median_deviation
from course_lib.datasets import noisy_copies
from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import rounded
from course_lib.results import provenance

KICK = 0.15  # rad: a spiked frame's joint moved more than this by the kick counts as spiked (jitter: 0.02 rad sd)


def kicked(noisy, clean) -> np.ndarray:
    """(T, J) bool: the joints that make_noisy's spikes moved more than KICK, on frames not dropped."""
    angle = 2 * np.arccos(np.clip(np.abs((noisy.rotations * clean.rotations).sum(-1)), 0, 1))
    out = np.zeros(angle.shape, bool)
    frames = noisy.meta["noise"]["spike_frames"]
    out[frames] = angle[frames] > KICK
    return out & ~dropped_mask(noisy)[:, None], angle


def detector(threshold: float) -> dict:
    clean = C.denoise_clips(0, 24)
    noisy = noisy_copies(clean, 1)
    dev_clean = [median_deviation(c) for c in clean]
    flagged = hit = kicks = other = 0
    missed = []
    for n, c in zip(noisy, clean, strict=True):
        truth, angle = kicked(n, c)
        found = median_deviation(fill_held(n)) > threshold
        hit, kicks = hit + int((found & truth).sum()), kicks + int(truth.sum())
        other += int((found & ~truth).sum())
        missed += angle[truth & ~found].tolist()
    flagged = int(sum((d > threshold).sum() for d in dev_clean))
    return {"clips": len(clean), "clean_pairs_flagged": flagged,
            "clean_largest_deviation_rad": float(max(d.max() for d in dev_clean)),
            "noisy_kicks": kicks, "noisy_kicks_flagged": hit, "noisy_other_pairs_flagged": other,
            "largest_missed_kick_rad": float(max(missed, default=0.0))}


def filter_rows(first: int) -> dict:
    clean = C.denoise_clips(first, 4)
    noisy = noisy_copies(clean, 1)
    out = {}
    for name, angle in (("eq. 25 as printed (spike_angle None)", None),
                        (f"spikes out ({SPIKE_ANGLE} rad)", SPIKE_ANGLE)):
        rows = []
        for n, c in zip(noisy, clean, strict=True):
            d = denoise(n, seed=0, config=DenoiseConfig(spike_angle=angle))
            err = np.linalg.norm(d.positions() - c.positions(), axis=-1).max(-1)  # (T,) the worst joint per frame
            spiked = np.zeros(len(err), bool)
            spiked[n.meta["noise"]["spike_frames"]] = True
            rows.append({**C._denoise_scores(d, c, n),  # with the largest error on the spiked frames
                         "max_error_elsewhere_m": float(err[~spiked].max()),
                         "worst_frame_is_spiked": bool(spiked[err.argmax()])})
            print(first, name, {k: round(float(v), 4) for k, v in rows[-1].items()}, flush=True)
        out[name] = {"mean": {k: float(np.nanmean([r[k] for r in rows])) for k in rows[0]},
                     "per_clip_max_joint_error_m": [r["max_joint_error_m"] for r in rows]}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    out = {"command": f"OMP_NUM_THREADS=1 python studies/04_map_control/control_denoise_spikes.py --out {args.out}",
           "threshold_rad": SPIKE_ANGLE, "kick_rad": KICK, "detector": detector(SPIKE_ANGLE)}
    print(out["detector"], flush=True)
    out["tuning clips (4-7)"] = filter_rows(4)
    out["scored clips (0-3)"] = filter_rows(0)
    out = {**out, **provenance()}  # the command run, the commit, the checkpoints' sha256
    with open(args.out, "w") as f:
        f.write(json.dumps(rounded(out, 4), indent=1) + "\n")


if __name__ == "__main__":
    main()
