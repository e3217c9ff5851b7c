"""Lesson 05 study: why is the Proposed model's diversity below real data's (APD of jump/A, Fig. 4's claim)?

    OMP_NUM_THREADS=1 python studies/05_hierarchical_vrnn/hvrnn_diversity.py --out studies/05_hierarchical_vrnn/hvrnn_diversity_results.json

The pretrained generators of `checkpoints/` (`python -m course_lib.reproduce hvrnn`), 100 samples of one attribute
per generation seed (0-2), beside the real sequences of that attribute (all 40 subjects, mirrored copies
included): the APD with and without each frame's heading, the root's travel and turn, and how far each sample
lies from its nearest real sequence (`experiments.hvrnn.diversity`).  A sample set can be less spread than
the data in two ways: it misses kinds of motion the data has (then its samples lie far from many real ones),
or it covers the data's typical motion only (its samples lie close to real ones, closer than real ones lie
to each other).  About a minute on one core.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

MODELS = ("hvrnn_proposed", "hvrnn_nl", "hvrnn_nc", "hvrnn_sl", "hvrnn_erd", "hvrnn_quaternet")
SEEDS = (0, 1, 2)
KEYS = ("apd", "apd_facing", "travel", "turn", "nearest_real")


def main(argv=None) -> int:
    from course_lib.evaluation import load_classifier
    from course_lib.experiments import hvrnn as H
    from course_lib.results import write_study_result

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--action", default="jump")
    parser.add_argument("--style", default="A")
    parser.add_argument("--n", type=int, default=100, help="samples per generation seed")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    data = H.load_data("full")
    judge = load_classifier("action")
    real = [m for m in H.to_motions(data["train"]) + H.to_motions(data["test"])
            if m.action == args.action and m.style == args.style]
    rows = {"Real data": H.diversity(real, judge, real)}  # nearest: another subject's sequence
    for name in MODELS:
        model = H.load_model(name)
        per_seed = [H.diversity(H.to_motions(H.generate(model, args.n, seed=s, attribute=(args.action, args.style))),
                                judge, real) for s in SEEDS]
        label = H.model_specs()[name].label
        rows[label] = {k: float(np.mean([r[k] for r in per_seed])) for k in KEYS}
        rows[label].update({f"{k}_sd": float(np.std([r[k] for r in per_seed], ddof=1)) for k in ("apd", "nearest_real")})
    real_row = rows["Real data"]
    ratios = {m: {"apd_over_real": r["apd"] / real_row["apd"],
                  "apd_facing_over_real": r["apd_facing"] / real_row["apd_facing"],
                  "nearest_over_real": r["nearest_real"] / real_row["nearest_real"]} for m, r in rows.items()}
    result = {"command": "python " + " ".join(["studies/05_hierarchical_vrnn/hvrnn_diversity.py",
                                                *(argv if argv is not None else sys.argv[1:])]),
              "attribute": f"{args.action}/{args.style}", "samples_per_seed": args.n, "seeds": list(SEEDS),
              "real_sequences": len(real), "rows": rows, "ratios_to_real": ratios}
    write_study_result(args.out, result)
    for m, r in rows.items():
        print(f"{m:13s} " + " ".join(f"{k} {r[k]:.4f}" for k in KEYS), f"| nearest/real {ratios[m]['nearest_over_real']:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
