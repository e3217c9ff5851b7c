"""Lesson 03's recipe study: what do its two changes of the RNN (residual means; features anchored on the feet) do
to the numbers the lesson asks of the RNN alone (no refiner, no contact clean-up)?  A 2 x 2 design, each row a
model trained for the recipe's 6000 steps at width 128 (a quarter of the shipped width's training time), plus
the shipped checkpoint (width 256) measured as it is:

- teacher-forced one-step skate: every frame predicted from the true frames before it (a sample at the
  generation's bias, and the most likely component's mean), decoded on each clip's skeleton;
- free-running skate, jitter, ground penetration, FID: 4-s continuations of the 120 held-out clips;
- the 100 x 20-s long-generation test from one start (root height in range, grounded, frozen, APD).

    python studies/03_gmm_rnn_refiner/gmm_rnn_skate.py --out studies/03_gmm_rnn_refiner/gmm_rnn_skate_results.json --shipped --only paper_features_absolute paper_features_residual anchored_absolute anchored_residual

Rows are merged into --out (one entry per variant, each with the provenance of the run that made it); the
file's own command, commit and checkpoints' sha256 are those of its last whole run (every row).  One
training at a time, one thread; nothing is written to checkpoints/.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

ALL_ABSOLUTE = tuple(range(68))  # the paper: every mean absolute, mu = mu_hat
VARIANTS = {  # Lesson03Spec overrides of BASE
    "paper_features_absolute": {"rnn_features": "state_features", "rnn_absolute_dims": ALL_ABSOLUTE},  # the paper
    "paper_features_residual": {"rnn_features": "state_features"},  # + residual angles and heading
    "anchored_absolute": {"rnn_absolute_dims": ALL_ABSOLUTE},  # + features anchored on the feet
    "anchored_residual": {},  # both: the lesson's recipe
}


def _base():
    from course_lib.experiments.gmm_rnn import Lesson03Spec

    return Lesson03Spec(rnn_width=128)


BASE = _base()  # the lesson's recipe at width 128


def measure(model, test, stats, spec, seed: int = 0) -> dict:
    """The RNN-alone numbers of one model (see the module docstring)."""
    from course_lib.evaluation import fid, foot_skate_at_floor, ground_penetration, jitter, root_jerk_split
    from course_lib.experiments import gmm_rnn as X

    T = int(round(spec.eval_seconds * spec.fps))
    mocap = [m[:T] for m in test]
    out = {}
    for name, kw in (("one_step_sample", {"mean": False}), ("one_step_mean", {"mean": True})):
        f = X.one_step(model, mocap, stats, bias=spec.sample_bias, seed=seed, angle_scale=spec.sample_angle_noise,
                       root_scale=spec.sample_root_noise, **kw)
        motions = X.to_motions(f, stats, mocap, spec.fps)
        out[f"{name}_skate"] = foot_skate_at_floor(motions)
        out[f"{name}_jitter"] = jitter(motions)
    feats = X.continuations(model, {}, test, stats, spec, seed)["RNN"]
    motions = X.to_motions(feats, stats, test, spec.fps)
    out.update({"free_skate": foot_skate_at_floor(motions), "free_jitter": jitter(motions),
                "free_penetration": ground_penetration(motions), "free_fid": fid(mocap, motions),
                "free_root_jerk": root_jerk_split(motions)})
    lg = X.long_generation(model, None, test[0], stats, spec, test, seed)
    out["long"] = lg["RNN"]
    out["data_root_height"] = lg["data_root_height"]
    return out


def mocap_row(test, spec) -> dict:
    from course_lib.evaluation import foot_skate_at_floor, ground_penetration, jitter, root_jerk_split

    T = int(round(spec.eval_seconds * spec.fps))
    mocap = [m[:T] for m in test]
    return {"free_skate": foot_skate_at_floor(mocap), "free_jitter": jitter(mocap),
            "free_penetration": ground_penetration(mocap), "free_root_jerk": root_jerk_split(mocap)}


def main(argv=None) -> None:
    from course_lib.experiments import gmm_rnn as X
    from course_lib.results import provenance, rounded

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--only", nargs="*", default=[], choices=sorted(VARIANTS))
    p.add_argument("--shipped", action="store_true", help="measure checkpoints/gmm_rnn.pt as it is")
    p.add_argument("--steps", type=int, default=None, help="override rnn_steps (a quick check)")
    p.add_argument("--seed", type=int, default=0,
                   help="the training seed, also the sampling seed of the measures (not 0: recorded as 'NAME, seed N')")
    a = p.parse_args(argv)
    torch.set_num_threads(1)
    torch.set_flush_denormal(True)
    _, test, ds = X.lesson03_data(X.Lesson03Spec(), progress=False)
    results = json.loads(a.out.read_text()) if a.out.exists() else {}
    results.setdefault("_about", __doc__.splitlines()[0])
    results["mocap"] = rounded(mocap_row(test, X.Lesson03Spec()))
    jobs = (["shipped"] if a.shipped else []) + list(a.only)
    for name in jobs:
        t0 = time.perf_counter()
        if name == "shipped":
            spec, model, res = X.Lesson03Spec(), X.load_models_rnn(), {"train_seconds": None}
        else:
            spec = replace(BASE, **VARIANTS[name])
            if a.steps:
                spec = replace(spec, rnn_steps=a.steps)
            model, hist, _ = X.train_rnn(ds, spec, seed=a.seed, progress=False)
            res = {"train_seconds": hist.seconds, "final_nll": hist.final("loss", 50), "steps": hist.num_steps,
                   "spec": dict(VARIANTS[name], rnn_width=BASE.rnn_width)}
        res.update(measure(model, test, ds.stats, spec, seed=a.seed))
        if a.seed:
            res["seed"] = a.seed
        res["eval_seconds"] = time.perf_counter() - t0 - (res["train_seconds"] or 0)
        key = name if not a.seed else f"{name}, seed {a.seed}"
        results[key] = {**rounded(res, 4), **provenance()}  # the run that added this row
        if a.shipped and set(a.only) == set(VARIANTS):  # a whole run: the command that regenerates the file
            results.update(provenance())
        a.out.write_text(json.dumps(results, indent=1) + "\n")
        print(key, json.dumps(results[key]), flush=True)


if __name__ == "__main__":
    main()
