"""Lesson 02's recipe comparison: train each VAE-LSTM recipe of `experiments.vae_lstm.VARIANTS` with the shipped
steps and batch, and score it as the shipped model is scored (Tables 1-2 on the 120 held-out clips, prior
diversity, latent diagnostics, issue 15's checks; baselines from the shipped checkpoints).

    python studies/02_vae_lstm/vae_lstm_sweep.py --out studies/02_vae_lstm/vae_lstm_sweep_results.json [--only NAME ...] [--smoke]

This is the search behind the shipped recipe; checkpoints/ come from `python -m course_lib.reproduce vae_lstm`.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def run(names, smoke: bool = False, out_path: Path | None = None) -> dict:
    from course_lib.experiments import vae_lstm as V
    from course_lib.results import provenance, rounded

    spec = V.DataSpec(n_clips=30) if smoke else V.DataSpec()
    clips = V.generate_clips(spec, progress=False) if smoke else V.load_clips(spec, progress=False)
    train_ds, test_ds = V.datasets(spec, clips)
    baselines = {name: V.load_model(name) for name in V.lesson02_models() if not name.startswith("vae_lstm")}
    base = V.lesson02_tables(baselines, test_ds)
    kept = json.loads(out_path.read_text())["variants"] if out_path and out_path.exists() else {}
    out = {"baselines": rounded({k: base[k] for k in ("table1", "table2")}), "variants": kept}  # --only adds to it
    for name in names:
        steps = 3 if smoke else V.VARIANTS[name].get("steps")
        model, hist = V.train_one("vae_lstm", train_ds, seed=0, steps=steps, progress=False,
                                  config=V.variant_config(name))
        res = V.recipe_results(model, test_ds, base, n_controls=10)
        res["posterior_pool_diversity"] = V.prior_diversity(model, test_ds, n_controls=10,
                                                            z1_pool=V.posterior_pool(model, test_ds))
        out["variants"][name] = rounded({
            "overrides": V.VARIANTS[name], "train_seconds": hist.seconds, "steps": hist.num_steps,
            "final_mse": hist.final("mse", 20), "final_gen_mse": hist.final("gen_mse", 20) if "gen_mse" in hist.step
            else None, "vae_rows": {k: {m: r for m, r in res[k].items() if m.startswith("VAE")}
                                    for k in ("table1", "table2")},
            "prior_diversity": res["prior_diversity"], "posterior_pool_diversity": res["posterior_pool_diversity"],
            "latent": res["latent"],
            "must_show": {k: list(v) for k, v in V.must_show(res).items()},
            **provenance()})  # the run that added this variant
        print(f"{name}: {hist}", file=sys.stderr, flush=True)
        if out_path:  # written after every variant: a long sweep keeps what it finished
            out_path.write_text(json.dumps({**out, **provenance()}, indent=1) + "\n")  # + the run that wrote it
    return out


def main(argv=None) -> int:
    from course_lib.experiments.vae_lstm import VARIANTS

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--only", nargs="*", default=None, choices=sorted(VARIANTS))
    parser.add_argument("--smoke", action="store_true", help="30 clips, 3 steps: checks the tool runs")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    result = run(args.only or list(VARIANTS), args.smoke, args.out)
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
