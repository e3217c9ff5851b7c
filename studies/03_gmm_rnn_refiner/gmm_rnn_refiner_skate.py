"""Lesson 03 side experiment: where do the refiners' sliding feet come from?

The paper's refiner removes foot sliding; ours (GAN1, and GAN2 before the contact handling) slides more than the RNN
it refines.  On the pretrained checkpoints (every refiner seed, the 120 held-out clips, generation seed 0, as the
lesson's table) R's change is split by column group: the refined motion with only R's root change (the RNN's pose
kept), only its leg change, only its upper-body change, and R's full change.  Each is scored by the foot skate, and
by the toes' speed on the (frame, foot) pairs where the RNN's own toe is planted (low and slow in the RNN's motion):
how fast R makes a foot move that the RNN had standing.

    OMP_NUM_THREADS=1 python studies/03_gmm_rnn_refiner/gmm_rnn_refiner_skate.py --out studies/03_gmm_rnn_refiner/gmm_rnn_refiner_skate_results.json

Writes nothing to checkpoints/ (about 2 min on one core).
"""

import argparse

import numpy as np
import torch

from course_lib.evaluation import foot_skate_at_floor
from course_lib.experiments import gmm_rnn as X
from course_lib.results import write_study_result


def toe_speed_where_planted(pos: np.ndarray, planted: np.ndarray, sk, fps: float) -> float:
    """pos (N, T, J, 3), planted (N, T, 2) the RNN's toe contacts -> mean horizontal toe speed (m/s) over the
    (frame pair, foot) where the RNN's toe is planted on both frames."""
    toes = pos[:, :, [sk.index("LeftToeBase"), sk.index("RightToeBase")]][..., [0, 2]]  # (N, T, 2, 2)
    speed = np.linalg.norm(np.diff(toes, axis=1), axis=-1) * fps  # (N, T-1, 2)
    both = planted[:, 1:] & planted[:, :-1]
    return float(speed[both].mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    spec = X.Lesson03Spec()
    _, test, _ = X.lesson03_data(spec, False)
    sk = test[0].skeleton
    groups = X.column_groups()  # {"legs", "upper body", "root"}
    out = {"test_clips": len(test), "seeds": {}}
    for seed in args.seeds:
        model, refiners, stats = X.load_models(seed=seed)
        cont = X.continuations(model, refiners, test, stats, spec, 0)
        rnn_motions = X.to_motions(cont["RNN"], stats, test, spec.fps)
        rnn_pos = np.stack([m.positions() for m in rnn_motions])
        planted = np.stack([m.contacts() for m in rnn_motions])  # (N, T, 2): the RNN's toes low and slow
        row = {"RNN": {"foot_skate": foot_skate_at_floor(rnn_pos, fps=spec.fps),
                       "toe speed where the RNN plants": toe_speed_where_planted(rnn_pos, planted, sk, spec.fps)}}
        for name in ("GAN1", "GAN2"):
            variants = {name: cont[name]}
            for g, cols in groups.items():
                only = cont["RNN"].clone()
                only[..., cols] = cont[name][..., cols]
                variants[f"{name}, only {g} from R"] = only
            for key, feats in variants.items():
                pos = np.stack([m.positions() for m in X.to_motions(feats, stats, test, spec.fps)])
                row[key] = {"foot_skate": foot_skate_at_floor(pos, fps=spec.fps),
                            "toe speed where the RNN plants": toe_speed_where_planted(pos, planted, sk, spec.fps)}
        out["seeds"][str(seed)] = row
        print(seed, {k: round(v["foot_skate"], 3) for k, v in row.items()}, flush=True)
    keys = next(iter(out["seeds"].values())).keys()
    out["mean"] = {k: {m: float(np.mean([r[k][m] for r in out["seeds"].values()])) for m in row[k]} for k in keys}
    write_study_result(args.out, out)  # + command, commit, checkpoints' sha256


if __name__ == "__main__":
    main()
