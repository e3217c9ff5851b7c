"""Issue 16's curve-end shortfall, measured: where along the curve do designed walks fall behind, and does the
RNN walk too slowly for the requested duration?  -> studies/04_map_control/control_shortfall.json

    OMP_NUM_THREADS=1 TQDM_DISABLE=1 python studies/04_map_control/control_shortfall.py          # ~7 min on one core
    python studies/04_map_control/control_shortfall.py --curves line --out /tmp/x.json

For each curve (`course_lib.experiments.control.curve`, at the durations of the first recorded run, SECONDS;
walking, seed 0) and each progress rule of ``DesignConfig``:
"net" (the previous rule: each window's net root displacement per second, in any direction, asked to be the
curve's length / seconds) and "arc" (the arc length gained along the curve by the window's last kept frame,
paced so that the end is due when the time is up), the arc length reached every 17 frames against the schedule,
the end distance and the mean distance to the curve.  Beside them, the RNN's own walking speed: the net speed of
free-running samples (no control) from held-out walking starts, against the speed each curve asks for.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

from course_lib.control import DesignConfig, design_motion
from course_lib.control.design import default_prior, prepare_start
from course_lib.control.energy import arc_lengths, arc_position
from course_lib.experiments import control as C
from course_lib.results import provenance

OUT = Path(__file__).with_name("control_shortfall.json")
SECONDS = {"line": 5.0, "circle_r2": 10.5, "s_curve": 5.5}  # the durations studies/04_map_control/control_results.json was run at


def free_walk_speeds(n: int = 8, seconds: float = 5.0) -> list[float]:
    """Net root speed (m/s) of the RNN run without control for ``seconds`` from n held-out walking starts."""
    prior = default_prior()
    out = []
    for seed in range(n):
        raw0, _, start = prepare_start(None, "walk", seed, None, prior)
        state = prior.start_state(raw0, start.skeleton)
        frames = prior.sample(raw0.double(), state, int(seconds * 30) - 2, start.skeleton,
                              torch.Generator().manual_seed(seed), bias=1.0)
        from course_lib.representations import decode_state_features

        m = decode_state_features(torch.cat((raw0[0], frames[0]), 0).numpy(), start.skeleton, 30.0, (0, 0, 0))
        out.append(float(np.linalg.norm(m.root_positions[-1, [0, 2]] - m.root_positions[0, [0, 2]]) / seconds))
    return out


def schedule(m, curve, hop: int = 17) -> dict:
    """The arc length reached (monotone, as design's progress) every ``hop`` frames, against the time's share."""
    L, T = float(arc_lengths(curve)[-1]), len(m) - 1
    s, reached, due = 0.0, [], []
    for i in range(0, len(m), hop):
        s = arc_position(curve, m.root_positions[i, [0, 2]], s, s + 2.0)
        reached.append(round(s, 3))
        due.append(round(L * i / T, 3))
    return {"frames": list(range(0, len(m), hop)), "arc_reached_m": reached, "arc_due_m": due}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--curves", default="line,circle_r2,s_curve")
    ap.add_argument("--rules", default="net,arc")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    speeds = free_walk_speeds()
    cmd = "OMP_NUM_THREADS=1 TQDM_DISABLE=1 python studies/04_map_control/control_shortfall.py " + " ".join(argv or sys.argv[1:])
    res = {"command": cmd.strip(),
           "rnn_free_walk_speed_m_s": {"median": float(np.median(speeds)), "each": speeds}, "rows": {}}
    print("RNN free walk speed m/s", np.round(speeds, 2), flush=True)
    for name in args.curves.split(","):
        curve, seconds = C.curve(name), SECONDS[name]
        asked = float(arc_lengths(curve)[-1]) / seconds
        for rule in args.rules.split(","):
            t0 = time.perf_counter()
            m = design_motion(curve, seconds, "walk", seed=0, config=DesignConfig(progress=rule))
            row = {**C.measure_design(m, curve), "asked_speed_m_s": asked,
                   "seconds": round(time.perf_counter() - t0, 1), **schedule(m, curve)}
            res["rows"][f"{name}/{rule}"] = row
            print(name, rule, {k: (round(v, 3) if isinstance(v, float) else v) for k, v in row.items()}, flush=True)
            res = {**res, **provenance(argv=None if argv is None else [__file__, *argv])}  # command run, commit, sha256
            args.out.write_text(json.dumps(res, indent=1) + "\n")
    return res


if __name__ == "__main__":
    main()
