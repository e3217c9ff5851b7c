"""Lesson 06 study: why do MoGlow's samples slide their feet and shake?  Inference-time causes first.

    python studies/06_moglow/moglow_history_temperature.py --out studies/06_moglow/moglow_history_temperature_results.json

The pretrained MoGlow (LSTM, dropout 0.95) and its no-dropout twin, sampled without retraining under each combination of
(a) the history rule outside training: scaled by 1 - dropout (the course's checkpoint rule) or unscaled (StyleGestures'
generator feeds the raw history), and (b) the sampling temperature.  Every held-out clip is driven by its own control
from its first tau mocap frames (the protocol of `experiments.moglow.quality`); foot skate on the known-floor rule
(`evaluation.foot_skate_at_floor`) and jitter on the decoded world positions, beside the held-out mocap's.
Writes nothing to checkpoints/.
"""

import argparse
import sys
import time

import torch

from course_lib.evaluation import foot_skate_at_floor, jitter
from course_lib.experiments import moglow as E
from course_lib.representations import root_start
from course_lib.results import write_study_result

TEMPERATURES = (1.0, 0.8, 0.6)
SEEDS = (0, 1)
MODELS = ("moglow", "moglow_nodrop")  # the no-dropout model's history is never scaled (1 - 0 = 1)


def scores(data, poses, controls, starts) -> dict:
    """Standardised poses (N, T, D) -> skate (m/s, known floor) and jitter (m/s^3) of their world positions."""
    pos = data.positions(poses, controls, starts)  # (N, T, 21, 3)
    skel = data.test_clips[0].skeleton
    return {"foot_skate": foot_skate_at_floor(pos, E.FPS, skel), "jitter": jitter(pos, E.FPS, skel)}


def kept_scores(data, poses, controls, starts) -> dict:
    """`scores` of the samples that did not blow up (`experiments.moglow.exploded`), and how many did."""
    ok = ~E.exploded(poses)
    kept = [s for s, k in zip(starts, ok, strict=True) if k]
    return {**(scores(data, poses[ok], controls[ok], kept) if ok.any() else {}), "exploded": int((~ok).sum())}


def sample_scores(model, data, starts, temperature: float) -> dict:
    """Skate and jitter averaged over the sampling seeds (samples that blew up left out), and the blow-ups' total."""
    x0, c0 = data.test["poses"][:, :E.TAU], data.test["controls"][:, :E.TAU]
    runs = [kept_scores(data, *E.generate(model, data, data.test["controls"], s, temperature, starts=(x0, c0)), starts)
            for s in SEEDS]
    out = {k: sum(r[k] for r in runs) / len(runs) for k in ("foot_skate", "jitter") if all(k in r for r in runs)}
    return {**out, "exploded": sum(r["exploded"] for r in runs)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    data = E.load_data("full")
    starts = [root_start(m) for m in data.test_clips]
    mocap = scores(data, data.test["poses"], data.test["controls"], starts)
    rows = {}
    for name in MODELS:
        model = E.load_model(name)
        for scaled, temp in [(s, t) for s in ((True, False) if model.config.dropout > 0 else (True,))
                             for t in TEMPERATURES]:
            model.config.history_scale = scaled
            key = f"{name}, history {'scaled' if scaled else 'unscaled'}, T={temp}"
            rows[key] = sample_scores(model, data, starts, temp)
            rows[key]["skate_x_mocap"] = rows[key]["foot_skate"] / mocap["foot_skate"]
            rows[key]["jitter_x_mocap"] = rows[key]["jitter"] / mocap["jitter"]
            print(key, rows[key], flush=True)
    out = {"command": "python " + " ".join(sys.argv), "models": list(MODELS), "seeds": list(SEEDS),
           "held_out_clips": len(data.test_clips), "mocap": mocap, "samples": rows,
           "seconds": time.perf_counter() - t0}
    write_study_result(args.out, out)
    print("mocap", mocap)


if __name__ == "__main__":
    main()
