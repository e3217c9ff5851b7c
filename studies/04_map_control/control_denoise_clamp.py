"""Lesson 04 side experiment (issue 16): the denoised motion's foot skate, root or pose?  A clamp test.

studies/04_map_control/control_denoise_contact.py found that neither design.py's contact rule nor a 100x eq. (18) lowers the denoised
motion's skate much.  This tool mixes each denoised clip with its clean original, part by part, and scores each mix
with `evaluation.foot_skate`:

- denoised root (positions and the root's rotation) + clean joints' rotations;
- clean root + denoised joints;
- the denoised root's positions alone (clean rotations everywhere);
- the denoised root's rotation alone.

The same 8 scored held-out clips and noise seed as ``experiments.control.denoise_eval`` (shipped settings).

    python studies/04_map_control/control_denoise_clamp.py --out studies/04_map_control/control_denoise_clamp_results.json   # ~1 min, one core
"""

import argparse
import json
from dataclasses import replace

import numpy as np
import torch

from course_lib.control import denoise
from course_lib.datasets import noisy_copies
from course_lib.evaluation import foot_skate
from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import rounded
from course_lib.results import provenance


def mixes(out, clean) -> dict:
    """denoised and clean Motions of one clip -> {mix name: Motion}."""
    root_rot = clean.rotations.copy()
    root_rot[:, 0] = out.rotations[:, 0]
    joints = out.rotations.copy()
    joints[:, 0] = clean.rotations[:, 0]
    return {
        "denoised": out,
        "clean": clean,
        "denoised root + clean joints": replace(out, rotations=root_rot),
        "clean root + denoised joints": replace(clean, rotations=joints),
        "denoised root positions only": replace(clean, root_positions=out.root_positions),
        "denoised root rotation only": replace(clean, rotations=root_rot),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    clean = C.denoise_clips()
    noisy = noisy_copies(clean, 1)
    per = [mixes(denoise(n, seed=0), c) for n, c in zip(noisy, clean, strict=True)]
    skate = {k: float(foot_skate([p[k] for p in per])) for k in per[0]}
    root_err = [np.linalg.norm(p["denoised"].root_positions - p["clean"].root_positions, axis=-1) for p in per]
    root_step = [np.linalg.norm(np.diff(p["denoised"].root_positions - p["clean"].root_positions, axis=0), axis=-1)
                 for p in per]
    results = {"command": "python studies/04_map_control/control_denoise_clamp.py --out studies/04_map_control/control_denoise_clamp_results.json",
               "clips": len(clean), "foot_skate_m_s": skate,
               "root_error_m": float(np.mean(np.concatenate(root_err))),
               "root_error_change_per_frame_m": float(np.mean(np.concatenate(root_step)))}
    for k, v in skate.items():
        print(f"{k:32s} skate {v:.4f} m/s")
    print(f"root error {results['root_error_m']:.4f} m, "
          f"its change per frame {results['root_error_change_per_frame_m']:.4f} m")
    results = {**results, **provenance()}  # the command run, the commit, the checkpoints' sha256
    with open(args.out, "w") as f:
        json.dump(rounded(results), f, indent=1)


if __name__ == "__main__":
    main()
