"""Motion datasets: one-file storage, subject splits, fixed-length feature windows, normalisation.

- `save_motions` / `load_motions`: a list of `Motion` <-> one ``.npz`` (clips
  concatenated along time + frame offsets + labels + per-clip skeleton offsets
  + a schema version).  Written deterministically (fixed zip timestamps, no
  compression) and atomically (temp file + ``os.replace``).
- `split_by_subject`: train / val / test with no subject in two splits.
- `FixedDofs`: the degrees of freedom a training set never varies (hinge joints' off-axis
  quaternion components, rigid shoulders and hands), detected from the data and set to their
  constants in every generator's output.
- `WindowDataset`: fixed-length windows of one representation of
  representations.py, normalised with mean/std from the training split only.
- `generate_locomotion_set`, `generate_actions_set`, `noisy_copies`,
  `data_card`: what data_scripts/ run (and `load_dataset` when no file exists).
- `load_dataset(name)`: ``data/<name>.npz`` if present, else a small seeded
  version generated in memory, so notebooks run on a fresh clone.

Taught in notebooks/00_data_and_skeletons.ipynb.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import io
import json
import multiprocessing
import os
import zipfile
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset
from tqdm.auto import tqdm

from course_lib.checksums import write_sidecar
from course_lib.manifest import record_file, verify_file
from course_lib.modes import course_mode
from course_lib.motion import Motion, foot_contacts
from course_lib.outputs import check_outputs
from course_lib.representations import REPRESENTATIONS, encode, feature_names, root_yaw_pitch_roll
from course_lib.skeleton import Skeleton

SCHEMA_VERSION = 1
STD_FLOOR = 1e-4  # features with a smaller std over the training set (constant ones) are divided by this
FIXED_TOL = 1e-6  # a feature whose range over the training frames is at most this is a fixed degree of freedom
DATA_DIR = Path(__file__).resolve().parents[1] / "data"
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)  # fixed timestamp: the same arrays give the same bytes
ACTIONS = ("walk", "jog", "jump", "lift")
STYLES = ("A", "B")

# --- storage ----------------------------------------------------------------------------


def _jsonable(x):
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return {f.name: getattr(x, f.name) for f in dataclasses.fields(x)}
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, (set, tuple)):
        return list(x)
    raise TypeError(f"cannot store a {type(x).__name__} in JSON meta")


def _json(x) -> str:
    return json.dumps(x, sort_keys=True, default=_jsonable)


def write_npz(arrays: dict[str, np.ndarray], path, *, overwrite: bool = False) -> Path:
    """Write arrays to an .npz that np.load reads, byte-for-byte deterministic, atomically.

    Refuses to replace an existing file unless overwrite=True; a crash or Ctrl-C leaves no
    partial file (the data goes to a temp file in the same folder, then os.replace).
    """
    path = check_outputs([path], overwrite=overwrite, who="write_npz")[0]
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        with open(tmp, "wb") as fh, zipfile.ZipFile(fh, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
            for name, arr in arrays.items():
                buf = io.BytesIO()
                np.lib.format.write_array(buf, np.asarray(arr), allow_pickle=False)
                info = zipfile.ZipInfo(name + ".npy", date_time=_ZIP_DATE)
                info.external_attr = 0o644 << 16
                zf.writestr(info, buf.getvalue())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def _frame_meta(motions: list[Motion]) -> dict[str, np.ndarray]:
    """Per-frame meta arrays (T, ...) -> {key: has (C,) bool}, for keys whose arrays share one trailing shape and
    dtype kind in every clip that has them (clips without the key are allowed)."""
    def sig(m, k):
        v = m.meta.get(k)
        ok = isinstance(v, np.ndarray) and v.ndim >= 1 and len(v) == len(m)
        return (v.shape[1:], v.dtype.kind) if ok else None
    out = {}
    for k in sorted({k for m in motions for k in m.meta}):
        sigs = [sig(m, k) for m in motions]
        has = np.array([s is not None for s in sigs])
        if has.any() and len({s for s in sigs if s is not None}) == 1 and all(
                k not in m.meta or s is not None for m, s in zip(motions, sigs, strict=True)):
            out[k] = has
    return out


def save_motions(motions: list[Motion], path, *, meta: dict | None = None, overwrite: bool = False) -> Path:
    """Store clips in one .npz: rotations (N, J, 4) float32 and root_positions (N, 3) float64 concatenated over
    all frames, offsets (C+1,) frame offsets, per-clip fps, labels ('' = None), skeleton offsets (C, J, 3),
    End Site offsets (C, E, 3), JSON meta per clip and for the file, schema_version.

    Per-frame meta arrays (T, ...) are concatenated like the frames ("frame_meta__<key>", over the clips
    that have the key: "frame_meta_has__<key>"); other meta goes to JSON (arrays and dataclasses come back
    as lists and dicts).
    All clips must share joint names and parents (bone lengths may differ).
    """
    if not motions:
        raise ValueError("save_motions: no motions to save")
    sk0 = motions[0].skeleton
    ends = sorted(sk0.end_sites)
    for i, m in enumerate(motions):
        if m.skeleton.names != sk0.names or m.skeleton.parents != sk0.parents or sorted(m.skeleton.end_sites) != ends:
            raise ValueError(f"save_motions: clip {i} has a different skeleton topology than clip 0")
    lengths = [len(m) for m in motions]
    arrays = {
        "schema_version": np.array(SCHEMA_VERSION),
        "rotations": np.concatenate([m.rotations for m in motions]).astype(np.float32),
        "root_positions": np.concatenate([m.root_positions for m in motions]),
        "offsets": np.concatenate(([0], np.cumsum(lengths))).astype(np.int64),
        "fps": np.array([m.fps for m in motions], dtype=np.float64),
        "skeleton_names": np.array(sk0.names),
        "skeleton_parents": np.array(sk0.parents, dtype=np.int64),
        "skeleton_offsets": np.stack([m.skeleton.offsets for m in motions]),
        "end_site_joints": np.array(ends, dtype=np.int64),
        "end_site_offsets": np.stack([np.stack([m.skeleton.end_sites[j] for j in ends]) if ends else np.zeros((0, 3))
                                      for m in motions]),
        "file_meta": np.array(_json(meta or {})),
    }
    frame_keys = _frame_meta(motions)
    arrays["frame_meta_keys"] = np.array(list(frame_keys), dtype=str)
    for k, has in frame_keys.items():
        arrays[f"frame_meta_has__{k}"] = has
        arrays[f"frame_meta__{k}"] = np.concatenate([m.meta[k] for m, h in zip(motions, has, strict=True) if h])
    arrays["clip_meta"] = np.array([_json({k: v for k, v in m.meta.items() if k not in frame_keys})
                                    for m in motions])
    for label in ("action", "style", "subject"):
        arrays[label] = np.array([getattr(m, label) or "" for m in motions])
    return write_npz(arrays, path, overwrite=overwrite)


def _starts_with(path: Path, magic: bytes) -> bool:
    with open(path, "rb") as fh:
        return fh.read(len(magic)) == magic


def _open(path) -> dict[str, np.ndarray]:
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist (make it with data_scripts/, see README)")
    if path.is_file() and path.stat().st_size == 0:
        raise ValueError(f"{path} is empty (0 bytes), not a .npz motion file; remake it with data_scripts/")
    if path.is_file() and not zipfile.is_zipfile(path) and not _starts_with(path, b"\x93NUMPY"):
        raise ValueError(f"{path} is not a .npz motion file (not a zip archive: a text or other file?); "
                         "motion files are written by data_scripts/ or course_lib.datasets.save_motions")
    try:
        loaded = np.load(path, allow_pickle=False)
        if not isinstance(loaded, np.lib.npyio.NpzFile):
            raise ValueError("it holds a single .npy array, not the .npz archive save_motions writes")
        with loaded as z:
            data = {k: z[k] for k in z.files}
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as e:
        raise ValueError(f"{path} is not a readable .npz motion file: {e}") from None
    if "schema_version" not in data:
        raise ValueError(f"{path} is not a course_lib motion file (no schema_version)")
    if int(data["schema_version"]) != SCHEMA_VERSION:
        raise ValueError(f"{path} has schema version {int(data['schema_version'])}, this course_lib reads "
                         f"{SCHEMA_VERSION}; regenerate it with data_scripts/")
    return data


def read_file_meta(path) -> dict:
    """The file-level meta dict stored by `save_motions`."""
    return json.loads(str(_open(path)["file_meta"]))


def load_motions(path) -> list[Motion]:
    """The clips stored by `save_motions`, in order (meta arrays come back as lists)."""
    d = _open(path)
    names, parents = tuple(str(n) for n in d["skeleton_names"]), tuple(int(p) for p in d["skeleton_parents"])
    ends = d["end_site_joints"]
    out, off = [], d["offsets"]
    lengths = np.diff(off)
    frame_meta = {}  # key -> (values, start offset per clip, has per clip)
    for k in map(str, d["frame_meta_keys"]):
        has = d.get(f"frame_meta_has__{k}", np.ones(len(lengths), bool))  # older files: every clip
        frame_meta[k] = d[f"frame_meta__{k}"], np.cumsum(np.where(has, lengths, 0)) - np.where(has, lengths, 0), has
    for c in range(len(off) - 1):
        sk = Skeleton(names, parents, d["skeleton_offsets"][c], dict(zip(ends.tolist(), d["end_site_offsets"][c],
                                                                           strict=True)))
        labels = {k: (str(d[k][c]) or None) for k in ("action", "style", "subject")}
        meta = json.loads(str(d["clip_meta"][c]))
        meta.update({k: v[s0[c]:s0[c] + lengths[c]] for k, (v, s0, has) in frame_meta.items() if has[c]})
        out.append(Motion(d["rotations"][off[c]:off[c + 1]], d["root_positions"][off[c]:off[c + 1]], sk,
                          float(d["fps"][c]), meta=meta, **labels))
    return out


def file_sha256(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


# --- splits -----------------------------------------------------------------------------


def split_by_subject(motions: list[Motion], fractions=(0.8, 0.1, 0.1), test_subjects=None, seed: int = 0):
    """-> (train, val, test) lists of clips; every subject's clips land in exactly one split.

    Subjects are shuffled with `seed` and dealt by `fractions` (each non-empty split gets >= 1
    subject when there are enough); with `test_subjects` those form the test split and the rest is
    dealt to train/val in the ratio fractions[0]:fractions[1].
    """
    if any(m.subject is None for m in motions):
        raise ValueError("split_by_subject: every clip needs a subject label")
    subjects = sorted({m.subject for m in motions})
    rng = np.random.default_rng(seed)
    if test_subjects is not None:
        test = set(test_subjects)
        if not test <= set(subjects):
            raise ValueError(f"split_by_subject: unknown test subjects {sorted(test - set(subjects))}")
        rest = [s for s in subjects if s not in test]
        fr = np.array(fractions[:2], float)
        n_val = int(round(len(rest) * fr[1] / fr.sum()))
        n_val = max(n_val, 1) if fr[1] > 0 and len(rest) > 1 else n_val
        order = [rest[i] for i in rng.permutation(len(rest))]
        groups = (set(order[n_val:]), set(order[:n_val]), test)
    else:
        fr = np.asarray(fractions, float)
        if fr.shape != (3,) or (fr < 0).any() or fr.sum() <= 0:
            raise ValueError(f"split_by_subject: fractions must be 3 non-negative numbers, got {fractions}")
        n = len(subjects)
        counts = [max(int(round(n * f / fr.sum())), 1 if f > 0 and n >= 3 else 0) for f in fr[1:]]
        if sum(counts) >= n:
            raise ValueError(f"split_by_subject: {n} subjects are too few for fractions {tuple(fractions)}")
        order = [subjects[i] for i in rng.permutation(n)]
        n_val, n_test = counts
        groups = (set(order[n_val + n_test:]), set(order[:n_val]), set(order[n_val:n_val + n_test]))
    return tuple([m for m in motions if m.subject in g] for g in groups)


# --- windows and normalisation ----------------------------------------------------------


def compute_stats(features: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """List of (T_i, D) -> mean (D,), std (D,) over all frames, std floored at STD_FLOOR."""
    allf = np.concatenate(features)
    return allf.mean(0), np.maximum(allf.std(0), STD_FLOOR)


@dataclasses.dataclass(frozen=True)
class FixedDofs:
    """Features that never vary in a training set: mask (D,) bool, True where fixed; values (D,) their constants.

    In ``quaternion_root`` 28 of the 84 quaternion channels are fixed (the knees', elbows' and toes'
    off-axis components; the shoulders and hands do not move).  A model should not be judged, nor
    fed, on channels the data never exercise: `apply` sets them to the data's constants, and the
    classifiers of `course_lib.evaluation` drop them from their inputs.
    """

    mask: np.ndarray
    values: np.ndarray

    @classmethod
    def detect(cls, frames, tol: float = FIXED_TOL) -> FixedDofs:
        """frames (..., D) (numpy or torch) -> the features whose range (max - min) is at most tol."""
        f = frames.detach().cpu().double().numpy() if isinstance(frames, torch.Tensor) else np.asarray(frames, float)
        if f.ndim < 2 or f.shape[-1] < 1 or f.size == 0:
            raise ValueError(f"FixedDofs.detect: expected (..., D) frames, got shape {f.shape}")
        f = f.reshape(-1, f.shape[-1])
        if not np.isfinite(f).all():
            raise ValueError("FixedDofs.detect: frames contain NaN or inf")
        return cls(mask=(f.max(0) - f.min(0)) <= tol, values=f.mean(0))

    @classmethod
    def from_stats(cls, mean, std) -> FixedDofs:
        """From normalisation statistics (`compute_stats`): the features whose std sits at STD_FLOOR."""
        mean, std = np.asarray(mean, np.float64), np.asarray(std, np.float64)
        return cls(mask=std <= STD_FLOOR, values=mean)

    def __len__(self) -> int:
        return int(self.mask.sum())

    def names(self, names: list[str]) -> list[str]:
        """The names of the fixed features, given all D feature names."""
        if len(names) != len(self.mask):
            raise ValueError(f"FixedDofs.names: {len(names)} names for {len(self.mask)} features")
        return [n for n, fixed in zip(names, self.mask, strict=True) if fixed]

    def apply(self, x):
        """(..., D) numpy array or tensor -> a copy with every fixed feature set to its constant."""
        if x.shape[-1] != len(self.mask):
            raise ValueError(f"FixedDofs.apply: expected (..., {len(self.mask)}) features, got {tuple(x.shape)}")
        if isinstance(x, torch.Tensor):
            mask = torch.as_tensor(self.mask, device=x.device)
            return torch.where(mask, torch.as_tensor(self.values, dtype=x.dtype, device=x.device), x)
        return np.where(self.mask, self.values, x)


def stats_path(data_path, representation: str, fps: float) -> Path:
    """Where a dataset's normalisation statistics live: beside it, named by representation and fps."""
    p = Path(data_path)
    return p.with_name(f"{p.stem}.stats.{representation}.{fps:g}fps.npz")


