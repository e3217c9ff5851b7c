"""Lesson 06 study: does dropout on the history cure reversion to a static pose (sec. 5.3) on our data?

    OMP_NUM_THREADS=1 python studies/06_moglow/moglow_reversion.py --out studies/06_moglow/moglow_reversion_results.json

The paper: early autoregressive models "tended to revert towards a static pose when sampling sequences several
seconds in duration", and dropout made this "virtually disappear".  A cure can only be shown where the disease
is.  The pretrained dropout and no-dropout models (`checkpoints/`), the protocol of `experiments.moglow.long_samples`
(held-out clips' controls back to back; a sample is frozen when the variance of its last 5 s of mean joint speed is
under the freeze floor), for 20-s and 60-s samples, 16 per sampling seed 0-2.  A few minutes on one core.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

MODELS = ("moglow", "moglow_nodrop")
SECONDS = (20.0, 60.0)
SEEDS = (0, 1, 2)


def main(argv=None) -> int:
    from course_lib.experiments import moglow as E
    from course_lib.results import write_study_result

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    data = E.load_data("full")
    models = {name: E.load_model(name) for name in MODELS}
    rows = {}
    for seconds in SECONDS:
        runs = [E.long_samples(models, data, seed, n=16, seconds=seconds) for seed in SEEDS]
        floor = runs[0]["freeze_floor"]
        for name in MODELS:
            ms = [r["models"][name] for r in runs]
            rows[f"{name}, {seconds:.0f} s"] = {
                "n": sum(m["n"] for m in ms), "exploded": sum(m["exploded"] for m in ms),
                "frozen": sum(m.get("frozen", 0) for m in ms),
                "min_speed_var": min(m.get("min_speed_var", float("inf")) for m in ms),
                "median_speed_var_per_seed": [m.get("median_speed_var") for m in ms],
                "min_over_floor": min(m.get("min_speed_var", float("inf")) for m in ms) / floor}
    result = {"seeds": list(SEEDS), "samples_per_seed": 16, "freeze_floor": floor, "rows": rows}
    write_study_result(args.out, result)
    for k, r in rows.items():
        print(f"{k:22s} frozen {r['frozen']}/{r['n']}, exploded {r['exploded']}, smallest speed variance "
              f"{r['min_speed_var']:.4f} ({r['min_over_floor']:.0f}x the floor)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
