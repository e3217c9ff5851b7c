"""Results for JSON: every experiment and study records its numbers rounded the same way.

`rounded` is used by the lessons' experiment modules (course_lib/experiments/), the benchmark and the studies in
tools/ before they write a result to the manifest or a JSON file, so that a re-run on another CPU changes a
recorded number only where it changes in its sixth decimal (or the ``digits`` asked).
"""

from __future__ import annotations

import numpy as np

__all__ = ["rounded"]


def rounded(d, digits: int = 6):
    """Results for JSON: floats rounded to ``digits`` decimals inside nested dicts/lists/tuples, keys as str."""
    if isinstance(d, dict):
        return {str(k): rounded(v, digits) for k, v in d.items()}
    if isinstance(d, (list, tuple)):
        return [rounded(v, digits) for v in d]
    return round(float(d), digits) if isinstance(d, (float, np.floating)) else d
