"""ONNX export of lesson 06's MoGlow sampling step, its parity check against torch, and the browser demo's files.

Taught in notebooks/06_moglow.ipynb (section "The model in a web page"); the page is web/ (onnxruntime-web + three).

What is exported is one frame of `MoGlowStream.step` (Henter et al. 2019, sec. 4.2, generation):

    h_t, state_t = LSTM([x_{t-tau:t-1} * (1 - dropout), c_{t-tau:t}], state_{t-1})     eq. (17)
    x_t          = f^-1(z_t; h_t)  through the K steps in reverse: coupling^-1, W^-1, actnorm^-1

inputs history (N, tau, D), controls (N, tau + 1, C), z (N, D), h, c (layers, N, H) -> pose (N, D), h, c.
The page keeps the history and the controls itself and calls the graph once per frame.

Why W^-1 is a constant: ONNX (opset 17) has no matrix inverse or log-determinant, so `torch.linalg.inv`
and `slogdet` do not export.  Sampling needs no log-determinant at all, and W is fixed after training, so
each step's W^-1 is computed once here (in float64) and stored in the graph as a constant.
A graph traced at batch 1 does not run at batch 4 (the tracer bakes the 1 into reshapes): trace at batch 2.

Differs from torch: nothing in the maths; float32 kernels sum in another order, so a long autoregressive
rollout can part from torch's by more than one step's rounding -- `parity` reports both.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import torch
from torch import nn

from course_lib.outputs import check_outputs

__all__ = ["SELFTEST_PHASES", "SamplingStep", "control_sequence", "export_step", "parity", "rollout_onnx",
           "rollout_torch", "start_window", "write_demo_files"]

OPSET = 17  # the first opset with LayerNorm etc.; LSTM, MatMul, Sigmoid are older
TRACE_BATCH = 2  # a batch of 1 would be baked into the graph's reshapes
CONTROL_LAG = 0.25  # s: the page's commands reach the model through c += (1 - exp(-dt / lag)) (target - c)
# The self-test's command program (name, seconds, forward m/s, sideways m/s, yaw rate rad/s; + = left turn).
SELFTEST_PHASES = (("stand", 2.0, 0.0, 0.0, 0.0), ("walk", 4.0, 1.2, 0.0, 0.0),
                   ("turn left", 3.0, 1.2, 0.0, 0.8), ("run", 3.0, 3.0, 0.0, 0.0))


class SamplingStep(nn.Module):
    """One generation frame of a trained MoGlow (LSTM conditioner, Glow next step), export-ready.

    history (N, tau, D) standardised poses x_{t-tau:t-1}, controls (N, tau + 1, C) c_{t-tau:t},
    z (N, D) latent, h, c (layers, N, H) LSTM state -> pose x_t (N, D), next h, next c."""

    def __init__(self, model):
        super().__init__()
        cfg = model.config
        if cfg.conditioner != "lstm" or cfg.next_step != "glow":
            raise ValueError(f"SamplingStep: exports the LSTM + Glow MoGlow, got {cfg.conditioner} + {cfg.next_step}")
        if cfg.coupling_net != "mlp":  # a recurrent coupling's state would need inputs and outputs of its own
            raise ValueError(f"SamplingStep: exports MLP couplings (coupling_net='mlp'), got {cfg.coupling_net!r}")
        self.lstm, self.flow, self.scale = model.lstm, model.flow, model.history_scale()
        for k, layer in enumerate(model.flow):  # W^-1 once, in float64, stored as a constant of the graph
            w_inv = torch.linalg.inv(layer.linear.weight().detach().double()).float()
            self.register_buffer(f"w_inv_{k}", w_inv)

    def forward(self, history, controls, z, h, c):
        inputs = torch.cat((history.flatten(1) * self.scale, controls.flatten(1)), -1)[:, None]  # (N, 1, I)
        out, (h, c) = self.lstm(inputs, (h, c))  # eq. (17): (N, 1, H)
        cond, x = out[:, 0], z
        for k in reversed(range(len(self.flow))):
            step = self.flow[k]
            x = step.coupling.inverse(x, cond)  # x_b = y_b / sigma - t
            x = x @ getattr(self, f"w_inv_{k}").T  # x = W^-1 y: the stored constant
            x = step.actnorm.inverse(x)  # x = y exp(-s) - b
        return x, h, c


def _example(model, batch: int) -> tuple[torch.Tensor, ...]:
    cfg = model.config
    g = torch.Generator().manual_seed(0)
    return (torch.randn(batch, cfg.tau, cfg.pose_dim, generator=g), torch.randn(batch, cfg.tau + 1, cfg.control_dim,
            generator=g), torch.randn(batch, cfg.pose_dim, generator=g),
            torch.zeros(cfg.layers, batch, cfg.hidden), torch.zeros(cfg.layers, batch, cfg.hidden))


NAMES_IN, NAMES_OUT = ("history", "controls", "z", "h", "c"), ("pose", "h_next", "c_next")


def export_step(model, path, opset: int = OPSET, overwrite: bool = False) -> Path:
    """Write the `SamplingStep` of `model` to `path` (ONNX, dynamic batch, traced at batch 2) -> path.
    An existing file is replaced only with overwrite=True."""
    if opset < 17:
        raise ValueError(f"export_step: opset must be >= 17, got {opset}")
    (path,) = check_outputs([path], overwrite=overwrite, who="export_step")
    path.parent.mkdir(parents=True, exist_ok=True)
    step = SamplingStep(model).eval()
    axes = {name: {0: "batch"} for name in ("history", "controls", "z", "pose")}
    axes.update({name: {1: "batch"} for name in ("h", "c", "h_next", "c_next")})
    with torch.no_grad(), warnings.catch_warnings():
        # the exporter warns about LSTMs traced at batch > 1 without initial states: ours are inputs (h, c)
        warnings.filterwarnings("ignore", message="Exporting a model to ONNX with a batch_size other than 1")
        torch.onnx.export(step, _example(model, TRACE_BATCH), str(path), input_names=list(NAMES_IN),
                          output_names=list(NAMES_OUT), dynamic_axes=axes, opset_version=opset, dynamo=False)
    return path


def _session(path):
    import onnxruntime as ort

    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    return ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])


@torch.no_grad()
def rollout_torch(model, x0, c0, controls, z) -> torch.Tensor:
    """x0 (N, tau, D), c0 (N, tau, C), controls (N, T, C), z (N, T, D) -> poses (N, T, D) by `MoGlowStream`."""
    stream = model.stream(x0, c0)
    return torch.stack([stream.step(controls[:, t], z=z[:, t]) for t in range(controls.shape[1])], 1)


def rollout_onnx(path_or_session, x0, c0, controls, z) -> np.ndarray:
    """The same rollout with the exported step in onnxruntime (float32 numpy in and out) -> (N, T, D)."""
    sess = path_or_session if hasattr(path_or_session, "run") else _session(path_or_session)
    hist, ctrl = np.asarray(x0, np.float32), np.asarray(c0, np.float32)
    controls, z = np.asarray(controls, np.float32), np.asarray(z, np.float32)
    H = sess.get_inputs()[3].shape[-1]
    layers = sess.get_inputs()[3].shape[0]
    h = c = np.zeros((layers, len(hist), H), np.float32)
    out = []
    for t in range(controls.shape[1]):
        ctrl = np.concatenate((ctrl, controls[:, t:t + 1]), 1)
        x, h, c = sess.run(None, {"history": hist, "controls": ctrl, "z": z[:, t], "h": h, "c": c})
        hist, ctrl = np.concatenate((hist[:, 1:], x[:, None]), 1), ctrl[:, 1:]
        out.append(x)
    return np.stack(out, 1)


def parity(model, path, pose_std, frames: int = 200, batch: int = 2, seed: int = 0, part: float = 1e-4) -> dict:
    """ONNX vs torch for the same noise and controls, in metres (pose_std (D,): the modelled features' std).

    -> single_step_max_abs_m (every frame from torch's own history and state), rollout_max_abs_m (both
    autoregressive over `frames`), first_parting_frame (first frame the rollouts differ by > `part` m, or None)."""
    cfg = model.config
    g = torch.Generator().manual_seed(seed)
    x0 = 0.3 * torch.randn(batch, cfg.tau, cfg.pose_dim, generator=g)
    c0 = 0.3 * torch.randn(batch, cfg.tau, cfg.control_dim, generator=g)
    controls = 0.3 * torch.randn(batch, frames, cfg.control_dim, generator=g)
    z = torch.randn(batch, frames, cfg.pose_dim, generator=g)
    ref = rollout_torch(model, x0, c0, controls, z)
    sess = _session(path)
    std = np.asarray(pose_std, np.float64)
    roll = np.abs(rollout_onnx(sess, x0, c0, controls, z) - ref.numpy()) * std  # (N, T, D) metres
    # one step from torch's own inputs: feed the reference history and the LSTM state torch had
    hist_all = torch.cat((x0, ref), 1)
    ctrl_all = torch.cat((c0, controls), 1)
    inputs = torch.cat((hist_all.unfold(1, cfg.tau, 1)[:, :frames].transpose(-1, -2).flatten(2) * model.history_scale(),
                        ctrl_all.unfold(1, cfg.tau + 1, 1).transpose(-1, -2).flatten(2)), -1)
    single, h, c = 0.0, torch.zeros(cfg.layers, batch, cfg.hidden), torch.zeros(cfg.layers, batch, cfg.hidden)
    with torch.no_grad():
        for t in range(frames):
            feed = {"history": hist_all[:, t:t + cfg.tau].numpy(), "controls": ctrl_all[:, t:t + cfg.tau + 1].numpy(),
                    "z": z[:, t].numpy(), "h": h.numpy(), "c": c.numpy()}
            x = sess.run(["pose"], feed)[0]
            single = max(single, float((np.abs(x - ref[:, t].numpy()) * std).max()))
            _, (h, c) = model.lstm(inputs[:, t:t + 1], (h, c))  # torch's state after frame t
    parted = np.nonzero(roll.max((0, 2)) > part)[0]
    return {"frames": frames, "single_step_max_abs_m": single, "rollout_max_abs_m": float(roll.max()),
            "first_parting_frame": int(parted[0]) if len(parted) else None}


# ----------------------------------------------------------------------------- the browser demo's files


def control_sequence(phases=SELFTEST_PHASES, fps: float = 20.0, start=(0.0, 0.0, 0.0), lag: float = CONTROL_LAG):
    """-> raw controls (T, 3) (forward, sideways m/s, yaw rate rad/s): the phases' commands through the page's
    first-order lag c += a (target - c), a = 1 - exp(-1 / (fps lag)), one update per frame, from `start`."""
    a = 1.0 - np.exp(-1.0 / (fps * lag))
    c, out = np.array(start, np.float64), []
    for _, seconds, *target in phases:
        for _ in range(round(seconds * fps)):
            c = c + a * (np.array(target, np.float64) - c)
            out.append(c.copy())
    return np.array(out)


def start_window(stats, fixed, tau: int, fps: float = 20.0, mode: str = "ci") -> tuple[np.ndarray, np.ndarray]:
    """A standing start: the tau frames of the course's locomotion clips with the smallest control,
    standardised with the checkpoint's stats -> poses (tau, D), controls (tau, 3)."""
    from course_lib.datasets import load_dataset
    from course_lib.representations import encode_positions_control

    mean, std = stats
    best = None
    for clip in load_dataset("locomotion", mode=mode, fps=fps):
        f = encode_positions_control(clip)  # (T, 66) raw
        speed = np.abs(f[:, 63:]).max(1)
        run = np.convolve(speed, np.ones(tau), "valid")  # (T - tau + 1,) summed over each window
        i = int(run.argmin())
        if best is None or run[i] < best[0]:
            best = (run[i], f[i:i + tau])
    w = (best[1] - mean) / std
    return w[:, :63][:, ~fixed].astype(np.float32), w[:, 63:].astype(np.float32)


def write_demo_files(out_dir, checkpoints=None, seed: int = 0, overwrite: bool = False) -> dict:
    """Write what web/ bundles into out_dir: moglow_step.onnx and demo.json (stats, skeleton, standing start,
    and the self-test: commands, noise z and torch's poses in metres).  -> the parity dict of the export.
    Existing files there are replaced only with overwrite=True (the command line: --force)."""
    from course_lib.datasets import FixedDofs, load_stats
    from course_lib.experiments import moglow as lesson06
    from course_lib.skeleton import Skeleton

    checkpoints = Path(checkpoints) if checkpoints is not None else lesson06.CHECKPOINTS
    out = Path(out_dir)
    check_outputs([out / "moglow_step.onnx", out / "demo.json"], overwrite=overwrite, who="course_lib.export")
    out.mkdir(parents=True, exist_ok=True)
    model = lesson06.load_model("moglow", checkpoints)  # sha256-verified, weights_only
    mean, std = load_stats(lesson06.stats_file(checkpoints))
    fixed = FixedDofs.from_stats(mean, std).mask[:63]
    cfg, fps = model.config, lesson06.FPS
    path = export_step(model, out / "moglow_step.onnx", overwrite=overwrite)
    check = parity(model, path, std[:63][~fixed])
    x0, c0 = start_window((mean, std), fixed, cfg.tau, fps)
    raw = control_sequence(fps=fps, start=tuple(c0[-1] * std[63:] + mean[63:]))
    controls = torch.from_numpy(((raw - mean[63:]) / std[63:]).astype(np.float32))[None]
    z = torch.randn(1, len(raw), cfg.pose_dim, generator=torch.Generator().manual_seed(seed))
    poses = rollout_torch(model, torch.from_numpy(x0)[None], torch.from_numpy(c0)[None], controls, z)[0]
    local = np.zeros((len(raw), 63))
    local[:, ~fixed] = poses.double().numpy() * std[:63][~fixed] + mean[:63][~fixed]
    local[:, fixed] = mean[:63][fixed]
    sk = Skeleton.canonical()
    demo = {"fps": fps, "tau": cfg.tau, "pose_dim": cfg.pose_dim, "layers": cfg.layers, "hidden": cfg.hidden,
            "mean": mean.tolist(), "std": std.tolist(), "fixed": fixed.astype(int).tolist(),
            "names": list(sk.names), "parents": [int(p) for p in sk.parents], "control_lag": CONTROL_LAG,
            "start_poses": x0.tolist(), "start_controls": c0.tolist(),
            "selftest": {"phases": [{"name": n, "seconds": s, "command": [f, d, y]}
                                    for n, s, f, d, y in SELFTEST_PHASES],
                         "controls_raw": raw.tolist(), "z": z[0].tolist(), "torch_local_m": local.tolist()},
            "export_parity": check}
    (out / "demo.json").write_text(json.dumps(demo, separators=(",", ":")))
    return check


if __name__ == "__main__":  # python -m course_lib.export OUT_DIR [--force]: the files web/build.mjs bundles
    import argparse

    ap = argparse.ArgumentParser(description="Write the browser demo's files: the ONNX MoGlow step and demo.json.")
    ap.add_argument("out", nargs="?", default="build/web-assets", help="output folder (default build/web-assets)")
    ap.add_argument("--force", action="store_true", help="replace the files already there")
    args = ap.parse_args()
    torch.set_num_threads(1)
    print(json.dumps(write_demo_files(args.out, overwrite=args.force), indent=1))
