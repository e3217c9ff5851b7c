"""Lesson 04's experiment: MAP motion control with the pretrained GMM-RNN as the prior (Wang, Chai et al. 2021,
sec. 5.2-5.4), measured on held-out start frames and clips, against the baselines a reader would try first.

    python -m course_lib.reproduce control              # every measurement -> results/control.json
    python -m course_lib.reproduce control --eval-only  # the same (nothing is trained: it uses gmm_rnn.pt)
    python -m course_lib.reproduce control --only denoise   # re-measure some PARTS, keep the others recorded

Taught in notebooks/04_map_control.ipynb, which reads the recorded results (``recorded_results``) in CI mode.

- offline design: 5 curves x walking and running (``CURVES``), ours (candidates -> PSO -> L-BFGS) against
  L-BFGS from one sample, the best of 64 samples per window, the RNN without control, greedy steering; and
  on two cases ours against L-BFGS alone and best-of-N at equal wall time;
- online control: a scripted run per gait (speed changes, +-180-degree turns), settling times and frames/s;
- denoising: held-out clips with data_scripts/make_noisy.py's noise (``datasets.noisy_copies``), ours against
  lesson 03's refiner alone and a zero-phase Butterworth low-pass and a Savitzky-Golay filter at their best
  settings (picked on the same clips, which favours them);
- eq. (26): the first-frame joint speed from the zero and the estimated initial state, beside mocap's.
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path

import numpy as np
import torch

from course_lib.paths import CHECKPOINTS
from course_lib.results import recorded, rounded, update_results

__all__ = ["CURVES", "PACE", "curve", "curve_heading_rate", "heading_rates", "offline_case", "measure_design",
           "online_run", "held_share", "parallel_map", "denoise_clips", "denoise_eval", "initial_state_eval",
           "eval_control", "train_control", "record_results", "recorded_results"]

COMMAND = "python -m course_lib.reproduce control"
PACE = {"walk": 1.2, "run": 2.5}  # m/s each curve is asked at (near the held-out walks' and runs' median net speeds)
CURVES = ("line", "circle_r2", "s_curve", "u_turn", "polyline")
METHODS = ("ours", "lbfgs", "best_of_n", "random", "greedy")


def curve(name: str) -> np.ndarray:
    """A named floor polyline (K, 2), metres, from (0, 0) heading +Z."""
    if name == "line":
        return np.array([[0.0, 0.0], [0.0, 6.0]])
    if name == "circle_r2":
        t = np.linspace(0, 2 * np.pi, 73)
        return np.stack((2 - 2 * np.cos(t), 2 * np.sin(t)), -1)
    if name == "s_curve":
        s = np.linspace(0, 1, 60)
        return np.stack((0.8 * np.sin(2 * np.pi * s), 6 * s), -1)
    if name == "u_turn":  # 2 m, a 180-degree turn of radius 1 m, 2 m back
        t = np.linspace(0, np.pi, 25)
        arc = np.stack((1 - np.cos(t), 2 + np.sin(t)), -1)
        return np.concatenate(([[0.0, 0.0]], arc, [[2.0, 0.0]]))
    if name == "polyline":  # the kind a student types
        return np.array([[0.0, 0.0], [0.0, 2.0], [1.5, 3.5], [1.5, 5.5]])
    raise ValueError(f"unknown curve {name!r}; choose one of {', '.join(CURVES)}")


def seconds_for(c: np.ndarray, gait: str) -> float:
    """The duration that asks the gait's pace (PACE) along the curve."""
    return float(np.linalg.norm(np.diff(c, axis=0), axis=1).sum() / PACE[gait])


# ----------------------------------------------------------------------------- offline design


TURN_WINDOW = 9  # frames (0.3 s at 30 fps) over which a heading rate is averaged


def heading_rates(motions, window: int = TURN_WINDOW) -> np.ndarray:
    """|d heading / dt| of every frame of ``motions``, deg/s, averaged over ``window`` frames (eq. 3's dyaw column):
    how fast the data's bodies turn."""
    from course_lib.representations import encode_state_features

    out = []
    for m in motions:
        dyaw = encode_state_features(m)[1:, 2]
        if len(dyaw) >= window:
            out.append(np.abs(np.convolve(dyaw, np.ones(window) / window, "valid")) * m.fps)
    if not out:
        raise ValueError(f"heading_rates: no motion has more than {window} frames")
    return np.degrees(np.concatenate(out))