def time_reversed(m: Motion) -> Motion:
    """The clip played backwards (per-frame meta arrays reversed too), meta["time_reversed"] = True."""
    T = len(m)
    meta = {k: (v[::-1].copy() if isinstance(v, np.ndarray) and v.ndim and len(v) == T else v)
            for k, v in m.meta.items()}
    return dataclasses.replace(m, rotations=m.rotations[::-1].copy(), root_positions=m.root_positions[::-1].copy(),
                               meta=meta | {"time_reversed": True})


class WindowDataset(Dataset):
    """Fixed-length windows of one representation: item i -> dict with "x" (length, D) float32 tensor
    (normalised), "action"/"style"/"subject" strings ('' if none), "action_id"/"style_id" ints into
    self.actions / self.styles, and "clip", "start" ints.

    motions: the clips (resampled to `fps` if given); stats: (mean, std) from the training split,
    None to compute them here (do that for the training split only, then pass train.stats on);
    mirror: add the left-right mirrored clips; reverse: add the time-reversed clips (both augmentations
    of MoGlow sec. 5; applied after each other, so both give 4x the clips).
    """

    def __init__(self, motions: list[Motion], representation: str, length: int, stride: int | None = None,
                 fps: float | None = None, mirror: bool = False, reverse: bool = False, stats=None, actions=None,
                 styles=None):
        if representation not in REPRESENTATIONS:
            raise ValueError(f"WindowDataset: unknown representation {representation!r}; "
                             f"choose one of {', '.join(REPRESENTATIONS)}")
        if length < 1 or (stride is not None and stride < 1):
            raise ValueError(f"WindowDataset: length and stride must be >= 1, got {length}, {stride}")
        clips = [m if fps is None or m.fps == fps else m.resample(fps) for m in motions]
        clips += [m.mirror() for m in clips] if mirror else []
        clips += [time_reversed(m) for m in clips] if reverse else []
        self.representation, self.length, self.stride = representation, int(length), int(stride or length)
        self.clips = clips
        self.feature_names = feature_names(representation, clips[0].skeleton) if clips else []
        feats = [encode(m, representation) for m in clips]  # (T_i, D) float64
        self.stats = compute_stats(feats) if stats is None else tuple(np.asarray(s, np.float64) for s in stats)
        self.features = [self.normalize(f).astype(np.float32) for f in feats]
        self.index = [(c, s) for c, f in enumerate(feats) for s in range(0, len(f) - self.length + 1, self.stride)]
        if not self.index:
            raise ValueError(f"WindowDataset: no clip has {self.length} frames (longest: "
                             f"{max((len(f) for f in feats), default=0)})")
        self.actions = sorted(actions or {m.action or "" for m in clips})
        self.styles = sorted(styles or {m.style or "" for m in clips})

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, i: int) -> dict:
        c, s = self.index[i]
        m = self.clips[c]
        action, style = m.action or "", m.style or ""
        return {"x": torch.from_numpy(self.features[c][s:s + self.length].copy()),  # (length, D)
                "action": action, "style": style, "subject": m.subject or "",
                "action_id": self.actions.index(action) if action in self.actions else -1,
                "style_id": self.styles.index(style) if style in self.styles else -1, "clip": c, "start": s}

    @property
    def dim(self) -> int:
        return len(self.stats[0])

    def normalize(self, x):
        """(..., D) raw features -> (x - mean) / std (numpy or torch)."""
        mean, std = self._stats_like(x)
        return (x - mean) / std

    def denormalize(self, x):
        """(..., D) normalised features -> raw features (numpy or torch)."""
        mean, std = self._stats_like(x)
        return x * std + mean

    def _stats_like(self, x):
        if x.shape[-1] != self.dim:
            raise ValueError(f"WindowDataset: expected (..., {self.dim}) features, got {tuple(x.shape)}")
        if isinstance(x, torch.Tensor):
            return tuple(torch.as_tensor(s, dtype=x.dtype, device=x.device) for s in self.stats)
        return self.stats

    def save_stats(self, path, *, overwrite: bool = True, command: str | None = None) -> Path:
        """Write mean/std (+ representation and feature names) to an .npz (see `stats_path`) and its sha256:
        in the manifest beside it with ``command`` (the statistics of a checkpoint), else in a sidecar."""
        path = write_npz({"mean": self.stats[0], "std": self.stats[1], "representation": np.array(self.representation),
                          "feature_names": np.array(self.feature_names)}, path, overwrite=overwrite)
        record_file(path, command=command) if command else write_sidecar(path)
        return path


