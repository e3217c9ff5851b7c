"""Lesson 06 side experiment (issue 17): why the Markov MoGlow explodes in 6 of 16 of its 20-s samples.

    python studies/06_moglow/moglow_markov_explosion.py --out studies/06_moglow/moglow_markov_explosion_results.json   # ~3 min, one core
    python studies/06_moglow/moglow_markov_explosion.py --checkpoints /tmp/mg6300 \\
        --out studies/06_moglow/moglow_longer_explosion_results.json   # studies/06_moglow/moglow_longer_training.py's models

The shipped checkpoints only (nothing is trained, nothing is written to checkpoints/).  The protocol is
`E.long_samples`' (seed 0 is the notebook's 16 samples), repeated over SEEDS; one condition changes one thing:

- ``protocol``: as the notebook;  ``T=0.8`` / ``T=0.5`` / ``T=0``: the same seeds at a lower temperature;
- ``clamp``: each generated pose clamped to the training poses' per-feature [min, max] before it enters the
  history (`MoGlow.sample`'s history_fn); the poses scored are the unclamped outputs;
- ``teacher``: the history is the mocap that goes with the program (`E.long_program`), every frame
  x_t = f^-1(z_t; h(mocap history, controls)): no feedback at all;
- ``smooth_seams``: the program's controls cross-faded over tau frames at each seam (a new clip's control
  starts there: a jump the training windows never have), nothing else changed;
- ``unscaled_history``: the history fed unscaled (StyleGestures' rule; ours multiplies it by 1 - dropout);
- ``stand`` / ``walk``: 20 s of a constant control (no seams).

Where it starts: for every seam of the protocol runs, the control jump there, the pose, the drawn z and the
coupling scales at that frame, and the counterfactual x with z = 0 (the same history and controls).
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch

from course_lib.experiments import moglow as E
from course_lib.results import write_study_result

SEEDS = list(range(10))  # generation seeds; 0 is the notebook's
N = 16  # samples per seed, as E.long_samples
SECONDS = 20.0
MODELS = ("moglow_markov", "moglow")
SEAM_WINDOW = 4  # a blow-up within this many frames after a seam is counted as starting at that seam


def smooth_seams(controls: torch.Tensor, seams: list, frames: int) -> torch.Tensor:
    """controls (N, T, 3) -> a copy where frames s .. s + frames - 1 of each seam s (but the first, the
    starting frames' own) are the straight line from c_{s-1} to c_{s+frames}."""
    out = controls.clone()
    w = torch.arange(1, frames + 1, dtype=controls.dtype)[:, None] / (frames + 1)  # (frames, 1)
    for s in seams[1:]:
        if s + frames < controls.shape[1]:
            out[:, s:s + frames] = (1 - w) * controls[:, s - 1:s] + w * controls[:, s + frames:s + frames + 1]
    return out


def draws(n: int, frames: int, dim: int, seed: int, temperature: float = 1.0) -> torch.Tensor:
    """The z that `MoGlow.sample` draws for this seed: (n, frames - tau, dim)."""
    return temperature * torch.randn(n, frames - E.TAU, dim, generator=torch.Generator().manual_seed(seed))


def teacher_forced(model, prog: dict, seed: int) -> torch.Tensor:
    """Every frame from the mocap's own history: x_t = f^-1(z_t; h(x_{t-tau:t-1} mocap, c_{t-tau:t}))."""
    poses, ctl = prog["poses"], prog["controls"]
    h, _ = model.condition(model.condition_inputs(poses, ctl))  # (n, T - tau, H)
    x = model.flow_inverse(draws(len(poses), poses.shape[1], poses.shape[-1], seed), h, model.weight_inverses())
    return torch.cat((poses[:, :E.TAU], x), 1)


def blow_up_frame(poses: torch.Tensor) -> np.ndarray:
    """(N, T, D) -> (N,) the first frame beyond BLOW_UP sd (or NaN), -1 where none."""
    bad = ~(torch.nan_to_num(poses, nan=np.inf).abs() < E.BLOW_UP).all(-1)  # (N, T)
    return np.where(bad.any(1).numpy(), bad.float().argmax(1).numpy(), -1)


def score(poses: torch.Tensor, seams: list, in_range: float) -> dict:
    """Explosions of (N, T, D) poses; ``at_seam``: blow-ups within SEAM_WINDOW frames after a seam;
    ``one_step``: blow-ups whose previous frame was inside the training poses' largest |value| (in_range);
    ``recovered``: exploded samples back within BLOW_UP (and finite) over the last 5 s."""
    frame = blow_up_frame(poses)
    a = torch.nan_to_num(poses, nan=np.inf).abs().amax(-1)  # (N, T)
    hit = frame >= 0
    at_seam = [any(s <= f < s + SEAM_WINDOW for s in seams[1:]) for f in frame[hit]]
    tail = (a[:, -int(5 * E.FPS):] < E.BLOW_UP).all(1).numpy()
    return {"exploded": int(hit.sum()), "n": len(poses), "at_seam": int(sum(at_seam)),
            "one_step": int(sum(float(a[i, f - 1]) <= in_range for i, f in enumerate(frame) if f > 0)),
            "non_finite": int((~torch.isfinite(poses).all(-1).all(-1)).sum()),
            "recovered": int((hit & tail).sum()), "blow_up_frames": frame.tolist()}


def clamp_fn(lo: torch.Tensor, hi: torch.Tensor):
    """pose (N, D) -> the pose clamped to [lo, hi] per feature (a non-finite value to the nearer bound, NaN 0)."""
    return lambda x: torch.maximum(torch.minimum(torch.nan_to_num(x, nan=0.0), hi), lo)


def conditions(model, data, seed: int, lo: torch.Tensor, hi: torch.Tensor) -> dict:
    """condition name -> generated poses (N, T, D) for one seed."""
    prog = E.long_program(data, seed, N, SECONDS)
    ctl, starts = prog["controls"], (prog["poses"][:, :E.TAU], prog["controls"][:, :E.TAU])
    T = ctl.shape[1]
    out = {"protocol": E.generate(model, data, ctl, seed, starts=starts)[0]}
    for temp in (0.8, 0.5, 0.0):
        out[f"T={temp}"] = E.generate(model, data, ctl, seed, temp, starts=starts)[0]
    out["clamp"] = E.generate(model, data, ctl, seed, starts=starts, history_fn=clamp_fn(lo, hi))[0]
    with torch.no_grad():
        out["teacher"] = teacher_forced(model, prog, seed)
    out["smooth_seams"] = E.generate(model, data, smooth_seams(ctl, prog["seams"], E.TAU), seed, starts=starts)[0]
    model.config.history_scale = False
    out["unscaled_history"] = E.generate(model, data, ctl, seed, starts=starts)[0]
    model.config.history_scale = True
    walk = float(np.median([np.mean(m.meta["speed"]) for m in data.test_clips if m.action == "walk"]))
    out["stand"] = E.generate(model, data, E.constant_control(data, N, T), seed, starts=starts)[0]
    out["walk"] = E.generate(model, data, E.constant_control(data, N, T, forward=walk), seed, starts=starts)[0]
    return out


@torch.no_grad()
def inverse_trace(model, z: torch.Tensor, h: torch.Tensor) -> dict:
    """z (M, D), h (M, H) -> per step of flow, in the order the inverse runs them: min coupling scale sigma
    (its 1/sigma multiplies in the inverse), max |t|, and max |value| after the step; x (M, D)."""
    sig, shift, size = [], [], []
    for layer in reversed(model.flow):
        log_sigma, t = layer.coupling.scale_and_shift(z[..., :layer.coupling.split], h)
        sig.append(log_sigma.exp().amin(-1))
        shift.append(t.abs().amax(-1))
        z = layer.inverse(z, h)
        size.append(z.abs().amax(-1))
    return {"min_sigma": torch.stack(sig, -1), "max_shift": torch.stack(shift, -1),
            "max_after": torch.stack(size, -1), "x": z}


def first_blow_up_step(tr: dict, i: int) -> tuple:
    """-> (index in the inverse order of the first step of flow after which |value| > BLOW_UP, or -1;
    the smallest coupling scale sigma up to that step, i.e. before any non-finite value)."""
    beyond = (torch.nan_to_num(tr["max_after"][i], nan=np.inf) > E.BLOW_UP).nonzero()
    k = int(beyond[0]) if len(beyond) else -1
    return k, float(tr["min_sigma"][i, : (k + 1 if k >= 0 else None)].min())


@torch.no_grad()
def seam_table(model, data, seed: int, poses: torch.Tensor) -> list:
    """One row per (sample, seam) of the protocol run: whether the blow-up starts there, the control jump
    into the seam frame (sd), and at that frame: the history's max |x|, |z| / sqrt(D), x's max |value|
    with the drawn z and with z = 0, the step of flow where the value first passes BLOW_UP and the
    smallest coupling scale up to it."""
    prog = E.long_program(data, seed, N, SECONDS)
    ctl, D = prog["controls"], poses.shape[-1]
    z = draws(N, ctl.shape[1], D, seed)
    frame = blow_up_frame(poses)
    h, _ = model.condition(model.condition_inputs(torch.nan_to_num(poses, nan=0.0).clamp(-1e6, 1e6), ctl))
    rows = []
    for s in prog["seams"][1:]:
        tr = inverse_trace(model, z[:, s - E.TAU], h[:, s - E.TAU])
        tr0 = inverse_trace(model, torch.zeros(N, D), h[:, s - E.TAU])
        hist = poses[:, s - E.TAU:s]  # (N, tau, D): the history the seam frame conditions on
        for i in range(N):
            if 0 <= frame[i] < s:
                continue  # already gone
            k, sigma = first_blow_up_step(tr, i)
            rows.append({"seed": seed, "sample": i, "seam": s,
                         "explodes_here": bool(s <= frame[i] < s + SEAM_WINDOW),
                         "control_jump": float((ctl[i, s] - ctl[i, s - 1]).abs().max()),
                         "history_max_abs": float(hist[i].abs().max()),
                         "x_max_abs": float(torch.nan_to_num(tr["x"][i], nan=np.inf).abs().max()),
                         "x_max_abs_z0": float(torch.nan_to_num(tr0["x"][i], nan=np.inf).abs().max()),
                         "z_norm": float(z[i, s - E.TAU].norm() / D ** 0.5),
                         "blow_up_step": k, "min_sigma": sigma})
    return rows


def summarise_seams(rows: list, train_step: float, in_range: float) -> dict:
    hit = [r for r in rows if r["explodes_here"]]
    miss = [r for r in rows if not r["explodes_here"]]

    def med(rs, k):
        return float(np.median([r[k] for r in rs])) if rs else None

    keys = ("control_jump", "history_max_abs", "x_max_abs", "x_max_abs_z0", "z_norm", "min_sigma")
    big = [r for r in rows if r["control_jump"] > train_step]
    small = [r for r in rows if r["control_jump"] <= train_step]
    steps = [r["blow_up_step"] for r in hit if r["blow_up_step"] >= 0]
    return {"seams": len(rows), "seams_with_blow_up": len(hit),
            "median_at_blow_up_seams": {k: med(hit, k) for k in keys},
            "median_at_other_seams": {k: med(miss, k) for k in keys},
            "blow_up_seams_history_in_range": sum(r["history_max_abs"] <= in_range for r in hit),
            "blow_up_seams_z0_out_of_range": sum(r["x_max_abs_z0"] > in_range for r in hit),
            "blow_up_seams_beyond_in_seam_frame": len(steps),
            "blow_up_step_counts": {str(k): steps.count(k) for k in sorted(set(steps))},
            "other_seams_min_sigma_p01": float(np.quantile([r["min_sigma"] for r in miss], 0.01)) if miss else None,
            "jump_above_train_max": {"seams": len(big), "blow_ups": sum(r["explodes_here"] for r in big)},
            "jump_within_train_max": {"seams": len(small), "blow_ups": sum(r["explodes_here"] for r in small)}}


def fixed_gains(model) -> dict:
    """The history-independent factors of the inverse: actnorm's exp(-s) and the 1x1 maps' inverses."""
    act = torch.stack([torch.exp(-layer.actnorm.log_scale.detach()) for layer in model.flow])  # (K, D)
    w_inv = [torch.linalg.matrix_norm(w.detach(), 2) for w in model.weight_inverses()]
    return {"actnorm_max_inverse_scale": float(act.max()), "actnorm_log_gain_per_step_max": float(
        torch.log(act).amax(-1).max()), "linear_inverse_spectral_norm_max": float(max(w_inv))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--checkpoints", type=Path, default=E.CHECKPOINTS,
                        help="the models' folder (default: the shipped checkpoints/)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    data = E.load_data("full")
    flat = data.train["poses"].reshape(-1, data.pose_dim)
    lo, hi = flat.amin(0), flat.amax(0)
    step = data.train["controls"].diff(dim=1).abs().amax(-1)
    train_step, in_range = float(step.max()), float(flat.abs().max())
    out = {"command": "python " + " ".join(sys.argv), "seeds": SEEDS, "n_per_seed": N, "seconds": SECONDS,
           "blow_up_sd": E.BLOW_UP, "seam_window": SEAM_WINDOW, "train_max_control_step": train_step,
           "train_pose_max_abs": in_range,
           "seams": E.long_program(data, 0, N, SECONDS)["seams"], "models": {}}
    for name in MODELS:
        model = E.load_model(name, args.checkpoints)
        counts, rows = {}, []
        for seed in SEEDS:
            seams = E.long_program(data, seed, N, SECONDS)["seams"]
            for cond, poses in conditions(model, data, seed, lo, hi).items():
                sc = score(poses, seams, in_range)
                totals = [k for k in sc if k != "blow_up_frames"]
                row = counts.setdefault(cond, {k: 0 for k in totals} | {"per_seed": []})
                for k in totals:
                    row[k] += sc[k]
                row["per_seed"].append(sc["exploded"])
                if cond == "protocol" and seed == 0:
                    row["seed0_blow_up_frames"] = sc["blow_up_frames"]
                if cond == "protocol":
                    rows += seam_table(model, data, seed, poses)
        out["models"][name] = {"counts": counts, "seams": summarise_seams(rows, train_step, in_range),
                               "fixed_gains": fixed_gains(model)}
        print(name, {k: f"{v['exploded']}/{v['n']}" for k, v in counts.items()}, file=sys.stderr)
    out["seconds_taken"] = round(time.perf_counter() - t0, 1)
    write_study_result(args.out, out, 5)  # + command, commit, checkpoints' sha256


if __name__ == "__main__":
    main()