def curve_heading_rate(c: np.ndarray, pace: float, fps: float = 30.0, window: int = TURN_WINDOW) -> float:
    """The largest heading rate (deg/s, averaged over ``window`` frames as `heading_rates`) that a point moving along
    the polyline ``c`` at ``pace`` m/s needs: the turn the curve asks of a body at that speed (a corner asks its
    angle within one window)."""
    if not (np.isfinite(pace) and pace > 0 and np.isfinite(fps) and fps > 0):
        raise ValueError(f"curve_heading_rate: pace and fps must be > 0, got {pace!r}, {fps!r}")
    seg = np.diff(c, axis=0)
    cum = np.concatenate(([0.0], np.cumsum(np.linalg.norm(seg, axis=1))))
    s = np.arange(0.0, cum[-1], pace / fps)
    if len(s) < window + 2:
        raise ValueError(f"curve_heading_rate: the curve is shorter than {window + 2} frames at {pace} m/s")
    d = np.diff(np.stack((np.interp(s, cum, c[:, 0]), np.interp(s, cum, c[:, 1])), 1), axis=0)
    dh = np.diff(np.unwrap(np.arctan2(d[:, 0], d[:, 1])))
    return float(np.degrees(np.abs(np.convolve(dh, np.ones(window) / window, "valid")).max() * fps))


def measure_design(m, c: np.ndarray) -> dict:
    """A designed motion against its curve: root-to-curve distance (mean, max), end distance, foot skate."""
    from course_lib.control.energy import nearest_on_polyline
    from course_lib.evaluation import foot_skate_at_floor

    xz = torch.from_numpy(m.root_positions[:, [0, 2]])
    _, dist = nearest_on_polyline(xz, torch.from_numpy(c))
    return {"mean_root_to_curve_m": float(dist.mean()), "max_root_to_curve_m": float(dist.max()),
            "end_distance_m": float(np.linalg.norm(m.root_positions[-1, [0, 2]] - c[-1])),
            "foot_skate_m_s": float(foot_skate_at_floor([m])), "frames": len(m)}


def _config(method: str, scale: float = 1.0):
    from course_lib.control import DesignConfig
    from course_lib.control.lbfgs import LbfgsConfig

    if method == "ours":
        return DesignConfig()
    if method == "lbfgs":  # L-BFGS from one RNN sample, no PSO (baseline d); no retries (they add samples)
        return DesignConfig(candidates=1, use_pso=False, lbfgs=LbfgsConfig(iterations=max(1, round(40 * scale))),
                            retry_control=None, retry_rise=None)
    if method == "best_of_n":  # sampling alone, no gradients (baseline c)
        return DesignConfig(candidates=max(1, round(64 * scale)), use_pso=False, use_lbfgs=False, retry_control=None,
                            retry_rise=None)
    raise ValueError(method)


def offline_case(name: str, gait: str, method: str, seed: int = 0, scale: float = 1.0):
    """-> (the designed / generated motion, its wall time in s) for one curve, gait and method."""
    from course_lib.control import design_motion

    c = curve(name)
    t0 = time.perf_counter()
    if method in ("random", "greedy"):  # the same planting as the designs' (DesignConfig.plant), for a fair skate
        from course_lib.control.design import default_prior
        from course_lib.control.planting import plant_with_prior

        m = plant_with_prior(_run_free(c, seconds_for(c, gait), gait, seed, greedy=method == "greedy"), default_prior())
    else:
        m = design_motion(c, seconds_for(c, gait), gait, seed=seed, config=_config(method, scale))
    return m, time.perf_counter() - t0


