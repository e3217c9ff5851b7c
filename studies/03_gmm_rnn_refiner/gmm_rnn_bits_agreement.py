"""Lesson 03 side experiment: why GAN2's contact bits agree with its own poses less often than the RNN's do.

    OMP_NUM_THREADS=1 python studies/03_gmm_rnn_refiner/gmm_rnn_bits_agreement.py --out studies/03_gmm_rnn_refiner/gmm_rnn_bits_agreement_results.json

On the shipped checkpoints (every refiner seed, the 120 held-out clips, generation seed 0, as section 7's table)
it crosses the bits and the poses: the RNN's bits against the RNN's poses (the table's RNN row), GAN2's bits
against GAN2's poses (the GAN2 row), and the two mixes.  If R's bits were the problem, the RNN's bits would agree
with GAN2's poses better than GAN2's own bits; if R's pose change is, they agree worse.  Each disagreement is then
split by what the pose says: a bit on where the foot is low but moving (at or above CONTACT_SPEED), on where the
foot is high, or off where the pose has the foot in contact.  Writes nothing to checkpoints/ (about 1 min).
"""

import argparse

import numpy as np
import torch

from course_lib.evaluation.contacts import contact_agreement
from course_lib.experiments import gmm_rnn as X
from course_lib.motion import CONTACT_HEIGHT, CONTACT_SPEED
from course_lib.results import write_study_result


def low_feet(motion) -> np.ndarray:
    """(T, 2) bool: the foot's ankle or toe below its contact height (the contact rule without the speed test)."""
    pos, sk = motion.positions(), motion.skeleton
    return np.stack([np.any([pos[:, sk.index(side + part), 1] < h for part, h in CONTACT_HEIGHT.items()], 0)
                     for side in ("Left", "Right")], -1)


def disagreements(motions, bits) -> dict:
    """Fractions of all (frame, foot) pairs where the bit and the pose's contact differ, by the pose's reason."""
    on = np.asarray(bits) > 0.5
    contact = np.stack([m.contacts() for m in motions])
    low = np.stack([low_feet(m) for m in motions])
    return {"bit on, foot low but moving": float((on & ~contact & low).mean()),
            "bit on, foot high": float((on & ~low).mean()),
            "bit off, foot in contact": float((~on & contact).mean())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    spec = X.Lesson03Spec()
    _, test, _ = X.lesson03_data(spec, False)
    out = {"command": f"OMP_NUM_THREADS=1 python studies/03_gmm_rnn_refiner/gmm_rnn_bits_agreement.py --out {args.out}",
           "test_clips": len(test), "contact_speed_m_s": CONTACT_SPEED, "seeds": {}}
    for seed in args.seeds:
        model, refiners, stats = X.load_models(seed=seed)
        cont = X.continuations(model, refiners, test, stats, spec, 0)
        motions = {k: X.to_motions(v, stats, test, spec.fps) for k, v in cont.items()}
        bits = {k: X.contact_bits(v, stats) for k, v in cont.items()}
        row = {f"{b} bits on {p} poses": contact_agreement(motions[p], bits[b])
               for p in ("RNN", "GAN1", "GAN2") for b in ("RNN", "GAN2")}
        row["GAN2 bits changed by R (fraction of pairs)"] = float(((bits["GAN2"] > 0.5) != (bits["RNN"] > 0.5)).mean())
        pose_contacts = {k: np.stack([m.contacts() for m in motions[k]]) for k in ("RNN", "GAN2")}
        row["pose contacts changed by R (GAN2 vs RNN)"] = float((pose_contacts["GAN2"] != pose_contacts["RNN"]).mean())
        row["disagreements"] = {f"{k} bits on {k} poses": disagreements(motions[k], bits[k]) for k in ("RNN", "GAN2")}
        out["seeds"][str(seed)] = row
        print(seed, {k: round(v, 3) for k, v in row.items() if isinstance(v, float)}, flush=True)
    write_study_result(args.out, out)  # + command, commit, checkpoints' sha256


if __name__ == "__main__":
    main()
