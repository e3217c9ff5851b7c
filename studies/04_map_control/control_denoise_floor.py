"""Lesson 04 side experiment (issue 16): where does MAP denoising's error floor come from?  The ablation
(studies/04_map_control/control_denoise_ablation.py) found an input 0.09 cm off the clean motion (make_noisy's spikes alone)
filtered to about 1 cm.  Here the same 8 held-out clips and noise seeds as ``experiments.control.denoise_eval``,
three inputs (the clean clips themselves, the spikes alone, all of make_noisy's noise), and one change at a time:

- the representation round trip alone (encode, fixed columns to their constants, decode; no optimisation);
- each energy term dropped (prior eq. 15, contact eq. 18, eq. 25's root term, its angle term) or d (eq. 16);
- the data-term sigmas; the optimiser's start (the clean motion itself: an oracle; a 5-frame running median of
  the input's eq. (3) features; the input low-passed, control/lowpass.py, which denoise now starts from) and its
  stopping rule (more L-BFGS evaluations, more rounds); the zero initial state; the model's
  own 0.01 sigma floor;
- the energy of eq. (19) (eq. 15 through each motion's own history) of the clean motion, the input and the
  filtered output, and each term's gradient at the clean motion (is it a minimum?  which term pulls, where?).

    python studies/04_map_control/control_denoise_floor.py --inputs clean --out studies/04_map_control/control_denoise_floor_results.json
    python studies/04_map_control/control_denoise_floor.py --inputs spikes --out studies/04_map_control/control_denoise_floor_results.json
    python studies/04_map_control/control_denoise_floor.py --inputs all --out studies/04_map_control/control_denoise_floor_results.json
    # each ~6 min on one core; each run adds its input's rows to the file
"""

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
from scipy.signal import medfilt

from course_lib.control import DenoiseConfig, denoise
from course_lib.control.denoise import denoise_problem
from course_lib.datasets import _clip_seed
from course_lib.experiments import control as C
from course_lib.experiments.gmm_rnn import rounded
from course_lib.representations import decode_state_features, encode_state_features, root_start
from course_lib.results import provenance
from course_lib.synthetic import add_noise

NOISE = {"clean": None, "spikes": {"jitter_sd": 0.0, "root_sd": 0.0, "drop_rate": 0.0}, "all": {}}
BIG = 1e3  # a sigma this wide drops its data term (its weight ~1e-4 of the default's)
BASE_NAME = "from the input (the earlier default)"
# the filter as it was: every row but the low-pass start searches from the input
BASE = DenoiseConfig(start_cutoff_hz=None, sigma_angle=0.05, first_frame="input", held_frames="keep")
CONDITIONS = {  # name -> (DenoiseConfig overrides, start)
    BASE_NAME: ({}, None),
    "no optimisation (round trip only)": ({"iterations": 0}, None),
    "start: the clean motion (oracle)": ({}, "clean"),
    "start: 5-frame running median of the input": ({}, "median"),
    "shipped: 4-Hz low-pass start, held frames filled, sigma 0.03": (
        {"start_cutoff_hz": 4.0, "sigma_angle": 0.03, "held_frames": "fill"}, None),
    "no prior (eq. 15)": ({"weights": {"prior": 0.0}}, None),
    "no contact term (eq. 18)": ({"weights": {"contact": 0.0}}, None),
    "no root data term (sigma_root 1e3)": ({"sigma_root": BIG}, None),
    "no angle data term (sigma_angle 1e3)": ({"sigma_angle": BIG}, None),
    "sigma_angle 0.02 rad (default 0.05)": ({"sigma_angle": 0.02}, None),
    "sigma_angle 0.01 rad": ({"sigma_angle": 0.01}, None),
    "sigma_root 0.003 m (default 0.01)": ({"sigma_root": 0.003}, None),
    "eq. 15 through the history, with d (rounds 0)": ({"rounds": 0}, None),
    "rounds 0, d held at 0 (noise weight 1e6)": ({"rounds": 0, "weights": {"noise": 1e6}}, None),
    "L-BFGS 300 evaluations per round (default 80)": ({"iterations": 300}, None),
    "10 rounds (default 3)": ({"rounds": 10}, None),
    "zero initial state (no eq. 26)": ({"initial_state_steps": 0}, None),
    "model's own sigma floor 0.01 (prior_min_std None)": ({"prior_min_std": None}, None),
}
SKIP_ON_CLEAN = ("start: the clean motion (oracle)",)  # the same as the default there


def median_start(m):
    """A 5-frame running median of each state-feature channel (isolated spikes removed) -> Motion."""
    f = encode_state_features(m)
    f[:, :-2] = np.stack([medfilt(col, 5) for col in f[:, :-2].T], 1)
    return decode_state_features(f, m.skeleton, m.fps, root_start(m))


