"""Why a designed motion fails, window by window: eq. (19)'s terms at the end of every window's search, and the root's
distance to the curve and arc length reached every 17 frames -> studies/04_map_control/control_window_energies.json

    OMP_NUM_THREADS=1 TQDM_DISABLE=1 python studies/04_map_control/control_window_energies.py                 # the walking circle
    python studies/04_map_control/control_window_energies.py --curve s_curve --gait run --out /tmp/x.json

The case is one of course_lib.experiments.control (seed 0, ours: candidates -> PSO -> L-BFGS) *without* the retry of
windows whose control energy stays high (``DesignConfig.retry_control=None``, the design before that rule); lesson 04
reads the json for the walking circle, the case that failed that way.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import torch

from course_lib.control import DesignConfig, design_motion
from course_lib.control.energy import arc_lengths, arc_position, nearest_on_polyline
from course_lib.experiments import control as X
from course_lib.results import provenance

OUT = Path(__file__).with_name("control_window_energies.json")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--curve", default="circle_r2", choices=X.CURVES)
    ap.add_argument("--gait", default="walk", choices=sorted(X.PACE))
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    import time

    c = X.curve(args.curve)
    t0 = time.perf_counter()
    m = design_motion(c, X.seconds_for(c, args.gait), args.gait, seed=0,
                      config=DesignConfig(retry_control=None, retry_rise=None))
    seconds = time.perf_counter() - t0
    xz = m.root_positions[:, [0, 2]]
    _, dist = nearest_on_polyline(torch.from_numpy(xz), torch.from_numpy(c))
    L, s, hops = float(arc_lengths(c)[-1]), 0.0, []
    for i in range(0, len(m), 17):
        s = arc_position(c, xz[i], s, s + 3.3)
        hops.append({"frame": i, "dist_m": float(dist[i]), "max_dist_next_17_m": float(dist[i:i + 17].max()),
                     "arc_m": s, "due_m": L * i / (len(m) - 1)})
    windows = [{k: round(v, 2) for k, v in w["terms"].items()} for w in m.meta["design"]["windows"]]
    out = {"command": f"OMP_NUM_THREADS=1 TQDM_DISABLE=1 python studies/04_map_control/control_window_energies.py --curve {args.curve} "
                      f"--gait {args.gait}", "case": f"{args.curve}/{args.gait}/ours",
           **X.measure_design(m, c), "seconds": seconds, "hops": hops, "windows": windows}
    # the command above is the script's own (it spells out --curve and --gait, which the argv may leave out)
    prov = provenance(argv=None if argv is None else [__file__, *argv])
    out = {**out, "commit": prov["commit"], "checkpoints_sha256": prov["checkpoints_sha256"]}
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps({k: v for k, v in out.items() if k not in ("hops", "windows")}, indent=1))
    for h, w in zip(hops, windows, strict=False):
        print(h["frame"], round(h["dist_m"], 3), round(h["arc_m"] - h["due_m"], 2), w)
    return out


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
