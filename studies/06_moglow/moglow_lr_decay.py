"""Lesson 06 side experiment (issue 17): does a learning rate that falls at the end of the same 5000 steps (the
paper decays its own, a Noam schedule over 80k steps; the shipped models keep 1e-3 throughout) lower the per-frame
sampling noise that keeps the zero-control stepping ratio at 0.30?  The dropout and no-dropout models train with
``E.STEPS`` steps, seed 0, the same data, LR 1e-3 until ``--decay-from`` of the steps, then a half cosine to 1 % of
it (``experiments.moglow.lr_factor``), into a folder of their own; then the held-out NLL per frame and the
zero-control stepping speed over sampling seeds 0-4 (studies/06_moglow/moglow_zero_control_seeds.py's measure), beside the
models in checkpoints/ (run "shipped" of the results file).  Writes nothing to checkpoints/.  The recorded
studies/06_moglow/moglow_lr_decay_results.json was made before the retraining, so its "shipped" run is the constant-LR models
of commit 9b2cd86 (lesson 06 labels it so); the checkpoints/ of today are its "decayed" run, retrained by
python -m course_lib.reproduce moglow.

    python studies/06_moglow/moglow_lr_decay.py --folder /tmp/mg_decay --out studies/06_moglow/moglow_lr_decay_results.json  # ~25 min
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

from course_lib.experiments import moglow as E
from course_lib.results import provenance, rounded

sys.path.insert(0, str(Path(__file__).resolve().parent))
from moglow_zero_control_seeds import stepping_speed  # noqa: E402

SEEDS = tuple(range(5))
NAMES = ("moglow", "moglow_nodrop")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--decay-from", type=float, default=0.6, help="fraction of the steps at constant LR")
    parser.add_argument("--folder", type=Path, required=True, help="where the checkpoints of this run go")
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    if args.folder.resolve() == E.CHECKPOINTS.resolve():
        raise SystemExit("--folder must not be checkpoints/ (this experiment does not replace the shipped models)")
    args.folder.mkdir(parents=True, exist_ok=True)
    data = E.load_data("full")
    train_seconds = {}
    for name in NAMES:
        t0 = time.perf_counter()
        model, hist = E.train_model(name, data, E.STEPS, 0, decay_from=args.decay_from)
        train_seconds[name] = time.perf_counter() - t0
        torch.save(model.state_dict(), args.folder / f"{name}.state.pt")
        print(name, hist, flush=True)
    out = {"command": "python " + " ".join(sys.argv), "decay_from": args.decay_from, "steps": E.STEPS,
           "train_seconds": train_seconds, "seeds": list(SEEDS), "runs": {}}
    for label in ("decayed", "shipped"):
        models = {n: E.load_model(n) for n in NAMES}
        if label == "decayed":
            for n, m in models.items():
                m.load_state_dict(torch.load(args.folder / f"{n}.state.pt", weights_only=True))
        sp = {n: [stepping_speed(m, data, s) for s in SEEDS] for n, m in models.items()}
        ratios = np.array(sp["moglow"]) / np.array(sp["moglow_nodrop"])
        out["runs"][label] = {"test_nll_per_frame": {n: E.nll_per_frame(m, data.test) for n, m in models.items()},
                              "feet_speed": sp, "ratios": ratios.tolist(), "mean": float(ratios.mean()),
                              "max": float(ratios.max())}
        print(label, out["runs"][label]["test_nll_per_frame"], np.round(ratios, 3).tolist(), flush=True)
    out = {**out, **provenance()}  # the command run, the commit, the checkpoints' sha256
    with open(args.out, "w") as f:
        f.write(json.dumps(rounded(out, 5), indent=1) + "\n")


if __name__ == "__main__":
    main()
