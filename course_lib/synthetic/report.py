"""Realism figures of synthetic (or any) motion clips, per gait / action.

    python -m course_lib.synthetic.report DATA.npz        # clips saved by course_lib.datasets.save_motions
    python -m course_lib.synthetic.report --generate 40   # a fresh sample of locomotion + actions

Figures (per label: the per-frame gait of locomotion clips, else the clip's action):
- skate_cm_s: mean horizontal speed (cm/s) of a toe joint on frames where it is within
  TOE_MARGIN of its rest height (y < toe rest height + 2 cm, i.e. 0.045 m for the canonical
  0.025 m); the usual foot-skate measure;
- min_foot_cm: lowest ankle / toe joint / toe End Site height (cm) -- ground penetration;
- bone_err_m: largest deviation of an FK bone length from the skeleton's (m);
- speed_m_s: hips horizontal speed (1 s moving average), 5th / 50th / 95th percentile;
- cadence_spm: steps per minute from ground-truth touch-downs (or derived contacts);
- duty / flight: stance fraction per foot and fraction of frames with both feet off the floor;
- heading_deg_s: 95th percentile of |yaw rate| of the root path (deg/s);
- contact_agree: agreement of ground-truth contacts with `course_lib.motion.foot_contacts`;
- jumps: flight time, flight height, the ballistic prediction g t^2 / 8 and g fitted to the root's
  height over the airborne frames (a parabola: 9.81 m/s^2 for a ballistic flight).

Taught in notebooks/00_data_and_skeletons.ipynb (the data card).
"""

from __future__ import annotations

import argparse
from collections import defaultdict

import numpy as np
import torch
from scipy.ndimage import uniform_filter1d

from course_lib.motion import Motion, foot_contacts
from course_lib.rotations import quat_rotate
from course_lib.synthetic.body import leg_geometry

TOE_MARGIN = 0.02  # m above the toe joint's rest height that counts as "on the floor"
G = 9.81


def clip_labels(m: Motion) -> np.ndarray:
    """(T,) label per frame: the locomotion gait name, else the action (or 'unlabelled')."""
    if "gait" in m.meta and "gait_names" in m.meta:
        return np.asarray(m.meta["gait_names"])[np.asarray(m.meta["gait"])]
    return np.full(len(m), m.action or "unlabelled")


def toe_rest_height(m: Motion) -> float:
    """Height of the toe joints above the floor in the rest pose standing on flat feet (m)."""
    return leg_geometry(m.skeleton, "Left").toe_height


def clip_figures(m: Motion) -> dict:
    """Per-frame realism quantities of one clip -> dict of (T,) / (T, 2) arrays and scalars."""
    P = m.positions()  # (T, J, 3)
    sk = m.skeleton
    toes = [sk.index("LeftToeBase"), sk.index("RightToeBase")]
    feet = [sk.index("LeftFoot"), sk.index("RightFoot")]
    vel = np.gradient(P[:, toes], axis=0) * m.fps  # (T, 2, 3)
    hspeed = np.linalg.norm(vel[..., [0, 2]], axis=-1)  # (T, 2)
    low = P[:, toes, 1] < toe_rest_height(m) + TOE_MARGIN
    G_rot = m.global_rotations()
    tips = [P[:, j] + quat_rotate(torch.from_numpy(G_rot[:, j]), torch.from_numpy(
        np.broadcast_to(sk.end_sites[j], (len(m), 3)).copy())).numpy() for j in toes]
    lowest = min(P[:, toes + feet, 1].min(), min(tip[:, 1].min() for tip in tips))
    bones = np.linalg.norm(P[:, 1:] - P[:, list(sk.parents[1:])], axis=-1)
    bone_err = np.abs(bones - sk.bone_lengths()[1:]).max()
    hips = P[:, 0, [0, 2]]
    sp = np.linalg.norm(np.gradient(hips, axis=0), axis=-1) * m.fps
    contacts = np.asarray(m.meta.get("contacts", foot_contacts(P, sk, m.fps)), bool)
    derived = foot_contacts(P, sk, m.fps)
    yaw = m.meta["root_path"][:, 2] if "root_path" in m.meta else None
    return dict(hspeed=hspeed, low=low, lowest=lowest, bone_err=bone_err,
                speed=uniform_filter1d(sp, max(int(m.fps), 1), mode="nearest"), contacts=contacts,
                derived=derived, yaw_rate=None if yaw is None else np.gradient(yaw) * m.fps,
                nan=not (np.isfinite(m.rotations).all() and np.isfinite(P).all()))


def jump_figures(m: Motion) -> dict | None:
    """Flight time (s), flight height (m, hips apex above take-off) and g t^2 / 8 for a jump clip."""
    c = np.asarray(m.meta.get("contacts", m.contacts()), bool)
    air = ~c.any(-1)
    if not air.any():
        return None
    idx = np.nonzero(air)[0]
    a, b = idx[0], idx[-1]  # the longest gap would matter for several jumps; one jump per clip here
    y = m.root_positions[:, 1]
    t = (b - a + 1) / m.fps
    # y(t) = c0 + c1 t + c2 t^2 over the airborne frames: a ballistic flight has -2 c2 = g
    g_fit = -2 * np.polyfit(np.arange(a, b + 1) / m.fps, y[a:b + 1], 2)[0] if b - a >= 2 else np.nan
    return dict(flight_s=t, height_m=float(y[a:b + 1].max() - 0.5 * (y[a - 1] + y[b + 1])),
                ballistic_m=G * t * t / 8, g_fit=float(g_fit))


