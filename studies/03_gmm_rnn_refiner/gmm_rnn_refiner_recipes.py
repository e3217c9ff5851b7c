"""Lesson 03 side experiment (issue 14): two refiner recipes tried on refiner seed 0 before the shipped refiners were
retrained, on RNN motions sampled with the joint limits.

Both use the balance band [0.3, 0.6] on D's 5-round mean loss (the previous 0.1 / ln 2 never fired in three of six
runs, whose D loss stayed at 0.5-0.7); they differ in what D sees and how strongly R's pose is held:
  - ``--d-joints all --pose-lam 30``: D on every joint's position and velocity, SimGAN's pose term at mu = 30 (the
    candidate that kept the FID order on the widths-128 RNN, studies/03_gmm_rnn_refiner/gmm_rnn_refiner_d_all_seeds_results.json);
  - ``--d-joints end_effectors --pose-lam 10``: the shipped recipe (eq. 12's end effectors, mu = 10).
Trains GAN1 and GAN2 on the pool of `experiments.gmm_rnn.rnn_pool` (seed 0), then runs `evaluate` (the quality
table on the 120 held-out clips and the 100 x 20-s long generation) and records the GAN training summaries.

    python studies/03_gmm_rnn_refiner/gmm_rnn_refiner_recipes.py --d-joints all --pose-lam 30 --out <file>            # ~12 min, one core
    python studies/03_gmm_rnn_refiner/gmm_rnn_refiner_recipes.py --d-joints end_effectors --pose-lam 10 --out <file>  # ~12 min

Recorded before the leg term (``Lesson03Spec.refiner_leg_pose_lam`` was 0); the spec's default is now 30, so a
rerun trains the current recipe, not the recorded one.
"""

import argparse
import json
from dataclasses import replace

import torch

from course_lib.experiments import gmm_rnn as X
from course_lib.results import provenance


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--d-joints", choices=("all", "end_effectors"), required=True)
    parser.add_argument("--pose-lam", type=float, required=True)
    parser.add_argument("--low", type=float, default=0.3)
    parser.add_argument("--high", type=float, default=0.6)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    spec = replace(X.Lesson03Spec(), discriminator_joints=args.d_joints, refiner_pose_lam=args.pose_lam,
                   d_loss_low=args.low, d_loss_high=args.high, joint_limits=True)
    _, test, ds = X.lesson03_data(spec, progress=False)
    model, _, stats = X.load_models()
    model.set_limits(*X.training_limits(model, ds))
    pool = X.rnn_pool(model, ds, spec, seed=0)
    refiners, summary = {}, {}
    for name in ("GAN1", "GAN2"):
        refiners[name], _, h = X.train_gan(pool, ds, spec, contacts=name == "GAN2", seed=args.seed, progress=False)
        summary[name] = X._gan_summary(h)
        print(name, json.dumps(X.rounded(summary[name])), flush=True)
    res = X.evaluate(model, refiners, stats, spec, test, 0)
    res["gan"] = summary
    res["setting"] = {"discriminator_joints": args.d_joints, "refiner_pose_lam": args.pose_lam,
                      "d_loss_low": args.low, "d_loss_high": args.high, "refiner_seed": args.seed}
    res = {**res, **provenance()}  # the command run, the commit, the checkpoints' sha256
    with open(args.out, "w") as f:
        json.dump(X.rounded(res), f, indent=1)


if __name__ == "__main__":
    main()
