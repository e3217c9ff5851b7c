"""Which change to the Proposed model's recipe plants its feet?  Each variant is trained from scratch as
`python -m course_lib.reproduce hvrnn` trains the Proposed model (same data, DAE, loss classifiers, seed 0) and
measured three ways: lesson 07's benchmark protocol (walk or jog samples, 5 generation seeds, the first 0.5 s
dropped, foot skate with the known floor), the teacher-forced reconstruction of the held-out walks and jogs,
and the legs' sweep against the root's speed on the samples' stance frames.  The "shipped_z_T*" rows sample the
pretrained model with its prior's sd scaled (TEMPERATURES), no training.

    OMP_NUM_THREADS=1 python studies/05_hierarchical_vrnn/hvrnn_skate_fix.py \\
        --out studies/05_hierarchical_vrnn/hvrnn_skate_fix_results.json [--only NAME ...] [--merge]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np
import torch

from course_lib import benchmark as bench
from course_lib.experiments import hvrnn as lesson05
from course_lib.results import rounded, write_study_result

# name -> (retarget the root to the canonical legs, steps, overrides: the config's, "batch", "dae_steps", "lr_end")
VARIANTS = {
    "before": (False, 1200, {"dae_steps": 300}),  # the recipe before the fix (measured by lesson 07's benchmark)
    "retarget": (True, 1200, {"dae_steps": 300}),
    "retarget_steps3600": (True, 3600, {"dae_steps": 300}),
    "retarget_drop06": (True, 1200, {"drop_max": 0.6, "dae_steps": 300}),  # the paper: word dropping "helps
    # with the problem of foot skating"
    "retarget_b64_2400": (True, 2400, {"batch": 64, "dae_steps": 300}),  # the paper's batch of 64
    # the pretrained recipe (retargeting, the 1875-step DAE, 3600 steps) with the rate decayed over the second half
    "lr_decay": (True, 3600, {"lr_end": 0.1}),
    # ... and twice the word dropping (the paper's remedy for exposure bias, which "helps with foot skating"): the
    # recipe `python -m course_lib.reproduce hvrnn` now trains
    "lr_decay_drop06": (True, 3600, {"lr_end": 0.1, "drop_max": 0.6}),
    # two milder versions of it: does either keep long jumps from freezing (lesson 05's collapse at 200 frames)?
    "lr_decay03_drop06": (True, 3600, {"lr_end": 0.3, "drop_max": 0.6}),
    "lr_decay_drop045": (True, 3600, {"lr_end": 0.1, "drop_max": 0.45}),
    # the recipe with short clips (the jumps) padded by playing them again instead of holding their last pose:
    # is the long-jump freeze learnt from the padding?
    "lr_decay_drop06_loop": (True, 3600, {"lr_end": 0.1, "drop_max": 0.6, "pad": "loop"}),
}
BASE = {"drop_max": 0.3, "lr_end": 1.0}  # the recipe before this study: words dropped up to 0.3, a constant rate
SHIPPED = "shipped"  # the pretrained checkpoints/hvrnn_proposed.pt, trained by `python -m course_lib.reproduce hvrnn`
# the pretrained model sampling z with its prior's sd scaled by T (eq. 12 at a temperature; 1 = the paper's)
TEMPERATURES = {"shipped_z_T0.5": 0.5, "shipped_z_T0": 0.0}


class TemperedPrior(torch.nn.Module):
    """p(z_t | h_{t-1}) with its sd multiplied by ``temperature``: wraps a model's ``prior``."""

    def __init__(self, prior: torch.nn.Module, temperature: float):
        super().__init__()
        self.inner, self.temperature = prior, temperature

    def forward(self, x):
        mu, sd = self.inner(x)
        return mu, sd * self.temperature


