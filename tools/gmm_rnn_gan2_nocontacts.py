"""Lesson 03 side experiment: GAN2 (refiner seed 0) retrained with the contact bits NOT shown to D, on the shipped
GMM-RNN, scored by the lesson's quality table beside the shipped RNN and GAN1 (seed 0).

    python tools/gmm_rnn_gan2_nocontacts.py --out tools/gmm_rnn_gan2_nocontacts_results.json   # ~8 min, one core

Writes nothing to checkpoints/.  Question: is D's view of the contact bits what broke the shipped GAN2?
"""

import argparse
import json
import time

import torch

from course_lib.experiments import gmm_rnn as X
from course_lib.models import refiner as refiner_module


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    torch.set_flush_denormal(True)
    cpu = refiner_module.RefinerConfig.cpu
    refiner_module.RefinerConfig.cpu = staticmethod(lambda **kw: cpu(**{**kw, "discriminator_contacts": False}))
    spec = X.Lesson03Spec()
    _, test, ds = X.lesson03_data(spec, False)
    model, refiners, stats = X.load_models(seed=0)
    t0 = time.perf_counter()
    gan2, _, hist = X.train_gan(X.rnn_pool(model, ds, spec, 0), ds, spec, contacts=True, seed=0, progress=False)
    out = {"train_seconds": round(time.perf_counter() - t0, 1), "summary": X._gan_summary(hist),
           "quality": X.quality_table(model, {"GAN1": refiners["GAN1"], "GAN2": gan2.eval()}, test, stats, spec, 0)}
    with open(args.out, "w") as f:
        json.dump(X.rounded(out), f, indent=1, default=float)
        f.write("\n")


if __name__ == "__main__":
    main()
