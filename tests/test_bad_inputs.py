"""tools/bad_inputs.py, issue 18's table of bad inputs: each input gives the outcome the table states (the
exception named, with a message that names the problem, or the correct result), so the table cannot drift."""

import pytest
from conftest import load_tool

TOOL = load_tool("bad_inputs")


@pytest.mark.parametrize("case", TOOL.CASES, ids=[c.what for c in TOOL.CASES])
def test_bad_input_outcome(case):
    kind, message = TOOL.outcome(case)
    assert kind == case.expect, message
    assert case.names in message
    assert "Traceback" not in message


def test_the_table_lists_every_case_once():
    rows = [(case, "handled", "ok") for case in TOOL.CASES]
    text = TOOL.table(rows)
    assert text.count("\n") == len(TOOL.CASES) + 2
    assert len({c.what for c in TOOL.CASES}) == len(TOOL.CASES)