def train_variant(retarget: bool, steps: int, overrides: dict, seed: int = 0):
    """-> (model, seconds): the Proposed recipe of `lesson05.model_specs`, scaled to `steps`, with the study's base
    (BASE: the recipe it started from) and then `overrides`."""
    overrides = {**BASE, **overrides}
    data = lesson05.load_data("full", retarget=retarget, pad=overrides.pop("pad", "hold"))
    dae, _ = lesson05.train_dae(overrides.pop("dae_steps", lesson05.DAE_STEPS), seed, "full", retarget=retarget)
    train = dict(data["train"], x=lesson05.clean(dae, data["train"]["x"]))
    classifiers = lesson05.train_loss_classifiers(train, 300, seed)
    spec = lesson05.model_specs(steps / lesson05.PROPOSED_STEPS)["hvrnn_proposed"]
    batch, lr_end = overrides.pop("batch", spec.batch), overrides.pop("lr_end", spec.lr_end)
    spec = dataclasses.replace(spec, batch=batch, lr_end=lr_end, config=dataclasses.replace(spec.config, **overrides))
    model, hist = lesson05.train_model(spec, train, classifiers, seed)
    return model, data, hist.seconds


def legs_vs_root(motions) -> dict:
    """On frames where the same toe stays the lower one (stance): the stance toe's speed relative to the root
    (the legs' sweep), the root's speed and the toe's world speed (the skate), m/s."""
    from course_lib.skeleton import Skeleton

    sk = Skeleton.canonical()
    toes = [sk.index("LeftToeBase"), sk.index("RightToeBase")]
    p = np.stack([m.positions()[lesson05.SKIP:] for m in motions])  # (N, T, J, 3)
    low = p[:, :, toes, 1].argmin(-1)
    toe = np.take_along_axis(p[:, :, toes], low[..., None, None].repeat(3, -1), 2)[:, :, 0]
    same = low[:, 1:] == low[:, :-1]

    def speed(x):
        return float(np.linalg.norm(np.diff(x[..., [0, 2]], axis=1), axis=-1)[same].mean() * lesson05.FPS)

    return {"legs_sweep": speed(toe - p[:, :, 0]), "root_speed": speed(p[:, :, 0]), "stance_toe": speed(toe),
            "root_height": float(p[:, :, 0, 1].mean())}


def on_benchmark(model, proto, seeds=range(5)) -> dict:
    """Lesson 07's HVRNN row: each seed's half B of the held-out clips, the clip's gait asked for, mean and sd."""
    row = bench.Hvrnn.__new__(bench.Hvrnn)  # the benchmark's adapter around a model in memory
    row.lesson, row.model, row.name = lesson05, model, "HVRNN (Proposed)"
    runs = []
    for s in seeds:
        _, b = bench.halves(len(proto.clips), s)
        pos = row.generate(proto, b, s).positions
        runs.append(bench.quality(bench.Sample(pos, proto.skeletons(b)), [], s, distribution=False))
    keys = ("foot_skate", "penetration", "jitter")
    return {k: float(np.mean([r[k] for r in runs])) for k in keys} | {
        f"{k}_sd": float(np.std([r[k] for r in runs])) for k in keys}


def long_collapse(model, frames: int = 200, n: int = 50) -> dict:
    """Lesson 05's mean-pose collapse at the paper's length: the fraction of n jump/A and n lift/A samples of
    ``frames`` frames (generation seed 0) whose last second is stiller than the recorded thresholds."""
    thr = lesson05.recorded_results()["collapse_thresholds"]
    out = {}
    for act in ("jump", "lift"):
        ms = lesson05.to_motions(lesson05.generate(model, n, frames, seed=0, attribute=(act, "A")))
        out[act] = lesson05.collapsed_fraction(ms, (thr[act]["speed_m_s"], thr[act]["variance_m2"]))
    return out


def word_boundary_jerk(motions, word_len: int = 3) -> dict:
    """Mean jerk (m/s^3, all joints) of the samples (frames k..k+3) whose middle step crosses from one Motion
    Word to the next, and of the others: a decoder that emits each word on its own jumps at the boundaries."""
    p = np.stack([m.positions()[lesson05.SKIP:] for m in motions])
    jerk = np.linalg.norm(np.diff(p, n=3, axis=1), axis=-1).mean((0, 2)) * lesson05.FPS**3  # (T - 3,)
    cross = (lesson05.SKIP + np.arange(len(jerk)) + 2) % word_len == 0
    return {"at_boundary": float(jerk[cross].mean()), "inside_word": float(jerk[~cross].mean())}


