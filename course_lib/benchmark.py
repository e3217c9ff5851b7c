"""Lesson 07: one benchmark of every model of the course on one protocol.

    python -m course_lib.benchmark --force  # the full benchmark -> results/benchmark_results.{json,md}, replaced
    python -m course_lib.benchmark --ci --out /tmp/bench.json  # fewer clips and seeds (CI: under 4 minutes)

Taught in notebooks/07_benchmark.ipynb.  No paper compares these models with each other; the course can,
because they all run on the same synthetic data.  The protocol:

- the held-out clips: lesson 02's test split (3 subjects never trained on by any model, 120 clips of 4 s);
- the same start: every model is given the first ``context`` seconds (0.5 s) of each clip, what MoGlow
  needs (tau = 10 frames at 20 fps); each reads as much of it as it uses (the GMM-RNN its last two frames,
  the VAE-LSTM its first four, Algorithm 1); the hierarchical VRNN and its QuaterNet baseline take no
  start, only the clip's action (walk or jog) and a style;
- the same control programs: models that take control get the clip's own (forward, sideways, yaw-rate)
  control; lesson 04's online controller steers the GMM-RNN with the clip's speed and heading per batch;
  the uncontrolled models run free from the same starts;
- one frame rate and length: every output is resampled to 30 fps (a cubic spline through the native
  frames: exact for 60 -> 30) and measured on the 3.5 s after the context;
- the same reference: for each generation seed, the clips are split in two random halves A and B; every
  model generates from B's starts and is scored against A's mocap; the Mocap row is B's mocap against A's
  (the floor of every measure: FID > 0 at this sample size, C2ST ~0.5);
- FID, IS and C2ST need rotations: every set, mocap included, goes positions -> rotations through
  `representations.motion_from_positions` (no bone twist is observable from positions), so all lose the
  same information.

Measures (all from `course_lib.evaluation`): foot skate, ground penetration, jitter, bone-length violation,
FID / IS / C2ST on the shared classifiers' features, APD of several samples from one start, control
following (root-path and speed error) where a model follows a control of its own making, stability over
20 s (in the mocap's root-height range, not frozen), held-out likelihood where a model has one, frames per
second on one core, parameters and training time (results/<lesson>.json).  A blank always says why.

Differs from the issue: the GMM-RNN's online-control row runs on fewer clips (the controller makes 35-70
frames/s on a shared core) and has no 20-s test (see BLANKS); the refined GMM-RNN uses the refiner of
generation seed mod 3 (refiner seeds 0-2), so its spread includes the refiner's training seed, and lesson
03's contact handling (`Lesson03Spec.contact_method`); the gallery is a video in the lesson, not a separate
site page.  Nothing runs at import time.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

from course_lib.motion import Motion
from course_lib.outputs import check_outputs
from course_lib.paths import CHECKPOINTS
from course_lib.results import rounded

ROOT = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).resolve().parents[1] / "results" / "benchmark_results.json"  # the repository's results/
FPS = 30.0  # the protocol's frame rate (the classifiers' and lesson 03's)

# measure -> (label, unit, better): "low", "high" or "ref" (closest to the Mocap row)
MEASURES = {
    "foot_skate": ("foot skate", "m/s", "low"), "penetration": ("penetration", "m", "low"),
    "jitter": ("jitter", "m/s^3", "ref"), "bone_length": ("bone-length violation", "rel.", "low"),
    "fid": ("FID", "", "low"), "is": ("IS", "", "ref"), "c2st": ("C2ST", "acc.", "low"),
    "apd": ("APD", "m", "ref"), "path_error": ("root-path error", "m", "low"),
    "speed_error": ("speed error", "m/s", "low"), "in_range": ("20 s in range", "frac.", "high"),
    "frozen": ("20 s frozen", "frac.", "low"), "nll": ("held-out NLL", "nats/frame, own space", "low"),
    "fps": ("speed", "frames/s, 1 core", "high"), "params": ("parameters", "", "low"),
    "train_seconds": ("training", "s", "low"),
}
SEEDED = ("foot_skate", "penetration", "jitter", "bone_length", "fid", "is", "c2st", "apd", "path_error",
          "speed_error", "in_range", "frozen")  # measured once per generation seed: mean and sd

UNCONTROLLED = "uncontrolled: runs free from the start"
NO_DENSITY = "deterministic regressor (MSE): no density"
BLANKS = {  # row -> measure -> why the measure does not apply
    "Mocap": {"apd": "one recording per start: no samples to compare", "nll": "not a model",
              "fps": "not a model", "params": "not a model", "train_seconds": "not a model"},
    "ERD": {"path_error": UNCONTROLLED, "speed_error": UNCONTROLLED, "nll": NO_DENSITY},
    "LSTM-3LR": {"path_error": UNCONTROLLED, "speed_error": UNCONTROLLED, "nll": NO_DENSITY},
    "cRBM (CD-15)": {"path_error": UNCONTROLLED, "speed_error": UNCONTROLLED,
                     "nll": "energy model: the partition function is intractable"},
    "VAE-LSTM": {},
    "GMM-RNN": {"path_error": UNCONTROLLED, "speed_error": UNCONTROLLED},
    "GMM-RNN + refiner (GAN2 + contacts)": {"path_error": UNCONTROLLED, "speed_error": UNCONTROLLED,
                                            "nll": "the refiner is a GAN generator: no density"},
    "GMM-RNN, online control": {"in_range": "20 s of MAP control cost ~17 s per sample: see the GMM-RNN row",
                                "frozen": "20 s of MAP control cost ~17 s per sample: see the GMM-RNN row",
                                "nll": "MAP control of the GMM-RNN row's density: no likelihood of its own"},
    "HVRNN (Proposed)": {"path_error": "uncontrolled: action and style labels only",
                         "speed_error": "uncontrolled: action and style labels only",
                         "nll": "its reconstruction term is a geodesic distance: no density in nats"},
    "QuaterNet-style GRU": {"path_error": "uncontrolled: action and style labels only",
                            "speed_error": "uncontrolled: action and style labels only",
                            "nll": "deterministic given its initial state: no density"},
    "MoGlow": {"path_error": "the root is the given control integrated: it follows it by construction",
               "speed_error": "the root is the given control integrated: it follows it by construction"},
}
NLL_NOTES = {"VAE-LSTM": "the negative ELBO, an upper bound on the NLL (<=), 66-D normalised features at 60 fps, "
                         "obs_std 0.2",
             "GMM-RNN": "exact, the RNN's normalised feet-anchored features at 30 fps",
             "MoGlow": "exact, 61-D standardised poses at 20 fps"}


@dataclasses.dataclass
class BenchSpec:
    """How much of the protocol runs (the defaults: the full benchmark, under 15 minutes on one core)."""

    clips: int = 120  # held-out clips (lesson 02's test split has 120)
    seeds: tuple = (0, 1, 2, 3, 4)  # generation seeds: halves A / B and every model's draws (refiner: seed % 3)
    context: float = 0.5  # s of each clip given to every model
    apd_starts: int = 8  # starts of the APD test ...
    apd_samples: int = 5  # ... and samples per start
    long_samples: int = 8  # 20-s samples per model and seed
    long_seconds: float = 20.0
    online_clips: int = 12  # clips per seed for the online controller (B's first ones)
    online_apd: tuple = (2, 3)  # (starts, samples) of the controller's APD
    min_distribution: int = 10  # FID / IS / C2ST need at least this many clips

    @classmethod
    def ci(cls) -> BenchSpec:
        """CI: 40 clips, 2 seeds, the online controller on 4 clips (no distribution scores for it)."""
        return cls(clips=40, seeds=(0, 1), apd_starts=4, apd_samples=3, long_samples=4, online_clips=4,
                   online_apd=(2, 2))


# ----------------------------------------------------------------------------- the protocol's data


@dataclasses.dataclass
class Protocol:
    """The held-out clips and everything derived from them once."""

    spec: BenchSpec
    clips: list  # the held-out Motions at 60 fps (4 s + 2 frames)
    ds: object  # lesson 02's test WindowDataset (its normalisation), one 240-frame window per clip
    x: torch.Tensor  # (N, 240, 66) normalised positions_control at 60 fps
    starts: list  # (x, z, yaw) of each clip's first frame
    truth: np.ndarray  # (N, T, 21, 3) the mocap's world positions on the measured window at FPS
    long_control: np.ndarray  # (L, 3) raw control at 60 fps: context + 20 s of held-out controls back to back

    @property
    def c0(self) -> int:
        """First measured frame at FPS."""
        return int(round(self.spec.context * FPS))

    @property
    def frames(self) -> int:
        """Measured frames at FPS."""
        return self.truth.shape[1]

    def times(self, offset: int = 0, frames: int | None = None) -> np.ndarray:
        """Times (s) of the measured frames (or ``frames`` from c0 + offset) at FPS."""
        return (self.c0 + offset + np.arange(self.frames if frames is None else frames)) / FPS

    def skeletons(self, idx) -> list:
        return [self.clips[i].skeleton for i in idx]

    def gait_action(self, i: int) -> str:
        """The clip's most frequent gait mapped onto the actions data's labels: jog for jog/run, else walk."""
        m = self.clips[i]
        names = list(m.meta["gait_names"])
        top = names[int(np.bincount(np.asarray(m.meta["gait"], int), minlength=len(names)).argmax())]
        return "jog" if top in ("jog", "run") else "walk"


def at_times(positions: np.ndarray, fps: float, times: np.ndarray) -> np.ndarray:
    """positions (N, T, J, 3) at fps -> (N, len(times), J, 3) at the given times (s): a cubic spline through
    the frames (exact on frames that exist: 60 -> 30 fps drops every other frame)."""
    from scipy.interpolate import CubicSpline

    t = np.arange(positions.shape[1]) / fps
    if times.min() < -1e-9 or times.max() > t[-1] + 1e-9:
        raise ValueError(f"at_times: times {times.min():.3f}-{times.max():.3f} s outside the {t[-1]:.3f} s given")
    return CubicSpline(t, positions, axis=1)(times)


def load_protocol(spec: BenchSpec, seed: int = 0) -> Protocol:
    """Lesson 02's held-out clips (the first spec.clips), their features and a 20-s control program."""
    from course_lib.experiments import vae_lstm as lesson02

    data = lesson02.DataSpec()
    _, ds = lesson02.datasets(data, lesson02.load_clips(data, progress=False))
    if spec.clips > len(ds):
        raise ValueError(f"BenchSpec.clips = {spec.clips} but the held-out split has {len(ds)} clips")
    x, starts = lesson02.test_batch(ds)
    clips = [ds.clips[c] for c, _ in ds.index][: spec.clips]
    c0, T = int(round(spec.context * FPS)), int(round(4.0 * FPS)) - int(round(spec.context * FPS))
    truth = np.stack([m.positions() for m in clips])
    proto = Protocol(spec, clips, ds, x[: spec.clips], starts[: spec.clips], truth[:, :0], np.zeros((0, 3)))
    proto.truth = at_times(truth, clips[0].fps, (c0 + np.arange(T)) / FPS)
    raw = ds.denormalize(x.double()).numpy()[..., -3:]  # (N, 240, 3) raw control, m/s and rad/s
    pick = np.random.default_rng(seed).permutation(len(raw))
    n60 = int(round((spec.context + spec.long_seconds) * 60)) + 1
    proto.long_control = np.concatenate([raw[i] for i in pick])[:n60]
    return proto


