"""tests/misuse_probes.py: every probe of the library and commands under misuse gives a clear error (the exception
named, with a message that names the problem) or the right answer; none loses a user's file or returns a plausible
wrong answer.  The probe set is also a command that prints its table and the count per outcome class."""

import misuse_probes as P
import pytest


@pytest.mark.parametrize("case", P.CASES, ids=[c.what for c in P.CASES])
def test_probe(case):
    kind, message = P.outcome(case)
    assert P.classify(case, kind, message) in ("clear error", "fine"), f"{kind}: {message}"


def test_the_probe_set_is_large_and_each_case_is_named_once():
    assert len(P.CASES) >= 150
    assert len({c.what for c in P.CASES}) == len(P.CASES)
    rows = [(case, "handled", case.names) for case in P.CASES]
    assert P.table(rows).count("\n") == len(P.CASES) + 2


def test_a_case_that_changes_a_users_file_is_data_loss(tmp_path):
    def clobber(tmp):
        path = P._write(tmp / "mine.txt")
        path.write_text("gone")
        return "handled: fine"
    case = P.Case("self-test", "clobber", clobber, "handled", "fine")
    kind, message = P.outcome(case)
    assert P.classify(case, kind, message) == "data loss" and "mine.txt" in message