@torch.no_grad()
def teacher_forced(model, data: dict) -> dict:
    """foot_quality of the held-out walks and jogs reconstructed with the posterior (the data's words), and of
    the two halves swapped in: the reconstructed joint rotations with the true root features ("legs_only"),
    the true rotations with the reconstructed root features ("root_only"); the data itself ("data")."""
    keep = [lesson05.ACTIONS[a] in lesson05.GAITS for a in data["action_id"].tolist()]
    d = lesson05.subset(data, keep)
    x_hat = model.reconstruct(d["x"], d["action_id"], d["style_id"], torch.Generator().manual_seed(0))["x_hat"]
    legs, root = x_hat.clone(), d["x"].clone()
    legs[..., -6:], root[..., -6:] = d["x"][..., -6:], x_hat[..., -6:]
    return {k: lesson05.foot_quality(lesson05.to_motions(dict(d, x=v.float())))
            for k, v in (("data", d["x"]), ("reconstruction", x_hat), ("legs_only", legs), ("root_only", root))}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--only", nargs="*", default=None, choices=sorted([*VARIANTS, SHIPPED, *TEMPERATURES]))
    parser.add_argument("--merge", action="store_true", help="add to the rows already in --out")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    proto = bench.load_protocol(bench.BenchSpec())
    old = json.loads(args.out.read_text()) if args.merge and args.out.exists() else {}
    result = {"question": __doc__.split("\n\n")[0], "variants": dict(old.get("variants", {}))}
    if "merged_rows" in old:  # rows run elsewhere and merged in, each with its own provenance
        result["merged_rows"] = old["merged_rows"]
    mocap = {}
    for s in range(5):
        _, b = bench.halves(len(proto.clips), s)
        mocap[s] = bench.quality(bench.Sample(proto.truth[b], proto.skeletons(b)), [], s, distribution=False)
    result["mocap_benchmark"] = {k: float(np.mean([r[k] for r in mocap.values()]))
                                 for k in ("foot_skate", "penetration", "jitter")}
    # the training sequences of each action ending in a held pose (a clip shorter than 3 s, padded by to_sequence):
    # what a model that fits its data well learns about how that action ends
    train = lesson05.load_data("full")["train"]
    held = lesson05.held_frames(train["x"])
    result["training_held_frames"] = {
        act: {"padded_fraction": float((held[train["action_id"].numpy() == i] > 0).mean()),
              "mean_held_frames": float(held[train["action_id"].numpy() == i].mean()),
              "max_held_frames": int(held[train["action_id"].numpy() == i].max())}
        for i, act in enumerate(lesson05.ACTIONS)}
    for name in args.only or [*VARIANTS, SHIPPED, *TEMPERATURES]:
        if name == SHIPPED or name in TEMPERATURES:  # no training: the pretrained model, on the reproduction's data
            model, data = lesson05.load_model("hvrnn_proposed"), lesson05.load_data("full")
            row = {"retarget": lesson05.RETARGET, "steps": lesson05.PROPOSED_STEPS, "dae_steps": lesson05.DAE_STEPS}
            if name in TEMPERATURES:
                model.prior = TemperedPrior(model.prior, TEMPERATURES[name])
                row["z_temperature"] = TEMPERATURES[name]
        else:
            retarget, steps, overrides = VARIANTS[name]
            model, data, seconds = train_variant(retarget, steps, overrides)
            row = {"retarget": retarget, "steps": steps, "overrides": overrides, "train_seconds": seconds}
        samples = lesson05.gait_samples(model, 120, seed=0)
        row |= {"benchmark": on_benchmark(model, proto), "teacher_forced": teacher_forced(model, data["test"]),
               "samples_legs_vs_root": legs_vs_root(samples), "samples_word_jerk": word_boundary_jerk(samples),
               "collapse_200_frames": long_collapse(model)}
        result["variants"][name] = rounded(row, 4)
        print(name, json.dumps(result["variants"][name]), file=sys.stderr, flush=True)
        write_study_result(args.out, result, checkpoints=[lesson05.CHECKPOINTS / "hvrnn_proposed.pt"]
                           if name == SHIPPED or name in TEMPERATURES else [])
    return 0


if __name__ == "__main__":
    sys.exit(main())
