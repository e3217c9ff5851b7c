"""course_lib.evaluation.tables: over_seeds (mean and sd over generation seeds) with known answers."""

import math

import pytest

from course_lib.evaluation import over_seeds


def test_over_seeds_known_answers_on_nested_dicts():
    mean, sd = over_seeds([{"a": 1.0, "b": {"c": 2, "ok": True}}, {"a": 3.0, "b": {"c": 6, "ok": False}}])
    assert mean == {"a": 2.0, "b": {"c": 4.0, "ok": 0.5}}
    assert sd["a"] == pytest.approx(math.sqrt(2)) and sd["b"]["c"] == pytest.approx(math.sqrt(8))
    assert sd["b"]["ok"] == pytest.approx(math.sqrt(0.5))


def test_over_seeds_one_seed_has_zero_sd():
    assert over_seeds([{"x": 5}]) == ({"x": 5.0}, {"x": 0.0})
