"""Lesson 06 study: does MoGlow trained with StyleGestures' locomotion settings (autoregressive dropout 0.7, history
fed unscaled at generation) plant its feet and move smoothly?  The training-time experiment after
moglow_history_temperature and moglow_teacher_forced.

    python studies/06_moglow/moglow_dropout_history.py --dropout 0.7 --out studies/06_moglow/moglow_dropout_history_results.json
    python studies/06_moglow/moglow_dropout_history.py --dropout 0.95 --history scaled --steps 7000 --out studies/06_moglow/moglow_dropout_history_7000_results.json

The second run is the pretrained recipe trained 7000 steps instead of 5000: the most one core allows in 15 minutes.
Two more runs take the pretrained recipe and change one thing that the paper or the authors' code does otherwise:

    python studies/06_moglow/moglow_dropout_history.py --dropout 0.95 --history scaled --one-body --out studies/06_moglow/moglow_dropout_history_one_body_results.json
    python studies/06_moglow/moglow_dropout_history.py --dropout 0.95 --history scaled --coupling lstm --out studies/06_moglow/moglow_dropout_history_coupling_lstm_results.json

--one-body: every clip on the canonical skeleton (the paper's data were retargeted to one skeleton; ours has 45
bodies, and a pose sampled frame by frame could change the body).  --coupling lstm: each coupling's NN is an LSTM
over the frames, as in the authors' code (StyleGestures' glow/models.py), whose state remembers every earlier
frame's pose features, which history dropout does not hide; ours is an MLP on the shared conditioning.
Trained four times as long (--steps 20000) the model overfits its 5920 windows; --extra-clips 3600 adds that many
generated clips of other subjects to the training split (the held-out clips unchanged):

    python studies/06_moglow/moglow_dropout_history.py --dropout 0.95 --history scaled --steps 20000 --extra-clips 3600 --out studies/06_moglow/moglow_dropout_history_20000_more_data_results.json

Trains one MoGlow (the `moglow` recipe of experiments.moglow: `MoGlowConfig.cpu()`, same steps, LR schedule and
seed) with the given dropout, history rule and steps, into memory only (nothing written to checkpoints/), then
measures: free-running foot skate (known floor) and jitter under the held-out clips' controls at temperatures 1.0
and 0.8 (moglow_history_temperature's protocol), teacher-forced skate (moglow_teacher_forced's), held-out NLL, and
the zero-control stepping ratio against the pretrained no-dropout model (lesson 06's control check).
"""

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import torch

from course_lib.experiments import moglow as E
from course_lib.representations import root_start
from course_lib.results import write_study_result

HERE = Path(__file__).resolve().parent


