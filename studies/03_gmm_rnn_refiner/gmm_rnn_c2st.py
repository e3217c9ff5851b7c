"""Lesson 03 side experiment: is GAN2's C2ST against mocap really further from chance than the RNN's,
and which part of R's change moves it?  And the FID of every row over the same generation seeds.

On the shipped checkpoints (the joint-limited RNN, the refiners of seeds 0-2), for RNN generation seeds 0-4 on the
120 held-out clips: the C2ST accuracy (`evaluation.c2st`, the shared classifiers' features, seeded by the generation
seed) of the RNN, GAN1 and GAN2 of every refiner seed; then the clamp test (generation seed 0): GAN1 and GAN2 with
one column group put back to the RNN's values (legs, upper body, root), scored by C2ST ("clamp") and FID
("clamp_fid").  The same continuations' FID against the held-out
mocap (`evaluation.fid`) is recorded per generation seed too ("fid_by_generation_seed", summarised in "fid_summary"):
lesson 03's FID order is measured on one generation seed, and this says how much that one draw moves it.

    OMP_NUM_THREADS=1 python studies/03_gmm_rnn_refiner/gmm_rnn_c2st.py --out studies/03_gmm_rnn_refiner/gmm_rnn_c2st_results.json  # a few minutes

Writes nothing to checkpoints/.
"""

import argparse
import json

import numpy as np
import torch

from course_lib.evaluation import c2st, fid
from course_lib.experiments import gmm_rnn as X
from course_lib.results import provenance, rounded

COMMAND = "OMP_NUM_THREADS=1 python studies/03_gmm_rnn_refiner/gmm_rnn_c2st.py --out studies/03_gmm_rnn_refiner/gmm_rnn_c2st_results.json"


def accuracy(feats, stats, test, mocap, spec, seed: int) -> float:
    """Normalised features (N, T, D) decoded on the test clips' skeletons -> their C2ST accuracy against mocap."""
    return float(c2st(mocap, X.to_motions(feats, stats, test, spec.fps), seed=seed)["accuracy"])


def summary(by_seed: dict) -> dict:
    """{generation seed: {row: value}} -> {row: mean, sd over the generation seeds, in how many it is below the
    RNN's}."""
    v = {k: np.array([r[k] for r in by_seed.values()]) for k in next(iter(by_seed.values()))}
    return {k: {"mean": float(a.mean()), "sd": float(a.std(ddof=1)), "below_rnn_in": int((a < v["RNN"]).sum())}
            for k, a in v.items()}


def write(out: dict, path: str) -> None:
    """Add each row's summary over the generation seeds (C2ST and FID) to ``out`` and write it, rounded, to path."""
    out["summary"] = summary(out["by_generation_seed"])
    if out.get("fid_by_generation_seed"):  # studies/03_gmm_rnn_refiner/gmm_rnn_c2st_bits.py records the C2ST alone
        out["fid_summary"] = summary(out["fid_by_generation_seed"])
    out.update(provenance())  # the command run (replaces COMMAND), the commit, the checkpoints' sha256
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
    out = {"command": COMMAND, "test_clips": len(test), "by_generation_seed": {}, "fid_by_generation_seed": {},
           "clamp": {}, "clamp_fid": {}}
    for g in range(args.generation_seeds):
        sets = X.continuations(model, refiners, test, stats, spec, seed=g)
        out["by_generation_seed"][str(g)] = {k: accuracy(v, stats, test, mocap, spec, g) for k, v in sets.items()}
        out["fid_by_generation_seed"][str(g)] = {
            k: float(fid(mocap, X.to_motions(v, stats, test, spec.fps))) for k, v in sets.items()}
        print(g, {k: round(v, 3) for k, v in out["by_generation_seed"][str(g)].items()}, flush=True)
        print("  FID", {k: round(v) for k, v in out["fid_by_generation_seed"][str(g)].items()}, flush=True)
        if g == 0:
            for s in spec.seeds:
                for name in ("GAN1", "GAN2"):
                    for group, cols in X.column_groups().items():
                        mixed = sets[f"{name} seed {s}"].clone()
                        mixed[..., cols] = sets["RNN"][..., cols]
                        key = f"{name} seed {s}, {group} from the RNN"
                        out["clamp"][key] = accuracy(mixed, stats, test, mocap, spec, 0)
                        out["clamp_fid"][key] = float(fid(mocap, X.to_motions(mixed, stats, test, spec.fps)))
            print({k: round(v, 3) for k, v in out["clamp"].items()}, flush=True)
            print("  FID", {k: round(v) for k, v in out["clamp_fid"].items()}, flush=True)
    write(out, args.out)


if __name__ == "__main__":
    main()