def load_stats(path, representation: str | None = None, *, verify: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """-> (mean (D,), std (D,)) saved by `WindowDataset.save_stats`; checks the representation if given.
    verify: the file's sha256 must match its manifest entry or sidecar first (`manifest.verify_file`): a model fed
    shifted statistics would give plausible wrong motion."""
    if verify:
        verify_file(path)
    with np.load(path, allow_pickle=False) as z:
        if representation is not None and str(z["representation"]) != representation:
            raise ValueError(f"{path} holds statistics of {str(z['representation'])!r}, not {representation!r}")
        return z["mean"].copy(), z["std"].copy()


# --- generation (what data_scripts/ call) ----------------------------------------------


def _clip_seed(seed: int, *keys: int) -> int:
    """An independent integer seed per clip: the same (seed, keys) always gives the same one."""
    return int(np.random.SeedSequence([int(seed), *map(int, keys)]).generate_state(1)[0])


def _at_fps(m: Motion, fps: float) -> Motion:
    """m resampled to fps, per-frame meta arrays included (nearest frame)."""
    from course_lib.synthetic.locomotion import resample_motion

    return resample_motion(m, fps)


def resample_clips(motions: list[Motion], fps: float | None) -> list[Motion]:
    """The clips at `fps` (unchanged if None), per-frame meta arrays resampled too."""
    return list(motions) if fps is None else [_at_fps(m, fps) for m in motions]


def _one_thread() -> None:
    # The generator's tensors are tiny: torch's intra-op threads cost ~5x (27 vs 137 ms a clip, bench)
    torch.set_num_threads(1)


@contextlib.contextmanager
def _single_threaded():
    """Run the block with one torch thread, then restore the caller's setting."""
    threads = torch.get_num_threads()
    _one_thread()
    try:
        yield
    finally:
        torch.set_num_threads(threads)


def _map(fn, jobs: list, workers: int, desc: str, progress: bool) -> list:
    """[fn(job) for job in jobs] in order, in `workers` processes (spawned: safe after torch was used),
    each with one torch thread."""
    bar = dict(total=len(jobs), desc=desc) if progress else dict(disable=True)  # TQDM_DISABLE=1 is honoured
    if workers <= 1 or len(jobs) < 2:
        with _single_threaded():
            return [fn(j) for j in tqdm(jobs, **bar)]
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(min(workers, len(jobs)), mp_context=ctx, initializer=_one_thread) as ex:
        return list(tqdm(ex.map(fn, jobs, chunksize=max(1, min(16, len(jobs) // (4 * workers)))), **bar))


MAX_ATTEMPTS = 3  # a clip whose generation raises is redrawn with the next seed; the card counts them


def _with_retries(make, keys: tuple) -> Motion:
    """make(seed) with seed _clip_seed(*keys), then _clip_seed(*keys, k) for attempt k = 1, 2 on ValueError;
    meta["attempt"] = k."""
    for k in range(MAX_ATTEMPTS):
        try:
            m = make(_clip_seed(*keys) if k == 0 else _clip_seed(*keys, k))
        except ValueError:
            if k == MAX_ATTEMPTS - 1:
                raise
            continue
        m.meta = dict(m.meta, attempt=k)
        return m


def _locomotion_clip(job) -> Motion:
    from course_lib.synthetic import generate_locomotion

    subject, duration, fps, keys = job
    return _with_retries(lambda seed: generate_locomotion(subject, None, duration=duration, fps=fps, seed=seed), keys)


def _action_clip(job) -> Motion:
    from course_lib.synthetic import generate_action

    subject, action, style, fps, keys = job
    return _with_retries(lambda seed: generate_action(subject, action, style, fps=fps, seed=seed), keys)


def generate_locomotion_set(n_clips: int, seed: int = 0, fps: float = 60.0, duration: float = 4.0,
                            n_subjects: int | None = None, workers: int = 1, progress: bool = False) -> list[Motion]:
    """n_clips locomotion clips, each from its own random control program (synthetic.generate_locomotion,
    generated at 120 fps and resampled to fps).  Clip i belongs to subject i mod n_subjects (default:
    one subject per 40 clips, between 8 and 60).  The result does not depend on `workers`."""
    from course_lib.synthetic import make_subjects

    n_subjects = n_subjects or max(8, min(60, n_clips // 40))
    subjects = make_subjects(n_subjects, seed)
    jobs = [(subjects[i % n_subjects], duration, fps, (seed, i)) for i in range(n_clips)]
    return _map(_locomotion_clip, jobs, workers, "locomotion", progress)


def generate_actions_set(n_subjects: int, seed: int = 0, fps: float = 60.0, actions=ACTIONS, styles=STYLES,
                         workers: int = 1, progress: bool = False) -> list[Motion]:
    """One clip per (subject, action, style) (synthetic.generate_action); independent of `workers`."""
    from course_lib.synthetic import make_subjects

    subjects = make_subjects(n_subjects, seed)
    jobs = [(subjects[s], a, st, fps, (seed, s, i, k)) for s in range(n_subjects)
            for i, a in enumerate(actions) for k, st in enumerate(styles)]
    return _map(_action_clip, jobs, workers, "actions", progress)


def noisy_copies(motions: list[Motion], seed: int = 0, progress: bool = False) -> list[Motion]:
    """A noisy copy of each clip (synthetic.add_noise: jitter, spikes, dropped frames; same length),
    meta["clean_index"] = its clip's index, meta["noise"] = what was corrupted."""
    from course_lib.synthetic import add_noise

    out = []
    with _single_threaded():
        for i, m in enumerate(tqdm(motions, desc="noise", **({} if progress else dict(disable=True)))):
            n = add_noise(m, seed=_clip_seed(seed, i))
            n.meta = {k: v for k, v in n.meta.items() if k != "clean"} | {"clean_index": i}  # clean: kept beside
            out.append(n)
    return out


# --- data card --------------------------------------------------------------------------

LACKS = (
    "kinematic, not dynamic: no ground-reaction forces, momentum or balance are simulated",
    "no soft tissue, clothing or marker wobble; rigid bones of fixed length",
    "no fingers, toes flex only at one joint, a 21-joint body with no face or spine detail",
    "a perfectly flat, level floor: no stairs, slopes, obstacles or objects (lift has no real box)",
    "a few procedural styles (2 groups) and subjects drawn from one parametric family, "
    "far less variety than real people",
    "no capture artefacts (occlusion gaps, marker swaps, calibration drift) except what make_noisy.py adds",
    "no interaction with other people, props or the environment",
)


def _summary(x: np.ndarray) -> dict:
    """(N,) -> rounded min / 1st, 50th, 99th percentile / max."""
    p = np.percentile(x, [1, 50, 99]) if len(x) else [np.nan] * 3
    vals = (x.min(), *p, x.max()) if len(x) else (np.nan,) * 5
    return {k: round(float(v), 4) for k, v in zip(("min", "p01", "median", "p99", "max"), vals, strict=True)}


def _gait_frames(motions: list[Motion]) -> dict:
    """Frames per gait from the generator's per-frame meta["gait"] (indices into meta["gait_names"])."""
    c = Counter()
    for m in motions:
        if "gait" in m.meta and "gait_names" in m.meta:
            c.update(str(m.meta["gait_names"][int(g)]) for g in m.meta["gait"])
    return dict(sorted(c.items()))


def data_card(motions: list[Motion], *, name: str, seed: int, command: str, description: str) -> dict:
    """What a dataset holds: counts per action/style/subject, ranges of speed, heading rate, duration,
    root height, lowest toe height and contact share, and what real mocap has that it lacks."""
    speeds, turn, clip_speed, lowest, contact = [], [], [], [], []
    for m in motions:
        step = np.linalg.norm(np.diff(m.root_positions[:, [0, 2]], axis=0), axis=-1) * m.fps  # (T-1,) m/s
        yaw = np.unwrap(root_yaw_pitch_roll(m)[:, 0])
        speeds.append(step)
        clip_speed.append(step.mean() if len(step) else 0.0)
        turn.append(np.degrees(np.abs(np.diff(yaw))) * m.fps)
        pos = m.positions()  # (T, J, 3)
        lowest.append(pos[:, list(m.skeleton.feet), 1].min())
        contact.append(foot_contacts(pos, m.skeleton, m.fps).any(-1).mean())
    cat = lambda xs: np.concatenate(xs) if xs else np.zeros(0)  # noqa: E731
    return {
        "name": name, "schema_version": SCHEMA_VERSION, "description": description, "seed": int(seed),
        "command": command, "clips": len(motions), "frames": int(sum(len(m) for m in motions)),
        "clips_redrawn_after_a_generator_error": sum(int(m.meta.get("attempt", 0) > 0) for m in motions),
        "fps": sorted({float(m.fps) for m in motions}),
        "counts": {k: dict(sorted(Counter(getattr(m, k) or "(none)" for m in motions).items()))
                   for k in ("action", "style", "subject")} | {"frames_per_gait": _gait_frames(motions)},
        "ranges": {"duration_s": _summary(np.array([m.duration for m in motions])),
                   "root_speed_m_per_s": _summary(cat(speeds)),
                   "clip_mean_speed_m_per_s": _summary(np.array(clip_speed)),
                   "heading_rate_deg_per_s": _summary(cat(turn)),
                   "root_height_m": _summary(cat([m.root_positions[:, 1] for m in motions])),
                   "lowest_foot_joint_height_m": _summary(np.array(lowest)),
                   "share_of_frames_with_a_foot_contact": _summary(np.array(contact))},
        "lacks": list(LACKS),
    }


def _card_markdown(card: dict) -> str:
    lines = [f"# Data card: {card['name']}", "", card["description"], "",
             f"- schema version {card['schema_version']}, seed {card['seed']}",
             f"- command: `{card['command']}`",
             f"- {card['clips']} clips, {card['frames']} frames at {', '.join(f'{f:g}' for f in card['fps'])} fps",
             f"- clips redrawn with the next seed after a generator error: "
             f"{card['clips_redrawn_after_a_generator_error']}", ""]
    for key, counts in card["counts"].items():
        lines.append(f"**{key}** ({len(counts)}): " + ", ".join(f"{k} {v}" for k, v in counts.items()))
        lines.append("")
    lines += ["| quantity | min | 1% | median | 99% | max |", "|---|---|---|---|---|---|"]
    lines += [f"| {k} | " + " | ".join(f"{v:g}" for v in r.values()) + " |" for k, r in card["ranges"].items()]
    lines += ["", "## What real motion capture has that this data lacks", ""] + [f"- {x}" for x in card["lacks"]]
    return "\n".join(lines) + "\n"


def _write_text(text: str, path: Path) -> None:
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_text(text)
    os.replace(tmp, path)


def card_paths(data_path) -> tuple[Path, Path]:
    """The data card's two companions of a data file: <stem>.card.json and <stem>.card.md beside it."""
    p = Path(data_path)
    return p.with_name(p.stem + ".card.json"), p.with_name(p.stem + ".card.md")


def dataset_paths(data_path) -> tuple[Path, Path, Path]:
    """Every file `write_dataset` writes: the .npz and its two card files."""
    return (Path(data_path), *card_paths(data_path))


def write_data_card(card: dict, data_path, *, overwrite: bool = False) -> tuple[Path, Path]:
    """Write <stem>.card.json and <stem>.card.md beside the data file (existing cards: overwrite=True)."""
    paths = card_paths(data_path)
    check_outputs(paths, overwrite=overwrite, who="write_data_card")
    _write_text(json.dumps(card, indent=1) + "\n", paths[0])
    _write_text(_card_markdown(card), paths[1])
    return paths


def write_dataset(motions: list[Motion], path, *, card: dict, meta: dict | None = None,
                  overwrite: bool = False, inputs=()) -> Path:
    """save_motions + the data card beside (the card's command line is not stored in the .npz, so the
    same data written to another path has the same bytes).  All three files are checked before any is
    written (`outputs.check_outputs`): none may be in `inputs`, none may exist unless overwrite=True."""
    check_outputs(dataset_paths(path), overwrite=overwrite, inputs=inputs, who="write_dataset")
    try:  # the card is checked before anything is written: no data file without its card
        _card_markdown(card)
    except (KeyError, TypeError) as err:
        raise ValueError(f"write_dataset: the card lacks {err}; make it with datasets.data_card(...)") from None
    path = save_motions(motions, path, meta=meta, overwrite=overwrite)
    write_data_card(card, path, overwrite=True)
    return path


# --- ready-made datasets ----------------------------------------------------------------

# The most a data script generates in one run: the full locomotion set is 1800 clips x 4 s = 7200 s, and
# generation holds every clip at 120 fps in memory (about 1 GB per 7200 s).
MAX_GENERATED_SECONDS = 100_000.0
MAX_ACTION_SUBJECTS = 1000  # the full actions set has 40 subjects x 8 clips

# In-memory sizes when data/<name>.npz is absent, per COURSE_MODE (locomotion: clips; actions:
# subjects, each doing 4 actions x 2 styles).  The data_scripts defaults are the "full" sizes.
GENERATED_SIZES = {"locomotion": {"ci": 24, "class": 240, "full": 1800},
                   "actions": {"ci": 4, "class": 12, "full": 40}}
DATASETS = ("locomotion", "actions", "locomotion_noisy", "actions_noisy")


def load_dataset(name: str, mode: str | None = None, data_dir=None, seed: int = 0, fps: float = 60.0,
                 progress: bool = False) -> list[Motion]:
    """The clips of a dataset at `fps`.

    In `mode` "ci" (default: COURSE_MODE) always a small seeded set generated in memory, so CI's
    results do not depend on what `make data` left in data/.  Otherwise data_dir/<name>.npz
    (default: the repository's data/) if it exists, resampled to `fps`; else a seeded set generated
    in memory, sized by `mode` -- see GENERATED_SIZES.

    Noisy sets ("locomotion_noisy") are noisy copies of the clean set; see `load_noisy_pairs`.
    """
    if name not in DATASETS:
        raise ValueError(f"load_dataset: unknown dataset {name!r}; choose one of {', '.join(DATASETS)}")
    mode = mode or course_mode()
    if mode not in GENERATED_SIZES[name.removesuffix("_noisy")]:
        raise ValueError(f"load_dataset: unknown mode {mode!r}; choose one of "
                         f"{', '.join(GENERATED_SIZES[name.removesuffix('_noisy')])}")
    path = Path(data_dir or DATA_DIR) / f"{name}.npz"
    if mode != "ci" and path.exists():
        return resample_clips([m for m in load_motions(path)], fps)
    if name.endswith("_noisy"):
        return noisy_copies(load_dataset(name[:-6], mode, data_dir, seed, fps, progress), seed + 1, progress)
    n = GENERATED_SIZES[name][mode]
    if name == "locomotion":
        return generate_locomotion_set(n, seed, fps, progress=progress)
    return generate_actions_set(n, seed, fps, progress=progress)


def load_noisy_pairs(name: str = "locomotion_noisy", mode: str | None = None, data_dir=None, seed: int = 0,
                     fps: float = 60.0) -> tuple[list[Motion], list[Motion]]:
    """-> (noisy, clean) clip lists in matching order.  From files: the clean file beside the noisy
    one (its sha256 is checked), clips picked by meta["clean_index"] and resampled to the noisy fps."""
    noisy_path = Path(data_dir or DATA_DIR) / f"{name}.npz"
    if not noisy_path.exists():
        clean = load_dataset(name[:-6] if name.endswith("_noisy") else name, mode, data_dir, seed, fps)
        return noisy_copies(clean, seed + 1), clean
    info = read_file_meta(noisy_path)
    clean_path = noisy_path.with_name(info["clean_file"])
    if file_sha256(clean_path) != info["clean_sha256"]:
        raise ValueError(f"{clean_path} changed since {noisy_path} was made from it; rerun make_noisy.py")
    noisy, clean = load_motions(noisy_path), load_motions(clean_path)
    return noisy, [_at_fps(clean[n.meta["clean_index"]], n.fps) for n in noisy]