def _run_free(c: np.ndarray, seconds: float, gait: str, seed: int, greedy: bool):
    """The RNN run without control (baseline a) or steered frame by frame (baseline b: each frame's sampled
    root step turned towards a point 0.5 m ahead on the curve, at most 0.1 rad, and scaled to the pace)."""
    from course_lib.control.design import default_prior, prepare_start
    from course_lib.control.energy import arc_lengths, arc_position, polyline_between
    from course_lib.control.kinematics import heading_yaw, second_pose
    from course_lib.representations import decode_state_features

    prior = default_prior()
    raw0, init0, start = prepare_start(None, gait, seed, (c[0, 0], c[0, 1], float(heading_yaw(
        torch.from_numpy(c[1] - c[0])))), prior)
    g = torch.Generator().manual_seed(seed)
    state, prev = prior.start_state(raw0, start.skeleton), raw0.double()
    x, z, yaw = (float(v) for v in second_pose(raw0, init0))
    L, step_len, s = float(arc_lengths(c)[-1]), float(arc_lengths(c)[-1]) / seconds / 30, 0.0
    frames = []
    for _ in range(max(int(round(seconds * 30)), 3) - 2):
        f = prior.sample(prev, state, 1, start.skeleton, g, bias=1.0)  # (1, 1, D)
        if greedy:
            s = arc_position(c, (x, z), s, s + 1.0)
            ahead = polyline_between(c, s, min(s + 0.5, L))[-1]
            turn = (math.atan2(ahead[0] - x, ahead[1] - z) - yaw + math.pi) % (2 * math.pi) - math.pi
            f[0, 0, 2] = float(np.clip(turn, -0.1, 0.1))
            n = float(torch.hypot(f[0, 0, 0], f[0, 0, 1]))
            if n > 1e-6:
                f[0, 0, 0:2] *= step_len / n
        state = prior.advance(prev, f, state, start.skeleton)
        prev = torch.cat((prev, f), 1)[:, -2:]
        d = f[0, 0].numpy()
        co, si = math.cos(yaw), math.sin(yaw)
        x, z, yaw = x + co * d[0] + si * d[1], z - si * d[0] + co * d[1], yaw + d[2]
        frames.append(f[0])
    feats = torch.cat([raw0[0]] + frames, 0).numpy()
    return decode_state_features(feats, start.skeleton, 30.0, tuple(float(v) for v in init0))


def _offline_row(task: tuple) -> tuple[str, dict]:
    """One (curve, gait, method, seed, budget scale) case -> ("curve/gait/method", measure_design + seconds); run
    in a worker process (one torch thread) by `parallel_map`."""
    name, gait, method, seed, scale = task
    torch.set_num_threads(1)
    m, sec = offline_case(name, gait, method, seed, scale=scale)
    row = {**measure_design(m, curve(name)), "seconds": sec}
    if method in ("ours", "lbfgs", "greedy"):  # the root path, every 3rd frame, for the lesson's plots
        row["root_xz"] = np.round(m.root_positions[::3, [0, 2]], 3).tolist()
    return f"{name}/{gait}/{method}", row


def parallel_map(fn, tasks: list, workers: int):
    """fn over tasks -> their results in task order, each as soon as it and those before it are done; workers > 1:
    that many processes of one torch thread each (each case's seconds are then its own process's wall time,
    measured with the other worker busy)."""
    if workers <= 1 or len(tasks) < 2:
        yield from map(fn, tasks)
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(min(workers, len(tasks)), mp_context=multiprocessing.get_context("spawn")) as pool:
        yield from pool.map(fn, tasks)


def offline_eval(seed: int = 0, curves=CURVES, gaits=("walk", "run"), methods=METHODS, progress=print,
                 workers: int = 1) -> dict:
    """Every curve x gait x method -> {"curve/gait/method": measure_design + seconds}; ``workers`` processes."""
    tasks = [(name, gait, method, seed, 1.0) for name in curves for gait in gaits for method in methods]
    rows = {}
    for key, row in parallel_map(_offline_row, tasks, workers):
        rows[key] = row
        if progress:
            progress(key, {k: round(v, 3) for k, v in row.items() if not isinstance(v, list)})
    return rows


