"""Lesson 03 side experiment (issue 14): every refiner retrained here, GAN2's D shown the contact bits or not.

studies/03_gmm_rnn_refiner/gmm_rnn_c2st_bits.py found that one refiner seed (1) scored closer to chance on the C2ST without D's view of the
bits.  This retrains every refiner of `python -m course_lib.reproduce gmm_rnn --only gans` (GAN1 as shipped, GAN2 with
``Lesson03Spec.discriminator_contacts`` on or off) in a scratch copy of checkpoints/ on this machine, evaluates them
with the lesson's protocol (`experiments.gmm_rnn.evaluate_seeds`: 120 held-out clips, 3 refiner seeds, the 20-s test)
and writes the results beside the shipped ones.  Each refiner records the torch cpu capability it was trained on:
the two runs on one machine compare the bits; GAN1, the same code in both, compares the machines.

    OMP_NUM_THREADS=1 python studies/03_gmm_rnn_refiner/gmm_rnn_refiners_retrain.py --bits off \
        --out studies/03_gmm_rnn_refiner/gmm_rnn_refiners_nobits_results.json
    OMP_NUM_THREADS=1 python studies/03_gmm_rnn_refiner/gmm_rnn_refiners_retrain.py --bits on --out studies/03_gmm_rnn_refiner/gmm_rnn_refiners_bits_results.json
    # ~45 min each on one core: six refiners and the evaluation

Writes nothing to checkpoints/.

Recorded before the leg term (``Lesson03Spec.refiner_leg_pose_lam`` was 0); the spec's default is now 30, so a
rerun trains the current recipe, not the recorded one.
"""

import argparse
import json
import shutil
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from course_lib.experiments import gmm_rnn as X
from course_lib.results import write_study_result

COMMAND = "OMP_NUM_THREADS=1 python studies/03_gmm_rnn_refiner/gmm_rnn_refiners_retrain.py --bits {bits} --out {out}"
ROWS = ("RNN", "GAN1", "GAN2", "GAN2 + contacts")
KEYS = ("foot_skate", "jitter", "penetration", "fid", "c2st", "contact_agreement")


def summary(results: dict) -> dict:
    """Per row and measure: the mean and sd over refiner seeds."""
    per = results["per_seed"]
    out = {}
    for row in ROWS:
        out[row] = {}
        for k in KEYS:
            v = [per[s]["quality"][row].get(k) for s in per]
            if v[0] is not None:
                out[row][k] = {"mean": float(np.mean(v)), "sd": float(np.std(v)), "per_seed": v}
    return out


def capabilities(checkpoints: Path) -> dict:
    manifest = json.loads((checkpoints / "MANIFEST.json").read_text())
    return {k: v.get("trained_on", {}).get("cpu_capability") for k, v in manifest.items() if k.startswith("refiner")}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--bits", choices=("on", "off"), required=True, help="GAN2's D shown the contact bits")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        scratch = Path(tmp) / "checkpoints"
        shutil.copytree(X.CHECKPOINTS, scratch)
        results = X.train_gmm_rnn(replace(X.Lesson03Spec(), discriminator_contacts=args.bits == "on"), only=["gans"],
                                  checkpoints=scratch, progress=False)
        trained_on = capabilities(scratch)
    out = {"command": COMMAND.format(bits=args.bits, out=args.out), "bits": args.bits, "retrained": summary(results),
           "retrained_on": trained_on, "shipped": summary(X.recorded_results()),
           "shipped_trained_on": capabilities(X.CHECKPOINTS), "retrained_results": results}
    write_study_result(args.out, out, 5)  # + command, commit, checkpoints' sha256


if __name__ == "__main__":
    main()
