"""Lesson 02 study: what do the 4 initial frames buy in Table 1, with the lesson's sampler?

    python studies/02_vae_lstm/vae_lstm_four_frames.py --out studies/02_vae_lstm/vae_lstm_four_frames_results.json

The lesson's Table 1 pairs the 4-frame row and the prior row on one sampler (z_t every step): the 4-frame row
takes z_1 from the posterior of the 4 frames and the prior row's draws for z_2, z_3, ... (common random numbers).
Here, on the 120 held-out clips and the pretrained `vae_lstm`: both rows over draw seeds 0-4, paired as the lesson
pairs them and with independent draws (the 4-frame row's seed + 100), Table 2 (pose error) for both, and the
pairing the lesson used before (Algorithm 1's 4-frame row against the z-every-step prior row).  No training.
"""

import argparse

import numpy as np
import torch

from course_lib.evaluation import pose_error, prediction_error
from course_lib.experiments import vae_lstm as V
from course_lib.results import write_study_result

SEEDS = range(5)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    spec = V.DataSpec()
    _, test_ds = V.datasets(spec, V.load_clips(spec, progress=False))
    model = V.load_model("vae_lstm")
    x, starts = V.test_batch(test_ds)
    gt, control = V.to_world(x, test_ds, starts), x[..., -3:]

    def table1(feats):
        return prediction_error(V.to_world(feats, test_ds, starts), gt, V.FRAMES)

    def table2(feats):
        curve = pose_error(V.to_world(V.with_control(feats, control), test_ds, starts), gt)
        return {f: float(curve[f]) for f in V.FRAMES}

    def draws(seed):
        return torch.Generator().manual_seed(seed)

    runs = {"prior": [], "four_paired": [], "four_independent": []}
    t2 = {}
    for s in SEEDS:
        prior = V.sample_prior(model, control, "per_step", draws(s))
        paired = model.predict(x[:, :4], control, per_step=True, generator=draws(s))
        runs["prior"].append(table1(prior))
        runs["four_paired"].append(table1(paired))
        runs["four_independent"].append(table1(model.predict(x[:, :4], control, per_step=True,
                                                             generator=draws(s + 100))))
        if s == 0:
            t2 = {"prior": table2(prior), "four_paired": table2(paired)}
    mean = {k: {f: float(np.mean([r[f] for r in v])) for f in V.FRAMES} for k, v in runs.items()}
    gap = {k: {f: (mean["prior"][f] - mean[k][f]) / mean[k][f] for f in V.FRAMES}
           for k in ("four_paired", "four_independent")}
    algorithm1_four = table1(model.predict(x[:, :4], control))
    out = {"clips": len(x), "seeds": list(SEEDS),
           "table1_mean_over_seeds": mean, "relative_gap_of_the_means": gap,
           "min_relative_gap_per_seed": {k: [min((p[f] - r[f]) / r[f] for f in V.FRAMES)
                                             for p, r in zip(runs["prior"], runs[k], strict=True)]
                                         for k in ("four_paired", "four_independent")},
           "table2_seed0": t2,
           "before": {"four_algorithm1": algorithm1_four, "prior_per_step_seed0": runs["prior"][0],
                      "relative_gap": {f: (runs["prior"][0][f] - algorithm1_four[f]) / algorithm1_four[f]
                                       for f in V.FRAMES}}}
    write_study_result(args.out, out)
    print(out)


if __name__ == "__main__":
    main()