def equal_time_eval(seed: int = 0, cases=(("s_curve", "walk"), ("line", "run")), progress=print,
                    offline: dict | None = None, workers: int = 1) -> dict:
    """Ours against L-BFGS alone and best-of-N given (about) ours' wall time: their budgets are scaled by the
    ratio of ours' time to theirs at the default budget (measured on the same case).

    offline: `offline_eval`'s rows of the same run and seed; ours and the default-budget timings are taken from
    them (the same motions, already measured) instead of being run again."""
    methods = ("ours", "lbfgs", "best_of_n")
    need = [(n, g, m, seed, 1.0) for n, g in cases for m in methods if f"{n}/{g}/{m}" not in (offline or {})]
    done = {**(offline or {}), **dict(parallel_map(_offline_row, need, workers))}
    scaled = [(n, g, m, seed, done[f"{n}/{g}/ours"]["seconds"] / max(done[f"{n}/{g}/{m}"]["seconds"], 1e-3))
              for n, g in cases for m in methods[1:]]
    again = dict(parallel_map(_offline_row, scaled, workers))
    out = {}
    for (name, gait, method, _, scale) in scaled:
        key = f"{name}/{gait}"
        row = out.setdefault(key, {"ours": {k: v for k, v in done[f"{key}/ours"].items() if k != "root_xz"}})
        row[method] = {k: v for k, v in again[f"{key}/{method}"].items() if k != "root_xz"}
        row[method]["budget_scale"] = scale
    if progress:
        for key, row in out.items():
            progress(key, {k: round(v["end_distance_m"], 3) for k, v in row.items()})
    return out


# ----------------------------------------------------------------------------- online control


def online_program(gait: str) -> list[tuple[float, float, float]]:
    """(seconds, speed m/s, direction rad) segments: speed changes, then +180 and -180-degree turns."""
    v = PACE[gait]
    return [(3.0, v, 0.0), (3.0, 0.6 * v, 0.0), (3.0, 1.3 * v, 0.0), (4.0, v, math.pi), (4.0, v, 0.0)]


SPEED_WINDOW = 10  # frames (1/3 s at 30 fps) over which online_run measures the net speed after every step


def online_run(gait: str = "walk", seed: int = 0, config=None, program=None) -> dict:
    """The scripted run (``program``: (seconds, speed, direction) segments, default ``online_program(gait)``;
    ``config``: an OnlineConfig, default the controller's) -> per batch (time, commanded speed and direction,
    the net speed over the last ``SPEED_WINDOW`` frames, whatever the batch size, and the heading),
    the speed settling times (within 10 % of a changed command), the turn times (heading within 10 degrees
    of a +-180-degree command), the share of batches whose speed stays within 10 % from 1 s after a change to the
    next (`held_share`), frames/s of the whole run on this core (and of its median step, and per second of the
    process's CPU time: wall time above CPU time is time the process waited for the core), the latency in frames."""
    from course_lib.control import OnlineController

    ctrl = OnlineController(gait, seed=seed, config=config)
    dt = ctrl.config.batch / ctrl.fps
    path = list(ctrl.motion().root_positions[1:, [0, 2]])  # the start's second frame, then every frame made
    log, t, t0, cpu0, step_s = [], 0.0, time.perf_counter(), time.process_time(), []
    for seconds, speed, direction in program or online_program(gait):
        for _ in range(int(round(seconds / dt))):
            ts = time.perf_counter()
            path.extend(ctrl.step(speed, direction).root_positions[:, [0, 2]])
            step_s.append(time.perf_counter() - ts)
            w = min(SPEED_WINDOW, len(path) - 1)  # the same window whatever the batch (the first batch: what exists)
            t += dt
            log.append({"t": t, "speed_cmd": speed, "dir_cmd": direction, "xz": path[-1],
                        "speed": float(np.linalg.norm(path[-1] - path[-1 - w]) * ctrl.fps / w),
                        "heading": ctrl.heading})
    wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    return {"batches": [{k: (float(v) if k != "xz" else [float(a) for a in v]) for k, v in r.items()} for r in log],
            "speed_settle_s": _settle(log, "speed_cmd", lambda r: abs(r["speed"] / r["speed_cmd"] - 1) <= 0.1),
            "turn_s": _settle(log, "dir_cmd", lambda r: abs(_wrap(r["heading"] - r["dir_cmd"])) <= math.radians(10)),
            "speed_held": held_share(log, lambda r: abs(r["speed"] / r["speed_cmd"] - 1) <= 0.1),
            "frames_per_s": len(log) * ctrl.config.batch / wall, "latency_frames": ctrl.config.batch,
            "frames_per_s_median_step": ctrl.config.batch / float(np.median(step_s)),
            "frames_per_s_cpu": len(log) * ctrl.config.batch / cpu, "seconds": wall, "cpu_seconds": cpu}