def realism_report(motions: list[Motion]) -> dict:
    """Clips -> {label: figures} (see the module docstring) plus an 'all' entry."""
    acc = defaultdict(lambda: defaultdict(list))
    for m in motions:
        f = clip_figures(m)
        labels = clip_labels(m)
        for lab in list(np.unique(labels)) + ["all"]:
            sel = labels == lab if lab != "all" else np.ones(len(m), bool)
            a = acc[lab]
            a["skate_sum"].append((f["hspeed"][sel] * f["low"][sel]).sum())
            a["skate_n"].append(f["low"][sel].sum())
            a["lowest"].append(f["lowest"])
            a["bone_err"].append(f["bone_err"])
            a["nan"].append(f["nan"])
            a["speed"].append(f["speed"][sel])
            a["contacts"].append(f["contacts"][sel])
            a["agree"].append((f["contacts"][sel] == f["derived"][sel]).mean(-1))
            rises = (f["contacts"][1:] & ~f["contacts"][:-1])[sel[1:]].sum()
            a["steps"].append(rises)
            a["seconds"].append(sel.sum() / m.fps)
            if f["yaw_rate"] is not None:
                a["yaw"].append(np.abs(f["yaw_rate"][sel]))
            if lab == "jump":
                j = jump_figures(m)
                if j:
                    a["jumps"].append(j)
    return {lab: _summarise(a) for lab, a in acc.items()}


def _summarise(a: dict) -> dict:
    speed = np.concatenate(a["speed"])
    con = np.concatenate(a["contacts"])
    out = dict(frames=int(sum(len(s) for s in a["speed"])),
               skate_cm_s=100 * float(np.sum(a["skate_sum"]) / max(np.sum(a["skate_n"]), 1)),
               min_foot_cm=100 * float(np.min(a["lowest"])), bone_err_m=float(np.max(a["bone_err"])),
               nan=bool(np.any(a["nan"])),
               speed_m_s=[round(float(x), 2) for x in np.percentile(speed, [5, 50, 95])],
               cadence_spm=float(60 * np.sum(a["steps"]) / max(np.sum(a["seconds"]), 1e-9)),
               duty=float(con.mean()), flight=float((~con.any(-1)).mean()),
               contact_agree=float(np.concatenate(a["agree"]).mean()))
    if a["yaw"]:
        out["heading_deg_s_p95"] = float(np.degrees(np.percentile(np.concatenate(a["yaw"]), 95)))
    if a["jumps"]:
        j = a["jumps"]
        out["jump_flight_s"] = float(np.mean([x["flight_s"] for x in j]))
        out["jump_height_m"] = float(np.mean([x["height_m"] for x in j]))
        out["jump_ballistic_m"] = float(np.mean([x["ballistic_m"] for x in j]))
        out["jump_g_fit"] = float(np.mean([x["g_fit"] for x in j]))
    return out


def format_report(rep: dict) -> str:
    """The report as an aligned text table."""
    cols = ["frames", "skate_cm_s", "min_foot_cm", "bone_err_m", "speed_m_s", "cadence_spm", "duty", "flight",
            "heading_deg_s_p95", "contact_agree", "jump_flight_s", "jump_height_m", "jump_ballistic_m", "jump_g_fit"]
    lines = []
    for lab in sorted(rep, key=lambda k: (k == "all", k)):
        r = rep[lab]
        cells = []
        for c in cols:
            if c in r:
                v = r[c]
                cells.append(f"{c}={v:.3g}" if isinstance(v, float) else f"{c}={v}")
        lines.append(f"{lab:>9}: " + "  ".join(cells))
    return "\n".join(lines)


def sample_motions(n: int, seed: int = 0) -> list[Motion]:
    """n random locomotion clips plus n // 4 of each action, on 8 subjects (for a quick report)."""
    from course_lib.synthetic import generate_action, generate_locomotion, make_subjects
    subs = make_subjects(8, seed)
    out = [generate_locomotion(subs[i % 8], None, duration=4.0, seed=seed * 100003 + i) for i in range(n)]
    for k, action in enumerate(("walk", "jog", "jump", "lift")):
        for i in range(max(n // 4, 1)):
            out.append(generate_action(subs[i % 8], action, style=None, seed=seed * 100003 + 7919 * (k + 1) + i))
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("data", nargs="?", help="an .npz written by course_lib.datasets.save_motions")
    ap.add_argument("--generate", type=int, default=0, help="generate N locomotion clips (+ N/4 per action)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    if args.data:
        from course_lib.datasets import load_motions
        motions = load_motions(args.data)
    elif args.generate:
        motions = sample_motions(args.generate, args.seed)
    else:
        ap.error("give DATA.npz or --generate N")
    print(f"{len(motions)} clips")
    print(format_report(realism_report(motions)))


if __name__ == "__main__":
    main()
