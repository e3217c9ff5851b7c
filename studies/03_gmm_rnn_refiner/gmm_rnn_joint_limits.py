"""Lesson 03 side experiment: the RNN's 100 twenty-second motions from one start, sampled without and with
the joint limits (Lesson03Spec.joint_limits: each sampled frame's joint angles clamped to the training data's range,
stored with the RNN by experiments.gmm_rnn.store_limits).

Per setting: the motions whose root height stays within the data's range +- 5 cm (the long-generation test's
measure), grounded motions, APD, the foot skate and jitter of the 20-s motions (against the held-out clips' 4 s), and,
without the limits, the fraction of sampled frames on which each joint-angle column leaves the training range (the
columns the limits would clamp; the six most frequent, by name, with the training range in radians).

    python studies/03_gmm_rnn_refiner/gmm_rnn_joint_limits.py --out studies/03_gmm_rnn_refiner/gmm_rnn_joint_limits_results.json   # ~4 min, one core
"""

import argparse
import json
from dataclasses import replace

import numpy as np
import torch

from course_lib.evaluation import apd, foot_skate_at_floor, jitter
from course_lib.evaluation.contacts import lower_toe
from course_lib.experiments import gmm_rnn as X
from course_lib.representations import feature_names
from course_lib.results import provenance


def run(spec, model, start, stats, mocap) -> tuple[dict, torch.Tensor]:
    feats = X.long_samples(model, start, stats, spec, seed=0)
    motions = X.to_motions(feats, stats, [start] * len(feats), spec.fps)
    pos = np.stack([m.positions() for m in motions])
    heights = np.concatenate([m.root_positions[:, 1] for m in mocap])
    lo, hi = float(heights.min()), float(heights.max())
    h = pos[:, :, 0, 1]
    toe_top = float(max(lower_toe(m.positions(), m.skeleton).max() for m in mocap))
    return {"in_range_motions": int(((h >= lo - 0.05) & (h <= hi + 0.05)).all(1).sum()),
            "grounded_motions": int((lower_toe(pos, start.skeleton) <= toe_top + 0.05).all(1).sum()),
            "root_height": [float(h.min()), float(h.max())], "apd_m": apd(pos),
            "foot_skate_m_s": foot_skate_at_floor(pos, fps=spec.fps), "jitter_m_s3": jitter(pos, fps=spec.fps)}, feats


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    spec = X.Lesson03Spec()
    _, test, _ = X.lesson03_data(spec, progress=False)
    model, _, stats = X.load_models()
    mocap_pos = np.stack([m.positions() for m in test])
    results = {"command": "python studies/03_gmm_rnn_refiner/gmm_rnn_joint_limits.py --out studies/03_gmm_rnn_refiner/gmm_rnn_joint_limits_results.json",
               "mocap_4s": {"foot_skate_m_s": foot_skate_at_floor(mocap_pos, fps=spec.fps),
                            "jitter_m_s3": jitter(mocap_pos, fps=spec.fps)}}
    for name, limits in (("without joint limits", False), ("with joint limits (shipped)", True)):
        results[name], feats = run(replace(spec, joint_limits=limits), model, test[0], stats, test)
        if not limits:  # where the limits would bind: the model's own features, against the stored bounds
            y = X.to_rnn(feats, stats, model, X.clip_offsets([test[0]] * len(feats)))[:, 2:]
            low, high = model.limits()
            out = ((y < low - 1e-6) | (y > high + 1e-6)).double().mean((0, 1)).numpy()  # (D,) per column
            names = feature_names("state_features")
            m, s = model.feature_mean.double().numpy(), model.feature_std.double().numpy()
            results[name]["frames_outside_training_range"] = {
                names[i]: {"fraction": float(out[i]), "range_rad": [float(low[i] * s[i] + m[i]),
                                                                  float(high[i] * s[i] + m[i])]}
                for i in np.argsort(-out)[:6]}
        print(name, json.dumps(X.rounded(results[name])), flush=True)
    results = {**results, **provenance()}  # the command run, the commit, the checkpoints' sha256
    with open(args.out, "w") as f:
        json.dump(X.rounded(results), f, indent=1)


if __name__ == "__main__":
    main()