def halves(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """-> (A, B): a seeded random split of range(n) into two halves (B the larger when n is odd)."""
    p = np.random.default_rng(seed).permutation(n)
    return np.sort(p[: n // 2]), np.sort(p[n // 2:])


# ----------------------------------------------------------------------------- the models, one adapter each


@dataclasses.dataclass
class Sample:
    """A model's output on the protocol: world positions (n, T, 21, 3) at FPS on the measured window, the
    skeleton each is measured against, and (controlled models) the positions with the model's own root."""

    positions: np.ndarray
    skeletons: list
    own: np.ndarray | None = None


def _size(*modules) -> int:
    return int(sum(p.numel() for m in modules for p in m.parameters()))


def _recorded_seconds(checkpoints: Path, *names: str) -> float:
    """Summed training seconds of the named checkpoints (their recorded train_seconds or seconds, in their
    lessons' results files)."""
    from course_lib.training import recorded_metrics

    metrics = [recorded_metrics(checkpoints / f"{n}.pt") for n in names]
    return float(sum(m.get("train_seconds", m.get("seconds", 0.0)) for m in metrics))


def long_controls(p: Protocol, idx) -> np.ndarray:
    """-> raw control (n, L, 3) at 60 fps: each clip's own control over the context, then the 20-s program."""
    n0 = int(round(p.spec.context * 60))
    own = p.ds.denormalize(p.x[idx].double()).numpy()[:, :n0, -3:]
    rest = np.broadcast_to(p.long_control[n0:], (len(idx), len(p.long_control) - n0, 3))
    L = -(-len(p.long_control) // 16) * 16  # the VAE-LSTM's pooling wants a multiple of 16 frames
    out = np.concatenate((own, rest), 1)
    return np.concatenate((out, np.repeat(out[:, -1:], L - out.shape[1], 1)), 1)


def long_times(p: Protocol) -> np.ndarray:
    """Times (s) of the 20-s test's frames at FPS, from the end of the context."""
    return p.spec.context + np.arange(int(round(p.spec.long_seconds * FPS))) / FPS


class Mocap:
    """The held-out clips themselves (the floor of every measure)."""

    name, controlled = "Mocap", True

    def generate(self, p: Protocol, idx, seed: int) -> Sample:
        return Sample(p.truth[idx], p.skeletons(idx), own=p.truth[idx])

    def long(self, p: Protocol, idx, seed: int) -> np.ndarray:
        return p.truth[idx]  # no 20-s recording: the 3.5-s windows


class Lesson02:
    """A lesson-02 model on positions_control at 60 fps: the ERD, LSTM-3LR and cRBM run free from the
    context (Table 1's protocol, own control); the VAE-LSTM follows the clip's control (Algorithm 1, z_1
    drawn from its posterior given the first 4 frames) and its own control outputs give its root path."""

    def __init__(self, name: str, label: str, checkpoints: Path):
        from course_lib.experiments import vae_lstm as lesson02

        self.lesson, self.name, self.checkpoint = lesson02, label, name
        self.model = lesson02.load_model(name, checkpoints)
        self.controlled = name == "vae_lstm"
        self.params, self.train_seconds = _size(self.model), _recorded_seconds(checkpoints, name)

    def _features(self, p: Protocol, x: torch.Tensor, control: torch.Tensor, seed: int) -> torch.Tensor:
        """x (n, >= context, 66) normalised starts, control (n, T, 3) -> features (n, T, 66) (own control)."""
        g = torch.Generator().manual_seed(seed)
        if self.controlled:
            z1 = self.model.posterior_z1(x[:, :4], control.shape[1], sample=True, generator=g)
            return self.model.generate(control, z1)
        n0 = int(round(p.spec.context * 60))
        kw = {"generator": g} if self.checkpoint.startswith("crbm") else {}
        return self.model.predict(x[:, :n0], control.shape[1] - n0, **kw)

    def _world(self, p: Protocol, feats: torch.Tensor, idx, times, control=None) -> np.ndarray:
        if control is not None:
            feats = self.lesson.with_control(feats, control)
        return at_times(self.lesson.to_world(feats, p.ds, [p.starts[i] for i in idx]), 60.0, times)

    def generate(self, p: Protocol, idx, seed: int) -> Sample:
        control = p.x[idx, :, -3:]
        feats = self._features(p, p.x[idx], control, seed)
        own = self._world(p, feats, idx, p.times()) if self.controlled else None
        body = self._world(p, feats, idx, p.times(), control if self.controlled else None)
        return Sample(body, p.skeletons(idx), own)

    def long(self, p: Protocol, idx, seed: int) -> np.ndarray:
        mean, std = (torch.as_tensor(s[-3:]) for s in p.ds.stats)
        control = ((torch.from_numpy(long_controls(p, idx)) - mean) / std).float()
        feats = self._features(p, p.x[idx], control, seed)
        return self._world(p, feats, idx, long_times(p), control if self.controlled else None)

    def nll(self, p: Protocol) -> float | None:
        """The VAE-LSTM's negative ELBO per frame on the held-out windows (a bound: >= the NLL)."""
        if not self.controlled:
            return None
        torch.manual_seed(0)  # the reparameterisation's draw
        with torch.no_grad():
            out = self.model.loss(p.x)
        return float(out["nll"] + out["kl"]) / p.x.shape[1]


class GmmRnn:
    """Lesson 03's GMM-RNN from the context's last two frames at 30 fps, alone or refined by GAN2 (the refiner of
    the generation seed) with the lesson's contact handling (`Lesson03Spec.contact_method`)."""

    controlled = False

    def __init__(self, checkpoints: Path, refined: bool = False):
        from course_lib.experiments import gmm_rnn as lesson03

        self.lesson, self.checkpoints, self.refined = lesson03, checkpoints, refined
        self.name = "GMM-RNN + refiner (GAN2 + contacts)" if refined else "GMM-RNN"
        self.model, refiners, self.stats = lesson03.load_models(checkpoints, 0)
        self.params = _size(self.model, refiners["GAN2"]) if refined else _size(self.model)
        seeds = [f"refiner_gan2_seed{s}" for s in range(3)] if refined else []
        self.train_seconds = _recorded_seconds(checkpoints, "gmm_rnn") + (
            _recorded_seconds(checkpoints, *seeds) / 3 if refined else 0.0)  # the RNN + a refiner's mean

    def _run(self, p: Protocol, idx, seed: int, frames: int) -> tuple[np.ndarray, list]:
        starts = [p.clips[i].resample(FPS)[p.c0 - 2:] for i in idx]  # the context's last two frames on
        spec = self.lesson.Lesson03Spec(eval_seconds=(frames + 2) / FPS)
        refiners = {}
        if self.refined:
            refiners = {"GAN2": self.lesson.load_models(self.checkpoints, seed % 3)[1]["GAN2"]}
        sets = self.lesson.continuations(self.model, refiners, starts, self.stats, spec, seed)
        feats = sets["RNN"]
        if self.refined:
            feats = self.lesson.with_contacts(sets["GAN2"], self.stats, starts, spec.contact_smooth,
                                              spec.contact_method)
        motions = self.lesson.to_motions(feats, self.stats, starts, FPS)
        return np.stack([m.positions() for m in motions])[:, 2:2 + frames], [m.skeleton for m in motions]

    def generate(self, p: Protocol, idx, seed: int) -> Sample:
        return Sample(*self._run(p, idx, seed, p.frames))

    def long(self, p: Protocol, idx, seed: int) -> np.ndarray:
        return self._run(p, idx, seed, len(long_times(p)))[0]

    def nll(self, p: Protocol) -> float | None:
        """Exact teacher-forced NLL per frame (nats) of the held-out clips at 30 fps in the RNN's features."""
        if self.refined:
            return None
        from course_lib.representations import encode_state_features

        clips = [m.resample(FPS) for m in p.clips]
        mean, std = self.stats
        x = torch.from_numpy(np.stack([(encode_state_features(m) - mean) / std for m in clips])).float()
        y = self.lesson.to_rnn(x, self.stats, self.model, self.lesson.clip_offsets(clips))
        with torch.no_grad():
            params, _ = self.model(y[:, :-1])
            return float(-self.model.log_prob(y[:, 1:], params).mean())


class OnlineControl:
    """Lesson 04's online controller steering the GMM-RNN: every 10-frame batch asks for the clip's net speed
    over that batch and its heading at the batch's last frame."""

    name, controlled = "GMM-RNN, online control", True

    def __init__(self, checkpoints: Path):
        from course_lib.control.rnn_prior import RnnPrior

        self.prior = RnnPrior.from_checkpoints(checkpoints)
        self.params, self.train_seconds = _size(self.prior.model), _recorded_seconds(checkpoints, "gmm_rnn")

    def _one(self, clip: Motion, c0: int, frames: int, seed: int) -> np.ndarray:
        from course_lib.control.online import OnlineController
        from course_lib.representations import root_yaw_pitch_roll

        m = clip.resample(FPS)
        root, yaw = m.root_positions[:, [0, 2]], root_yaw_pitch_roll(m)[:, 0]
        ctrl = OnlineController("walk", seed, start=m[c0 - 2:], prior=self.prior)
        batch = ctrl.config.batch
        for k in range(-(-frames // batch)):
            a, b = c0 - 1 + k * batch, min(c0 - 1 + (k + 1) * batch, len(m) - 1)
            speed = float(np.linalg.norm(root[b] - root[a]) * FPS / max(b - a, 1))
            ctrl.step(speed, float(yaw[b]))
        return ctrl.motion().positions()[2:2 + frames]

    def generate(self, p: Protocol, idx, seed: int) -> Sample:
        pos = np.stack([self._one(p.clips[i], p.c0, p.frames, seed * 1000 + k) for k, i in enumerate(idx)])
        return Sample(pos, p.skeletons(idx), own=pos)

    def nll(self, p: Protocol) -> None:
        return None


class Hvrnn:
    """A lesson-05 attribute model (the Proposed hierarchical VRNN or the QuaterNet-style GRU): no start and no
    control; each clip's sample asks for the clip's action (walk or jog) and a seeded random style; the first
    ``context`` seconds are dropped as the others' context."""

    controlled = False

    def __init__(self, name: str, label: str, checkpoints: Path):
        from course_lib.experiments import hvrnn as lesson05

        self.lesson, self.name = lesson05, label
        self.model = lesson05.load_model(name, checkpoints)
        self.params, self.train_seconds = _size(self.model), _recorded_seconds(checkpoints, name)

    def _run(self, p: Protocol, idx, seed: int, frames: int) -> np.ndarray:
        from course_lib.datasets import ACTIONS, STYLES

        g = torch.Generator().manual_seed(seed)
        a = torch.tensor([ACTIONS.index(p.gait_action(i)) for i in idx])
        s = torch.randint(len(STYLES), (len(idx),), generator=g)
        x = self.model.sample(a, s, p.c0 + frames, generator=g)
        motions = self.lesson.to_motions({"x": x.float(), "action_id": a, "style_id": s,
                                          "subject": ["generated"] * len(idx)})
        return np.stack([m.positions() for m in motions])[:, p.c0:p.c0 + frames]

    def generate(self, p: Protocol, idx, seed: int) -> Sample:
        from course_lib.skeleton import Skeleton

        return Sample(self._run(p, idx, seed, p.frames), [Skeleton.canonical()] * len(idx))

    def long(self, p: Protocol, idx, seed: int) -> np.ndarray:
        return self._run(p, idx, seed, len(long_times(p)))

    def nll(self, p: Protocol) -> None:
        return None


class MoGlowRow:
    """Lesson 06's MoGlow (LSTM, dropout 0.95) at 20 fps, driven by the clip's control from its first tau = 10
    frames; positions through lesson 06's `MoGlowData` built on the protocol's clips."""

    name, controlled = "MoGlow", True

    def __init__(self, checkpoints: Path):
        from course_lib.datasets import FixedDofs, load_stats
        from course_lib.experiments import moglow as lesson06

        self.lesson = lesson06
        self.model = lesson06.load_model("moglow", checkpoints)
        self.stats = load_stats(lesson06.stats_file(checkpoints))
        self.fixed = FixedDofs.from_stats(*self.stats).mask[:63]
        self.params, self.train_seconds = _size(self.model), _recorded_seconds(checkpoints, "moglow")

    def data(self, p: Protocol, idx=None, raw_control: np.ndarray | None = None):
        """-> lesson 06's MoGlowData holding the clips (idx: these) at 20 fps as its held-out set; raw_control
        (n, L, 3) at 60 fps replaces the clips' controls (the 20-s test)."""
        from course_lib.representations import encode_positions_control

        idx = range(len(p.clips)) if idx is None else idx
        clips = [p.clips[i].resample(self.lesson.FPS) for i in idx]
        mean, std = self.stats
        f = (np.stack([encode_positions_control(m) for m in clips]) - mean) / std  # (n, 81, 66)
        controls = f[..., 63:] if raw_control is None else (raw_control[:, ::3] - mean[63:]) / std[63:]
        test = {"poses": torch.from_numpy(f[..., :63][..., ~self.fixed]).float(),
                "controls": torch.from_numpy(np.ascontiguousarray(controls)).float()}
        return self.lesson.MoGlowData({}, {}, test, self.stats, self.fixed, clips)

    def _run(self, p: Protocol, idx, seed: int, times, raw_control=None) -> np.ndarray:
        from course_lib.representations import root_start

        data, tau = self.data(p, idx, raw_control), self.lesson.TAU
        x0, c0 = data.test["poses"][:, :tau], data.test["controls"][:, :tau]
        poses, c = self.lesson.generate(self.model, data, data.test["controls"], seed, starts=(x0, c0))
        pos = data.positions(poses, c, [root_start(m) for m in data.test_clips])
        return at_times(pos, self.lesson.FPS, times)

    def generate(self, p: Protocol, idx, seed: int) -> Sample:
        return Sample(self._run(p, idx, seed, p.times()), p.skeletons(idx))

    def long(self, p: Protocol, idx, seed: int) -> np.ndarray:
        return self._run(p, idx, seed, long_times(p), long_controls(p, idx))

    def nll(self, p: Protocol) -> float:
        return self.lesson.nll_per_frame(self.model, self.data(p).test)


ROWS = {  # row name -> its adapter, built from the checkpoints folder
    "Mocap": lambda c: Mocap(), "ERD": lambda c: Lesson02("erd", "ERD", c),
    "LSTM-3LR": lambda c: Lesson02("lstm3lr", "LSTM-3LR", c),
    "cRBM (CD-15)": lambda c: Lesson02("crbm_cd15", "cRBM (CD-15)", c),
    "VAE-LSTM": lambda c: Lesson02("vae_lstm", "VAE-LSTM", c), "GMM-RNN": lambda c: GmmRnn(c),
    "GMM-RNN + refiner (GAN2 + contacts)": lambda c: GmmRnn(c, refined=True),
    "GMM-RNN, online control": lambda c: OnlineControl(c),
    "HVRNN (Proposed)": lambda c: Hvrnn("hvrnn_proposed", "HVRNN (Proposed)", c),
    "QuaterNet-style GRU": lambda c: Hvrnn("hvrnn_quaternet", "QuaterNet-style GRU", c),
    "MoGlow": lambda c: MoGlowRow(c),
}


def build_rows(checkpoints: Path = CHECKPOINTS, names=None) -> list:
    """The adapters of the named rows (default: every row), in the table's order."""
    names = list(ROWS) if names is None else names
    unknown = set(names) - set(ROWS)
    if unknown:
        raise ValueError(f"build_rows: unknown rows {sorted(unknown)}; the rows are {list(ROWS)}")
    return [ROWS[n](checkpoints) for n in ROWS if n in names]


# ----------------------------------------------------------------------------- measures


def fitted(positions: np.ndarray, skeletons: list) -> list[Motion]:
    """Positions (n, T, 21, 3) at FPS -> Motions with rotations fitted (FID, IS and C2ST read rotations)."""
    from course_lib.representations import motion_from_positions

    return [motion_from_positions(x, sk, FPS) for x, sk in zip(positions, skeletons, strict=True)]


def quality(sample: Sample, reference: list[Motion], seed: int, distribution: bool = True) -> dict:
    """The per-set measures of one sample against the reference mocap (half A)."""
    from course_lib.evaluation import (
        bone_length_violation,
        c2st,
        fid,
        foot_skate_at_floor,
        ground_penetration,
        inception_score,
        jitter,
    )

    pos = sample.positions
    out = {"foot_skate": foot_skate_at_floor(pos, fps=FPS), "penetration": ground_penetration(pos),
           "jitter": jitter(pos, fps=FPS),
           # per clip, against that clip's skeleton; the mean over clips of each clip's worst bone
           "bone_length": float(np.mean([bone_length_violation(x[None], sk)
                                         for x, sk in zip(pos, sample.skeletons, strict=True)]))}
    if distribution:
        motions = fitted(pos, sample.skeletons)
        # C2ST on one window per clip: overlapping windows of one clip on both sides of a fold would leak
        test = c2st(reference, motions, seed=seed)
        out.update(fid=fid(windows(reference), windows(motions)), c2st=test["accuracy"], c2st_low=test["ci_low"],
                   c2st_high=test["ci_high"])
        out["is"] = inception_score(windows(motions))
    return out


def windows(motions: list[Motion], length: int = 60, stride: int = 15) -> list[Motion]:
    """Every `length`-frame window (the classifiers' 2 s) of each motion, `stride` frames apart: 4 per 3.5-s clip,
    so that FID and IS see the whole measured window (at 60 clips a set, FID on one window per clip moved by
    +-100 between random halves of the mocap)."""
    return [m[k:k + length] for m in motions for k in range(0, m.num_frames - length + 1, stride)]


def control_errors(own: np.ndarray, truth: np.ndarray) -> dict:
    """own, truth (n, T, 21, 3) at FPS -> the root's mean distance to the clip's root path (m) and its mean
    |speed - the clip's speed| (m/s)."""
    from course_lib.evaluation import path_distance, speed_error

    path = np.mean([path_distance(o[None], t[:, 0]) for o, t in zip(own, truth, strict=True)])
    target = np.linalg.norm(np.gradient(truth[..., 0, [0, 2]], axis=1), axis=-1) * FPS  # (n, T) the clip's speed
    return {"path_error": float(path), "speed_error": speed_error(own, target, fps=FPS)}


def stability(long: np.ndarray, p: Protocol, floor: float) -> dict:
    """long (n, T, 21, 3) -> the fraction of samples whose root height stays within the mocap's range +- 5 cm
    on every frame (NaN or inf: out of range) and the fraction frozen: the variance of the joint speed over the
    last 5 s under the freeze floor (`evaluation.freeze_floor` of the clips at FPS)."""
    from course_lib.evaluation import joint_speed

    h = p.truth[..., 0, 1]
    lo, hi = float(h.min()) - 0.05, float(h.max()) + 0.05
    finite = np.isfinite(long).all((1, 2, 3))
    root = np.where(finite[:, None], long[..., 0, 1], np.inf)
    inside = ((root >= lo) & (root <= hi)).all(1)
    last = int(5 * FPS)
    var = np.array([joint_speed(x[-last:], FPS).var() if ok else np.inf for x, ok in zip(long, finite, strict=True)])
    return {"in_range": float(inside.mean()), "frozen": float((var < floor).mean())}


def apd_of(row, p: Protocol, idx, samples: int, seed: int) -> float:
    """APD (m) of `samples` draws from each start in idx (the same control), over the measured window."""
    from course_lib.evaluation import apd

    rep = np.repeat(np.asarray(idx), samples)
    pos = row.generate(p, rep, seed).positions
    return apd(pos.reshape(len(idx), samples, *pos.shape[1:]))


def evaluate_seed(row, p: Protocol, seed: int, reference: list[Motion], floor: float) -> dict:
    """Every seeded measure of one row for one generation seed."""
    spec = p.spec
    _, b = halves(len(p.clips), seed)
    online = isinstance(row, OnlineControl)
    b = b[: spec.online_clips] if online else b
    t0 = time.perf_counter()
    sample = row.generate(p, b, seed)
    out = {"fps": len(b) * p.frames / (time.perf_counter() - t0)}
    out.update(quality(sample, reference, seed, distribution=len(b) >= spec.min_distribution))
    if online and len(b) >= spec.min_distribution:  # the mocap of the same clips: this row's own floor
        same = quality(Mocap().generate(p, b, seed), reference, seed)
        out.update({f"{k}_mocap_same_clips": same[k] for k in ("fid", "is", "c2st")})
    if sample.own is not None:  # a root path of the model's own making
        out.update(control_errors(sample.own, p.truth[b]))
    if not isinstance(row, Mocap):
        starts, samples = spec.online_apd if online else (spec.apd_starts, spec.apd_samples)
        out["apd"] = apd_of(row, p, b[:starts], samples, seed + 100)
    if not online:
        out.update(stability(row.long(p, b[: spec.long_samples] if not isinstance(row, Mocap) else b, seed),
                             p, floor))
    if isinstance(row, Mocap):
        del out["fps"]
    return out


# ----------------------------------------------------------------------------- the benchmark


def blanks_of(row_name: str, spec: BenchSpec, measured: dict) -> dict:
    """The row's blanks: BLANKS, plus any measure the budget left out (e.g. too few clips)."""
    out = dict(BLANKS.get(row_name, {}))
    for key in MEASURES:
        if key not in measured and key not in out:
            out[key] = (f"{spec.online_clips} clips per seed: too few for a distribution score"
                        if key in ("fid", "is", "c2st") else "not measured")
    return out


def run(spec: BenchSpec | None = None, checkpoints: Path = CHECKPOINTS, progress: bool = True, rows=None) -> dict:
    """The benchmark (of the named rows; default every row) -> JSON-able {"spec", "rows": {name: {"mean", "sd",
    "per_seed", "blanks", "seconds"}}, "seconds", ...}."""
    from course_lib.evaluation import freeze_floor, over_seeds

    spec = spec or BenchSpec()
    t0 = time.perf_counter()
    p = load_protocol(spec)
    floor = freeze_floor([m.resample(FPS) for m in p.clips])
    references = {s: fitted(p.truth[halves(len(p.clips), s)[0]], p.skeletons(halves(len(p.clips), s)[0]))
                  for s in spec.seeds}
    out = {}
    for row in build_rows(checkpoints, rows):
        t = time.perf_counter()
        runs = [evaluate_seed(row, p, s, references[s], floor) for s in spec.seeds]
        if row.name != "Mocap" and "Mocap" in out:  # paired with the floor on the same halves: the split's noise
            for r, floor_run in zip(runs, out["Mocap"]["per_seed"].values(), strict=True):  # cancels
                if "fid" in r:
                    r["fid_excess"] = r["fid"] - r.get("fid_mocap_same_clips", floor_run["fid"])
        mean, sd = over_seeds(runs)
        nll = getattr(row, "nll", lambda _: None)(p)
        fixed = {"params": getattr(row, "params", None), "train_seconds": getattr(row, "train_seconds", None),
                 "nll": nll}
        mean.update({k: v for k, v in fixed.items() if v is not None})
        out[row.name] = {"mean": mean, "sd": sd, "per_seed": dict(zip(map(str, spec.seeds), runs, strict=True)),
                         "blanks": blanks_of(row.name, spec, mean), "seconds": time.perf_counter() - t}
        if row.name in NLL_NOTES:
            out[row.name]["nll_note"] = NLL_NOTES[row.name]
        if progress:
            print(f"{row.name}: {out[row.name]['seconds']:.1f} s", file=sys.stderr)
    result = {"spec": dataclasses.asdict(spec), "rows": out, "freeze_floor": floor, "git_head": _git_head(),
              "clips": len(p.clips), "measured_frames": p.frames, "fps": FPS,
              "seconds": time.perf_counter() - t0, "measures": {k: list(v) for k, v in MEASURES.items()}}
    return rounded(result, 5)


def _git_head() -> str | None:
    """The repository's commit (with '+' when the working tree differs from it), for the record; None outside git."""
    import subprocess

    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                              timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                               capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+" if dirty else "")


def cell(row: dict, key: str, digits: int = 3) -> str:
    """One table cell: 'mean ± sd' over the seeds, the value alone when it is not seeded, or a blank."""
    from course_lib.evaluation import mean_sd

    if key not in row["mean"]:
        return "—"
    m, sd = row["mean"][key], row["sd"].get(key)
    if key == "params":
        return f"{m / 1e6:.2f} M"
    if key == "train_seconds":
        return f"{m:.0f}"
    if sd is None:
        return f"{m:.{digits}g}"
    if m == 0 and sd == 0:
        return "0"
    return mean_sd(m, sd, digits)


def _table(results: dict, measures) -> tuple[list[str], list[list[str]], list[str], list[str]]:
    """-> (header, rows of cells, the blanks' reasons in the order of their numbers, footer lines)."""
    head = ["model"] + [f"{MEASURES[k][0]} ({MEASURES[k][1]})" if MEASURES[k][1] else MEASURES[k][0]
                        for k in measures]
    rows, reasons = [], []
    for name, row in results["rows"].items():
        cells = []
        for k in measures:
            text = cell(row, k)
            if k == "nll" and "upper bound" in NLL_NOTES.get(name, "") and text != "—":
                text = "≤ " + text  # the negative ELBO bounds the NLL from above
            if text == "—":
                why = row["blanks"].get(k, "not measured")
                reasons.append(why) if why not in reasons else None
                text = f"— [{reasons.index(why) + 1}]"
            cells.append(text)
        rows.append([name] + cells)
    spec = results["spec"]
    footer = [f"Mean ± sd over generation seeds {spec['seeds']}; {results['clips']} held-out clips (halves of "
              f"{results['clips'] // 2}), {results['measured_frames']} frames at {results['fps']:g} fps each; "
              f"{results['seconds']:.0f} s in all."]
    footer += [f"NLL of {n}: {NLL_NOTES.get(n, r['nll_note'])}" for n, r in results["rows"].items() if "nll_note" in r]
    return head, rows, reasons, footer


def markdown(results: dict, measures=None) -> str:
    """The results table as Markdown: rows x measures; each blank is numbered and its reason listed below."""
    head, rows, reasons, footer = _table(results, list(measures or MEASURES))
    lines = ["| " + " | ".join(head) + " |", "|---" + "|---:" * (len(head) - 1) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    lines += ["", footer[0], ""] + [f"[{i + 1}] {r}" for i, r in enumerate(reasons)] + [""] + footer[1:]
    return "\n".join(lines) + "\n"


def html(results: dict, measures=None) -> str:
    """The same table as HTML (for notebooks and the site: a Markdown output is not parsed as a table there)."""
    import html as h

    head, rows, reasons, footer = _table(results, list(measures or MEASURES))
    th = "".join(f"<th>{h.escape(c)}</th>" for c in head)
    body = "".join("<tr>" + "".join(f"<td>{h.escape(c)}</td>" if i == 0 else
                                    f'<td style="text-align:right">{h.escape(c)}</td>' for i, c in enumerate(r))
                   + "</tr>" for r in rows)
    notes = "".join(f"<li>[{i + 1}] {h.escape(r)}</li>" for i, r in enumerate(reasons))
    extra = "".join(f"<p>{h.escape(f)}</p>" for f in footer)
    return (f"<table><thead><tr>{th}</tr></thead><tbody>{body}</tbody></table>"
            f'<ul style="list-style:none;padding-left:0">{notes}</ul>{extra}')


def gallery_samples(p: Protocol, clip: int = 0, seed: int = 0, checkpoints: Path = CHECKPOINTS, names=None) -> dict:
    """{row name: Motion}: every model's sample from the same start (held-out clip ``clip``), the measured window
    at FPS with rotations fitted (`fitted`), for the gallery's video and its BVH files."""
    out = {}
    for row in build_rows(checkpoints, names):
        s = row.generate(p, np.array([clip]), seed)
        out[row.name] = fitted(s.positions, s.skeletons)[0]
    return out


SHORT = {"cRBM (CD-15)": "cRBM", "GMM-RNN + refiner (GAN2 + contacts)": "GMM+GAN2", "GMM-RNN, online control":
         "GMM online", "HVRNN (Proposed)": "HVRNN", "QuaterNet-style GRU": "QuaterNet"}  # the plots' labels
LOG_SCALE = ("foot_skate", "jitter", "fid", "bone_length", "penetration", "apd", "fps", "params", "train_seconds")


def plot_panels(results: dict, measures=None, cols: int = 4, width: float = 16.0):
    """A panel per measure: one bar per row (mean, the seeds' sd as an error bar), the Mocap row's value as a
    dashed line; a blank row is marked "n/a".  -> the matplotlib Figure."""
    import matplotlib.pyplot as plt

    measures = list(measures or MEASURES)
    names = list(results["rows"])
    rows_n = -(-len(measures) // cols)
    fig, axes = plt.subplots(rows_n, cols, figsize=(width, 3.9 * rows_n), squeeze=False)
    colours = plt.cm.tab20(np.linspace(0, 1, len(names)))
    for ax, key in zip(axes.flat, measures, strict=False):
        label, unit, better = MEASURES[key]
        for i, name in enumerate(names):
            row = results["rows"][name]
            m = row["mean"].get(key)
            if m is not None and not (key in LOG_SCALE and m <= 0):
                ax.bar(i, m, yerr=row["sd"].get(key, 0.0), color=colours[i], capsize=3)
            else:  # a blank, or a 0 that a log axis cannot draw
                ax.text(i, 0.03, "n/a" if m is None else "0", ha="center", va="bottom", fontsize=9,
                        transform=ax.get_xaxis_transform(), color="0.3")
        mocap = results["rows"]["Mocap"]["mean"].get(key)
        if mocap is not None and not (key in LOG_SCALE and mocap <= 0):
            ax.axhline(mocap, color="k", ls="--", lw=1)
        if key in LOG_SCALE:
            ax.set_yscale("log")
        arrow = {"low": "lower is better", "high": "higher is better", "ref": "closest to mocap (dashed)"}[better]
        ax.set_title(f"{label}" + (f" ({unit})" if unit else "") + f"\n{arrow}", fontsize=10)
        ax.set_xticks(range(len(names)), [SHORT.get(n, n) for n in names], rotation=60, ha="right", fontsize=9)
    for ax in list(axes.flat)[len(measures):]:
        ax.axis("off")
    fig.tight_layout()
    return fig


def plot_quality_speed(results: dict, qualities=("fid", "foot_skate"), size=(16.0, 6.0)):
    """Each quality (log) against generation speed (30-fps frames per second on one core, log), one panel each:
    a point per model with the seeds' sd as error bars, the Mocap row dashed, real time (30 frames/s) dotted."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(qualities), figsize=size, squeeze=False)
    for ax, quality in zip(axes[0], qualities, strict=True):
        for name, row in results["rows"].items():
            m = row["mean"]
            if quality in m and "fps" in m:
                ax.errorbar(m["fps"], m[quality], xerr=row["sd"].get("fps"), yerr=row["sd"].get(quality), fmt="o",
                            capsize=3)
                ax.annotate(SHORT.get(name, name), (m["fps"], m[quality]),
                            textcoords="offset points", xytext=(6, 4), fontsize=9)
        mocap = results["rows"]["Mocap"]["mean"].get(quality)
        if mocap:
            ax.axhline(mocap, color="k", ls="--", lw=1, label=f"Mocap (half vs half): {mocap:.3g}")
        ax.axvline(FPS, color="0.5", ls=":", lw=1, label="real time (30 frames/s)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        label, unit, _ = MEASURES[quality]
        ax.set_xlabel("generation speed, 30-fps frames per second on one core")
        ax.set_ylabel(label + (f" ({unit})" if unit else ""))
        ax.legend(loc="lower left", fontsize=9)
        ax.set_title(f"{label} against speed: lower right is better")
    fig.tight_layout()
    return fig


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m course_lib.benchmark", description=__doc__.split("\n")[0])
    parser.add_argument("--ci", action="store_true", help="40 clips, 2 seeds (under 4 minutes)")
    parser.add_argument("--out", type=Path, default=None,
                        help=f"results JSON (default {RESULTS.name}, --ci: benchmark_results_ci.json beside it); "
                             "the Markdown table goes beside it")
    parser.add_argument("--checkpoints", type=Path, default=CHECKPOINTS)
    parser.add_argument("--force", action="store_true", help="replace existing results (.json and .md)")
    args = parser.parse_args(argv)
    out = args.out or (RESULTS.with_name("benchmark_results_ci.json") if args.ci else RESULTS)
    if out.suffix.lower() != ".json":
        parser.error(f"--out {out}: give a .json path (the Markdown table is written beside it as {out.stem}.md)")
    try:  # both files, before the run: nothing existing is replaced without --force
        check_outputs([out, out.with_suffix(".md")], overwrite=args.force, who="course_lib.benchmark")
    except (FileExistsError, ValueError) as err:
        parser.error(str(err))
    torch.set_num_threads(1)
    results = run(BenchSpec.ci() if args.ci else BenchSpec(), args.checkpoints)
    out.write_text(json.dumps(results, indent=1) + "\n")
    out.with_suffix(".md").write_text(markdown(results))
    print(markdown(results))
    print(f"wrote {out} and {out.with_suffix('.md')} in {results['seconds']:.0f} s", file=sys.stderr)
    return 0


def load_results(path: Path = RESULTS) -> dict:
    """The recorded results (the full benchmark's by default)."""
    return json.loads(Path(path).read_text())


if __name__ == "__main__":
    raise SystemExit(main())
