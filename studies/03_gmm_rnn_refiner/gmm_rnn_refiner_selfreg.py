"""Lesson 03's study of R's leg term: on the shipped GMM-RNN, refiner seed 0 (or --seeds), train refiners with a
second self-regularisation term on the hip, knee and ankle angles (RefinerConfig.leg_pose_lam, beside SimGAN's
||R(x) - x||^2 on every pose column, weight pose_lam) and score each with the clamp test: R's change kept on one
group of columns only (root; legs; the rest), the RNN's elsewhere.

    python studies/03_gmm_rnn_refiner/gmm_rnn_refiner_selfreg.py --pose-lam 10 --leg-pose-lam 0 100 --gans GAN1 --out studies/03_gmm_rnn_refiner/gmm_rnn_refiner_selfreg_results.json

The shipped refiners (trained at pose_lam 10, leg_pose_lam 30) are scored as they are.  Writes nothing to
checkpoints/ (about 5 min per GAN on one core).
"""

import argparse
import dataclasses
import json
import time
from pathlib import Path

import numpy as np
import torch

from course_lib.evaluation import fid, foot_skate_at_floor, jitter
from course_lib.experiments import gmm_rnn as X
from course_lib.results import provenance

LEGS = ("UpLeg", "Leg", "Foot", "ToeBase")


def column_groups(skeleton) -> dict:
    """{group: state-feature columns}: the root's six, the legs' angles, the other angles."""
    legs = [c for j, name in enumerate(skeleton.names[1:]) if name.replace("Left", "").replace("Right", "") in LEGS
            for c in range(6 + 3 * j, 9 + 3 * j)]
    return {"root": list(range(6)), "legs": legs, "upper body": [c for c in range(6, 66) if c not in legs]}


def score(features, stats, test, fps) -> dict:
    motions = X.to_motions(features, stats, test, fps)
    pos = np.stack([m.positions() for m in motions])
    return {"fid": float(fid(test, motions)), "foot_skate": float(foot_skate_at_floor(pos, fps=fps)),
            "jitter": float(jitter(pos, fps=fps))}


def clamp_test(rnn, refined, stats, test, fps) -> dict:
    """R's change kept on one group of columns only, the RNN's elsewhere -> {group: score}; plus the change's
    rms per group (sd units)."""
    out = {}
    for name, cols in column_groups(test[0].skeleton).items():
        mix = rnn.clone()
        mix[..., cols] = refined[..., cols]
        out[f"only {name} from R"] = score(mix, stats, test, fps)
        out[f"only {name} from R"]["rms_change_sd"] = float((refined - rnn)[..., cols].pow(2).mean().sqrt())
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pose-lam", type=float, nargs="+", default=[0.0, 1.0, 10.0])
    parser.add_argument("--d-joints", nargs="+", default=["end_effectors"], choices=["end_effectors", "all"],
                        help="what D sees (RefinerConfig.discriminator_joints); every pose_lam runs with each")
    parser.add_argument("--leg-pose-lam", type=float, nargs="+", default=[0.0],
                        help="extra self-regularisation weight on the leg angles (RefinerConfig.leg_pose_lam); "
                             "a run per value")
    parser.add_argument("--gans", nargs="+", default=["GAN1", "GAN2"], choices=["GAN1", "GAN2"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0], help="refiner seeds (a run per seed)")
    parser.add_argument("--out", required=True)
    parser.add_argument("--save-dir", type=Path, help="also save each run's refiners here (state dicts)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    torch.set_flush_denormal(True)
    spec = X.Lesson03Spec()
    _, test, ds = X.lesson03_data(spec, False)
    model, shipped, stats = X.load_models(seed=0)
    pool = X.rnn_pool(model, ds, spec, 0)
    cont = X.continuations(model, {"GAN1 shipped": shipped["GAN1"], "GAN2 shipped": shipped["GAN2"]}, test, stats,
                           spec, 0)
    out = {"command": "python studies/03_gmm_rnn_refiner/gmm_rnn_refiner_selfreg.py --pose-lam " + " ".join(map(str, args.pose_lam))
           + " --d-joints " + " ".join(args.d_joints) + " --seeds " + " ".join(map(str, args.seeds))
           + " --leg-pose-lam " + " ".join(map(str, args.leg_pose_lam))
           + (" --gans " + " ".join(args.gans) if args.gans != ["GAN1", "GAN2"] else "")
           + f" --out {args.out}",
           "RNN": score(cont["RNN"], stats, test, spec.fps),
           "RNN + contacts": score(X.with_contacts(cont["RNN"], stats, test, spec.contact_smooth), stats, test,
                                   spec.fps),
           "shipped GAN1": {"all": score(cont["GAN1 shipped"], stats, test, spec.fps),
                                        **clamp_test(cont["RNN"], cont["GAN1 shipped"], stats, test, spec.fps)},
           "shipped GAN2": {"all": score(cont["GAN2 shipped"], stats, test, spec.fps)},
           "runs": {}}
    if Path(args.out).exists():  # runs are merged into an earlier file
        out["runs"] = json.loads(Path(args.out).read_text()).get("runs", {})
    for lam, joints, seed, legs in [(v, j, k, g) for v in args.pose_lam for j in args.d_joints for k in args.seeds
                                    for g in args.leg_pose_lam]:
        s = dataclasses.replace(spec, refiner_pose_lam=lam, discriminator_joints=joints, refiner_leg_pose_lam=legs)
        t0, refiners, run = time.perf_counter(), {}, {}
        for name, contacts in [(n, n == "GAN2") for n in args.gans]:
            r, _, hist = X.train_gan(pool, ds, s, contacts=contacts, seed=seed, progress=False)
            refiners[name], run[f"{name} training"] = r, X._gan_summary(hist)
            if args.save_dir:
                args.save_dir.mkdir(parents=True, exist_ok=True)
                stem = f"{name}_pose{lam}_{joints}_legs{legs}_seed{seed}"
                torch.save(r.state_dict(), args.save_dir / f"{stem}.pt")
        run["quality"] = X.quality_table(model, refiners, test, stats, s, 0)
        run["contact_handling"] = s.contact_method
        cont = X.continuations(model, refiners, test, stats, s, 0)
        for name in refiners:
            run[f"{name} clamp test"] = clamp_test(cont["RNN"], cont[name], stats, test, spec.fps)
        run["seconds"] = time.perf_counter() - t0
        run.update(provenance())  # the run that made this record (runs from an earlier file keep theirs)
        out["runs"][f"pose_lam {lam}, D sees {joints}, legs {legs}"
                    + (f", seed {seed}" if args.seeds != [0] else "")] = run
        brief = {k: {m: round(v[m], 3) for m in ("fid", "foot_skate", "jitter")} for k, v in run["quality"].items()}
        print(lam, joints, seed, legs, brief, flush=True)
        # the command above is the script's own: it spells out the defaults the argv may leave out
        out.update({k: v for k, v in provenance().items() if k != "command"})
        with open(args.out, "w") as f:
            json.dump(X.rounded(out), f, indent=1, default=float)
            f.write("\n")


if __name__ == "__main__":
    main()