def held_share(log: list, ok, after: float = 1.0) -> float:
    """The share of batches, among those more than ``after`` seconds past the last change of either command
    (and past the start), for which ok(row) holds: does the speed stay where it settled?  log: rows with "t",
    "speed_cmd", "dir_cmd" (`online_run`'s batches).  Known answer: mocap at a constant command scores 1."""
    last, rows = 0.0, []
    for i, r in enumerate(log):
        if i and (r["speed_cmd"], r["dir_cmd"]) != (log[i - 1]["speed_cmd"], log[i - 1]["dir_cmd"]):
            last = log[i - 1]["t"]
        if r["t"] - last > after + 1e-9:
            rows.append(bool(ok(r)))
    return float(np.mean(rows)) if rows else float("nan")


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def _settle(log: list, key: str, ok) -> list:
    """For every change of log[i][key]: seconds from the change until ok(row) first holds (None: never)."""
    out = []
    for i in range(1, len(log)):
        if log[i][key] != log[i - 1][key]:
            t_change = log[i - 1]["t"]
            hit = next((r["t"] - t_change for r in log[i:] if r[key] == log[i][key] and ok(r)), None)
            out.append({"at_s": t_change, "to": log[i][key], "seconds": hit})
    return out


# ----------------------------------------------------------------------------- denoising


def _denoise_scores(out, clean, noisy=None) -> dict:
    """Joint error (mean, max), skate, contact agreement of ``out`` against ``clean``; with ``noisy`` (a noisy_copies
    clip) also the largest joint error on its spiked frames (nan without one): whether the spikes are gone."""
    from course_lib.evaluation import foot_skate_at_floor

    err = np.linalg.norm(out.positions() - clean.positions(), axis=-1)  # (T, J)
    scores = {"mean_joint_error_m": float(err.mean()), "max_joint_error_m": float(err.max()),
              "foot_skate_m_s": float(foot_skate_at_floor([out])),
              "contact_agreement": float((out.contacts() == clean.contacts()).mean())}
    if noisy is not None:
        spiked = noisy.meta["noise"]["spike_frames"]
        scores["max_error_on_spiked_frames_m"] = float(err[spiked].max()) if len(spiked) else float("nan")
    return scores


BUTTER_CUTOFFS = (3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0)  # Hz (Nyquist: 15)
SAVGOL_WINDOWS = (5, 7, 9, 13, 17)  # frames at 30 fps


def refine_alone(motions: list, checkpoints: Path = CHECKPOINTS) -> list:
    """The refiner-alone denoising baseline: lesson 03's pretrained refiner (GAN2, seed 0) and its contact handling
    applied to each motion's state features directly (no prior, no data term) -> Motions."""
    from course_lib.experiments.gmm_rnn import Lesson03Spec, clip_offsets, load_models, to_motions, with_contacts
    from course_lib.representations import encode_state_features

    _, refiners, stats = load_models(checkpoints)
    spec, out = Lesson03Spec(), []
    for m in motions:
        x = torch.from_numpy((encode_state_features(m) - stats[0]) / stats[1]).float()[None]
        with torch.no_grad():
            r = refiners["GAN2"](x, clip_offsets([m]))
        r = with_contacts(r, stats, [m], spec.contact_smooth, spec.contact_method)
        out += to_motions(r, stats, [m], spec.fps)
    return out


def denoise_clips(first: int = 0, per_gait: int = 4) -> list:
    """The held-out walks then runs the denoising is measured on: clips first .. first + per_gait - 1 of each gait
    (0-3: the scored clips of `denoise_eval`; 4-7: the tuning clips `DenoiseConfig`'s settings were chosen on)."""
    from course_lib.control.starts import held_out_clips

    return [m for g in ("walk", "run") for m in held_out_clips(g)[first:first + per_gait]]


