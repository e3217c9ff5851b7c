"""Lesson 02's body study: what does z carry when the bodies vary?  The lesson's models are trained on one body
(every clip retargeted to the canonical skeleton, as the paper's data were).  Here the VAE-LSTM and the baselines
are trained with the same recipes on the ten subjects' own bodies (`DataSpec(one_body=False)`) and scored as the
lesson's models are: Tables 1-2 on the 120 held-out clips, both prior samplers beside the data's matched-control
spread (which the bodies widen), latent diagnostics and the course's targets.

    python studies/02_vae_lstm/vae_lstm_ten_bodies.py --out studies/02_vae_lstm/vae_lstm_ten_bodies_results.json [--smoke]

It writes no checkpoint: checkpoints/ come from `python -m course_lib.reproduce vae_lstm` on the lesson's data.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def run(smoke: bool = False, out_path: Path | None = None) -> dict:
    from course_lib.experiments import vae_lstm as V
    from course_lib.results import rounded, write_study_result

    spec = V.DataSpec(n_clips=30, one_body=False) if smoke else V.DataSpec(one_body=False)
    clips = V.generate_clips(spec, progress=False) if smoke else V.load_clips(spec, progress=False)
    train_ds, test_ds = V.datasets(spec, clips)
    models, seconds = {}, {}
    for name in V.lesson02_models():
        if name == "vae_lstm_paper":
            continue
        model, hist = V.train_one(name, train_ds, seed=0, steps=3 if smoke else None, progress=False)
        models[name], seconds[name] = model, hist.seconds
        print(f"{name}: {hist}", file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    res = V.lesson02_tables(models, test_ds)
    res.pop("curves")
    vae = models["vae_lstm"]
    res["matched_control_pairs"] = pairs = V.matched_control_pairs(train_ds, test_ds)
    res["prior_diversity"] = V.prior_diversity(vae, test_ds, data_apd_m=pairs["best10_cm"] / 100)
    res["posterior_pool_diversity"] = V.prior_diversity(vae, test_ds, z1_pool=V.posterior_pool(vae, test_ds))
    res["latent"] = V.latent_diagnostics(vae, test_ds)
    res["latent"].pop("kl_per_dim")
    res["body_size"] = V.body_size_study(vae, train_ds, test_ds)
    out = rounded({"data": "DataSpec(one_body=False): the lesson's 400 clips on their ten subjects' own bodies",
                   "train_seconds": seconds, "eval_seconds": time.perf_counter() - t0, **res,
                   "checks": {k: list(v) for k, v in V.must_show(res).items()}})
    if out_path:
        write_study_result(out_path, out)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--smoke", action="store_true", help="30 clips, 3 steps: checks the tool runs")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    print(json.dumps(run(args.smoke, args.out)["checks"], indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