def channel_groups(skeleton) -> dict:
    """Names -> state-feature columns, for the gradient table."""
    from course_lib.representations import feature_names

    names = feature_names("state_features")
    legs = [i for i, n in enumerate(names) if any(j in n for j in ("UpLeg", "Leg_", "Foot", "Toe"))]
    upper = [i for i in range(6, len(names) - 2) if i not in legs]
    return {"root velocity dx,dz": [0, 1], "root dyaw": [2], "root height": [3], "root pitch,roll": [4, 5],
            "leg joints": legs, "spine, arms, head": upper}


def energy_study(m, n, out) -> dict:
    """Eq. (19) (eq. 15 through each motion's own history) of the clean clip, the input and the output; the
    gradient of each term at the clean clip, per channel group (normalised units, as the solver sees them)."""
    P = denoise_problem(n, config=BASE)
    E = P.energy

    def raw(x):
        r = P.prior.clean(torch.from_numpy(encode_state_features(x)))[None][:, 1:].double()
        r[..., P.prior.contact_cols] = P.bits
        return r
    rows = {}
    for k, x in (("clean", m), ("input", n), ("output", out)):
        t = P.terms(raw(x))
        d = P.data_terms(raw(x))
        rows[k] = {"prior": float(t["prior"]), "contact": float(t["contact"]), "data_root": float(d["root"]),
                   "data_angle": float(d["angle"]), "total": float(t["total"])}
    z = E.to_z(raw(m)).requires_grad_(True)
    free = np.nonzero(P.prior.free)[0].tolist()
    grads = {}
    for term in ("prior", "contact", "data"):
        r = E.frames(z, P.bits)
        t = P.terms(r)
        e = t["control"] if term == "data" else t[term]
        g, = torch.autograd.grad(e.sum(), z)
        g = g[0]  # (T-1, F)
        grads[term] = {name: float(g[:, [free.index(c) for c in cols if c in free]].norm())
                       for name, cols in channel_groups(m.skeleton).items()}
    return {"energy": rows, "grad_at_clean": grads}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--inputs", choices=tuple(NOISE), required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--only", nargs="*", help="condition names (default: all)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    clean = C.denoise_clips()  # as denoise_eval
    kw = NOISE[args.inputs]
    noisy = clean if kw is None else [add_noise(m, seed=_clip_seed(1, i), **kw) for i, m in enumerate(clean)]
    path = Path(args.out)
    res = json.loads(path.read_text()) if path.exists() else {"clips": len(clean), "inputs": {}, "commands": {}}
    cmd = "python " + " ".join(sys.argv)
    if args.only:  # rows added to a full run: keep the full run's command beside this one
        prev = res["commands"].get(args.inputs, [])
        res["commands"][args.inputs] = ([prev] if isinstance(prev, str) else prev) + [cmd]
    else:
        res["commands"][args.inputs] = [cmd]
    # each run's provenance beside its command: kept for --only runs, as the commands are
    runs = res.get("provenance", {}).get(args.inputs, []) if args.only else []
    block = res["inputs"].setdefault(args.inputs, {})
    block["input_error_m"] = float(np.mean([C._denoise_scores(n, c)["mean_joint_error_m"]
                                            for n, c in zip(noisy, clean, strict=True)]))
    conds = {k: v for k, v in CONDITIONS.items() if not args.only or k in args.only}
    for name, (over, start) in conds.items():
        if args.inputs == "clean" and name in SKIP_ON_CLEAN:
            continue
        t0, per = time.perf_counter(), []
        for n, c in zip(noisy, clean, strict=True):
            s = {"clean": c, "median": median_start(n) if start == "median" else None}.get(start)
            out = denoise(n, seed=0, config=replace(BASE, **over), start=s)
            per.append(C._denoise_scores(out, c))
            if name == BASE_NAME:
                per[-1]["study"] = energy_study(c, n, out)
        row = {s: float(np.mean([r[s] for r in per])) for s in per[0] if s != "study"}
        row["per_clip_mean_joint_error_m"] = [r["mean_joint_error_m"] for r in per]
        row["ratio_to_input"] = row["mean_joint_error_m"] / max(block["input_error_m"], 1e-12)
        row["seconds"] = time.perf_counter() - t0
        if name == BASE_NAME:
            row["studies"] = [r["study"] for r in per]
        block.setdefault("conditions", {})[name] = row
        print(f"{args.inputs:6s} {name:50s} {100 * row['mean_joint_error_m']:.3f} cm "
              f"(input {100 * block['input_error_m']:.3f}; {row['seconds']:.0f} s)", flush=True)
        res.setdefault("provenance", {})[args.inputs] = runs + [provenance()]
        path.write_text(json.dumps(rounded(res), indent=1) + "\n")


if __name__ == "__main__":
    main()
