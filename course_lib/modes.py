"""The course's run modes, chosen by one environment variable, COURSE_MODE.

- ``ci``: minutes per notebook; pretrained weights, short live training (CI, nbval);
- ``class`` (default): trains small models live, a few minutes per lesson;
- ``full``: the reproduction runs of ``make reproduce``.
"""

from __future__ import annotations

import os

MODES = ("ci", "class", "full")


def course_mode() -> str:
    """The mode in COURSE_MODE ('class' when unset); raises on an unknown value."""
    mode = os.environ.get("COURSE_MODE", "class").strip().lower() or "class"
    if mode not in MODES:
        raise ValueError(f"COURSE_MODE={mode!r} is not one of {', '.join(MODES)}")
    return mode


def by_mode(ci, class_, full):
    """Pick a value for the current mode: ``epochs = by_mode(ci=2, class_=20, full=200)``."""
    return {"ci": ci, "class": class_, "full": full}[course_mode()]
