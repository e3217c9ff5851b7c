"""Lesson 03: the measured causes of three shortfalls of the shipped GMM-RNN + refiners (issue 14), on the SHIPPED
checkpoints (nothing is trained, nothing is written to checkpoints/).

    OMP_NUM_THREADS=1 python studies/03_gmm_rnn_refiner/gmm_rnn_open_causes.py --out studies/03_gmm_rnn_refiner/gmm_rnn_open_causes_results.json  # ~2 min, 1 core

1. fid: GAN1's FID over its three refiner seeds is 291 +- 64, seed 1 alone 381 (RNN 254).  Clamp test (R's change
   kept on one column group, the RNN's values elsewhere, and the converse), per-feature mean / sd shift of each
   seed's output against the RNN's input (data sd units), leave-clips-out (the most influential clips) and FID per
   test subject, FID = mean term + covariance term, and the estimator's own noise: a paired bootstrap over clips,
   the FID of two halves of the held-out mocap and of 120 training clips against the 120 held-out ones, and the
   same refiners on the RNN motions of four other generation seeds.
2. bits: GAN2's contact bits agree with its poses less often than the RNN's.  Agreement split by the pose's foot
   state (stance / swing), R's bits against the RNN's bits and poses, which of bits and poses moved, and where R's
   raw bits lie with respect to the straight-through gradient's window [0, 1] (autograd: which bits get gradient).
3. grounding: GAN2 seed 1 leaves 8 of its 100 20-s motions ungrounded.  Which motions and frames, the root height
   and the lower toe there, and the same motions with R's change kept on some columns only (root height, root, legs,
   upper body), the RNN's unrefined motions, and with the contact handling (plant_feet) on the refined ones.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

from course_lib.datasets import FixedDofs
from course_lib.evaluation import classifier_features, fid, load_classifier
from course_lib.evaluation.contacts import contact_agreement, lower_toe
from course_lib.experiments import gmm_rnn as X
from course_lib.representations import encode_state_features, feature_names
from course_lib.results import provenance

COMMAND = "OMP_NUM_THREADS=1 python studies/03_gmm_rnn_refiner/gmm_rnn_open_causes.py --out studies/03_gmm_rnn_refiner/gmm_rnn_open_causes_results.json"
GROUPS = {"root": list(range(6)), "legs": list(range(6, 30)), "spine/arms": list(range(30, 66)),
          "contact bits": [66, 67]}


class Scorer:
    """Classifier features of normalised state features (N, T, D) decoded on the held-out clips' skeletons."""

    def __init__(self, stats, clips, fps):
        self.stats, self.clips, self.fps, self.clf = stats, clips, fps, load_classifier("action")

    def features(self, feats: torch.Tensor, clips=None) -> np.ndarray:
        return classifier_features(X.to_motions(feats, self.stats, clips or self.clips, self.fps), self.clf)


def mix(rnn: torch.Tensor, refined: torch.Tensor, cols) -> torch.Tensor:
    """The RNN's motions with R's change kept on cols only."""
    out = rnn.clone()
    out[..., cols] = refined[..., cols]
    return out


def column_shift(rnn: torch.Tensor, refined: torch.Tensor, varying: np.ndarray) -> dict:
    """Per varying column, in data sd units (the features are normalised): mean shift of R's output from its input,
    sd ratio, rms change."""
    a = rnn[..., varying].reshape(-1, len(varying)).double()
    b = refined[..., varying].reshape(-1, len(varying)).double()
    return {"mean_shift": (b.mean(0) - a.mean(0)).numpy(), "sd_ratio": (b.std(0) / a.std(0)).numpy(),
            "rms_change": ((b - a) ** 2).mean(0).sqrt().numpy()}


def fid_terms(fr: np.ndarray, fg: np.ndarray) -> dict:
    """FID = ||mu_r - mu_g||^2 (the mean term) + the covariance term."""
    m = float(((fr.mean(0) - fg.mean(0)) ** 2).sum())
    return {"fid": fid(fr, fg), "mean_term": m, "covariance_term": fid(fr, fg) - m}


