"""Lesson 06 study: on the long-trained MoGlow, do the generation-time settings (history rule, temperature) matter?

    python studies/06_moglow/moglow_long_inference.py --state runs/moglow_long_60000.pt --extra-clips 3600 --out studies/06_moglow/moglow_long_inference_results.json

moglow_history_temperature asked this of the 5000-step model: feeding the history unscaled (as StyleGestures'
generator does) slid the feet more, and a lower temperature calmed the shaking, not the sliding.  A model trained
12 times as long (a `moglow_long_run` state file) may read its history better.  Three history rules outside
training: scaled by 1 - dropout (the course's), drawn like training (each history frame of each output frame kept
with probability 1 - dropout, unscaled), and unscaled (the authors'); temperatures 1, 0.5 and 0.  The protocol is
moglow_history_temperature's (held-out clips' own controls and start frames, sampling seeds 0 and 1, known-floor
skate and jitter of the world positions); a sample that blows up (`experiments.moglow.exploded`) is counted and
left out of the scores.  Nothing is trained or written to checkpoints/.
"""

import argparse
import importlib.util
import time
from pathlib import Path

import torch

from course_lib.checksums import sha256_file
from course_lib.experiments import moglow as E
from course_lib.models.moglow import MoGlow
from course_lib.representations import root_start
from course_lib.results import write_study_result

HERE = Path(__file__).resolve().parent
RULES = ("scaled", "drawn", "unscaled")
TEMPERATURES = (1.0, 0.5, 0.0)
SEEDS = (0, 1)


def _study(name: str):
    spec = importlib.util.spec_from_file_location(name, HERE / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def drawn_history(model: MoGlow, seed: int):
    """-> a stand-in for model.condition that zeroes each history frame of its input with probability dropout
    (the training masks, unscaled), drawn from `seed`."""
    condition, c = model.condition, model.config
    gen, width = torch.Generator().manual_seed(seed), c.tau * c.pose_dim

    def masked(inputs, state=None):
        hist = inputs[..., :width].unflatten(-1, (c.tau, c.pose_dim))
        keep = torch.rand(hist.shape[:-1] + (1,), generator=gen) >= c.dropout
        return condition(torch.cat(((hist * keep).flatten(-2), inputs[..., width:]), -1), state)

    return masked


def rule_scores(model, data, rule: str, temperature: float, kept_scores) -> dict:
    """Mean skate and jitter over the sampling seeds of the samples that did not blow up, and how many did."""
    x0, c0 = data.test["poses"][:, :E.TAU], data.test["controls"][:, :E.TAU]
    starts = [root_start(m) for m in data.test_clips]
    runs = []
    for seed in SEEDS:
        model.config.history_scale = rule == "scaled"
        vars(model).pop("condition", None)  # the class's own method
        if rule == "drawn":
            model.condition = drawn_history(model, seed)
        runs.append(kept_scores(data, *E.generate(model, data, data.test["controls"], seed, temperature,
                                                  starts=(x0, c0)), starts))
    row = {k: sum(r[k] for r in runs) / len(runs) for k in ("foot_skate", "jitter") if all(k in r for r in runs)}
    return {**row, "exploded": sum(r["exploded"] for r in runs), "samples": len(SEEDS) * len(starts)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--state", required=True, help="a moglow_long_run state file")
    parser.add_argument("--extra-clips", type=int, default=0, help="as the run that wrote the state")
    args = parser.parse_args()
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    ht = _study("moglow_history_temperature")
    data = E.load_data("full", extra_clips=args.extra_clips)
    model, saved = _study("moglow_standing_blowups").model_from_state(args.state, data.pose_dim)
    starts = [root_start(m) for m in data.test_clips]
    mocap = ht.scores(data, data.test["poses"], data.test["controls"], starts)
    rows = {}
    for rule in RULES:
        for temp in TEMPERATURES:
            row = rule_scores(model, data, rule, temp, ht.kept_scores)
            if "jitter" in row:
                row["jitter_x_mocap"] = row["jitter"] / mocap["jitter"]
            rows[f"history {rule}, T={temp}"] = row
            print(rule, temp, row, flush=True)
    write_study_result(args.out, {"state_sha256": sha256_file(args.state), "run": saved["run"], "step": saved["step"],
                                  "seeds": list(SEEDS), "held_out_clips": len(starts), "mocap": mocap,
                                  "samples": rows, "seconds": time.perf_counter() - t0})


if __name__ == "__main__":
    main()
