"""Lesson 03's GMM-RNN recipe search: train several RNN variants in parallel and measure each one's
generation (the numbers the issue asks of the RNN: foot skate, jitter, FID, contact agreement on 4-s
continuations of the held-out clips, and the 100 x 20 s long-generation test).

    python studies/03_gmm_rnn_refiner/gmm_rnn_sweep.py --out sweep_out [--device cuda] [--jobs 8] [--only NAME ...]

Each variant is a set of GmmRnnConfig / Lesson03Spec overrides (VARIANTS).  The results go to
OUT/results.json (one entry per variant) and the trained weights to OUT/models.pt.  This is the search
behind the shipped recipe (checkpoints/ come from `python -m course_lib.reproduce gmm_rnn` only).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

ROOT_DIMS = (0, 1, 2, 3, 4, 5)
CONTACTS = (66, 67)
TILT = (3, 4, 5) + CONTACTS  # absolute root height, pitch, roll and contacts; residual velocities and angles
HYBRID = ROOT_DIMS + CONTACTS  # absolute means for the root and the contact bits, residual for the angles
POSE = tuple(range(3, 68))  # only the root's floor velocities (dx, dz, dyaw) residual

FT = {"finetune": ((10, 10, 1000),)}  # the self-fed fine-tuning stage of the previous recipe
# every variant starts from Lesson03Spec() and GmmRnnConfig.cpu() (all means residual unless absolute_dims is given)
VARIANTS = {
    "base": {"spec": FT},  # the previous shipped recipe
    "steps12k": {"spec": {**FT, "rnn_steps": 12000}},
    "steps24k": {"spec": {**FT, "rnn_steps": 24000}},
    "hybrid": {"config": {"absolute_dims": HYBRID}, "spec": FT},
    "hybrid12k": {"config": {"absolute_dims": HYBRID}, "spec": {**FT, "rnn_steps": 12000}},
    "hybrid24k": {"config": {"absolute_dims": HYBRID}, "spec": {**FT, "rnn_steps": 24000}},
    "height_abs": {"config": {"absolute_dims": (3,) + CONTACTS}, "spec": FT},
    "w256": {"config": {"fc_width": 256, "lstm_width": 256, "out_width": 256}, "spec": FT},
    "w256_hybrid12k": {"config": {"fc_width": 256, "lstm_width": 256, "out_width": 256, "absolute_dims": HYBRID},
                       "spec": {**FT, "rnn_steps": 12000}},
    "w500_hybrid12k": {"config": {"fc_width": 500, "lstm_width": 500, "out_width": 500, "absolute_dims": HYBRID},
                       "spec": {**FT, "rnn_steps": 12000}},
    "window100": {"config": {"window": 100}, "spec": FT},
    "ft_10_40": {"spec": {"finetune": ((10, 40, 1000),)}},
    "ft_3k": {"spec": {"finetune": ((10, 10, 3000),)}},
    "hybrid_ft_10_40_12k": {"config": {"absolute_dims": HYBRID}, "spec": {"rnn_steps": 12000,
                                                                           "finetune": ((10, 40, 1000),)}},
    "hybrid_ft": {"config": {"absolute_dims": HYBRID}, "spec": FT},
    "tilt_abs": {"config": {"absolute_dims": TILT}, "spec": FT},
    "tilt_abs_noft": {"config": {"absolute_dims": TILT}, "spec": {"finetune": ()}},
    "tilt_abs_w256": {"config": {"absolute_dims": TILT, "fc_width": 256, "lstm_width": 256, "out_width": 256},
                      "spec": FT},
    "tilt_abs_window100": {"config": {"absolute_dims": TILT, "window": 100}, "spec": FT},
    "contacts_abs": {"config": {"absolute_dims": CONTACTS}, "spec": FT},
    "noft": {"spec": {"finetune": ()}},
    "pose_abs": {"config": {"absolute_dims": POSE}},
    "pose_abs12k": {"config": {"absolute_dims": POSE}, "spec": {"rnn_steps": 12000}},
    "paper_means": {"config": {"residual": False}},
    "tilt_abs_noise01": {"config": {"absolute_dims": TILT}, "spec": {"rnn_noise": 0.1}},
    "tilt_abs12k": {"config": {"absolute_dims": TILT}, "spec": {"rnn_steps": 12000}},
    "tilt_abs_w100_noft": {"config": {"absolute_dims": TILT, "window": 100}},
    "pose_abs_ft": {"config": {"absolute_dims": POSE}, "spec": {"finetune": ((10, 10, 1000),)}},
    "hybrid_noft": {"config": {"absolute_dims": HYBRID}, "spec": {"finetune": ()}},
}


def evaluate_rnn(model, test, stats, spec, biases=(1.0, 2.0)) -> dict:
    """Generation quality of one RNN on the held-out clips, per sampling bias."""
    from course_lib.evaluation import contact_agreement, fid, foot_skate, jitter
    from course_lib.experiments.gmm_rnn import (
        contact_bits,
        continuations,
        long_generation,
        to_motions,
        with_contacts,
    )

    T = int(round(spec.eval_seconds * spec.fps))
    mocap = [m[:T] for m in test]
    out = {}
    for b in biases:
        feats = continuations(model, {}, test, stats, replace(spec, sample_bias=b), seed=0)["RNN"]
        row = {}
        for name, f in (("raw", feats), ("enforced", with_contacts(feats, stats, test, spec.contact_smooth))):
            motions = to_motions(f, stats, test, spec.fps)
            pos = np.stack([m.positions() for m in motions])
            agree = contact_agreement(motions, contact_bits(f, stats))
            row[name] = {"foot_skate": foot_skate(pos, fps=spec.fps), "jitter": jitter(pos, fps=spec.fps),
                         "fid": fid(mocap, motions), "contact_agreement": agree}
        lg = long_generation(model, None, test[0], stats, replace(spec, sample_bias=b), test)
        row["long"] = {k: lg["RNN"][k] for k in ("nan_motions", "in_range_motions", "in_range_first_10s",
                                                   "grounded_motions", "grounded_first_10s", "grounded_frames",
                                                   "frozen", "root_height", "apd_m")}
        out[f"bias{b:g}"] = row
    return out


def run_variant(args) -> tuple[str, dict, dict]:
    name, device, data, smoke = args
    torch.set_num_threads(1)
    from course_lib.experiments.gmm_rnn import Lesson03Spec, train_rnn
    from course_lib.models.gmm_rnn import GmmRnnConfig

    v = VARIANTS[name]
    spec = replace(Lesson03Spec(), **v.get("spec", {}))
    if smoke:  # a few steps only, to check the script
        spec = replace(spec, rnn_steps=20, finetune=tuple((k, m, 5) for k, m, _ in spec.finetune), n_random=4)
    config = GmmRnnConfig.cpu(fps=spec.fps, noise_std=spec.rnn_noise, **v.get("config", {}))
    _, test, ds = data
    t0 = time.perf_counter()
    model, hist, ft = train_rnn(ds, spec, seed=0, progress=False, config=config, device=device)
    train_s = time.perf_counter() - t0
    res = {"train_seconds": train_s, "final_nll": hist.final("loss", 50),
           "ft_final_nll": ft.final("loss", 50) if ft.num_steps else None, **evaluate_rnn(model, test, ds.stats, spec)}
    res["eval_seconds"] = time.perf_counter() - t0 - train_s
    print(f"{name}: {json.dumps(res)}", flush=True)
    return name, res, model.state_dict()


def main(argv=None) -> None:
    from course_lib.experiments.gmm_rnn import Lesson03Spec, lesson03_data
    from course_lib.results import provenance

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--device", default="cpu")
    p.add_argument("--jobs", type=int, default=4)
    p.add_argument("--only", nargs="*", default=None)
    p.add_argument("--smoke", action="store_true", help="a few training steps per variant (checks the script)")
    a = p.parse_args(argv)
    names = a.only or list(VARIANTS)
    data = lesson03_data(Lesson03Spec(), progress=False)
    a.out.mkdir(parents=True, exist_ok=True)
    ctx = mp.get_context("spawn" if a.device != "cpu" else "fork")
    results, models = {}, {}
    with ctx.Pool(a.jobs) as pool:
        for name, res, state in pool.imap_unordered(run_variant, [(n, a.device, data, a.smoke) for n in names]):
            results[name], models[name] = res, state
            (a.out / "results.json").write_text(json.dumps({**results, **provenance()}, indent=1))
            torch.save(models, a.out / "models.pt")


if __name__ == "__main__":
    main()
