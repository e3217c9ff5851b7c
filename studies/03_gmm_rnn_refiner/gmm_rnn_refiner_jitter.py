"""Lesson 03 side experiment: why does the refiner remove only part of the RNN's jerkiness?

On the pretrained checkpoints (the 120 held-out clips, generation seed 0, as the lesson's table) the jitter of the
RNN, of GAN2's full change, and of GAN2's change restricted to one column group at a time (root, legs, upper body;
the rest kept from the RNN), beside mocap's; the root's jerk split at the changes of support
(`evaluation.root_jerk_split`); and the RNN's teacher-forced one-step toe error and its jerk
(`experiments.gmm_rnn_jitter.teacher_forced_toe_error`: is the jerk the model's one-step error, or free running?).

    OMP_NUM_THREADS=1 python studies/03_gmm_rnn_refiner/gmm_rnn_refiner_jitter.py --out studies/03_gmm_rnn_refiner/gmm_rnn_refiner_jitter_results.json

Writes nothing to checkpoints/ (about 2 min a seed on one core).
"""

import argparse

import numpy as np
import torch

from course_lib.evaluation import jitter, root_jerk_split
from course_lib.experiments import gmm_rnn as X
from course_lib.experiments.gmm_rnn_jitter import teacher_forced_toe_error
from course_lib.results import write_study_result


def scores(pos: np.ndarray, fps: float) -> dict:
    split = root_jerk_split(pos, fps=fps)
    return {"jitter": jitter(pos, fps=fps), "root_jerk": split["all"], "root_jerk_near_change_share": split["near_share"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    spec = X.Lesson03Spec()
    _, test, _ = X.lesson03_data(spec, False)
    mocap = np.stack([m.resample(spec.fps).positions() for m in test])
    out = {"test_clips": len(test), "mocap": scores(mocap, spec.fps), "seeds": {}}
    for seed in args.seeds:
        model, refiners, stats = X.load_models(seed=seed)
        cont = X.continuations(model, {"GAN2": refiners["GAN2"]}, test, stats, spec, 0)
        variants = {"RNN": cont["RNN"], "GAN2": cont["GAN2"]}
        for g, cols in X.column_groups().items():
            only = cont["RNN"].clone()
            only[..., cols] = cont["GAN2"][..., cols]
            variants[f"GAN2, only {g} from R"] = only
        row = {k: scores(np.stack([m.positions() for m in X.to_motions(f, stats, test, spec.fps)]), spec.fps)
               for k, f in variants.items()}
        out["seeds"][str(seed)] = row
        print(seed, {k: round(v["jitter"], 1) for k, v in row.items()}, flush=True)
    model, _, stats = X.load_models(seed=args.seeds[0])
    tf = teacher_forced_toe_error(model, test, stats, spec.fps)
    out["teacher_forced_toe_error"] = {k: {kk: float(vv) for kk, vv in v.items() if np.isscalar(vv)} for k, v in tf.items()}
    write_study_result(args.out, out)  # + command, commit, checkpoints' sha256


if __name__ == "__main__":
    main()
