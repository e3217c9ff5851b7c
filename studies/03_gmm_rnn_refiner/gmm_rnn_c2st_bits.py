"""Lesson 03 side experiment (issue 14): does D's view of the contact bits move GAN2's legs away from mocap?

studies/03_gmm_rnn_refiner/gmm_rnn_c2st.py found GAN2 of refiner seed 1 the furthest from chance on the C2ST, and its legs the part that
takes it there.  This retrains that refiner with one change, D not shown the contact bits
(``Lesson03Spec.discriminator_contacts=False``; the same RNN pool, seed and budget as
`python -m course_lib.reproduce gmm_rnn --only gans`), and scores both on the C2ST over RNN generation seeds 0-4, with
the leg clamp test on generation seed 0, beside the RNN and the shipped GAN2.

    OMP_NUM_THREADS=1 python studies/03_gmm_rnn_refiner/gmm_rnn_c2st_bits.py --out studies/03_gmm_rnn_refiner/gmm_rnn_c2st_bits_results.json  # ~6 min

Writes nothing to checkpoints/.
"""

import argparse
import time
from dataclasses import replace

import torch
from gmm_rnn_c2st import accuracy, write  # the script's own folder is on sys.path

from course_lib.experiments import gmm_rnn as X

COMMAND = "OMP_NUM_THREADS=1 python studies/03_gmm_rnn_refiner/gmm_rnn_c2st_bits.py --out studies/03_gmm_rnn_refiner/gmm_rnn_c2st_bits_results.json"
SEED = 1  # the refiner seed whose GAN2 is furthest from chance (studies/03_gmm_rnn_refiner/gmm_rnn_c2st_results.json)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    spec = X.Lesson03Spec()
    _, test, ds = X.lesson03_data(spec, False)
    model, refiners, stats = X.load_models(seed=SEED)
    pool = X.rnn_pool(model, ds, spec, 0)  # the pool every shipped refiner was trained on (train seed 0)
    t0 = time.perf_counter()
    no_bits, _, h = X.train_gan(pool, ds, replace(spec, discriminator_contacts=False), contacts=True, seed=SEED,
                                progress=False)
    out = {"command": COMMAND, "refiner_seed": SEED, "train_seconds": time.perf_counter() - t0,
           "gan": X._gan_summary(h), "by_generation_seed": {}, "clamp_legs": {}}
    rows = {"GAN2 (shipped: D sees the bits)": refiners["GAN2"], "GAN2, D without the bits": no_bits}
    T = int(round(spec.eval_seconds * spec.fps))
    mocap = [m[:T] for m in test]
    legs = X.column_groups()["legs"]
    for g in range(5):
        sets = X.continuations(model, rows, test, stats, spec, seed=g)
        out["by_generation_seed"][str(g)] = {k: accuracy(v, stats, test, mocap, spec, g) for k, v in sets.items()}
        print(g, {k: round(v, 3) for k, v in out["by_generation_seed"][str(g)].items()}, flush=True)
        if g == 0:
            for k in rows:
                mixed = sets[k].clone()
                mixed[..., legs] = sets["RNN"][..., legs]
                out["clamp_legs"][k] = accuracy(mixed, stats, test, mocap, spec, 0)
    write(out, args.out)


if __name__ == "__main__":
    main()
