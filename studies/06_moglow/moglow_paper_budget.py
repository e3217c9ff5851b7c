"""Lesson 06 study: how long would the paper's MoGlow recipe train on the course's CPU?

    python studies/06_moglow/moglow_paper_budget.py --out studies/06_moglow/moglow_paper_budget_results.json

The feet studies (moglow_dropout_history, moglow_lstm_size, moglow_long_run) find that the skate falls with training
steps and model size, and slower than a course model's budget allows.  The paper trains K = 16 steps of flow with
2-layer LSTMs of 512 units for 80k steps of batch 100 (sec. 5.2; StyleGestures' hparams/paper_version/locomotion.json:
one LSTM per coupling).  This times optimiser steps on one core: the course's preset (batch 32), the preset with
K = 16, and the paper's sizes at batch 100, with MLP couplings sharing one conditioning LSTM (ours) and with an LSTM
per coupling (the authors' code).  For each: steps per second (`REPEAT` timed steps after `WARMUP` untimed ones) and
the hours that 5000 (the course's), 60000 (moglow_long_run) and 80000 (the paper's) steps would take.
"""

import argparse
import time

import torch

from course_lib.experiments import moglow as E
from course_lib.models.moglow import MoGlow, MoGlowConfig
from course_lib.results import write_study_result
from course_lib.training import fit

WARMUP, REPEAT = 2, 8
STEPS = (5000, 60000, 80000)


def recipes(pose_dim: int) -> dict:
    """name -> (config, batch)."""
    return {"course preset (K = 8, LSTM 1 x 128, MLP couplings 128), batch 32": (E.config_for("moglow", pose_dim), 32),
            "course preset with K = 16, batch 32": (MoGlowConfig.cpu(pose_dim, 3, E.TAU, steps=16), 32),
            "paper sizes (K = 16, LSTM 2 x 512, MLP couplings 512), batch 100": (MoGlowConfig(pose_dim, 3, E.TAU), 100),
            "paper sizes with an LSTM per coupling (the authors' code), batch 100":
                (MoGlowConfig(pose_dim, 3, E.TAU, coupling_net="lstm"), 100)}


def steps_per_second(config: MoGlowConfig, batch: int, data: dict) -> float:
    torch.manual_seed(0)
    model, it = MoGlow(config), E.batches(data, batch, 0)
    fit(model, it, steps=WARMUP, lr=E.LR, grad_clip=E.GRAD_CLIP)
    t = time.perf_counter()
    fit(model, it, steps=REPEAT, lr=E.LR, grad_clip=E.GRAD_CLIP)
    return REPEAT / (time.perf_counter() - t)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    data = E.load_data("full")
    rows = {}
    for name, (config, batch) in recipes(data.pose_dim).items():
        rate = steps_per_second(config, batch, data.train)
        rows[name] = {"batch": batch, "steps_per_second": rate,
                      "hours": {str(n): n / rate / 3600 for n in STEPS}}
        print(name, rows[name], flush=True)
    write_study_result(args.out, {"threads": torch.get_num_threads(), "warmup": WARMUP, "repeat": REPEAT,
                                  "recipes": rows})


if __name__ == "__main__":
    main()