def denoise_eval(seed: int = 0, clips_per_gait: int = 4, progress=print) -> dict:
    """Held-out walks and runs with make_noisy.py's noise: noisy input, ours, lesson 03's refiner alone, the best
    Butterworth and the best Savitzky-Golay (best mean joint error over these clips; control/lowpass.py), each
    also on the input with its dropped frames interpolated (control/dropouts.py, as ours does) -> mean scores per
    method, the best settings ({method: Hz or frames}), and the clean clips'."""
    from course_lib.control import denoise
    from course_lib.control.dropouts import fill_held
    from course_lib.control.lowpass import lowpass
    from course_lib.datasets import noisy_copies

    clean = denoise_clips(0, clips_per_gait)
    noisy = noisy_copies(clean, seed + 1)
    per = {"noisy": [_denoise_scores(n, c, n) for n, c in zip(noisy, clean, strict=True)]}
    t0 = time.perf_counter()
    per["ours"] = [_denoise_scores(denoise(n, seed=seed), c, n) for n, c in zip(noisy, clean, strict=True)]
    ours_s = time.perf_counter() - t0
    per["refiner"] = [_denoise_scores(r, c, n) for r, c, n in zip(refine_alone(noisy), clean, noisy, strict=True)]
    on_clean = [_denoise_scores(r, c)["mean_joint_error_m"] for r, c in zip(refine_alone(clean), clean, strict=True)]
    best = {}
    filled = [fill_held(n) for n in noisy]  # the dropped frames interpolated first, as ours does
    for kind, params in (("butter", BUTTER_CUTOFFS), ("savgol", SAVGOL_WINDOWS)):
        for name, inputs in ((kind, noisy), (f"{kind} (held frames filled)", filled)):
            pairs = list(zip(inputs, clean, noisy, strict=True))
            tries = {p: [_denoise_scores(lowpass(n, kind, p), c, raw) for n, c, raw in pairs] for p in params}
            p = min(tries, key=lambda q: np.mean([r["mean_joint_error_m"] for r in tries[q]]))
            per[name], best[name] = tries[p], p
    mean = {k: {s: float(np.nanmean([r[s] for r in v])) for s in v[0]} for k, v in per.items()}  # nan: no spike
    from course_lib.evaluation import foot_skate_at_floor

    out = {"mean": mean, "best_setting": best,
           "clean_foot_skate_m_s": float(foot_skate_at_floor(clean)), "clips": len(clean), "ours_seconds": ours_s,
           "refiner_on_clean_mean_joint_error_m": float(np.mean(on_clean))}  # its known answer: a clean input
    if progress:
        progress("denoise", {k: round(v["mean_joint_error_m"], 4) for k, v in mean.items()})
    return out


# ----------------------------------------------------------------------------- eq. (26)


def initial_state_eval(clips_per_gait: int = 10) -> dict:
    """Mean joint speed (m/s) from s_1 to the predicted s_2 with the zero and the eq. (26) state, and mocap's own
    s_1 -> s_2, over held-out walks and runs (frames 10, 11 of each clip)."""
    from course_lib.control.design import default_prior
    from course_lib.control.initial_state import estimate_initial_state, first_frame_speed, predicted_second
    from course_lib.control.starts import held_out_clips
    from course_lib.representations import encode_state_features

    prior = default_prior()
    rows = {"zero_state": [], "estimated_state": [], "mocap": []}
    for gait in ("walk", "run"):
        for clip in held_out_clips(gait)[:clips_per_gait]:
            raw = prior.clean(torch.from_numpy(encode_state_features(clip)[10:12]))[None]
            state, _ = estimate_initial_state(prior, raw, clip.skeleton, steps=100)
            for name, h1 in (("zero_state", None), ("estimated_state", state)):
                pair = torch.cat((raw[:, :1], predicted_second(prior, raw, h1, clip.skeleton)), 1)
                rows[name].append(first_frame_speed(pair, clip.skeleton))
            rows["mocap"].append(first_frame_speed(raw, clip.skeleton))
    out = {k: {"mean_joint_speed_m_s": float(np.mean(v)), "max": float(np.max(v))} for k, v in rows.items()}
    out["clips"] = len(rows["mocap"])
    return out


