"""Lesson 03 side experiment (issue 14): is GAN2's C2ST against mocap really further from chance than the RNN's,
and which part of R's change moves it?

On the shipped checkpoints (the joint-limited RNN, the refiners of seeds 0-2), for RNN generation seeds 0-4 on the
120 held-out clips: the C2ST accuracy (`evaluation.c2st`, the shared classifiers' features, seeded by the generation
seed) of the RNN, GAN1 and GAN2 of every refiner seed; then GAN2's clamp test (generation seed 0): GAN2 with one
column group put back to the RNN's values (legs, upper body, root).

    OMP_NUM_THREADS=1 python tools/gmm_rnn_c2st.py --out tools/gmm_rnn_c2st_results.json  # a few minutes

Writes nothing to checkpoints/.
"""

import argparse
import json

import numpy as np
import torch

from course_lib.evaluation import c2st
from course_lib.experiments import gmm_rnn as X
from course_lib.reproduce import rounded

COMMAND = "OMP_NUM_THREADS=1 python tools/gmm_rnn_c2st.py --out tools/gmm_rnn_c2st_results.json"


def accuracy(feats, stats, test, mocap, spec, seed: int) -> float:
    """Normalised features (N, T, D) decoded on the test clips' skeletons -> their C2ST accuracy against mocap."""
    return float(c2st(mocap, X.to_motions(feats, stats, test, spec.fps), seed=seed)["accuracy"])


def write(out: dict, path: str) -> None:
    """Add each row's summary over the generation seeds (mean, sd, in how many it is below the RNN's) to ``out``
    and write it, rounded, to path."""
    acc = {k: np.array([r[k] for r in out["by_generation_seed"].values()]) for k in out["by_generation_seed"]["0"]}
    out["summary"] = {k: {"mean": float(v.mean()), "sd": float(v.std(ddof=1)),
                          "below_rnn_in": int((v < acc["RNN"]).sum())} for k, v in acc.items()}
    with open(path, "w") as f:
        json.dump(rounded(out, 4), f, indent=1)
        f.write("\n")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--generation-seeds", type=int, default=5)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    spec = X.Lesson03Spec()
    _, test, _ = X.lesson03_data(spec, False)
    T = int(round(spec.eval_seconds * spec.fps))
    mocap = [m[:T] for m in test]
    model, _, stats = X.load_models(seed=0)
    refiners = {f"{name} seed {s}": X.load_models(seed=s)[1][name] for s in spec.seeds for name in ("GAN1", "GAN2")}
    out = {"command": COMMAND, "test_clips": len(test), "by_generation_seed": {}, "clamp": {}}
    for g in range(args.generation_seeds):
        sets = X.continuations(model, refiners, test, stats, spec, seed=g)
        out["by_generation_seed"][str(g)] = {k: accuracy(v, stats, test, mocap, spec, g) for k, v in sets.items()}
        print(g, {k: round(v, 3) for k, v in out["by_generation_seed"][str(g)].items()}, flush=True)
        if g == 0:
            for s in spec.seeds:
                gan2 = sets[f"GAN2 seed {s}"]
                for group, cols in X.column_groups().items():
                    mixed = gan2.clone()
                    mixed[..., cols] = sets["RNN"][..., cols]
                    out["clamp"][f"GAN2 seed {s}, {group} from the RNN"] = accuracy(mixed, stats, test, mocap, spec, 0)
            print({k: round(v, 3) for k, v in out["clamp"].items()}, flush=True)
    write(out, args.out)


if __name__ == "__main__":
    main()
