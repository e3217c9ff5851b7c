"""Lesson 03 side experiment (issue 14): why do 14 of the shipped RNN's 100 twenty-second motions leave the data's
root-height range, and does the sampling decide it?

The long-generation test (experiments.gmm_rnn.long_generation on long_samples: 100 motions of 20 s from the first
held-out clip's first two frames) keeps every motion in range for the first 10 s and 86 of 100 for 20 s; the lowest
root height reached is 0.13 m against the data's 0.68. This tool generates the same 100 motions with the RNN alone
(seed 0) at the shipped sampling (Graves' bias 2, angle noise 0.3, root noise 1), without the joint limits the RNN
now samples with (Lesson03Spec.joint_limits; this study found the cause they remove), and at a few others, and reports,
per setting: the motions in range for 20 s (the measure of the test) and for 10 s, APD, the first second a motion
leaves the range (median and the earliest), and, for the motions that leave, the mean knee flexion (the angle of the
LeftLeg and RightLeg expmaps) over their last second against the in-range motions' (a crouch bends the knees; a fall
tilts the root), and the root pitch. At each leaving motion's lowest frame it splits the root height into the lower
toe's height (the feet-anchored features' own channel: a body that sinks through the floor) and the root's height
above that toe (the pose: a body that folds), against the data's, and names the state-feature columns furthest from
the data there (z-scores against the held-out clips).

    python studies/03_gmm_rnn_refiner/gmm_rnn_long_range.py --out studies/03_gmm_rnn_refiner/gmm_rnn_long_range_results.json   # ~6 min, one core
"""

import argparse
import json
from dataclasses import replace

import numpy as np
import torch

from course_lib.evaluation.contacts import lower_toe
from course_lib.experiments import gmm_rnn as X
from course_lib.representations import encode_state_features, feature_names
from course_lib.results import provenance

PITCH = feature_names("state_features").index("root_pitch")
SETTINGS = {"shipped (bias 2, angle noise 0.3)": {},
            "bias 3": {"sample_bias": 3.0},
            "angle noise 0.15": {"sample_angle_noise": 0.15},
            "angle noise 0 (component means)": {"sample_angle_noise": 0.0},
            "root noise 0.5": {"sample_root_noise": 0.5}}


def lowest_frame_split(pos, h, raw, out_idx, sk, mocap) -> dict:
    """At each leaving motion's lowest root frame: the lower toe's height, the root's height above it, and the six
    state-feature columns furthest from the held-out clips' (mean |z| over the leaving motions)."""
    lowest = h[out_idx].argmin(1)
    toe = lower_toe(pos[out_idx], sk)[np.arange(len(out_idx)), lowest]
    data_pos = [m.positions() for m in mocap]
    data_toe = np.concatenate([lower_toe(p, m.skeleton) for p, m in zip(data_pos, mocap, strict=True)])
    data_above = np.concatenate([p[:, 0, 1] for p in data_pos]) - data_toe
    data_raw = np.concatenate([encode_state_features(m) for m in mocap])
    z = np.abs((raw[out_idx, lowest] - data_raw.mean(0)) / (data_raw.std(0) + 1e-6)).mean(0)
    names = feature_names("state_features", sk)
    low = h[out_idx, lowest]
    return {"lowest_root_m": float(low.mean()), "lower_toe_m": float(toe.mean()),
            "root_above_toe_m": float((low - toe).mean()),
            "data_lower_toe_m": [float(np.percentile(data_toe, 1)), float(np.percentile(data_toe, 99))],
            "data_root_above_toe_m": [float(np.percentile(data_above, 1)), float(np.percentile(data_above, 99))],
            "furthest_columns_mean_abs_z": {names[i]: float(z[i]) for i in np.argsort(-z)[:6]}}


def run(spec, model, start, stats, mocap) -> dict:
    from course_lib.evaluation import apd

    feats = X.long_samples(model, start, stats, spec, seed=0)
    motions = X.to_motions(feats, stats, [start] * len(feats), spec.fps)
    pos = np.stack([m.positions() for m in motions])
    heights = np.concatenate([m.root_positions[:, 1] for m in mocap])
    lo, hi = float(heights.min()), float(heights.max())
    h = pos[:, :, 0, 1]
    inside = (h >= lo - 0.05) & (h <= hi + 0.05)
    out_idx = np.where(~inside.all(1))[0]
    first_out = [int(np.argmin(inside[i])) / spec.fps for i in out_idx]
    raw = feats.double().numpy() * stats[1] + stats[0]  # (N, T, D) state features
    sk = start.skeleton
    knees = [sk.index(n) for n in ("LeftLeg", "RightLeg")]
    flex = np.stack([np.linalg.norm(raw[..., 3 * j + 3:3 * j + 6], axis=-1) for j in knees], -1).mean(-1)  # (N, T)
    last = int(spec.fps)
    ok_idx = np.where(inside.all(1))[0]
    data_flex = np.concatenate([np.stack([np.linalg.norm(encode_state_features(m)[:, 3 * j + 3:3 * j + 6], axis=-1)
                                          for j in knees], -1).mean(-1) for m in mocap])
    split = lowest_frame_split(pos, h, raw, out_idx, sk, mocap) if len(out_idx) else None
    return {"lowest_frame_split": split,
            "in_range_motions": int(inside.all(1).sum()), "in_range_first_10s": int(inside[:, :300].all(1).sum()),
            "apd_m": apd(pos), "root_height": [float(h.min()), float(h.max())], "data_root_height": [lo, hi],
            "first_out_s_median": float(np.median(first_out)) if first_out else None,
            "first_out_s_min": float(min(first_out)) if first_out else None,
            "knee_flexion_last_s_out_rad": float(flex[out_idx, -last:].mean()) if len(out_idx) else None,
            "knee_flexion_last_s_in_rad": float(flex[ok_idx, -last:].mean()) if len(ok_idx) else None,
            "knee_flexion_data_rad": [float(np.percentile(data_flex, 1)), float(np.percentile(data_flex, 99))],
            "root_pitch_last_s_out_rad": float(np.abs(raw[out_idx, -last:, PITCH]).mean()) if len(out_idx) else None,
            "root_height_last_s_out_m": float(h[out_idx, -last:].mean()) if len(out_idx) else None}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    spec = X.Lesson03Spec(joint_limits=False)  # the study of the RNN without joint limits (their cause)
    _, test, _ = X.lesson03_data(spec, progress=False)
    model, _, stats = X.load_models()
    results = {"command": "python studies/03_gmm_rnn_refiner/gmm_rnn_long_range.py --out studies/03_gmm_rnn_refiner/gmm_rnn_long_range_results.json"}
    for name, change in SETTINGS.items():
        results[name] = r = run(replace(spec, **change), model, test[0], stats, test)
        print(name, json.dumps(X.rounded(r)), flush=True)
    results = {**results, **provenance()}  # the command run, the commit, the checkpoints' sha256
    with open(args.out, "w") as f:
        json.dump(X.rounded(results), f, indent=1)


if __name__ == "__main__":
    main()
