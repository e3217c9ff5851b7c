"""Eq. (26) measured: the first-frame hop of the GMM-RNN started from the zero state vs from the estimated
initial state, beside mocap's, on held-out clips -> the "initial_state" entry of tools/control_results.json.

    OMP_NUM_THREADS=1 TQDM_DISABLE=1 python tools/control_initial_state.py

For each held-out clip (first 20 of the walk and run clips) and its frames s_1, s_2: the RNN reads s_1 from the
zero state, or from the state h_1 of eq. (26) (fitted so that s_1 predicts s_2), and predicts s_2 as its most
likely component's mean; the joint speed (mean over joints, m/s) from s_1 to that prediction, and the mocap's
own s_1 -> s_2 joint speed.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import torch

from course_lib.control.design import default_prior
from course_lib.control.initial_state import estimate_initial_state, first_frame_speed, predicted_second
from course_lib.control.starts import held_out_clips
from course_lib.representations import encode_state_features

OUT = Path(__file__).with_name("control_results.json")


def main():
    torch.set_num_threads(1)
    prior, t0 = default_prior(), time.perf_counter()
    rows = {"zero_state": [], "estimated_state": [], "mocap": []}
    for gait in ("walk", "run"):
        for clip in held_out_clips(gait)[:10]:
            raw = prior.clean(torch.from_numpy(encode_state_features(clip)[10:12]))[None]
            skel = clip.skeleton
            state, _ = estimate_initial_state(prior, raw, skel, steps=100)
            for name, h1 in (("zero_state", None), ("estimated_state", state)):
                pair = torch.cat((raw[:, :1], predicted_second(prior, raw, h1, skel)), 1)
                rows[name].append(first_frame_speed(pair, skel))
            rows["mocap"].append(first_frame_speed(raw, skel))
    out = {k: {"mean_joint_speed_m_s": float(np.mean(v)), "max": float(np.max(v))} for k, v in rows.items()}
    out["clips"] = len(rows["mocap"])
    out["command"] = "OMP_NUM_THREADS=1 TQDM_DISABLE=1 python tools/control_initial_state.py"
    out["seconds"] = round(time.perf_counter() - t0, 1)
    results = json.loads(OUT.read_text()) if OUT.exists() else {}
    results["initial_state"] = out
    OUT.write_text(json.dumps(results, indent=1))
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
