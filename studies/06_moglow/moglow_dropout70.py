"""Lesson 06 side experiment: MoGlow with the autoregressive dropout at 0.7 (the rate of StyleGestures'
``hparams/preferred/locomotion.json``; the paper's, and ours, is 0.95), scored beside the shipped models.

    python studies/06_moglow/moglow_dropout70.py --out studies/06_moglow/moglow_dropout70_results.json   # ~11 min training on one core

Writes nothing to checkpoints/.  Question: does seeing more of the history narrow the next-frame density
(less per-frame noise, lower jitter) while keeping the zero-control feet still?
"""

import argparse
import time

import torch

from course_lib.experiments import moglow as E
from course_lib.results import write_study_result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    E.MODELS["moglow_drop70"] = {"dropout": 0.7}
    data = E.load_data("full")
    t0 = time.perf_counter()
    model, _ = E.train_model("moglow_drop70", data, E.STEPS, 0)
    out = {"train_seconds": round(time.perf_counter() - t0, 1), "steps": E.STEPS,
           "nll_per_frame": E.nll_per_frame(model, data.test)}
    models = {"moglow_drop70": model, "moglow_nodrop": E.load_model("moglow_nodrop"), "moglow": E.load_model("moglow")}
    out["control"] = E.control_consistency(models, data, 0)
    speeds = {k: v["zero_control_feet_speed"] for k, v in out["control"]["models"].items()}
    out["control"]["zero_control_ratio_drop70"] = speeds["moglow_drop70"] / speeds["moglow_nodrop"]
    out["quality"] = E.quality({"moglow_drop70": model}, data, 0)
    out["long"] = E.long_samples({"moglow_drop70": model}, data, 0)
    write_study_result(args.out, out, 5)  # + command, commit, checkpoints' sha256


if __name__ == "__main__":
    main()
