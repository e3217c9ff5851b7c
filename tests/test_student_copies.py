"""Student copies (tools/student_copies.py, nbgrader): every exercise's check fails on the stub, passes on the solution.

Fast: only each lesson's exercise cells run (its `exercises-setup` cell, then every solution and check
cell in order: they sit in the sections they practise and are built to run on their own), once with
the solutions (the release notebook) and once with nbgrader's stubs (the student copy).  With the
stubs every check must fail *as a check* -- AssertionError, raised because a computed value differs --
and no other exercise cell may fail; with the solutions nothing may fail.  The whole release notebooks
run under nbval (`make nbval`).
"""

from __future__ import annotations

import ast
import copy
import sys
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tools"))
import student_copies as S  # noqa: E402

# lessons whose exercises are autograded (every lesson)
LESSONS = sorted(p.stem for p in (REPO / "notebooks").glob("[0-9]*.ipynb"))
MIN_EXERCISES = 4


def release(lesson: str):
    return nbformat.read(REPO / "notebooks" / f"{lesson}.ipynb", as_version=4)


def run_section(nb) -> list[tuple[dict, str | None]]:
    """Execute the exercise section of nb in a fresh kernel -> (cell, error name or None) per code cell."""
    cells = [copy.deepcopy(c) for c in S.exercise_section(nb)]
    section = nbformat.v4.new_notebook(cells=cells, metadata=nb.metadata)
    NotebookClient(section, timeout=300, kernel_name="python3", allow_errors=True,
                   resources={"metadata": {"path": str(REPO / "notebooks")}}).execute()
    return [(c, next((o["ename"] for o in c.outputs if o["output_type"] == "error"), None)) for c in section.cells]


def names(source: str) -> tuple[set[str], set[str]]:
    """(names a cell assigns or defines, names it reads) -- IPython magics aside, cells are plain Python."""
    stored, loaded = set(), set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Name):
            (stored if isinstance(node.ctx, ast.Store) else loaded).add(node.id)
        elif isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            stored.add(node.name)
        elif isinstance(node, ast.arg):  # a function's or lambda's parameter is its own name
            stored.add(node.arg)
    return stored, loaded


def test_every_lesson_with_nbgrader_cells_is_listed():
    marked = sorted(p.stem for p in (REPO / "notebooks").glob("[0-9]*.ipynb")
                    if S.has_exercises(nbformat.read(p, as_version=4)))
    assert marked == sorted(LESSONS)


@pytest.mark.parametrize("lesson", LESSONS)
def test_exercises_are_marked_for_nbgrader(lesson):
    nb = release(lesson)
    pairs = S.exercises(nb)
    assert len(pairs) >= MIN_EXERCISES, f"{lesson}: {len(pairs)} exercises"
    ids = [S.nbgrader_meta(c)["grade_id"] for c in nb.cells if S.nbgrader_meta(c)]
    assert len(ids) == len(set(ids)), "grade_ids must be unique"
    for c in nb.cells:
        meta = S.nbgrader_meta(c)
        if S.is_solution(c):
            assert "### BEGIN SOLUTION" in c.source and "### END SOLUTION" in c.source, meta["grade_id"]
            assert not meta["locked"] and meta["schema_version"] == 3
        if S.is_check(c):
            assert meta["locked"] and meta["points"] > 0 and "BEGIN SOLUTION" not in c.source, meta["grade_id"]


@pytest.mark.parametrize("lesson", LESSONS)
def test_student_copy_has_no_solutions_and_no_outputs(lesson):
    nb = release(lesson)
    student = S.student_copy(nb)
    assert len(student.cells) == len(nb.cells)
    for before, after in zip(nb.cells, student.cells, strict=True):
        assert "BEGIN SOLUTION" not in after.source
        if after.cell_type == "code":
            assert after.outputs == []
        if S.is_solution(before):
            answer = before.source.split("### BEGIN SOLUTION")[1].split("### END SOLUTION")[0]
            lines = [ln.strip() for ln in answer.splitlines() if ln.strip()]
            assert not any(ln in after.source.splitlines() for ln in map(str, lines) if len(ln) > 12), \
                f"{S.nbgrader_meta(before)['grade_id']}: a solution line is left in the student copy"
            assert S.CODE_STUB["python"] in after.source or after.cell_type == "markdown"
        else:
            assert after.source == before.source
    assert release(lesson).cells[0].source == nb.cells[0].source  # the release notebook is not modified


@pytest.mark.slow  # make test-slow: runs every exercise section twice
@pytest.mark.parametrize("lesson", LESSONS)
def test_stubs_fail_every_check_and_solutions_pass(lesson):
    nb = release(lesson)
    n = len(S.exercises(nb))
    solved = run_section(nb)
    failed = [(S.nbgrader_meta(c).get("grade_id"), err) for c, err in solved if err]
    assert not failed, f"{lesson}: the release's exercise section fails: {failed}"
    stubbed = run_section(S.student_copy(nb))
    checks = [(S.nbgrader_meta(c)["grade_id"], err) for c, err in stubbed if S.is_check(c)]
    others = [(S.nbgrader_meta(c).get("grade_id"), err) for c, err in stubbed if not S.is_check(c) and err]
    assert len(checks) == n
    assert not others, f"{lesson}: with the stubs a cell other than a check fails: {others}"
    not_failing = [(gid, err) for gid, err in checks if err != "AssertionError"]
    assert not not_failing, f"{lesson}: checks that do not fail with AssertionError on the stubs: {not_failing}"
    print(f"{lesson}: {n} exercises; stubs: {sum(e == 'AssertionError' for _, e in checks)}/{n} checks fail "
          f"(AssertionError); solutions: {n}/{n} pass")


@pytest.mark.parametrize("lesson", LESSONS)
def test_lesson_cells_do_not_read_the_answers(lesson):
    # in a student copy the answers are stubs and a check stops at its first failed assertion: a lesson cell
    # (any code cell that is not an exercise's) that reads a name only an answer or a check defines would
    # compute with the stub, or fail with a NameError
    cells = release(lesson).cells
    exercise = [c for c in cells if S.is_solution(c) or S.is_check(c)]
    answered = set().union(*(names(c.source)[0] for c in exercise))
    lesson_cells = [c for c in cells if c.cell_type == "code" and not (S.is_solution(c) or S.is_check(c))]
    elsewhere = set().union(*(names(c.source)[0] for c in lesson_cells))
    for c in lesson_cells:
        stored, loaded = names(c.source)
        reads = (loaded - stored) & (answered - elsewhere)
        assert not reads, f"{lesson}: a lesson cell reads {sorted(reads)}, set only by an exercise"
