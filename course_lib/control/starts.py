"""Held-out start frames for lesson 04's control problems: lesson 02/03's synthetic locomotion clips of the
held-out subjects (``DataSpec.test_subjects``), resampled to the GMM-RNN's 30 fps, labelled by gait.

Taught in notebooks/04_map_control.ipynb.  Loading reads data/habibie_locomotion.npz (generated and cached on
first use by ``corpus.load_clips``); nothing is read at import time.
"""

from __future__ import annotations

import functools

import numpy as np

from course_lib.corpus import DataSpec, load_clips
from course_lib.motion import Motion

__all__ = ["held_out_clips", "held_out_start", "gaits", "training_clips"]

FPS = 30.0  # the GMM-RNN's frame rate (sec. 4.1.3)


@functools.lru_cache(maxsize=2)
def _clips(fps: float) -> tuple[Motion, ...]:
    spec = DataSpec()
    return tuple(m.resample(fps) for m in load_clips(spec, progress=False) if m.subject in spec.test_subjects)


@functools.lru_cache(maxsize=1)
def _training(fps: float) -> tuple[Motion, ...]:
    spec = DataSpec()
    return tuple(m.resample(fps) for m in load_clips(spec, progress=False) if m.subject not in spec.test_subjects)


def training_clips(gait: str | None = None, fps: float = FPS) -> list[Motion]:
    """The clips of the other subjects (the RNN's training data), all or those of ``gait``."""
    return [m for m in _training(float(fps)) if gait is None or m.action == gait]


def held_out_clips(gait: str | None = None, fps: float = FPS) -> list[Motion]:
    """The held-out clips (4 s each), all or those whose label (``Motion.action``) is ``gait``."""
    clips = list(_clips(float(fps)))
    if gait is None:
        return clips
    if gait not in gaits(fps):
        raise ValueError(f"unknown gait {gait!r}; the held-out data has {sorted(gaits(fps))}")
    return [m for m in clips if m.action == gait]


def gaits(fps: float = FPS) -> set:
    """The gait labels of the held-out clips (walk, jog, run, ...)."""
    return {m.action for m in _clips(float(fps))}


def held_out_start(gait: str = "walk", seed: int = 0, frames: int = 30, fps: float = FPS) -> Motion:
    """A held-out clip of ``gait`` and a start frame in it, both drawn with ``seed`` -> the ``frames`` frames from
    there (the first two are the start; the rest give the contact labels and the stance toe height)."""
    clips = held_out_clips(gait, fps)
    rng = np.random.default_rng(seed)
    clip = clips[int(rng.integers(len(clips)))]
    s = int(rng.integers(0, len(clip) - frames + 1))
    return clip[s:s + frames]
