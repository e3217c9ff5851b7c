"""Lesson 04 side experiment (issue 16): is the sampling stage needed when the search runs over the paper's variables?

On our data L-BFGS from one RNN sample is as good as candidates -> PSO -> L-BFGS (the equal-time table), against the
paper's claim.  Our search's variables are the sampler's own noise (rollout.py), so every point it visits is a motion
of the RNN; the paper's are the frames s and d.  The guess: over frames the start matters more.  The test: the same
cases, budgets and seeds with ``DesignConfig(space="frames")`` (design._solve_window_frames), ours and L-BFGS alone
(also with 4x its evaluations), beside the recorded noise-space rows of ``experiments.control.offline_eval``.

    python studies/04_map_control/control_frame_space.py --out studies/04_map_control/control_frame_space_results.json   # ~5 min, one core
"""

import argparse
import json
from dataclasses import replace

import torch

from course_lib.control import design_motion
from course_lib.control.lbfgs import LbfgsConfig
from course_lib.experiments import control as X
from course_lib.experiments.gmm_rnn import rounded
from course_lib.results import provenance

CASES = (("s_curve", "walk"), ("line", "run"), ("circle_r2", "walk"), ("u_turn", "run"))
KEYS = ("mean_root_to_curve_m", "end_distance_m", "foot_skate_m_s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    recorded = X.recorded_results()["offline"]
    res = {"command": f"python studies/04_map_control/control_frame_space.py --out {args.out}", "seed": 0, "cases": {}}
    for name, gait in CASES:
        c = X.curve(name)
        row = {f"noise/{m}": {k: recorded[f"{name}/{gait}/{m}"][k] for k in KEYS + ("seconds",)}
               for m in ("ours", "lbfgs")}
        lb = X._config("lbfgs")
        for label, cfg in (("frames/ours", replace(X._config("ours"), space="frames")),
                           ("frames/lbfgs", replace(lb, space="frames")),
                           ("frames/lbfgs x4", replace(lb, space="frames", lbfgs=LbfgsConfig(iterations=160)))):
            m = design_motion(c, X.seconds_for(c, gait), gait, seed=0, config=cfg)
            w = m.meta["design"]["windows"]
            row[label] = {**{k: X.measure_design(m, c)[k] for k in KEYS}, "seconds": m.meta["design"]["seconds"],
                          "first_window": {"start": w[0]["pso"][0], "after_pso": w[0]["pso"][-1],
                                           "end": w[0]["terms"]["total"], "control_end": w[0]["terms"]["control"]}}
        res["cases"][f"{name}/{gait}"] = row
        print(name, gait, {k: round(v["end_distance_m"], 3) for k, v in row.items()}, flush=True)
    res = {**res, **provenance()}  # the command run, the commit, the checkpoints' sha256
    with open(args.out, "w") as f:
        f.write(json.dumps(rounded(res), indent=1) + "\n")


if __name__ == "__main__":
    main()
