"""Lesson 06 study: is MoGlow's foot skate made by the next-step distribution itself, or by free running?

    python studies/06_moglow/moglow_teacher_forced.py --out studies/06_moglow/moglow_teacher_forced_results.json

Teacher-forced: every pose x_t of the held-out windows is sampled from p(x_t | the *mocap's* history and controls)
(z ~ N(0, T^2 I)); its toes are compared with the mocap's toes one frame earlier, both placed on the mocap's own root
path.  Skate = the horizontal toe speed over frame pairs (mocap t-1, sample t) where both toes are under 5 cm
(`foot_skate_at_floor`'s rule on those pairs); the mocap's own pairs give the floor.  For the toes the mocap plants
(under 5 cm), the study also compares the mode's horizontal error with the spread of 8 draws at T = 1: a density
calibrated to its own error has a spread (the root of the summed x, z variances) about 1.13 times its mean error
(2-D Gaussian: sqrt(2) sigma against sqrt(pi / 2) sigma).  Free-running numbers are in moglow_history_temperature.
Writes nothing to checkpoints/.
"""

import argparse
import sys
import time

import numpy as np
import torch

from course_lib.evaluation.metrics import CONTACT_HEIGHT
from course_lib.experiments import moglow as E
from course_lib.representations import root_start
from course_lib.results import write_study_result

MODELS = ("moglow", "moglow_nodrop")
TEMPERATURES = (1.0, 0.0)


@torch.no_grad()
def one_step(model, p, c, temperature: float, seed: int = 0) -> torch.Tensor:
    """x_t ~ p(x_t | mocap x_{t-tau:t-1}, c_{t-tau:t}) for every t >= tau -> (N, T, D), the first tau the mocap's."""
    h, _ = model.condition(model.condition_inputs(p, c))  # (N, T', H)
    z = temperature * torch.randn(p[:, E.TAU:].shape, generator=torch.Generator().manual_seed(seed))
    x = model.flow_inverse(z, h, model.weight_inverses())
    return torch.cat((p[:, :E.TAU], x), 1)


def pair_skate(prev: np.ndarray, nxt: np.ndarray, toes) -> float:
    """World positions (N, T, 21, 3) of frames t-1 (prev) and t (nxt) -> mean toe speed, m/s, over pairs in contact."""
    a, b = prev[:, E.TAU - 1:-1][:, :, toes], nxt[:, E.TAU:][:, :, toes]  # (N, T', 2, 3)
    contact = (a[..., 1] < CONTACT_HEIGHT["ToeBase"]) & (b[..., 1] < CONTACT_HEIGHT["ToeBase"])
    v = np.linalg.norm(b[..., [0, 2]] - a[..., [0, 2]], axis=-1) * E.FPS
    return float(v[contact].mean())


SPREAD_DRAWS = 8


def planted_toe_spread(model, data, p, c, starts, toes, mocap) -> dict:
    """Planted toes (mocap's under 5 cm): the mode's horizontal error and the spread of SPREAD_DRAWS draws at
    T = 1 around their mean, m (means over those toe-frames)."""
    def toe_xz(seed, temperature):
        return data.positions(one_step(model, p, c, temperature, seed), c, starts)[:, E.TAU:, toes][..., [0, 2]]

    gt = mocap[:, E.TAU:, toes]
    planted = gt[..., 1] < CONTACT_HEIGHT["ToeBase"]
    error = np.linalg.norm(toe_xz(0, 0.0) - gt[..., [0, 2]], axis=-1)[planted]
    draws = np.stack([toe_xz(s, 1.0) for s in range(SPREAD_DRAWS)])
    spread = np.sqrt(draws.var(0).sum(-1))[planted]
    return {"mode_error_m": float(error.mean()), "spread_m": float(spread.mean()),
            "spread_over_error": float(spread.mean() / error.mean())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    data = E.load_data("full")
    p, c = data.test["poses"], data.test["controls"]
    starts = [root_start(m) for m in data.test_clips]
    skel = data.test_clips[0].skeleton
    toes = [skel.index("LeftToeBase"), skel.index("RightToeBase")]
    mocap = data.positions(p, c, starts)
    out = {"command": "python " + " ".join(sys.argv), "held_out_windows": len(p),
           "mocap_skate": pair_skate(mocap, mocap, toes), "models": {}}
    for name in MODELS:
        model = E.load_model(name)
        for scaled in ((True, False) if model.config.dropout > 0 else (True,)):
            model.config.history_scale = scaled
            for temp in TEMPERATURES:
                key = f"{name}, history {'scaled' if scaled else 'unscaled'}, T={temp}"
                pred = data.positions(one_step(model, p, c, temp), c, starts)
                out["models"][key] = {"teacher_forced_skate": pair_skate(mocap, pred, toes),
                                      "pose_rmse_m": float(np.sqrt(((pred - mocap)[:, E.TAU:] ** 2).sum(-1).mean()))}
                print(key, out["models"][key], flush=True)
        model.config.history_scale = True  # the shipped rule
        out["models"][f"{name}, planted toes"] = planted_toe_spread(model, data, p, c, starts, toes, mocap)
        print(name, out["models"][f"{name}, planted toes"], flush=True)
    out["seconds"] = time.perf_counter() - t0
    write_study_result(args.out, out)
    print("mocap", out["mocap_skate"])


if __name__ == "__main__":
    main()
