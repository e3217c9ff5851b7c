"""Lesson 03 study: why does D let the refiner's sliding feet through?

    OMP_NUM_THREADS=1 python studies/03_gmm_rnn_refiner/gmm_rnn_refiner_discriminator.py --out studies/03_gmm_rnn_refiner/gmm_rnn_refiner_discriminator_results.json

gmm_rnn_refiner_skate found that R's root and leg changes make the RNN's planted toes slide, although D sees the
end effectors' velocities (eq. 12).  D is not saved with the checkpoints, so this study retrains GAN1 and GAN2 of
refiner seed 0 with the recipe of `python -m course_lib.reproduce gmm_rnn` (the same pool, seed and schedule).  It
records whether R's weights equal the shipped checkpoint's (they need not: the shipped refiners were trained on
AVX2 kernels and an RNN pool sampled under joint limits 2.6e-14 apart), and scores the shipped R beside the
retrained one on the same windows: the toes' speed where they are planted, computed from D's own input.
Then it asks D, on 120 held-out mocap windows and on the RNN's and R's windows (the pool's, as in training):

- how real it finds each (mean probability), and
- whether it notices sliding of a known size: the same mocap windows with the whole body dragged forward at
  0.1, 0.3 and 1.0 m/s (every planted foot then slides at that speed), and the RNN's windows dragged alike.

Writes nothing to checkpoints/ (two refiner trainings: about 12 minutes on one core).
"""

import argparse

import numpy as np
import torch

from course_lib.evaluation import foot_skate_at_floor
from course_lib.experiments import gmm_rnn as X
from course_lib.results import write_study_result

DRAGS = (0.1, 0.3, 1.0)  # m/s, forward
WINDOWS = 120


def dragged(features: torch.Tensor, stats, speed: float, fps: float) -> torch.Tensor:
    """Normalised state features (N, T, D) with the root's forward floor step (column 1, metres per frame) raised by
    speed / fps: the whole body slides forward at `speed` m/s on top of its own motion."""
    mean, std = stats
    out = features.clone()
    out[..., 1] += float(speed / fps / std[1])
    return out


@torch.no_grad()
def toe_slide(refiner, features: torch.Tensor, offsets, height: float = 0.05) -> float:
    """Mean horizontal toe speed (m/s) over the frames where a toe is below `height` m, from D's input: the
    end effectors' floor-frame positions and velocities (eq. 12)."""
    p, v = (t.unflatten(-1, (-1, 3)) for t in refiner.end_effectors(features, offsets))  # (N, T, E, 3)
    toes = [list(refiner.skeleton.end_effectors).index(refiner.skeleton.index(n))
            for n in ("LeftToeBase", "RightToeBase")]
    low = p[..., toes, 1] < height
    return float(v[..., toes, :][..., [0, 2]].norm(dim=-1)[low].mean())


@torch.no_grad()
def realness(refiner, disc, features: torch.Tensor, offsets) -> float:
    """Mean probability D gives windows (N, T, D) of being real (D's input as in training, each window's offsets)."""
    return float(disc(refiner.discriminator_input(features, offsets)).mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    spec = X.Lesson03Spec()
    _, test, ds = X.lesson03_data(spec, False)
    model, shipped, stats = X.load_models(seed=0)
    pool = X.rnn_pool(model, ds, spec, 0)
    T, clips = spec.refiner_window, test[:WINDOWS]  # mocap: the first T frames of each held-out clip
    real_x = torch.from_numpy(np.stack([(X.encode_state_features(m)[:T] - stats[0]) / stats[1] for m in clips])).float()
    real_off = X.clip_offsets(clips)
    g = torch.Generator().manual_seed(1234)
    rnn_x, rnn_off = X.window_sampler(list(pool.features.numpy()), T, WINDOWS, g, pool.offsets)()
    out = {"windows": WINDOWS, "window_frames": T, "drags_m_per_s": list(DRAGS), "refiners": {}}
    for name in ("GAN1", "GAN2"):
        refiner, disc, _ = X.train_gan(pool, ds, spec, contacts=name == "GAN2", seed=0, progress=True)
        same = all(torch.equal(a, b) for a, b in zip(refiner.state_dict().values(),
                                                     shipped[name].state_dict().values(), strict=True))
        with torch.no_grad():
            refined = refiner(rnn_x, rnn_off)
        with torch.no_grad():
            shipped_refined = shipped[name](rnn_x, rnn_off)
        row = {"same_weights_as_shipped": same,
               "toe_slide_m_per_s": {"mocap": toe_slide(refiner, real_x, real_off),
                                     "RNN": toe_slide(refiner, rnn_x, rnn_off),
                                     "R(RNN)": toe_slide(refiner, refined, rnn_off),
                                     "shipped R(RNN)": toe_slide(refiner, shipped_refined, rnn_off),
                                     **{f"mocap dragged {v}": toe_slide(refiner, dragged(real_x, stats, v, spec.fps),
                                                                        real_off) for v in DRAGS}},
               "p_real": {"mocap": realness(refiner, disc, real_x, real_off),
                          "RNN": realness(refiner, disc, rnn_x, rnn_off),
                          "R(RNN)": realness(refiner, disc, refined, rnn_off),
                          "shipped R(RNN)": realness(refiner, disc, shipped_refined, rnn_off)},
               "p_real_mocap_dragged": {str(v): realness(refiner, disc, dragged(real_x, stats, v, spec.fps), real_off)
                                        for v in DRAGS},
               "p_real_rnn_dragged": {str(v): realness(refiner, disc, dragged(rnn_x, stats, v, spec.fps), rnn_off)
                                      for v in DRAGS}}
        out["refiners"][name] = row
        print(name, row, flush=True)
    # the known answer: dragging the mocap windows slides their planted feet at about the drag
    pos = lambda f: np.stack([m.positions() for m in X.to_motions(f, stats, clips, spec.fps)])  # noqa: E731
    out["mocap_window_skate"] = {"0": foot_skate_at_floor(pos(real_x), fps=spec.fps),
                                 **{str(v): foot_skate_at_floor(pos(dragged(real_x, stats, v, spec.fps)), fps=spec.fps)
                                    for v in DRAGS}}
    write_study_result(args.out, out)  # + command, commit, checkpoints' sha256


if __name__ == "__main__":
    main()
