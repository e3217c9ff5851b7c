"""The synthetic locomotion corpus shared by lessons 02-04: 400 clips of 4 s at 60 fps, 10 subjects, 3 held out.

Lesson 02 (experiments/vae_lstm.py) trains on it at 60 fps, lesson 03 (experiments/gmm_rnn.py) at 30 fps, and
lesson 04's start frames (control/starts.py) are its held-out clips.  `load_clips` caches the clips in
data/habibie_locomotion.npz with the `DataSpec` that made them; nothing is read or generated at import time.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

from tqdm.auto import tqdm

from course_lib.datasets import DATA_DIR, _clip_seed, load_motions, read_file_meta, resample_clips, save_motions
from course_lib.motion import Motion
from course_lib.synthetic import generate_locomotion, make_subjects

__all__ = ["CACHE_KEYS", "DATA_FILE", "DataSpec", "generate_clips", "load_clips"]

DATA_FILE = DATA_DIR / "habibie_locomotion.npz"


@dataclass
class DataSpec:
    """Which clips (n_clips .. length decide them, `CACHE_KEYS`), the held-out subjects, and how lesson 02 windows
    them (mirror, one_body: `experiments.vae_lstm.datasets`)."""

    n_clips: int = 400  # 4-s clips; 10 subjects of 40 clips each
    n_subjects: int = 10
    test_subjects: tuple = ("s00", "s05", "s09")  # held out: 120 test clips
    seed: int = 2017
    fps: float = 60.0
    length: int = 240  # frames per clip (4 s), Habibie sec. 4.1
    mirror: bool = True  # left-right mirrored training clips (augmentation)
    one_body: bool = False  # every clip retargeted to the canonical skeleton (`Motion.retarget`): one body
    extra: dict = field(default_factory=dict)


def generate_clips(spec: DataSpec, progress: bool = True) -> list[Motion]:
    """spec.n_clips locomotion clips at spec.fps.  A clip whose generation fails (the generator can
    produce NaN for rare programs) is redrawn with the next seed, so the count is always met."""
    subjects = make_subjects(spec.n_subjects, spec.seed)
    clips, redrawn = [], 0
    bar = {} if progress else dict(disable=True)  # an empty dict lets TQDM_DISABLE=1 apply
    for i in tqdm(range(spec.n_clips), desc="clips", **bar):
        for attempt in range(20):
            try:
                m = generate_locomotion(subjects[i % spec.n_subjects], None, duration=(spec.length + 1) / spec.fps,
                                        seed=_clip_seed(spec.seed, i, attempt))
                break
            except ValueError:
                redrawn += 1
        else:
            raise RuntimeError(f"clip {i}: the generator failed 20 times")
        clips.append(resample_clips([m], spec.fps)[0])
    if redrawn:
        print(f"generate_clips: {redrawn} clip(s) redrawn after a generator failure", file=sys.stderr)
    return clips


CACHE_KEYS = ("n_clips", "n_subjects", "seed", "fps", "length")  # the DataSpec fields that decide the clips


def load_clips(spec: DataSpec, path: Path = DATA_FILE, progress: bool = True) -> list[Motion]:
    """The cached clips at ``path`` if it exists, else generated (and cached, with the spec that made them).

    A cache made from another spec is refused with an error naming the difference (it is not overwritten: delete
    it or pass another ``path``); a cache from before the spec was recorded must at least hold spec.n_clips clips
    at spec.fps."""
    wanted = {k: getattr(spec, k) for k in CACHE_KEYS}
    if not path.exists():
        clips = generate_clips(spec, progress)
        save_motions(clips, path, meta={"data_spec": wanted}, overwrite=True)
        return clips
    made = read_file_meta(path).get("data_spec")
    clips = load_motions(path)
    if made is None:
        made = {"n_clips": len(clips), "fps": clips[0].fps}
    differ = {k: (v, wanted[k]) for k, v in made.items() if k in wanted and v != wanted[k]}
    if differ:
        what = ", ".join(f"{k} {a!r}, asked {b!r}" for k, (a, b) in differ.items())
        raise ValueError(f"{path}: these clips were made with another DataSpec ({what}); delete the file to "
                         "regenerate it, or pass another path")
    return clips
