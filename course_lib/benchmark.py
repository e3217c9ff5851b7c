"""Lesson 07: one benchmark of every model of the course on one protocol.

    python -m course_lib.benchmark --force  # the full benchmark -> results/benchmark_results.{json,md}, replaced
    python -m course_lib.benchmark --ci --out /tmp/bench.json  # fewer clips and seeds (CI: under 3 minutes)
    (each run also writes results/benchmark_protocol.{json,md}, the protocol card: `protocol_card`)

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
Beside the known-floor foot skate (`foot_skate_at_floor`, the course's targets) the table reports the real-mocap
rule (`foot_skate`, floor estimated, 0.1-s intervals) and the diffusion papers' skating ratio.

Motion matching (`models.motion_matching`, Clavet 2016; Holden et al. 2020) is a row twice: free and following
the clip's control; its database is lesson 02's training split.  Memorisation: each generated 1-s window's RMS
joint distance to its nearest training window (a brute-force matrix product), and the fraction of windows closer
than held-out mocap's 5th percentile (`Memorisation`).  Every seeded cell carries a 95 % interval (`intervals`) and
`orderings` lists, per measure, which rows' intervals are apart.

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
    "foot_skate": ("foot skate", "m/s", "low"),
    "foot_skate_auto": ("foot skate, floor estimated", "m/s", "low"),
    "skating_ratio": ("skating ratio", "frac.", "low"), "penetration": ("penetration", "m", "low"),
    "jitter": ("jitter", "m/s^3", "ref"), "bone_length": ("bone-length violation", "rel.", "low"),
    "fid": ("FID", "", "low"), "is": ("IS", "", "ref"), "c2st": ("C2ST", "acc.", "low"),
    "apd": ("APD", "m", "ref"), "path_error": ("root-path error", "m", "low"),
    "speed_error": ("speed error", "m/s", "low"), "in_range": ("20 s in range", "frac.", "high"),
    "frozen": ("20 s frozen", "frac.", "low"),
    "memorised": ("closer than mocap's 5th pct.", "frac.", "ref"),
    "nn_distance": ("distance to training", "m", "ref"), "nll": ("held-out NLL", "nats/frame, own space", "low"),
    "fps": ("speed", "frames/s, 1 core", "high"), "params": ("parameters", "", "low"),
    "train_seconds": ("training", "s", "low"),
}
SEEDED = ("foot_skate", "foot_skate_auto", "skating_ratio", "penetration", "jitter", "bone_length", "fid", "is", "c2st",
          "apd", "path_error", "speed_error", "in_range", "frozen", "memorised", "nn_distance", "fid_excess",
          "fps")  # measured once per generation seed: mean, sd and a 95 % interval
FRACTIONS = ("skating_ratio", "c2st", "in_range", "frozen", "memorised")  # in [0, 1]
SET_LEVEL = ("fid", "fid_excess", "is", "c2st", "fps")  # one number per seed: a t-interval over the seeds
BOOTSTRAP = 1000  # resamples of the two-level bootstrap (seeds, then clips within a seed)
SKATING_SPEED = 0.5  # m/s: the skating ratio's threshold (2.5 cm per frame at 20 fps, the diffusion papers')
MEMO_WINDOW, MEMO_STEP, MEMO_STRIDE = 30, 3, 15  # memorisation: 1-s windows, every 3rd frame, 0.5 s apart

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
    "Motion matching": {"path_error": "free generation: no control asked", "speed_error":
                        "free generation: no control asked", "nll": "a search, not a distribution: no density"},
    "Motion matching, control": {"nll": "a search, not a distribution: no density"},
}
REPLAYS = {"Motion matching": "replays the training clips by construction",
           "Motion matching, control": "replays the training clips by construction"}
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
    train: list = dataclasses.field(default_factory=list)  # lesson 02's training clips (60 fps, with mirrors)

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
    train, ds = lesson02.datasets(data, lesson02.load_clips(data, progress=False))
    if spec.clips > len(ds):
        raise ValueError(f"BenchSpec.clips = {spec.clips} but the held-out split has {len(ds)} clips")
    x, starts = lesson02.test_batch(ds)
    clips = [ds.clips[c] for c, _ in ds.index][: spec.clips]
    c0, T = int(round(spec.context * FPS)), int(round(4.0 * FPS)) - int(round(spec.context * FPS))
    truth = np.stack([m.positions() for m in clips])
    proto = Protocol(spec, clips, ds, x[: spec.clips], starts[: spec.clips], truth[:, :0], np.zeros((0, 3)),
                     list(train.clips))
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


class MotionMatchingRow:
    """Motion matching (`models.motion_matching`) over lesson 02's training clips at 30 fps: from the context's
    last frame, free (one of the k nearest at each search, seeded) or asking for the clip's own control."""

    def __init__(self, controlled: bool = False, config=None):
        self.controlled, self.config = controlled, config
        self.name = "Motion matching, control" if controlled else "Motion matching"
        self.model = None  # built on the first protocol it sees (the database is the protocol's training split)

    def _database(self, p: Protocol):
        from course_lib.models.motion_matching import MotionMatching

        if self.model is None:
            t0 = time.perf_counter()
            self.model = MotionMatching(p.train, self.config)
            self.train_seconds = time.perf_counter() - t0  # building the database and its tree
            self.params = int(self.model.where.shape[0] * (len(self.model.frames[0][0]) + len(self.model.scale)))
        return self.model

    def _run(self, p: Protocol, idx, seed: int, frames: int, control60: np.ndarray | None) -> np.ndarray:
        from course_lib.representations import decode_positions, encode_positions_control, root_start

        mm, out = self._database(p), []
        for k, i in enumerate(idx):
            m = p.clips[i].resample(FPS)
            start = encode_positions_control(m)[: p.c0]  # (c0, 66) the context
            request = None if control60 is None else control60[k, ::2][p.c0:]  # (.., 3) from the first new frame
            new = mm.generate(start, frames, request, np.random.default_rng([seed, k]))
            pos = decode_positions(np.concatenate((start[-1:], new)), FPS, root_start(m[p.c0 - 1:p.c0]))
            out.append(pos[1:])
        return np.stack(out)

    def _control(self, p: Protocol, idx) -> np.ndarray | None:
        return p.ds.denormalize(p.x[idx].double()).numpy()[..., -3:] if self.controlled else None

    def generate(self, p: Protocol, idx, seed: int) -> Sample:
        pos = self._run(p, idx, seed, p.frames, self._control(p, idx))
        return Sample(pos, p.skeletons(idx), own=pos if self.controlled else None)

    def long(self, p: Protocol, idx, seed: int) -> np.ndarray:
        control = long_controls(p, idx) if self.controlled else None
        return self._run(p, idx, seed, len(long_times(p)), control)

    def search_per_frame(self) -> float:
        """Mean search time per generated frame so far (s): the k-d tree's queries only."""
        mm = self.model
        return mm.search_seconds / max(1, mm.frames_made) if mm else float("nan")

    def nll(self, p: Protocol) -> None:
        return None


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
    "Motion matching": lambda c: MotionMatchingRow(controlled=False),
    "Motion matching, control": lambda c: MotionMatchingRow(controlled=True),
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


