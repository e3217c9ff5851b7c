"""Lesson 03's RNN foot-skate study (issue: the RNN skates): train RNN variants one after the other and measure
what each change does to the numbers the lesson asks of the RNN alone (no refiner, no contact clean-up):

- teacher-forced one-step skate: every frame predicted from the true frames before it (a sample at the
  generation's bias, and the most likely component's mean), decoded on each clip's skeleton;
- free-running skate, jitter, ground penetration, FID: 4-s continuations of the 120 held-out clips;
- the 100 x 20-s long-generation test from one start (root height in range, grounded, frozen, APD).

    python studies/03_gmm_rnn_refiner/gmm_rnn_skate.py --out studies/03_gmm_rnn_refiner/gmm_rnn_skate_results.json --only NAME [NAME ...] [--seed N]
    python studies/03_gmm_rnn_refiner/gmm_rnn_skate.py --out ... --shipped          # the checkpoint in checkpoints/ (the "before" row)

Each variant is a set of Lesson03Spec overrides (VARIANTS); results are merged into --out (one entry per variant).
One training at a time, one thread.  Every variant overrides BASE: the recipe shipped until stop 28 (widths 128),
the one the study's rows were measured against.  `python -m course_lib.reproduce gmm_rnn` now trains wide256.
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

STATE_ABS = tuple(range(3, 68))  # the previous recipe: every column absolute but dx, dz, dyaw
VARIANTS = {
    # the previous recipe, with each fix of the issue added one at a time
    "before": {"rnn_features": "state_features", "rnn_absolute_dims": STATE_ABS, "rnn_fixed_dims": False,
               "rnn_bernoulli_contacts": False},
    "fixed_bernoulli": {"rnn_features": "state_features", "rnn_absolute_dims": STATE_ABS},
    "residual_angles": {"rnn_features": "state_features", "rnn_absolute_dims": (3, 4, 5)},
    "anchored_absolute": {"rnn_absolute_dims": tuple(range(0, 2)) + tuple(range(3, 68))},
    "anchored": {},  # the feet-anchored root + residual angles + fixed columns + Bernoulli contacts
    "anchored_12k": {"rnn_steps": 12000},
    "anchored_ft": {"finetune": ((10, 10, 1000),)},  # + acLSTM-style self-fed fine-tuning
    "anchored_noise01": {"rnn_noise": 0.1},  # twice the paper's input noise
    "anchored_absolute_ft": {"rnn_absolute_dims": tuple(range(0, 2)) + tuple(range(3, 68)),
                             "finetune": ((10, 10, 1000),)},
    # sampling only: the "anchored" model (trained above) generating with another bias
    "anchored_bias0": {"sample_bias": 0.0, "_model": "anchored"},
    "anchored_bias1": {"sample_bias": 1.0, "_model": "anchored"},
    "anchored_bias3": {"sample_bias": 3.0, "_model": "anchored"},
    "anchored_angles_mean": {"sample_angle_noise": 0.0, "_model": "anchored"},  # joint angles: component means
    "anchored_angles_03": {"sample_angle_noise": 0.3, "_model": "anchored"},
    "noise01_angles_mean": {"rnn_noise": 0.1, "sample_angle_noise": 0.0, "_model": "anchored_noise01"},
    "noise01_angles_03": {"rnn_noise": 0.1, "sample_angle_noise": 0.3, "_model": "anchored_noise01"},
    "anchored_noise02": {"rnn_noise": 0.2},
    "noise01_means": {"rnn_noise": 0.1, "sample_angle_noise": 0.0, "sample_root_noise": 0.0,
                      "_model": "anchored_noise01"},  # every column at its component's mean
    "noise02_angles_03": {"rnn_noise": 0.2, "sample_angle_noise": 0.3, "_model": "anchored_noise02"},
    # the shipped recipe (noise 0.1, angles drawn at 0.3) with the soft anchor: both toes weighted by height, so the
    # anchor does not jump from toe to toe at a change of support (where the shipped RNN's root jerks most)
    "anchored_soft_2cm": {"rnn_anchor_tau": 0.02},
    "anchored_soft_1cm": {"rnn_anchor_tau": 0.01},
    "shipped_recipe": {},  # BASE as it is: the recipe shipped until stop 28 (widths 128)
    # the anchor follows the contact bits, and in a flight the root (the lower toe's slip in a flight, the velocity
    # of whichever swinging toe is lower, held 93 % of the shipped RNN's teacher-forced slip error)
    "contact_anchor": {"rnn_anchor_rule": "contact"},
    # twice the widths: the root jerk is the per-frame error of the stance toe's position relative to the root
    # (experiments.gmm_rnn_jitter); measured on 3 seeds, shipped (Lesson03Spec.rnn_width's default since stop 29)
    "wide256": {"rnn_width": 256},
    "noise02_means": {"rnn_noise": 0.2, "sample_angle_noise": 0.0, "sample_root_noise": 0.0,
                      "_model": "anchored_noise02"},
}


def _base():
    from course_lib.experiments.gmm_rnn import Lesson03Spec

    return Lesson03Spec(rnn_width=128)


# every variant overrides the study's base: the recipe shipped until stop 28, its widths (128) spelled out
BASE = _base()


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
    p.add_argument("--only", nargs="*", default=[])
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
            spec = replace(X.Lesson03Spec(), rnn_features="state_features")
            model = X.load_models_rnn()
            if float(model.feature_std.min()) == 1.0:  # saved before the model kept its stats: ds's
                model.feature_mean.copy_(torch.as_tensor(ds.stats[0]))
                model.feature_std.copy_(torch.as_tensor(ds.stats[1]))
            res = {"train_seconds": None}
        elif "_model" in VARIANTS[name]:  # the weights of an earlier variant, another way of sampling
            spec = replace(BASE, **{k: v for k, v in VARIANTS[name].items() if k != "_model"})
            model, _, _ = X.train_rnn(ds, spec, seed=0, steps=0, progress=False)
            model.load_state_dict(torch.load(Path("/tmp") / f"gmm_rnn_skate_{VARIANTS[name]['_model']}.pt",
                                             weights_only=True))
            res = {"train_seconds": None, "spec": VARIANTS[name]}
        else:
            spec = replace(BASE, **VARIANTS[name])
            if a.steps:
                spec = replace(spec, rnn_steps=a.steps)
            model, hist, _ = X.train_rnn(ds, spec, seed=a.seed, progress=False)
            res = {"train_seconds": hist.seconds, "final_nll": hist.final("loss", 50), "steps": hist.num_steps,
                   "spec": {k: v for k, v in VARIANTS[name].items()}}
            tag = f"_seed{a.seed}" if a.seed else ""  # the sampling variants' "_model" reads the seed-0 file
            torch.save(model.state_dict(), Path("/tmp") / f"gmm_rnn_skate_{name}{tag}.pt")
        res.update(measure(model, test, ds.stats, spec, seed=a.seed))
        if a.seed:
            res["seed"] = a.seed
        res["eval_seconds"] = time.perf_counter() - t0 - (res["train_seconds"] or 0)
        key = name if not a.seed else f"{name}, seed {a.seed}"
        results[key] = {**rounded(res, 4), **provenance()}  # the run that added this row
        a.out.write_text(json.dumps(results, indent=1) + "\n")
        print(key, json.dumps(results[key]), flush=True)


if __name__ == "__main__":
    main()
