"""Lesson 06 study: is one step's precision limited by the conditioning LSTM's size?

    python studies/06_moglow/moglow_lstm_size.py --hidden 128 256 --steps 2500 --out studies/06_moglow/moglow_lstm_size_results.json

The no-dropout MoGlow (the `moglow_nodrop` recipe, so that the full history is an input it trained on) retrained in
memory with each LSTM width in ``--hidden`` (units; the course's 128, the paper 512) for the same ``--steps`` steps (the
pretrained one: 128 units, 5000 steps), then moglow_teacher_forced's measure: the pose drawn given the mocap's history at T = 0 and T = 1, its toes
against the mocap's one frame earlier, and the one-step pose error; plus the held-out NLL.  Nothing is written to
checkpoints/.
"""

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np
import torch

from course_lib.experiments import moglow as E
from course_lib.representations import root_start
from course_lib.results import write_study_result

HERE = Path(__file__).resolve().parent


def _study(name: str):
    spec = importlib.util.spec_from_file_location(name, HERE / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--hidden", type=int, nargs="+", default=[128, 256])
    parser.add_argument("--steps", type=int, default=2500)
    args = parser.parse_args()
    torch.set_num_threads(1)
    tf = _study("moglow_teacher_forced")
    t0 = time.perf_counter()
    data = E.load_data("full")
    p, c = data.test["poses"], data.test["controls"]
    starts = [root_start(m) for m in data.test_clips]
    skel = data.test_clips[0].skeleton
    toes = [skel.index("LeftToeBase"), skel.index("RightToeBase")]
    mocap = data.positions(p, c, starts)
    out = {"command": "python " + " ".join(sys.argv), "steps": args.steps, "models": {}}
    for hidden in args.hidden:
        t1 = time.perf_counter()
        E.MODELS["moglow_nodrop"] = {"dropout": 0.0, "hidden": hidden}
        model, _ = E.train_model("moglow_nodrop", data, args.steps, seed=0)
        row = {"train_seconds": time.perf_counter() - t1, "nll_per_frame": E.nll_per_frame(model, data.test)}
        for temp in (1.0, 0.0):
            pred = data.positions(tf.one_step(model, p, c, temp), c, starts)
            row[f"T={temp}"] = {"teacher_forced_skate": tf.pair_skate(mocap, pred, toes),
                                "pose_rmse_m": float(np.sqrt(((pred - mocap)[:, E.TAU:] ** 2).sum(-1).mean()))}
        out["models"][f"hidden {hidden}"] = row
        print(hidden, row, flush=True)
    out["seconds"] = time.perf_counter() - t0
    write_study_result(args.out, out)


if __name__ == "__main__":
    main()