def _study(name: str):
    spec = importlib.util.spec_from_file_location(name, HERE / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


STANDING_SAMPLES = 32


def stepping(model, data, seed: int = 0, n: int = STANDING_SAMPLES) -> tuple[float, int]:
    """-> the feet's stepping speed (m/s) of n 10-s samples told to stand, over those that did not blow up
    (`experiments.moglow.exploded`), and how many blew up."""
    frames = E.TAU + int(10 * E.FPS)
    poses, ctl = E.generate(model, data, E.constant_control(data, n, frames), seed)
    ok = ~E.exploded(poses)
    speed = E.foot_speed(E.local_positions(data, poses[ok, E.TAU:], ctl[ok, E.TAU:]), E.STEP_LAG) if ok.any() else None
    return speed, int((~ok).sum())


@torch.no_grad()
def window_nll(model, data: dict) -> torch.Tensor:
    """-> (N,) held-out NLL of each window, nats per frame (its mean is `experiments.moglow.nll_per_frame`)."""
    frames = data["poses"].shape[1] - model.config.tau
    return torch.cat([-model.log_prob(data["poses"][i:i + 64], data["controls"][i:i + 64]) / frames
                      for i in range(0, len(data["poses"]), 64)])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--dropout", type=float, default=0.7)
    parser.add_argument("--steps", type=int, default=E.STEPS)
    parser.add_argument("--history", choices=("scaled", "unscaled"), default="unscaled",
                        help="the history rule at generation: x (1 - dropout) (the course's) or as is (StyleGestures')")
    parser.add_argument("--one-body", action="store_true", help="every clip retargeted to the canonical skeleton")
    parser.add_argument("--extra-clips", type=int, default=0,
                        help="more generated clips (other subjects) added to the training split only")
    parser.add_argument("--coupling", choices=("mlp", "lstm"), default="mlp",
                        help="each coupling's NN: an MLP (the course's) or an LSTM over the frames (the authors' code)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    data = E.load_data("full", one_body=args.one_body, extra_clips=args.extra_clips)
    E.MODELS["moglow"] = {"dropout": args.dropout, "history_scale": args.history == "scaled",
                          "coupling_net": args.coupling}
    model, hist = E.train_model("moglow", data, args.steps, seed=0)
    out = {"command": "python " + " ".join(sys.argv), "dropout": args.dropout, "history_scale": args.history == "scaled",
           "steps": args.steps, "one_body": args.one_body, "extra_clips": args.extra_clips,
           "train_windows": len(data.train["poses"]), "coupling_net": args.coupling,
           "train_seconds": time.perf_counter() - t0, **measure(model, data, args.one_body)}
    out["seconds"] = time.perf_counter() - t0
    write_study_result(args.out, out)
    print(out)


def with_ratio(row: dict, mocap: dict) -> dict:
    """A free-running row with its jitter as a multiple of mocap's (NaN when every sample blew up)."""
    return {**row, "jitter_x_mocap": row.get("jitter", float("nan")) / mocap["jitter"]}


def measure(model, data, one_body: bool = False) -> dict:
    """The study's measures of one trained model: held-out NLL, free-running skate and jitter at T = 1, 0.8 and 0
    beside mocap's, teacher-forced skate (MLP couplings), and the zero-control stepping against the pretrained
    no-dropout model's."""
    ht, tf = _study("moglow_history_temperature"), _study("moglow_teacher_forced")
    starts = [root_start(m) for m in data.test_clips]
    p, c = data.test["poses"], data.test["controls"]
    out = {"nll_per_frame": E.nll_per_frame(model, data.test),
           "nll_per_frame_median_window": float(window_nll(model, data.test).median()),
           "mocap": ht.scores(data, p, c, starts), "free_running": {}}
    for temp in (1.0, 0.8):
        row = ht.sample_scores(model, data, starts, temp)
        out["free_running"][f"T={temp}"] = with_ratio(row, out["mocap"])
        print(temp, row, flush=True)
    skel = data.test_clips[0].skeleton
    toes = [skel.index("LeftToeBase"), skel.index("RightToeBase")]
    mocap = data.positions(p, c, starts)
    if model.config.coupling_net == "mlp":  # one_step's parallel inverse would feed a recurrent coupling sampled, not mocap, frames
        out["teacher_forced_skate"], out["teacher_forced_exploded"] = {}, {}
        for t in (1.0, 0.0):
            pred = tf.one_step(model, p, c, t)
            ok = ~E.exploded(pred)  # a step that blows up is counted and left out
            kept = [s for s, k in zip(starts, ok, strict=True) if k]
            out["teacher_forced_skate"][f"T={t}"] = tf.pair_skate(mocap[ok.numpy()],
                                                                  data.positions(pred[ok], c[ok], kept), toes)
            out["teacher_forced_exploded"][f"T={t}"] = int((~ok).sum())
    row = ht.kept_scores(data, *E.generate(model, data, data.test["controls"], 0, 0.0, starts=(p[:, :E.TAU], c[:, :E.TAU])),
                         starts)  # z = 0: every frame the flow's mode given its history (no sampling noise)
    out["free_running"]["T=0.0"] = with_ratio(row, out["mocap"])
    # the pretrained no-dropout model reads the course's (many-body) standardisation
    (speed, blew_up), (speed_nodrop, _) = stepping(model, data), stepping(
        E.load_model("moglow_nodrop"), E.load_data("full") if one_body else data)
    out["zero_control"] = {"feet_speed": speed, "nodrop_feet_speed": speed_nodrop, "samples": STANDING_SAMPLES,
                           "exploded": blew_up,
                           "ratio": None if speed is None else speed / speed_nodrop}
    return out


if __name__ == "__main__":
    main()