def toe_contacts(pos: np.ndarray, height: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """pos (n, T, 21, 3) at FPS -> (speed (n, T-1, 2) of each toe's (x, z) frame to frame, m/s; contact
    (n, T-1, 2): the toe below ``height`` above y = 0 on both frames) -- the pairs `foot_skate_at_floor` counts."""
    from course_lib.motion import CONTACT_HEIGHT
    from course_lib.skeleton import Skeleton

    sk = Skeleton.canonical()
    toes = pos[..., [sk.index("LeftToeBase"), sk.index("RightToeBase")], :]  # (n, T, 2, 3)
    low = toes[..., 1] < (CONTACT_HEIGHT["ToeBase"] if height is None else height)
    return np.linalg.norm(np.diff(toes[..., [0, 2]], axis=1), axis=-1) * FPS, low[:, 1:] & low[:, :-1]


def skating_ratio(pos: np.ndarray, threshold: float = SKATING_SPEED) -> float:
    """The skating ratio of the diffusion-model papers: of the toes' contact frame pairs (`toe_contacts`), the
    fraction sliding faster than ``threshold`` m/s (0 when no toe touches the floor).  pos (n, T, 21, 3) at FPS."""
    speed, contact = toe_contacts(pos)
    return float((speed[contact] > threshold).mean()) if contact.any() else 0.0


def quality(sample: Sample, reference: list[Motion], seed: int, distribution: bool = True,
            units: dict | None = None) -> dict:
    """The per-set measures of one sample against the reference mocap (half A).  ``units``, when given, is
    filled with each per-clip measure's (numerator, denominator) per clip, for the bootstrap."""
    from course_lib.evaluation import (
        bone_length_violation,
        c2st,
        fid,
        foot_skate,
        foot_skate_at_floor,
        ground_penetration,
        inception_score,
        jitter,
    )

    pos = sample.positions
    n = len(pos)
    speed, contact = toe_contacts(pos)
    per_clip = {"foot_skate_auto": [foot_skate(x[None], fps=FPS) for x in pos],
                "penetration": [ground_penetration(x[None]) for x in pos],
                "jitter": [jitter(x[None], fps=FPS) for x in pos],
                # per clip, against that clip's skeleton; the mean over clips of each clip's worst bone
                "bone_length": [bone_length_violation(x[None], sk)
                                for x, sk in zip(pos, sample.skeletons, strict=True)]}
    out = {"foot_skate": foot_skate_at_floor(pos, fps=FPS), "foot_skate_auto": foot_skate(pos, fps=FPS),
           "skating_ratio": skating_ratio(pos), "penetration": ground_penetration(pos), "jitter": jitter(pos, fps=FPS),
           "bone_length": float(np.mean(per_clip["bone_length"]))}
    if units is not None:  # the pooled measures as exact sums and counts; the others one value per clip
        units["foot_skate"] = ((speed * contact).sum((1, 2)), contact.sum((1, 2)))
        units["skating_ratio"] = (((speed > SKATING_SPEED) & contact).sum((1, 2)), contact.sum((1, 2)))
        units.update({k: (np.asarray(v, float), np.ones(n)) for k, v in per_clip.items()})
    if distribution:
        motions = fitted(pos, sample.skeletons)
        # C2ST on one window per clip: overlapping windows of one clip on both sides of a fold would leak
        test = c2st(reference, motions, seed=seed)
        out.update(fid=fid(windows(reference), windows(motions)), c2st=test["accuracy"], c2st_low=test["ci_low"],
                   c2st_high=test["ci_high"], c2st_n=test["n"])
        out["is"] = inception_score(windows(motions))
    return out


# ----------------------------------------------------------------------------- memorisation


def memo_windows(pos: np.ndarray) -> np.ndarray:
    """pos (n, T, 21, 3) at FPS -> (n, W, 10 * 21 * 3): every 1-s window, 0.5 s apart, every 3rd frame, in the
    floor frame of its first frame (root on the floor at the origin, facing +Z): where and which way a window
    walks do not count, only the body's motion."""
    from course_lib.evaluation import facing_yaw

    starts = range(0, pos.shape[1] - MEMO_WINDOW + 1, MEMO_STRIDE)
    yaw = facing_yaw(pos)  # (n, T)
    out = []
    for s0 in starts:
        w = pos[:, s0:s0 + MEMO_WINDOW:MEMO_STEP] - pos[:, s0:s0 + 1, :1] * np.array([1.0, 0.0, 1.0])  # (n, 10, 21, 3)
        c, s = np.cos(-yaw[:, s0])[:, None, None], np.sin(-yaw[:, s0])[:, None, None]
        x, z = w[..., 0], w[..., 2]
        out.append(np.stack((c * x + s * z, w[..., 1], -s * x + c * z), -1).reshape(len(pos), -1))
    return np.stack(out, 1)


@dataclasses.dataclass
class Memorisation:
    """The training set's windows and held-out mocap's distance to them (the reference of the check)."""

    train: np.ndarray  # (M, D) windows of lesson 02's training clips, 0.1 s apart
    mocap: np.ndarray  # every held-out window's distance to its nearest training window (m)

    @classmethod
    def build(cls, p: Protocol) -> Memorisation:
        pos = np.stack([m.resample(FPS).positions() for m in p.train])  # (M, T, 21, 3)
        train = np.concatenate([memo_windows(pos[:, k:]) for k in range(0, MEMO_STRIDE, 3)], 1)
        memo = cls(train.reshape(-1, train.shape[-1]), np.zeros(0))
        memo.mocap = memo.distance(p.truth).ravel()
        return memo

    @property
    def p5(self) -> float:
        """Held-out mocap's 5th percentile: a window closer than this is closer than 95 % of real unseen motion."""
        return float(np.percentile(self.mocap, 5))

    def distance(self, pos: np.ndarray) -> np.ndarray:
        """pos (n, T, 21, 3) -> (n, W): each window's RMS joint distance (m) to its nearest training window,
        by a brute-force matrix product (|a - b|^2 = |a|^2 + |b|^2 - 2 a.b)."""
        q = memo_windows(pos)  # (n, W, D)
        flat = q.reshape(-1, q.shape[-1])
        d2 = (flat ** 2).sum(1)[:, None] + (self.train ** 2).sum(1)[None] - 2 * flat @ self.train.T
        joints = q.shape[-1] // 3
        return np.sqrt(np.clip(d2.min(1), 0, None) / joints).reshape(q.shape[:2])

    def measure(self, pos: np.ndarray, units: dict | None = None) -> dict:
        d = self.distance(pos)  # (n, W)
        below = d < self.p5
        if units is not None:
            units["memorised"] = (below.sum(1).astype(float), np.full(len(d), float(d.shape[1])))
            units["nn_distance"] = (d.sum(1), np.full(len(d), float(d.shape[1])))
        return {"memorised": float(below.mean()), "nn_distance": float(d.mean())}


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


def stability(long: np.ndarray, p: Protocol, floor: float, units: dict | None = None) -> dict:
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
    if units is not None:
        units.update(in_range=(inside.astype(float), np.ones(len(long))),
                     frozen=((var < floor).astype(float), np.ones(len(long))))
    return {"in_range": float(inside.mean()), "frozen": float((var < floor).mean())}


def apd_of(row, p: Protocol, idx, samples: int, seed: int, units: dict | None = None) -> float:
    """APD (m) of `samples` draws from each start in idx (the same control), over the measured window
    (``units``: filled with each start's APD)."""
    from course_lib.evaluation import apd

    rep = np.repeat(np.asarray(idx), samples)
    pos = row.generate(p, rep, seed).positions.reshape(len(idx), samples, -1, 21, 3)
    if units is not None:
        units["apd"] = (np.array([apd(x) for x in pos]), np.ones(len(idx)))
    return apd(pos)


def evaluate_seed(row, p: Protocol, seed: int, reference: list[Motion], floor: float,
                  memo: Memorisation | None = None, units: dict | None = None) -> dict:
    """Every seeded measure of one row for one generation seed (memorisation where ``memo`` is given);
    ``units``, when given, is filled with the per-clip (per-start, per-sample) values the bootstrap resamples."""
    spec = p.spec
    _, b = halves(len(p.clips), seed)
    online = isinstance(row, OnlineControl)
    b = b[: spec.online_clips] if online else b
    t0 = time.perf_counter()
    sample = row.generate(p, b, seed)
    out = {"fps": len(b) * p.frames / (time.perf_counter() - t0)}
    out.update(quality(sample, reference, seed, distribution=len(b) >= spec.min_distribution, units=units))
    if memo is not None:
        out.update(memo.measure(sample.positions, units))
    if online and len(b) >= spec.min_distribution:  # the mocap of the same clips: this row's own floor
        same = quality(Mocap().generate(p, b, seed), reference, seed)
        out.update({f"{k}_mocap_same_clips": same[k] for k in ("fid", "is", "c2st")})
    if sample.own is not None:  # a root path of the model's own making
        out.update(control_errors(sample.own, p.truth[b]))
        if units is not None:
            per = [control_errors(o[None], t[None]) for o, t in zip(sample.own, p.truth[b], strict=True)]
            units.update({k: (np.array([e[k] for e in per]), np.ones(len(per))) for k in ("path_error", "speed_error")})
    if not isinstance(row, Mocap):
        starts, samples = spec.online_apd if online else (spec.apd_starts, spec.apd_samples)
        out["apd"] = apd_of(row, p, b[:starts], samples, seed + 100, units)
    if not online:
        out.update(stability(row.long(p, b[: spec.long_samples] if not isinstance(row, Mocap) else b, seed),
                             p, floor, units))
    if isinstance(row, Mocap):
        del out["fps"]
    return out


# ----------------------------------------------------------------------------- the benchmark


def bootstrap_interval(per_seed: list, rng: np.random.Generator, draws: int = BOOTSTRAP) -> tuple[float, float]:
    """per_seed: one (numerator (n,), denominator (n,)) per seed, a unit per clip -> the 95 % percentile interval
    of sum(num) / sum(den), mean over the seeds, under a two-level bootstrap: the seeds drawn with replacement,
    then within each seed its clips."""
    stats = []
    for num, den in per_seed:
        i = rng.integers(0, len(num), (draws, len(num)))
        with np.errstate(invalid="ignore", divide="ignore"):
            stats.append(num[i].sum(1) / den[i].sum(1))  # (draws,)
    stats = np.stack(stats)  # (S, draws)
    pick = rng.integers(0, len(per_seed), (draws, len(per_seed)))
    mean = np.nanmean(stats[pick, np.arange(draws)[:, None]], 1)
    lo, hi = np.nanpercentile(mean, [2.5, 97.5])
    return float(lo), float(hi)


def t_interval(values) -> tuple[float, float]:
    """One value per seed -> mean -+ t_{0.975, S-1} sd / sqrt(S): a 95 % interval over the seeds (each seed a new
    random split of the clips, so their spread holds the clips' sampling noise too)."""
    from scipy.stats import t

    v = np.asarray(values, float)
    if len(v) < 2:
        return float(v[0]), float(v[0])
    half = t.ppf(0.975, len(v) - 1) * v.std(ddof=1) / np.sqrt(len(v))
    return float(v.mean() - half), float(v.mean() + half)


def intervals(runs: list, units: list, mean: dict, seed: int = 0) -> dict:
    """{measure: [low, high]}: a 95 % interval for every seeded measure of one row.  Per-clip measures: the
    two-level bootstrap (`bootstrap_interval`), shifted by the row's mean minus the units' own estimate (0 for
    the measures pooled exactly); one-number-per-seed measures (FID, IS, C2ST, speed): `t_interval`, and C2ST
    widened to its pooled Wilson interval over all predictions where that is wider."""
    from course_lib.evaluation import wilson_interval

    rng = np.random.default_rng(seed)
    out = {}
    for key in SEEDED:
        if key not in mean:
            continue
        if key in SET_LEVEL or not all(key in u for u in units):
            lo, hi = t_interval([r[key] for r in runs])
        else:
            per_seed = [u[key] for u in units]
            own = np.mean([n.sum() / d.sum() for n, d in per_seed if d.sum() > 0])
            lo, hi = np.add(bootstrap_interval(per_seed, rng), mean[key] - own)
        if key == "c2st" and all("c2st_n" in r for r in runs):
            n = sum(r["c2st_n"] for r in runs)
            w = wilson_interval(int(round(sum(r["c2st"] * r["c2st_n"] for r in runs))), int(n))
            lo, hi = min(lo, w[0]), max(hi, w[1])
        lo, hi = (max(lo, 0.0), hi) if key != "fid_excess" else (lo, hi)  # these measures are >= 0
        hi = min(hi, 1.0) if key in FRACTIONS else hi
        out[key] = [float(lo), float(hi)]
    return out


def orderings(results: dict, measures=None) -> list[dict]:
    """For each measure with intervals: the rows by mean, low to high, as a chain ('A < B ~ C': '<' where the
    two neighbours' 95 % intervals do not overlap, '~' where they do), and every pair (a, b) whose intervals
    are apart with a below b: the orderings that hold outside the noise."""
    out = []
    for key in measures or [k for k in SEEDED if k in MEASURES]:
        rows = [(n, r) for n, r in results["rows"].items() if key in r.get("ci", {})]
        if len(rows) < 2:
            continue
        rows.sort(key=lambda nr: nr[1]["mean"][key])
        chain = rows[0][0]
        for (_, a), (nb, b) in zip(rows, rows[1:], strict=False):
            chain += (" < " if a["ci"][key][1] < b["ci"][key][0] else " ~ ") + nb
        pairs = [[na, nb] for i, (na, a) in enumerate(rows) for nb, b in rows[i + 1:]
                 if a["ci"][key][1] < b["ci"][key][0]]
        out.append({"measure": key, "chain": chain, "apart": pairs,
                    "pairs": len(rows) * (len(rows) - 1) // 2})
    return out


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
    t0, cpu0 = time.perf_counter(), time.process_time()
    p = load_protocol(spec)
    floor = freeze_floor([m.resample(FPS) for m in p.clips])
    references = {s: fitted(p.truth[halves(len(p.clips), s)[0]], p.skeletons(halves(len(p.clips), s)[0]))
                  for s in spec.seeds}
    memo = Memorisation.build(p)
    out = {}
    for row in build_rows(checkpoints, rows):
        t = time.perf_counter()
        units = [{} for _ in spec.seeds]
        runs = [evaluate_seed(row, p, s, references[s], floor, memo, u) for s, u in zip(spec.seeds, units, strict=True)]
        if row.name != "Mocap" and "Mocap" in out:  # paired with the floor on the same halves: the split's noise
            for r, floor_run in zip(runs, out["Mocap"]["per_seed"].values(), strict=True):  # cancels
                if "fid" in r:
                    r["fid_excess"] = r["fid"] - r.get("fid_mocap_same_clips", floor_run["fid"])
        mean, sd = over_seeds(runs)
        nll = getattr(row, "nll", lambda _: None)(p)
        fixed = {"params": getattr(row, "params", None), "train_seconds": getattr(row, "train_seconds", None),
                 "nll": nll}
        mean.update({k: v for k, v in fixed.items() if v is not None})
        out[row.name] = {"mean": mean, "sd": sd, "ci": intervals(runs, units, mean),
                         "per_seed": dict(zip(map(str, spec.seeds), runs, strict=True)),
                         "blanks": blanks_of(row.name, spec, mean), "seconds": time.perf_counter() - t}
        if row.name in REPLAYS:
            out[row.name]["flag"] = REPLAYS[row.name]
        if isinstance(row, MotionMatchingRow):
            out[row.name]["search_us_per_frame"] = 1e6 * row.search_per_frame()
        if row.name in NLL_NOTES:
            out[row.name]["nll_note"] = NLL_NOTES[row.name]
        if progress:
            print(f"{row.name}: {out[row.name]['seconds']:.1f} s", file=sys.stderr)
    result = {"spec": dataclasses.asdict(spec), "rows": out, "freeze_floor": floor, "git_head": _git_head(),
              "memorisation": {"mocap_p5": memo.p5, "mocap_median": float(np.median(memo.mocap)),
                               "train_windows": len(memo.train), "heldout_windows": len(memo.mocap)},
              "clips": len(p.clips), "measured_frames": p.frames, "fps": FPS,
              "seconds": time.perf_counter() - t0, "cpu_seconds": time.process_time() - cpu0,
              "measures": {k: list(v) for k, v in MEASURES.items()}}
    result["orderings"] = orderings(result)
    return rounded(result, 5)


LITERATURE = {  # measure -> (its definition here, the literature's name for it)
    "foot_skate": ("mean horizontal speed of a toe in contact (below 5 cm over the known floor y = 0 on two "
                   "frames), frame to frame", "foot skate / foot sliding (lesson 00c; the course's targets)"),
    "foot_skate_auto": ("the same speed with the floor estimated (the lowest toe within 1 s) over 0.1-s "
                        "intervals, the rule for real capture", "foot skate on real mocap"),
    "skating_ratio": (f"the fraction of toe-contact frame pairs sliding faster than {SKATING_SPEED} m/s "
                      "(2.5 cm per frame at 20 fps)", "skating ratio (the diffusion-model papers, e.g. GMD)"),
    "penetration": ("mean depth of the lowest joint below y = 0", "ground penetration ('Penetrate')"),
    "jitter": ("mean magnitude of the joints' third time derivative", "jerk"),
    "bone_length": ("the worst bone's relative change of length, mean over clips", "bone-length error"),
    "fid": ("Frechet distance of the action classifier's features, 2-s windows", "FID (Ghorbani eq. 29; "
            "HumanML3D's FID)"),
    "is": ("exp of the mean KL of the action classifier's posterior to its marginal", "Inception Score"),
    "c2st": ("held-out accuracy of a logistic regression telling the sets apart (target 0.5)",
             "classifier two-sample test (Lopez-Paz and Oquab 2017)"),
    "apd": ("mean joint distance between samples from one start and control",
            "APD (average pairwise distance); HumanML3D's MultiModality is the same idea in feature space"),
    "path_error": ("mean distance of the root to the clip's root path", "trajectory error"),
    "speed_error": ("mean |root speed - the clip's speed|", "velocity error"),
    "in_range": ("fraction of 20-s samples whose root height stays in mocap's range +- 5 cm", "long-term stability"),
    "frozen": ("fraction of 20-s samples whose joint-speed variance over the last 5 s is under the freeze floor",
               "freezing (mean-pose collapse)"),
    "memorised": ("fraction of 1-s windows nearer to a training window than held-out mocap's 5th percentile",
                  "nearest-neighbour memorisation test"),
    "nn_distance": ("RMS joint distance of a 1-s window (its own floor frame) to the nearest training window",
                    "distance to the closest training record"),
    "nll": ("each model's own held-out negative log-likelihood", "NLL"),
    "fps": ("frames generated per second, batched, one core", "inference speed"),
    "params": ("trained parameters (motion matching: the numbers its database stores)", "model size"),
    "train_seconds": ("training time (motion matching: building its database and tree)", "training time"),
}


def protocol_card() -> dict:
    """The benchmark's protocol card: data, splits, clip length, frame rate, seeds, each measure's definition, unit
    and the literature's name (what results/benchmark_protocol.{json,md} hold)."""
    full, ci = BenchSpec(), BenchSpec.ci()
    return {
        "data": "the course's synthetic locomotion corpus (lesson 02's 400 clips of 4 s at 60 fps, 10 subjects, "
                "every clip on one canonical 21-joint skeleton)",
        "splits": "training: 7 subjects' 280 clips (+ mirrors, 560); held out: subjects s00, s05, s09, 120 clips; per "
                  "generation seed the held-out clips split into random halves A (reference) and B (starts)",
        "clip": f"{full.context} s context given, then {4.0 - full.context} s measured, resampled to {FPS:g} fps",
        "seeds": {"full": list(full.seeds), "ci": list(ci.seeds)},
        "clips": {"full": full.clips, "ci": ci.clips},
        "intervals": "95 %: per-clip measures a two-level bootstrap (seeds, then clips within a seed, "
                     f"{BOOTSTRAP} draws); FID, IS, C2ST and speed a t-interval over the seeds (each seed a new "
                     "split of the clips), C2ST widened to its pooled Wilson interval",
        "memorisation": f"{MEMO_WINDOW / FPS:g}-s windows every {MEMO_STRIDE / FPS:g} s (every {MEMO_STEP}rd frame), "
                        "against lesson 02's training clips' windows every 0.1 s",
        "measures": {k: {"label": MEASURES[k][0], "unit": MEASURES[k][1], "better": MEASURES[k][2],
                         "definition": LITERATURE[k][0], "literature": LITERATURE[k][1]} for k in MEASURES},
    }


def card_markdown(card: dict) -> str:
    """The protocol card as Markdown: the settings, then a table of the measures."""
    lines = ["# Benchmark protocol card (lesson 07)", ""]
    for k in ("data", "splits", "clip", "seeds", "clips", "intervals", "memorisation"):
        lines.append(f"- **{k}**: {card[k]}")
    lines += ["", "| column | unit | definition | the literature's name |", "|---|---|---|---|"]
    lines += [f"| {m['label']} | {m['unit'] or '-'} | {m['definition']} | {m['literature']} |"
              for m in card["measures"].values()]
    return "\n".join(lines) + "\n"


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


def _num(v: float, digits: int = 3) -> str:
    return f"{v:.{digits}g}" if abs(v) < 10 ** digits else f"{v:,.0f}"


def cell(row: dict, key: str, digits: int = 3) -> str:
    """One table cell: 'mean [low, high]' (its 95 % interval) where the row has intervals, else 'mean ± sd' over
    the seeds; the value alone when it is not seeded, or a blank."""
    from course_lib.evaluation import mean_sd

    if key in row.get("ci", {}) and key in row["mean"]:
        lo, hi = row["ci"][key]
        m = row["mean"][key]
        if m == 0 and lo == 0 and hi == 0:
            return "0"
        return f"{_num(m, digits)} [{_num(lo, digits)}, {_num(hi, digits)}]"
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
    spread = ("Mean [95 % interval: a two-level bootstrap over seeds and clips; FID, IS, C2ST and speed a "
              "t-interval over the seeds]" if any("ci" in r for r in results["rows"].values()) else "Mean ± sd")
    footer = [f"{spread} over generation seeds {spec['seeds']}; {results['clips']} held-out clips (halves of "
              f"{results['clips'] // 2}), {results['measured_frames']} frames at {results['fps']:g} fps each; "
              f"{results['seconds']:.0f} s in all" + (f" ({results['cpu_seconds']:.0f} s of CPU time)."
                                                       if "cpu_seconds" in results else ".")]
    footer += [f"{n}: {r['flag']} (its memorisation is its design, not a failure)." for n, r in results["rows"].items()
               if "flag" in r]
    footer += [f"{n}: {r['search_us_per_frame']:.0f} µs of k-d tree search per generated frame on one core."
               for n, r in results["rows"].items() if "search_us_per_frame" in r]
    if "memorisation" in results:
        memo = results["memorisation"]
        footer += [f"Memorisation: held-out mocap's windows lie {memo['mocap_median']:.3f} m (median) from the nearest "
                   f"training window; its 5th percentile, {memo['mocap_p5']:.3f} m, is the threshold."]
    footer += [f"NLL of {n}: {NLL_NOTES.get(n, r['nll_note'])}" for n, r in results["rows"].items() if "nll_note" in r]
    return head, rows, reasons, footer


def markdown(results: dict, measures=None) -> str:
    """The results table as Markdown: rows x measures; each blank is numbered and its reason listed below."""
    head, rows, reasons, footer = _table(results, list(measures or MEASURES))
    lines = ["| " + " | ".join(head) + " |", "|---" + "|---:" * (len(head) - 1) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    lines += ["", footer[0], ""] + [f"[{i + 1}] {r}" for i, r in enumerate(reasons)] + [""] + footer[1:]
    if "orderings" in results:
        lines += ["", "Orderings by mean, low to high ('<': the 95 % intervals are apart; '~': they overlap):", ""]
        lines += [f"- {MEASURES[o['measure']][0]}: {o['chain']}" for o in results["orderings"]
                  if measures is None or o["measure"] in measures]
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


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m course_lib.benchmark", description=__doc__.split("\n")[0])
    parser.add_argument("--ci", action="store_true", help="40 clips, 2 seeds (under 3 minutes)")
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
    card = RESULTS.with_name("benchmark_protocol.json")  # the same card for every run: always rewritten
    card.write_text(json.dumps(protocol_card(), indent=1) + "\n")
    card.with_suffix(".md").write_text(card_markdown(protocol_card()))
    out.with_suffix(".md").write_text(markdown(results))
    print(markdown(results))
    print(f"wrote {out} and {out.with_suffix('.md')} in {results['seconds']:.0f} s "
          f"({results['cpu_seconds']:.0f} s CPU)",
          file=sys.stderr)
    return 0


def load_results(path: Path = RESULTS) -> dict:
    """The recorded results (the full benchmark's by default)."""
    return json.loads(Path(path).read_text())


if __name__ == "__main__":
    raise SystemExit(main())
