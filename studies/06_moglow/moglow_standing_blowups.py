"""Lesson 06 study: when and how do long-trained MoGlow samples blow up under a standing control?

    python studies/06_moglow/moglow_standing_blowups.py --state runs/moglow_long_60000.pt --extra-clips 3600 --out studies/06_moglow/moglow_standing_blowups_results.json

moglow_dropout_history found that models trained 20000 steps blow up (a pose value beyond 20 sd) in 2 of 32 (10
of 32 with more data) 10-s samples told to stand, where the 5000-step model never does.  For the model in a
`moglow_long_run` state file: 32 standing samples per sampling seed (0-2) at T = 1, and at T = 0 for seed 0;
for each sample that blows up, the first frame beyond 10 sd and beyond 20 sd (the training windows hold 80 frames
of which 70 are predicted), and the largest value over the first 70 frames; the same for 32 held-out controls.
The start poses are held-out windows chosen at random (`experiments.moglow.start_frames`), so the control jumps at
frame tau from the start window's own to the one asked for.  Two more conditions test that jump: the standing
control reached by a 1-s linear ramp from the start window's last control, and the held-out controls each started
from its own window's first tau frames (no jump).
"""

import argparse

import numpy as np
import torch

from course_lib.checksums import sha256_file
from course_lib.experiments import moglow as E
from course_lib.models.moglow import MoGlow, MoGlowConfig
from course_lib.results import write_study_result

SAMPLES = 32
SEEDS = (0, 1, 2)


def onsets(poses: torch.Tensor) -> dict:
    """Standardised poses (N, T, D) -> per sample the first frame (after tau) whose largest |value| passes 10 sd and
    E.BLOW_UP sd (None: never), and how many samples blow up.  (Samples that stay sane peak near 5 sd.)"""
    peak = torch.nan_to_num(poses[:, E.TAU:], nan=np.inf).abs().amax(-1)  # (N, T - tau)
    first = lambda above: [int(row.nonzero()[0]) if row.any() else None for row in above]  # noqa: E731
    out = {"exploded": int(E.exploded(poses).sum()), "beyond_10sd": first(peak > 10.0),
           "beyond_blow_up": first(peak > E.BLOW_UP)}
    out["first_70_frames_peak_sd"] = [float(p) for p in peak[:, :E.WINDOW - E.TAU].amax(-1)]
    return out


def model_from_state(state, pose_dim: int) -> tuple[MoGlow, dict]:
    """A `moglow_long_run` state file -> (its model, in eval mode; the saved dict)."""
    saved = torch.load(state, weights_only=True)
    run = saved["run"]  # states written since train_resumable checks the config carry it
    model = MoGlow(MoGlowConfig(**run["config"]) if "config" in run else E.config_for(run["name"], pose_dim))
    model.load_state_dict(saved["model"])
    return model.eval(), saved


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--state", required=True, help="a moglow_long_run state file")
    parser.add_argument("--extra-clips", type=int, default=0, help="as the run that wrote the state")
    args = parser.parse_args()
    torch.set_num_threads(1)
    data = E.load_data("full", extra_clips=args.extra_clips)
    model, saved = model_from_state(args.state, data.pose_dim)
    frames = E.TAU + int(10 * E.FPS)
    standing = E.constant_control(data, SAMPLES, frames)
    out = {"state_sha256": sha256_file(args.state), "run": saved["run"],
           "step": saved["step"], "frames_after_tau": frames - E.TAU, "standing": {}, "held_out_controls": {}}
    for seed in SEEDS:
        out["standing"][f"T=1 seed {seed}"] = onsets(E.generate(model, data, standing, seed)[0])
    out["standing"]["T=0 seed 0"] = onsets(E.generate(model, data, standing, 0, 0.0)[0])
    held = data.test["controls"][:SAMPLES]
    out["held_out_controls"]["T=1 seed 0"] = onsets(E.generate(model, data, held, 0)[0])
    own = (data.test["poses"][:SAMPLES, :E.TAU], held[:, :E.TAU])
    out["held_out_controls"]["T=1 seed 0, own start"] = onsets(E.generate(model, data, held, 0, starts=own)[0])
    out["standing_ramped"] = {}
    for seed in SEEDS:
        x0, c0 = E.start_frames(data, SAMPLES, seed)
        ramp = torch.linspace(0, 1, int(E.FPS) + 1)[None, :, None]  # 1 s from the start's last control to standing
        ramped = standing.clone()
        ramped[:, E.TAU:E.TAU + len(ramp[0])] = c0[:, -1:] + ramp * (standing[:, :1] - c0[:, -1:])
        out["standing_ramped"][f"T=1 seed {seed}"] = onsets(E.generate(model, data, ramped, seed, starts=(x0, c0))[0])
    write_study_result(args.out, out)
    print({f"{part} {k}": v["exploded"] for part in ("standing", "standing_ramped", "held_out_controls")
           for k, v in out[part].items()})


if __name__ == "__main__":
    main()
