"""Lesson 02's body-size experiment: is the subjects' body size what keeps the prior row far from the 4-frame row
and Table 2 from being flat?  Every clip is put on the canonical skeleton (`DataSpec(one_body=True)`, as a
retargeted mocap set puts every performer on one body); the VAE-LSTM and the baselines are trained on it with the
shipped recipes and scored as the shipped models are (Tables 1-2 on the 120 held-out clips, prior diversity,
latent diagnostics, issue 15's checks).

    python studies/02_vae_lstm/vae_lstm_one_body.py --out studies/02_vae_lstm/vae_lstm_one_body_results.json [--smoke]

Nothing here is shipped: checkpoints/ come from `python -m course_lib.reproduce vae_lstm` on the lesson's data.
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
    from course_lib.results import provenance, rounded

    spec = V.DataSpec(n_clips=30, one_body=True) if smoke else V.DataSpec(one_body=True)
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
    vae = models["vae_lstm"]
    res["prior_diversity"] = V.prior_diversity(vae, test_ds)
    res["posterior_pool_diversity"] = V.prior_diversity(vae, test_ds, z1_pool=V.posterior_pool(vae, test_ds))
    res["latent"] = V.latent_diagnostics(vae, test_ds)
    res["latent"].pop("kl_per_dim")
    res["matched_control_pairs"] = V.matched_control_pairs(train_ds, test_ds)
    out = rounded({"command": "python studies/02_vae_lstm/vae_lstm_one_body.py --out studies/02_vae_lstm/vae_lstm_one_body_results.json",
                   "data": "DataSpec(one_body=True): the lesson's 400 clips, each retargeted to the canonical skeleton",
                   "train_seconds": seconds, "eval_seconds": time.perf_counter() - t0,
                   **{k: res[k] for k in ("table1", "table2", "prior_diversity", "posterior_pool_diversity", "latent",
                                         "matched_control_pairs")},
                   "must_show": {k: list(v) for k, v in V.must_show(res).items()}})
    if out_path:
        out = {**out, **provenance()}  # the command run, the commit, the checkpoints' sha256
        out_path.write_text(json.dumps(out, indent=1) + "\n")
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--smoke", action="store_true", help="30 clips, 3 steps: checks the tool runs")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    print(json.dumps(run(args.smoke, args.out)["must_show"], indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
