"""Lesson 06 study: does the power law of moglow_dropout_history (skate against training steps) hold further out?

    python studies/06_moglow/moglow_long_run.py --steps 60000 --extra-clips 3600 --state runs/moglow_long_60000.pt --out studies/06_moglow/moglow_long_run_60000_results.json

moglow_dropout_history measured the pretrained recipe (dropout 0.95, history scaled) at 5000, 7000 and 20000
steps; a power law through 5000 and 20000 reaches the 0.10 m/s skate target near 350,000 steps.  This run tests
that line at a third point: the same recipe, the LR schedule over its own steps, with 3600 more generated training
clips (at 20000 steps they cured the overfitting and left the skate as it was).  Training is resumable
(`experiments.moglow.train_resumable`): the state file keeps weights, optimiser and step after every 10000 steps,
and the same command continues a run that stopped.  Nothing is written to checkpoints/.  The measures are
moglow_dropout_history's (`measure`; a sample that blows up is counted and left out).  --hidden and
--coupling-hidden widen the model, --flow-steps deepens the flow (capacity, the next suspect):

    python studies/06_moglow/moglow_long_run.py --steps 20000 --extra-clips 3600 --flow-steps 16 --state runs/moglow_long_k16_20000.pt --out studies/06_moglow/moglow_long_run_k16_20000_results.json
"""

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import torch

from course_lib.checksums import sha256_file
from course_lib.experiments import moglow as E
from course_lib.results import write_study_result

HERE = Path(__file__).resolve().parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--steps", type=int, required=True, help="the run's length (the LR schedule spans it)")
    parser.add_argument("--until", type=int, default=None, help="stop (resumably) after this many steps")
    parser.add_argument("--extra-clips", type=int, default=0)
    parser.add_argument("--state", required=True, help="the resumable state file (kept out of checkpoints/)")
    parser.add_argument("--hidden", type=int, default=None, help="the conditioning LSTM's units (default: the preset's)")
    parser.add_argument("--coupling-hidden", type=int, default=None, help="the coupling MLPs' units")
    parser.add_argument("--flow-steps", type=int, default=None, help="K, the steps of flow (the paper's 16)")
    args = parser.parse_args()
    sizes = {k: v for k, v in (("hidden", args.hidden), ("coupling_hidden", args.coupling_hidden),
                               ("steps", args.flow_steps)) if v}
    E.MODELS["moglow"] = {**E.MODELS["moglow"], **sizes}
    torch.set_num_threads(1)
    spec = importlib.util.spec_from_file_location("moglow_dropout_history", HERE / "moglow_dropout_history.py")
    study = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(study)
    t0 = time.perf_counter()
    data = E.load_data("full", extra_clips=args.extra_clips)
    Path(args.state).parent.mkdir(parents=True, exist_ok=True)
    model, step = E.train_resumable("moglow", data, args.steps, Path(args.state), until=args.until, progress=True)
    if step < args.steps:
        print(f"stopped at step {step} of {args.steps}: run the same command to continue")
        return
    out = {"command": "python " + " ".join(sys.argv), "steps": args.steps, "extra_clips": args.extra_clips,
           "hidden": model.config.hidden, "coupling_hidden": model.config.coupling_hidden, "flow_steps": model.config.steps,
           "train_windows": len(data.train["poses"]), "state_sha256": sha256_file(args.state),
           "seconds_this_sitting": time.perf_counter() - t0, **study.measure(model, data)}
    write_study_result(args.out, out)
    print(out)


if __name__ == "__main__":
    main()
