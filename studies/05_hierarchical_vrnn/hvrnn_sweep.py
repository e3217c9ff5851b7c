"""Lesson 05's seed spread: train the four Motion-Cell models (Proposed, NL, NC, SL) for the same 1200 steps with
three training seeds each, and score each on free-running samples and on teacher-forced reconstructions of the
held-out sequences (FID, IS, action accuracy, C2ST).

    python studies/05_hierarchical_vrnn/hvrnn_sweep.py --out studies/05_hierarchical_vrnn/hvrnn_sweep_results.json [--only NAME ...] [--merge] [--smoke]

Each variant is a base model of `experiments.hvrnn.model_specs` with its schedules scaled to the variant's
length, a number of steps, config overrides and a training seed (VARIANTS).  The evaluation is lighter than
the lesson's: one generation seed, 50 samples per action x style.  checkpoints/ come from
`python -m course_lib.reproduce hvrnn` only.  With --merge the variants run are added to (or replace their own
rows in) an existing results file, whose other rows are kept, and the command that made each added row is
recorded under "added_by".
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

VARIANTS = {  # name: (base model, optimiser steps, config overrides, training seed)
    # the four Motion-Cell models at one training length (the ablations' shipped 1200 steps), three training seeds
    # each: are the gaps between them larger than the spread between seeds of one model?
    **{f"{base[6:]}_1200" + (f"_seed{seed}" if seed else ""): (base, 1200, {}, seed)
       for base in ("hvrnn_proposed", "hvrnn_nl", "hvrnn_nc", "hvrnn_sl") for seed in (0, 1, 2)},
}


def run(names, smoke: bool = False, n_per: int = 50) -> dict:
    from course_lib.evaluation import classifier_features, fid, load_classifier
    from course_lib.experiments import hvrnn as H
    from course_lib.models.hvrnn import DaeConfig, DenoisingAutoencoder
    from course_lib.training import load_checkpoint

    mode = "ci" if smoke else "full"
    data = H.load_data(mode)
    dae = load_checkpoint(H.CHECKPOINTS / "hvrnn_dae.pt", DenoisingAutoencoder, DaeConfig)
    train = dict(data["train"], x=H.clean(dae, data["train"]["x"]))
    classifiers = H.train_loss_classifiers(train, 3 if smoke else 300, 0)
    real_test = H.to_motions(data["test"])
    judges = {"action": load_classifier("action"), "style": load_classifier("style")}
    real_features = classifier_features(real_test, judges["action"])
    out = {}
    for name in names:
        base, steps, overrides, seed = VARIANTS[name]
        steps = 4 if smoke else steps
        shipped = H.PROPOSED_STEPS if base == "hvrnn_proposed" else H.STEPS
        spec = H.model_specs(steps / shipped)[base]  # its schedules scaled to the variant's length
        spec = dataclasses.replace(spec, config=dataclasses.replace(spec.config, **overrides), steps=steps)
        t0 = time.perf_counter()
        model, _ = H.train_model(spec, train, classifiers, seed=seed)
        seconds = time.perf_counter() - t0
        with torch.no_grad():
            rec = model.reconstruct(data["test"]["x"], data["test"]["action_id"], data["test"]["style_id"],
                                    torch.Generator().manual_seed(0))["x_hat"]
        recon = H.to_motions(dict(data["test"], x=rec.float()))
        samples = H.to_motions(H.generate(model, 2 if smoke else n_per, H.SEQ_LEN, seed=0))
        s = H.scores(samples, real_test, judges, seed=0)
        out[name] = {"base": base, "steps": steps, "config": overrides, "seed": seed,
                     "train_seconds": round(seconds, 1),
                     "reconstruction_FID": round(fid(real_features, classifier_features(recon, judges["action"]),
                                                     judges["action"]), 1),
                     **{k: round(s[k], 3) for k in ("FID", "IS", "accuracy_action", "C2ST")}}
        print(json.dumps({name: out[name]}), file=sys.stderr, flush=True)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, required=True, help="results JSON (refuses to overwrite unless --force)")
    parser.add_argument("--only", nargs="*", choices=sorted(VARIANTS), help="run only these variants")
    parser.add_argument("--smoke", action="store_true", help="a few steps on CI-sized data (tests)")
    parser.add_argument("--force", action="store_true", help="overwrite --out")
    parser.add_argument("--merge", action="store_true", help="add the variants run to an existing --out, keeping its "
                                                             "other rows")
    args = parser.parse_args(argv)
    if args.merge and not args.out.exists():
        parser.error(f"--merge needs an existing {args.out}")
    if args.out.exists() and not (args.force or args.merge):
        parser.error(f"{args.out} exists; pass --force to overwrite it or --merge to add to it")
    command = "python studies/05_hierarchical_vrnn/hvrnn_sweep.py " + " ".join(argv if argv is not None else sys.argv[1:])
    n_per = 2 if args.smoke else 50
    if args.merge:
        record = json.loads(args.out.read_text())
        if record["n_per_attribute"] != n_per:
            parser.error(f"{args.out} was scored on {record['n_per_attribute']} samples per attribute, not {n_per}")
    else:
        record = {"command": command, "n_per_attribute": n_per, "results": {}}
    torch.set_num_threads(1)
    results = run(args.only or list(VARIANTS), smoke=args.smoke)
    record["results"].update(results)
    from course_lib.results import provenance

    prov = provenance(argv=None if argv is None else [__file__, *argv])  # command run, commit, checkpoints' sha256
    if args.merge:
        record.setdefault("added_by", {}).update({name: command for name in results})
        record.setdefault("added_provenance", {}).update({name: prov for name in results})
    else:
        record = {**record, **prov}
    args.out.write_text(json.dumps(record, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
