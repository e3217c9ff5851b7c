"""Do the training sequences themselves skate on the skeleton the samples are played on?  Every lesson-05
sample is decoded on the canonical skeleton; the subjects' legs are 0.91 to 1.10 times as long.  The walk and
jog sequences (90 frames at 30 fps, the first 15 dropped as in lesson 07) are measured on their own skeletons,
on the canonical one, on the canonical one with the root's velocities and height retargeted
(`lesson05.retarget_root`), and after the denoising autoencoder the lesson trains on them.  No model.

    OMP_NUM_THREADS=1 python studies/05_hierarchical_vrnn/hvrnn_skate_data.py \\
        --out studies/05_hierarchical_vrnn/hvrnn_skate_data_results.json
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch

from course_lib.experiments import hvrnn as lesson05
from course_lib.results import write_study_result


def gaits(data: dict) -> dict:
    return lesson05.subset(data, [lesson05.ACTIONS[a] in lesson05.GAITS for a in data["action_id"].tolist()])


def measure(split: str, retarget: bool) -> dict:
    """foot_quality of one split's walk/jog sequences: decoded on the canonical skeleton, and after the DAE
    trained 300 steps (48 epochs, the recipe before) and DAE_STEPS (the paper's 300 epochs)."""
    data = lesson05.load_data("full", retarget=retarget)
    d = gaits(data[split])
    out = {"canonical": lesson05.foot_quality(lesson05.to_motions(d))}
    if split == "train":
        for steps, key in ((300, "canonical_after_dae"), (lesson05.DAE_STEPS, "canonical_after_dae_300_epochs")):
            dae, _ = lesson05.train_dae(steps, 0, "full", retarget=retarget)
            out[key] = lesson05.foot_quality(lesson05.to_motions(dict(d, x=lesson05.clean(dae, d["x"]))))
    clips = data[f"{split}_clips"]
    own = [m.resample(lesson05.FPS)[: lesson05.SEQ_LEN] for m in clips if m.action in lesson05.GAITS]
    out["own_skeleton"] = lesson05.foot_quality(own)
    legs = [m.skeleton.leg_length() for m in clips]
    out["leg_length_range_m"] = [min(legs), max(legs)]
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    from course_lib.skeleton import Skeleton

    result = {"question": __doc__.split("\n\n")[0], "canonical_leg_length_m": Skeleton.canonical().leg_length(),
              "before_retarget": {s: measure(s, False) for s in ("train", "test")},
              "retargeted": {s: measure(s, True) for s in ("train", "test")}}
    write_study_result(args.out, result)
    print(result, file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