# ----------------------------------------------------------------------------- the commands


PARTS = ("offline", "equal_time", "online", "denoise", "initial_state")


WORKERS = min(2, os.cpu_count() or 1)  # processes for the offline designs (the course machine has 2 cores)


def eval_control(seed: int = 0, checkpoints: Path = CHECKPOINTS, progress=print, only=None,
                 workers: int = WORKERS) -> dict:
    """Every measurement of lesson 04 on the pretrained GMM-RNN (checkpoints/gmm_rnn.pt), or only the `PARTS`
    named in `only` (the others kept as recorded; ``measured_by`` says which command measured each part).
    The offline and equal-time designs run in ``workers`` processes of one thread each; online control, whose
    frames/s are a target, runs alone afterwards."""
    import json

    torch.set_num_threads(1)
    unknown = sorted(set(only or ()) - set(PARTS))
    if unknown:
        raise ValueError(f"control: --only takes parts of {PARTS}, got {unknown}")
    t0 = time.perf_counter()
    sha = json.loads((checkpoints / "MANIFEST.json").read_text())["gmm_rnn"]["sha256"]
    from course_lib.training import training_environment

    # the host's torch cpu capability decides rounding, which the online search amplifies
    out = {"command": COMMAND, "seed": seed, "pace_m_s": PACE, "gmm_rnn_sha256": sha, "workers": workers,
           "environment": training_environment()}
    times, by = {}, {}
    if only:
        kept = recorded_results(checkpoints)
        for key, now in (("seed", seed), ("gmm_rnn_sha256", sha), ("pace_m_s", PACE)):
            if kept.get(key) != now:
                raise ValueError(f"control: the recorded parts have {key} {kept.get(key)!r}, not {now!r}: "
                                 f"re-measure every part (no --only)")
        out = dict(kept)
        times, by = dict(out.get("seconds", {})), dict(out.get("measured_by", {}))
    runs = {"offline": lambda: offline_eval(seed, progress=progress, workers=workers),
            "equal_time": lambda: equal_time_eval(  # reuses the offline rows measured in this run
                seed, progress=progress, offline=out["offline"] if not only or "offline" in only else None,
                workers=workers),
            "online": lambda: {g: online_run(g, seed) for g in ("walk", "run")},
            "denoise": lambda: denoise_eval(seed, progress=progress),
            "initial_state": initial_state_eval}
    for key in PARTS:
        if only and key not in only:
            by.setdefault(key, COMMAND)
            continue
        t = time.perf_counter()
        out[key] = runs[key]()
        times[key] = time.perf_counter() - t
        by[key] = COMMAND + (f" --only {' '.join(only)}" if only else "")
    out["seconds"], out["measured_by"] = times, by
    out["total_seconds"] = sum(times.values()) if only else time.perf_counter() - t0  # only: the parts' sum
    out = rounded(out, 5)
    record_results(out, checkpoints)
    return out


def train_control(seed: int = 0, only=None, checkpoints: Path = CHECKPOINTS) -> dict:
    """Nothing to train (the prior is lesson 03's gmm_rnn.pt): the evaluation (or its parts in `only`), recorded
    in results/control.json."""
    return eval_control(seed, checkpoints, only=only)


def record_results(results: dict, checkpoints: Path = CHECKPOINTS) -> None:
    """Store the results in results/control.json (``["results"]``; lesson 04 has no checkpoint of its own: it
    uses lesson 03's gmm_rnn.pt, whose sha256 the results name)."""
    update_results("control", lambda data: data.update(uses=["gmm_rnn.pt"], results=results), checkpoints,
                   command=COMMAND)


def recorded_results(checkpoints: Path = CHECKPOINTS) -> dict:
    """The results stored by `record_results`; FileNotFoundError (naming the command) when none are recorded."""
    return recorded("control", "results", checkpoints=checkpoints)
