"""Where lesson 03's RNN jitter comes from: the feet-anchored features put the root wherever the anchor toe and
the predicted pose place it, root = toe in the world - toe relative to the root.  So an error e_t in where the
predicted pose puts the toe relative to the root moves the whole body by -e_t on that frame, and the root's jerk
is the jerk of e_t: its third difference x fps^3.

- `toe_error_jerk`: the error of the toes relative to the root between two sets of raw state features (only the
  pose differs: the root tilt and the joint angles), its mean size and its jerk;
- `teacher_forced_toe_error`: that error for the RNN's one-step predictions (the most likely component's mean,
  every frame predicted from the true ones before it), with the pose columns split into the root tilt and the
  joint angles, and beside two predictors with no model, copying the previous frame and extrapolating linearly;
- `slip_error_by_phase`: the teacher-forced error of the anchor toe's slip on frames where the anchor passes to
  the other toe and on a flight (no foot in contact on the frame before), against the rest.
"""

from __future__ import annotations

import numpy as np
import torch

from course_lib.motion import Motion
from course_lib.representations import encode_state_features, toes_relative
from course_lib.skeleton import Skeleton

POSE_COLUMNS = (4, 5)  # the root's pitch and roll; the joint angles are columns 6 .. D-3


def _toes_relative(raw: torch.Tensor, offsets: torch.Tensor) -> torch.Tensor:
    """Raw state features (N, T, D) on skeletons offsets (N, J, 3) -> both toes relative to the root (N, T, 2, 3)."""
    return toes_relative(raw, Skeleton.canonical(), offsets)


def toe_error_jerk(pred: torch.Tensor, true: torch.Tensor, offsets: torch.Tensor, fps: float) -> dict:
    """Raw state features pred, true (N, T, D) of the same motions (skeletons offsets (N, J, 3)) -> the error of
    the toes relative to the root that pred's pose makes: mean and median size (m) over frames and both toes, and
    the mean size of its third difference x fps^3 (m/s^3), the jerk it gives an anchored root.

    Only the pose is compared (the root tilt and the joint angles): pred's other columns are taken from true."""
    if pred.shape != true.shape or pred.ndim != 3 or pred.shape[1] < 4:
        raise ValueError(f"toe_error_jerk: pred and true must be the same (N, T >= 4, D), got {tuple(pred.shape)} "
                         f"and {tuple(true.shape)}")
    mixed = true.clone()
    cols = list(POSE_COLUMNS) + list(range(6, true.shape[-1] - 2))
    mixed[..., cols] = pred[..., cols]
    e = _toes_relative(mixed.double(), offsets.double()) - _toes_relative(true.double(), offsets.double())
    d3 = e[:, 3:] - 3 * e[:, 2:-1] + 3 * e[:, 1:-2] - e[:, :-3]
    size = e.norm(dim=-1)
    return {"mean_m": float(size.mean()), "median_m": float(size.median()),
            "jerk": float(d3.norm(dim=-1).mean()) * fps ** 3}


def _teacher_forced(model, clips: list[Motion], stats) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """-> the model's raw features (N, T, D) of the clips, its one-step means for frames 1..T-1 (N, T-1, D) (row t:
    p(y_{t+1} | y_{<=t}), the most likely component's mean, raw units) and the clips' skeletons (N, J, 3)."""
    from course_lib.experiments.gmm_rnn import clip_offsets, to_rnn

    x = torch.from_numpy(np.stack([(encode_state_features(m) - stats[0]) / stats[1] for m in clips])).float()
    off = clip_offsets(clips)
    y = to_rnn(x, stats, model, off)
    mean, std = model.feature_mean.double(), model.feature_std.double()
    with torch.no_grad():
        params, _ = model(y[:, :-1])
    top = params["logits"].argmax(-1)[..., None, None].expand(*params["logits"].shape[:2], 1, params["mu"].shape[-1])
    mu = params["mu"].gather(2, top)[:, :, 0].double() * std + mean
    return y.double() * std + mean, mu, off


def teacher_forced_toe_error(model, clips: list[Motion], stats, fps: float = 30.0) -> dict:
    """`toe_error_jerk` of the RNN's one-step means on the clips (frames 2..T-1: each predicted from the true
    frames before it) -> {"model": ..., "model, root tilt only": ..., "model, joint angles only": ...,
    "copy the previous frame": ..., "linear extrapolation": ...}."""
    raw, mu, off = _teacher_forced(model, clips, stats)
    true = raw[:, 2:]
    out = {"model": toe_error_jerk(mu[:, 1:], true, off, fps)}
    for name, cols in (("model, root tilt only", list(POSE_COLUMNS)),
                       ("model, joint angles only", list(range(6, raw.shape[-1] - 2)))):
        part = true.clone()
        part[..., cols] = mu[:, 1:, cols]
        out[name] = toe_error_jerk(part, true, off, fps)
    out["copy the previous frame"] = toe_error_jerk(raw[:, 1:-1], true, off, fps)
    out["linear extrapolation"] = toe_error_jerk(2 * raw[:, 1:-1] - raw[:, :-2], true, off, fps)
    return out


def slip_error_by_phase(model, clips: list[Motion], stats) -> dict:
    """The RNN's teacher-forced error in the anchor toe's slip (m/s, the one-step means of columns 0-1) on the
    clips, by phase of step t: whether the anchor (the lower toe on frame t-1) is another toe than step t-1's
    (a change) and whether frame t-1 has no foot in contact (a flight) -> {phase: {"steps", "error", "true",
    "share"}} with share the phase's part of the summed error.  For a model that reads ``feet_anchored``
    features with the "lower" rule."""
    raw, mu, off = _teacher_forced(model, clips, stats)
    fps = float(model.config.fps)
    rel = _toes_relative(raw, off.double())
    anchor = rel[:, :-1, :, 1].argmin(-1)  # step t's anchor (t = 1..T-1): the lower toe on frame t-1
    change = anchor[:, 1:] != anchor[:, :-1]  # steps 2..T-1
    flight = (raw[:, 1:-1, -2:] < 0.5).all(-1)  # frame t-1 of steps 2..T-1
    err = (mu[:, 1:, :2] - raw[:, 2:, :2]).norm(dim=-1) * fps
    true = raw[:, 2:, :2].norm(dim=-1) * fps
    out = {}
    for name, m in (("stance, same anchor", ~change & ~flight), ("stance, anchor changes", change & ~flight),
                    ("flight, anchor changes", change & flight), ("flight, same anchor", ~change & flight)):
        out[name] = {"steps": int(m.sum()), "error": float(err[m].mean()) if m.any() else float("nan"),
                     "true": float(true[m].mean()) if m.any() else float("nan"),
                     "share": float(err[m].sum() / err.sum())}
    return out
