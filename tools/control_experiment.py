"""Lesson 04's offline must-show, measured: design_motion (PSO + L-BFGS) on a line, a circle of radius 2 m and
an S-curve, walking, against the baselines of issue 16 -> tools/control_results.json.

    OMP_NUM_THREADS=1 TQDM_DISABLE=1 python tools/control_experiment.py            # -> tools/control_results.json
    python tools/control_experiment.py --curves line --methods ours,random --out /tmp/x.json

Methods: ours (candidates -> PSO -> L-BFGS per window), lbfgs (L-BFGS from one RNN sample, no PSO),
pso (PSO, no L-BFGS), best_of_n (the best of 64 RNN samples per window, no gradients), random (the RNN run
without control), greedy (each frame an RNN sample whose root step is turned and scaled towards a point 0.5 m
ahead on the curve).  Every method starts from the same held-out start frame (seed), placed at the curve's start.
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
import time
from pathlib import Path

import numpy as np
import torch

from course_lib.control import DesignConfig, design_motion
from course_lib.control.design import default_prior, prepare_start
from course_lib.control.energy import nearest_on_polyline
from course_lib.control.kinematics import heading_yaw
from course_lib.evaluation import foot_skate
from course_lib.representations import decode_state_features

OUT = Path(__file__).with_name("control_results.json")


def curves() -> dict:
    """name -> (curve (K, 2), seconds): ~1.2 m/s walking."""
    t = np.linspace(0, 2 * np.pi, 73)
    circle = np.stack((2 - 2 * np.cos(t), 2 * np.sin(t)), -1)  # from (0, 0) heading +Z, radius 2 m
    s = np.linspace(0, 1, 60)
    scurve = np.stack((0.8 * np.sin(2 * np.pi * s), 6 * s), -1)
    return {"line": (np.array([[0.0, 0.0], [0.0, 6.0]]), 5.0), "circle_r2": (circle, 10.5), "s_curve": (scurve, 5.5)}


CONFIGS = {
    "ours": DesignConfig(),
    "lbfgs": DesignConfig(candidates=1, use_pso=False),
    "pso": DesignConfig(use_lbfgs=False),
    "best_of_n": DesignConfig(candidates=64, use_pso=False, use_lbfgs=False),
}


def _run_free(curve, seconds, seed, greedy: bool):
    """The RNN with no control (random) or steered frame by frame (greedy)."""
    prior = default_prior()
    seg = curve[1] - curve[0]
    init0 = (curve[0, 0], curve[0, 1], float(heading_yaw(torch.from_numpy(seg))))
    raw0, init0, start = prepare_start(None, "walk", seed, init0, prior)
    g = torch.Generator().manual_seed(seed)
    state, prev = prior.start_state(raw0, start.skeleton), raw0.double()
    T = int(round(seconds * 30)) - 2
    L = float(np.linalg.norm(np.diff(curve, axis=0), axis=1).sum())
    frames, (x, z, yaw) = [], (float(init0[0]), float(init0[1]), float(init0[2]))
    # frame 0 at the curve's start; frame 1's step is the start clip's
    c, s_ = math.cos(yaw), math.sin(yaw)
    d1 = raw0[0, 1].numpy()
    x, z, yaw = x + c * d1[0] + s_ * d1[1], z - s_ * d1[0] + c * d1[1], yaw + d1[2]
    ct = torch.from_numpy(curve)
    for _ in range(T):
        f = prior.sample(prev, state, 1, start.skeleton, g, bias=1.0)  # (1, 1, D)
        if greedy:
            near, _ = nearest_on_polyline(torch.tensor([[x, z]], dtype=torch.float64), ct)
            ahead = _ahead(curve, near[0].numpy(), 0.5)
            want = math.atan2(ahead[0] - x, ahead[1] - z)
            turn = (want - yaw + math.pi) % (2 * math.pi) - math.pi
            f[0, 0, 2] = float(np.clip(turn, -0.1, 0.1))  # dyaw towards the point ahead, at most 0.1 rad/frame
            step = float(torch.hypot(f[0, 0, 0], f[0, 0, 1]))
            if step > 1e-6:
                f[0, 0, 0:2] *= (L / seconds / 30) / step  # the speed that reaches the end in time
        state = prior.advance(prev, f, state, start.skeleton)
        prev = torch.cat((prev, f), 1)[:, -2:]
        d = f[0, 0].numpy()
        c, s_ = math.cos(yaw), math.sin(yaw)
        x, z, yaw = x + c * d[0] + s_ * d[1], z - s_ * d[0] + c * d[1], yaw + d[2]
        frames.append(f[0])
    feats = torch.cat([raw0[0]] + frames, 0).numpy()
    return decode_state_features(feats, start.skeleton, 30.0, tuple(float(v) for v in init0))


def _ahead(curve, point, dist):
    """The point ``dist`` metres further along the polyline than ``point`` (which lies on it)."""
    seg = np.diff(curve, axis=0)
    lens = np.linalg.norm(seg, axis=1)
    d = np.linalg.norm(curve[:-1] - point, axis=1) + np.linalg.norm(curve[1:] - point, axis=1) - lens
    k = int(np.argmin(d))
    s = np.concatenate(([0.0], np.cumsum(lens)))[k] + np.linalg.norm(point - curve[k]) + dist
    s = min(s, float(lens.sum()))
    j = min(int(np.searchsorted(np.cumsum(lens), s)), len(seg) - 1)
    return curve[j] + seg[j] * ((s - np.concatenate(([0.0], np.cumsum(lens)))[j]) / max(lens[j], 1e-9))


def measure(m, curve) -> dict:
    xz = torch.from_numpy(m.root_positions[:, [0, 2]])
    _, dist = nearest_on_polyline(xz, torch.from_numpy(curve))
    return {"mean_root_to_curve_m": float(dist.mean()), "max_root_to_curve_m": float(dist.max()),
            "end_distance_m": float(np.linalg.norm(m.root_positions[-1, [0, 2]] - curve[-1])),
            "foot_skate_m_s": float(foot_skate([m])), "frames": len(m)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--curves", default="line,circle_r2,s_curve")
    ap.add_argument("--methods", default="ours,lbfgs,pso,best_of_n,random,greedy")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    cmd = " ".join(shlex.quote(a) for a in (sys.argv[1:] if argv is None else argv))
    results = {"command": f"OMP_NUM_THREADS=1 TQDM_DISABLE=1 python tools/control_experiment.py {cmd}".strip(),
               "seed": args.seed, "gait": "walk", "rows": {}}
    for name in args.curves.split(","):
        curve, seconds = curves()[name]
        for method in args.methods.split(","):
            t0 = time.perf_counter()
            if method in CONFIGS:
                m = design_motion(curve, seconds, "walk", seed=args.seed, config=CONFIGS[method])
            else:
                m = _run_free(curve, seconds, args.seed, greedy=method == "greedy")
            row = measure(m, curve)
            row["seconds"] = round(time.perf_counter() - t0, 1)
            results["rows"][f"{name}/{method}"] = row
            print(name, method, {k: round(v, 3) for k, v in row.items()}, flush=True)
            args.out.write_text(json.dumps(results, indent=1))
    return results


if __name__ == "__main__":
    main()