def fid_experiment(model, stats, spec, test, train, n_boot: int, seed: int = 0) -> dict:
    T = int(round(spec.eval_seconds * spec.fps))
    mocap = [m[:T] for m in test]
    gan1 = {s: X.load_models(seed=s)[1]["GAN1"] for s in spec.seeds}
    sets = X.continuations(model, {f"GAN1 seed {s}": r for s, r in gan1.items()}, test, stats, spec, seed)
    sc = Scorer(stats, test, spec.fps)
    fr = classifier_features(mocap, sc.clf)
    feats = {k: sc.features(v) for k, v in sets.items()}
    out = {"fid": {k: fid(fr, f) for k, f in feats.items()}, "feature_dim": int(fr.shape[1]),
           "fid_terms": {k: fid_terms(fr, f) for k, f in feats.items()}}
    # real vs real at the same size: 120 random training clips (other subjects) against the 120 held-out ones
    rng = np.random.default_rng(seed)
    real = [fid(fr, classifier_features([train[i][:T] for i in rng.choice(len(train), len(test), replace=False)],
                                           sc.clf)) for _ in range(20)]
    out["mocap_train_vs_heldout_same_size"] = {"n_draws": 20, "mean": float(np.mean(real)), "sd": float(np.std(real)),
                                               "min": float(np.min(real)), "max": float(np.max(real))}
    names = feature_names("state_features")
    varying = np.flatnonzero(~FixedDofs.from_stats(*stats).mask)
    # clamp test: R's change kept on one group only / everywhere but that group
    clamp = {}
    for s in spec.seeds:
        ref = sets[f"GAN1 seed {s}"]
        row = {}
        for g, cols in GROUPS.items():
            vc = [c for c in cols if c in set(varying)]
            row[f"only {g} from R"] = fid(fr, sc.features(mix(sets["RNN"], ref, cols)))
            row[f"all but {g} from R"] = fid(fr, sc.features(mix(ref, sets["RNN"], cols)))
            row[f"rms change {g} (sd)"] = float(((ref - sets["RNN"])[..., vc] ** 2).mean().sqrt()) if vc else 0.0
        clamp[f"GAN1 seed {s}"] = row
    out["clamp"] = clamp
    # per-column shift of R's output vs the RNN's (its input), data sd units
    shifts = {s: column_shift(sets["RNN"], sets[f"GAN1 seed {s}"], varying) for s in spec.seeds}
    top = np.argsort(-np.abs(shifts[1]["mean_shift"]))[:10]
    out["column_shift_top10_seed1"] = [
        {"column": names[varying[i]], **{f"mean_shift seed {s}": float(shifts[s]["mean_shift"][i]) for s in spec.seeds},
         **{f"sd_ratio seed {s}": float(shifts[s]["sd_ratio"][i]) for s in spec.seeds}} for i in top]
    out["column_shift_by_group"] = {
        g: {f"seed {s}": {"mean_abs_mean_shift": float(np.abs(shifts[s]["mean_shift"][idx]).mean()),
                          "max_abs_mean_shift": float(np.abs(shifts[s]["mean_shift"][idx]).max()),
                          "mean_abs_log_sd_ratio": float(np.abs(np.log(shifts[s]["sd_ratio"][idx])).mean())}
            for s in spec.seeds}
        for g, cols in GROUPS.items() if g != "contact bits"
        for idx in [np.flatnonzero(np.isin(varying, cols))]}
    # per joint of seed 1: R's change on that joint's three angles only
    per_joint = {}
    for j in range(2, 22):
        cols = [c for c in range(3 * j, 3 * j + 3) if c in set(varying)]
        if cols:
            per_joint[names[3 * j][:-3]] = fid(fr, sc.features(mix(sets["RNN"], sets["GAN1 seed 1"], cols)))
    out["seed1_only_one_joint_from_R"] = per_joint
    out.update(fid_noise(fr, feats, mocap, test, spec, n_boot, seed))
    # a few clips?  each clip's influence on seed 1's FID (leave one out), then drop the top k from every set
    f1 = feats["GAN1 seed 1"]
    infl = np.array([out["fid"]["GAN1 seed 1"] - fid(fr, np.delete(f1, i, 0)) for i in range(len(f1))])
    order = np.argsort(-infl)
    out["leave_clips_out"] = {"top10_clips": order[:10].tolist(), "top10_influence": infl[order[:10]].tolist()}
    for k in [k for k in (5, 10, 20) if k < len(f1) // 2]:
        keep = np.setdiff1d(np.arange(len(f1)), order[:k])
        out["leave_clips_out"][f"drop top {k} of seed 1"] = {n: fid(fr, f[keep]) for n, f in feats.items()}
    subj = np.array([m.subject for m in test])
    out["fid_per_subject"] = {str(u): {n: fid(fr[subj == u], f[subj == u]) for n, f in feats.items()}
                              for u in np.unique(subj)}
    # other RNN samples of the same clips, the same refiners
    gen = {0: out["fid"]}
    for g_seed in (1, 2, 3, 4):
        other = X.continuations(model, {f"GAN1 seed {s}": r for s, r in gan1.items()}, test, stats, spec, g_seed)
        gen[g_seed] = {k: fid(fr, sc.features(v)) for k, v in other.items()}
    out["fid_by_rnn_generation_seed"] = {str(k): v for k, v in gen.items()}
    out["fid_by_rnn_generation_seed_summary"] = {
        k: {"mean": float(np.mean([v[k] for v in gen.values()])), "sd": float(np.std([v[k] for v in gen.values()]))}
        for k in gen[0]}
    out["seed 1 highest in every generation seed"] = all(
        v["GAN1 seed 1"] > max(v["GAN1 seed 0"], v["GAN1 seed 2"], v["RNN"]) for v in gen.values())
    return out


def fid_noise(fr, feats, mocap, test, spec, n_boot: int, seed: int) -> dict:
    """The FID estimator's noise: a paired bootstrap over clips (a clip's mocap and its continuations resampled
    together) and the FID of random halves of the mocap."""
    rng = np.random.default_rng(seed)
    N = len(fr)
    boot = {k: [] for k in feats}
    diff = {"seed 1 - seed 0": [], "seed 1 - seed 2": [], "seed 1 - RNN": []}
    for _ in range(n_boot):
        i = rng.integers(0, N, N)
        v = {k: fid(fr[i], f[i]) for k, f in feats.items()}
        for k in feats:
            boot[k].append(v[k])
        diff["seed 1 - seed 0"].append(v["GAN1 seed 1"] - v["GAN1 seed 0"])
        diff["seed 1 - seed 2"].append(v["GAN1 seed 1"] - v["GAN1 seed 2"])
        diff["seed 1 - RNN"].append(v["GAN1 seed 1"] - v["RNN"])
    halves = []
    for _ in range(50):
        p = rng.permutation(N)
        halves.append(fid(fr[p[: N // 2]], fr[p[N // 2:]]))
    q = lambda a: {"mean": float(np.mean(a)), "sd": float(np.std(a)), "p2.5": float(np.percentile(a, 2.5)),  # noqa: E731
                   "p97.5": float(np.percentile(a, 97.5))}
    return {"bootstrap": {"n": n_boot, **{k: q(v) for k, v in boot.items()},
                          **{f"difference {k}": {**q(v), "fraction_above_0": float(np.mean(np.array(v) > 0))}
                             for k, v in diff.items()}},
            "mocap_half_vs_half_60_clips": {"n_splits": 50, **q(halves)}}


def bits_experiment(model, stats, spec, test, seed: int = 0) -> dict:
    gan2 = {s: X.load_models(seed=s)[1]["GAN2"] for s in spec.seeds}
    sets = X.continuations(model, {f"GAN2 seed {s}": r for s, r in gan2.items()}, test, stats, spec, seed)
    motions = {k: X.to_motions(v, stats, test, spec.fps) for k, v in sets.items()}
    derived = {k: np.stack([m.contacts() for m in ms]) for k, ms in motions.items()}  # (N, T, 2) from the pose
    raw = {k: X.contact_bits(v, stats) for k, v in sets.items()}  # (N, T, 2) raw bits
    bits = {k: b > 0.5 for k, b in raw.items()}
    out = {}
    for k in sets:
        d, b = derived[k], bits[k]
        out[k] = {"agreement": contact_agreement(motions[k], raw[k]),
                  "stance_fraction (pose)": float(d.mean()),
                  "P(bit on | pose stance)": float(b[d].mean()), "P(bit off | pose swing)": float((~b[~d]).mean()),
                  "bit_on_fraction": float(b.mean())}
        if k == "RNN":
            continue
        r, rb, rd = raw[k], bits["RNN"], derived["RNN"]
        lost = rd & ~d  # pose contacts of the RNN that R's pose no longer has
        low, slow = foot_low_slow(motions[k], spec.fps)
        out[k].update({
            "pose contacts lost (of the RNN's)": float(lost.sum() / rd.sum()),
            "lost contacts: foot still low, now too fast": float((low & ~slow)[lost].mean()),
            "lost contacts: foot lifted above the height limit": float((~low)[lost].mean()),
            "RNN bits vs these poses": float((rb == d).mean()),
            "these bits vs RNN poses": float((b == rd).mean()),
            "bits flipped from the RNN's": float((b != rb).mean()),
            "pose contacts changed from the RNN's": float((d != rd).mean()),
            # the straight-through gradient of discriminator_input passes only where the raw bit is in [0, 1]
            "raw bit in [0, 1] (gets gradient)": float(((r >= 0) & (r <= 1)).mean()),
            "raw bit < 0": float((r < 0).mean()), "raw bit > 1": float((r > 1).mean()),
            "raw bit in [0, 1] where the RNN bit is 0": float(((r >= 0) & (r <= 1))[~rb].mean()),
            "raw bit in [0, 1] where the RNN bit is 1": float(((r >= 0) & (r <= 1))[rb].mean()),
            # a bit R flipped and pushed past the window gets no gradient that could flip it back
            "flipped bits outside [0, 1] (of the flipped)": float((~((r >= 0) & (r <= 1)))[b != rb].mean()),
            "flipped bits that now disagree with the pose (of the flipped)": float((b != d)[b != rb].mean()),
            "mean |R's bit change|": float(np.abs(r - raw["RNN"]).mean()),
            # GAN2's disagreeing (frame, foot) pairs, by what R changed there (fractions of all pairs)
            "disagree: RNN already disagreed, nothing changed": float(((b != d) & (b == rb) & (d == rd)).mean()),
            "disagree: R moved the pose (bit kept)": float(((b != d) & (b == rb) & (d != rd)).mean()),
            "disagree: R flipped the bit (pose contact kept)": float(((b != d) & (b != rb) & (d == rd)).mean()),
            "disagree: R changed both": float(((b != d) & (b != rb) & (d != rd)).mean()),
            "disagree: bit on, pose swing": float((b & ~d).mean()),
            "disagree: bit off, pose stance": float((~b & d).mean()),
            "RNN disagree: bit on, pose swing": float((rb & ~rd).mean()),
            "RNN disagree: bit off, pose stance": float((~rb & rd).mean()),
            "max |R's bit change|": float(np.abs(r - raw["RNN"]).max()),
            "autograd: fraction of bits with nonzero gradient":
                bit_gradient_fraction(gan2[int(k[-1])], sets[k], X.clip_offsets(test))})
    return out


def foot_low_slow(motions, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """motion.foot_contacts' two tests apart, motions (N of T frames) -> (low, slow) (N, T, 2) bool: "low", the ankle
    or the toe under its CONTACT_HEIGHT; "slow", one of them under its height and slower than CONTACT_SPEED (this is
    motion.foot_contacts itself), so low & ~slow is a foot near the floor that moves too fast to count."""
    from course_lib.motion import CONTACT_HEIGHT, CONTACT_SPEED

    pos = np.stack([m.positions() for m in motions])  # (N, T, J, 3)
    speed = np.linalg.norm(np.gradient(pos, axis=1) * fps, axis=-1)  # (N, T, J)
    sk = motions[0].skeleton
    low, slow = [], []
    for side in ("Left", "Right"):
        js = [(sk.index(side + part), h) for part, h in CONTACT_HEIGHT.items()]
        under = [pos[..., j, 1] < h for j, h in js]
        low.append(np.logical_or.reduce(under))
        slow.append(np.logical_or.reduce([u & (speed[..., j] < CONTACT_SPEED)
                                          for u, (j, _) in zip(under, js, strict=True)]))
    return np.stack(low, -1), np.stack(slow, -1)


def bit_gradient_fraction(refiner, refined: torch.Tensor, offsets: torch.Tensor) -> float:
    """Fraction of the bit entries of R's output (N, T, D), motions on skeletons offsets (N, J, 3), through which
    D's input passes a gradient (autograd on Refiner.discriminator_input, the path R's bits get D's gradient from)."""
    x = refined.detach().clone().requires_grad_(True)
    d_in = refiner.discriminator_input(x, offsets)
    d_in[..., -2:].sum().backward()
    return float((x.grad[..., list(refiner.config.contact_dims)] != 0).float().mean())


def ungrounded_report(pos: np.ndarray, skeleton, toe_top: float, lo: float, hi: float) -> dict:
    low = lower_toe(pos, skeleton)  # (N, T)
    grounded = low <= toe_top + 0.05
    bad = np.flatnonzero(~grounded.all(1))
    rows = []
    for i in bad:
        t = np.flatnonzero(~grounded[i])
        rows.append({"motion": int(i), "first_frame": int(t[0]), "frames_ungrounded": int(len(t)),
                     "frames": t.tolist(),
                     "max_lower_toe_m": float(low[i].max()), "root_height_at_first_m": float(pos[i, t[0], 0, 1]),
                     "root_height_max_m": float(pos[i, :, 0, 1].max())})
    h = pos[:, :, 0, 1]
    return {"grounded_motions": int(grounded.all(1).sum()), "max_lower_toe_m": float(low.max()),
            "motions_within_2cm_of_the_limit": int((low.max(1) > toe_top + 0.03).sum()),
            "lower_toe_p99.9_m": float(np.percentile(low, 99.9)),
            "in_range_motions": int(((h >= lo - 0.05) & (h <= hi + 0.05)).all(1).sum()), "ungrounded": rows}


def still_ungrounded(fixed, ungrounded: list, stats, pos_of, skeleton, around: int = 2) -> list:
    """For each frame the contact handling leaves ungrounded: its lower toe and contact bits (raw), and how many
    frames within ``around`` of it have either bit above 0.5 (plant_feet holds only flagged feet)."""
    rows = []
    for r in ungrounded:
        bits = X.contact_bits(fixed[[r["motion"]]], stats)[0]  # (T, 2) raw
        low = lower_toe(pos_of(fixed[[r["motion"]]])[0], skeleton)  # (T,)
        for t in r["frames"]:
            near = bits[max(0, t - around): t + around + 1]
            rows.append({"motion": r["motion"], "frame": int(t), "lower toe (m)": float(low[t]),
                         "contact bits (raw)": [float(b) for b in bits[t]],
                         f"frames within {around} with a bit > 0.5": int((near > 0.5).any(-1).sum()),
                         "frames around": len(near)})
    return rows


def grounding_experiment(model, stats, spec, test, seed: int = 0) -> dict:
    """long_generation's grounding check, per motion, with R's change kept on some columns only."""
    start = test[0]
    T = int(round(spec.random_seconds * spec.fps))
    x0 = torch.from_numpy((encode_state_features(start)[:2] - stats[0]) / stats[1]).float().expand(spec.n_random, 2, -1)
    off = X.clip_offsets([start] * spec.n_random)
    rnn = X.generate(model, x0.contiguous(), T - 2, off, stats, torch.Generator().manual_seed(seed), spec.sample_bias,
                     spec.sample_angle_noise, spec.sample_root_noise)
    like = [start] * spec.n_random
    heights = np.concatenate([m.root_positions[:, 1] for m in test])
    lo, hi = float(heights.min()), float(heights.max())
    toe_top = float(max(lower_toe(m.positions(), m.skeleton).max() for m in test))
    pos_of = lambda f: np.stack([m.positions() for m in X.to_motions(f, stats, [start] * len(f), spec.fps)])  # noqa: E731
    out = {"data_lower_toe_max_m": toe_top, "data_root_height_m": [lo, hi],
           "RNN": ungrounded_report(pos_of(rnn), start.skeleton, toe_top, lo, hi)}
    variants = {"root height from R only": [3], "all but root height from R": [c for c in range(68) if c != 3],
                "root from R only": GROUPS["root"], "legs from R only": GROUPS["legs"],
                "spine/arms from R only": GROUPS["spine/arms"],
                "all but root from R": [c for c in range(68) if c >= 6]}
    for s in spec.seeds:
        refiner = X.load_models(seed=s)[1]["GAN2"]
        with torch.no_grad():
            ref = refiner(rnn, off)
        res = {"GAN2": ungrounded_report(pos_of(ref), start.skeleton, toe_top, lo, hi)}
        if s == 1:
            for name, cols in variants.items():
                res[name] = ungrounded_report(pos_of(mix(rnn, ref, cols)), start.skeleton, toe_top, lo, hi)
            bad = [r["motion"] for r in res["GAN2"]["ungrounded"]]
            d = (ref - rnn)[bad].double() * torch.as_tensor(stats[1])  # raw units
            res["R's root-height change on the ungrounded motions (m)"] = {  # none ungrounded: nothing to measure
                "mean": float(d[..., 3].mean()), "max": float(d[..., 3].max())} if bad else None
            rnn_low = lower_toe(pos_of(rnn[bad]), start.skeleton) if bad else None
            ref_pos = pos_of(ref[bad]) if bad else None
            res["at the ungrounded frames"] = [
                {"motion": int(i), "frame": int(t),
                 "GAN2 lower toe (m)": float(lower_toe(ref_pos[k], start.skeleton)[t]),
                 "RNN lower toe (m)": float(rnn_low[k, t]), "RNN root height (m)": float(pos_of(rnn[[i]])[0, t, 0, 1]),
                 "GAN2 root height (m)": float(ref_pos[k, t, 0, 1]), "R's root-height change (m)": float(d[k, t, 3])}
                for k, i in enumerate(bad) for t in res["GAN2"]["ungrounded"][k]["frames"][:1]]
            d_all = (ref - rnn).double() * torch.as_tensor(stats[1])
            res["R's root-height change on all motions (m)"] = {"mean": float(d_all[..., 3].mean()),
                                                                 "max": float(d_all[..., 3].max())}
            fixed = X.with_contacts(ref, stats, like, spec.contact_smooth, spec.contact_method)
            res["GAN2 + contacts"] = ungrounded_report(pos_of(fixed), start.skeleton, toe_top, lo, hi)
            res["still ungrounded after the contact handling"] = still_ungrounded(
                fixed, res["GAN2 + contacts"]["ungrounded"], stats, pos_of, start.skeleton)
        out[f"seed {s}"] = res
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--only", nargs="*", choices=("fid", "bits", "grounding"), default=None)
    parser.add_argument("--clips", type=int, default=None, help="held-out clips (default all 120; fewer: a test run)")
    parser.add_argument("--motions", type=int, default=100, help="long-generation motions (100 as shipped)")
    parser.add_argument("--boot", type=int, default=500)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    torch.set_flush_denormal(True)
    spec = X.Lesson03Spec(n_random=args.motions)
    train, test, _ = X.lesson03_data(spec, False)
    test = test[: args.clips] if args.clips else test
    model, _, stats = X.load_models(seed=0)
    cmd = "python studies/03_gmm_rnn_refiner/gmm_rnn_open_causes.py " + " ".join(sys.argv[1:] if argv is None else argv)
    out = {"command": COMMAND if argv is None and sys.argv[1:] == ["--out", "studies/03_gmm_rnn_refiner/gmm_rnn_open_causes_results.json"]
           else cmd, "test_clips": len(test), "motions": args.motions}
    merged = False
    if args.only and Path(args.out).exists():  # re-measure some parts, keep the others (and the full run's command)
        kept = json.loads(Path(args.out).read_text())
        if (kept.get("test_clips"), kept.get("motions")) == (len(test), args.motions):
            out = dict(kept, re_measured_by=kept.get("re_measured_by", []) + [cmd])
            merged = True
    parts = {"fid": lambda: fid_experiment(model, stats, spec, test, train, args.boot),
             "bits": lambda: bits_experiment(model, stats, spec, test),
             "grounding": lambda: grounding_experiment(model, stats, spec, test)}
    for name in args.only or parts:
        t0 = time.perf_counter()
        out[name] = parts[name]()
        out[f"{name}_seconds"] = time.perf_counter() - t0
        print(f"{name}: {out[f'{name}_seconds']:.0f} s", file=sys.stderr)
    prov = provenance(argv=None if argv is None else [__file__, *argv])  # command run, commit, checkpoints' sha256
    if merged:  # the parts this run re-measured carry its provenance; the file's own is the full run's
        out["added_provenance"] = {**out.get("added_provenance", {}), **{name: prov for name in args.only}}
    else:
        out = {**out, **prov}
    with open(args.out, "w") as f:
        json.dump(X.rounded(out), f, indent=1, default=float)
        f.write("\n")


if __name__ == "__main__":
    main()
