"""course_lib.results.rounded: what every experiment writes to JSON."""

import json

import numpy as np

from course_lib.results import rounded


def test_rounded_rounds_floats_at_every_depth_and_keys_become_str():
    d = {1: np.float32(0.5), "a": [1.23456789, (2, np.float64(3.0000004))], "b": {"c": 0.1 + 0.2}}
    out = rounded(d)
    assert out == {"1": 0.5, "a": [1.234568, [2, 3.0]], "b": {"c": 0.3}}
    assert type(out["1"]) is float and type(out["a"][1][1]) is float
    assert json.loads(json.dumps(out)) == out
    assert rounded({"x": 1.23456789}, 3) == {"x": 1.235}
    assert rounded([7, "s", None, True]) == [7, "s", None, True]  # ints, strings, None, bools as given
