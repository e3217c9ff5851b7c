"""Write the student copies of the lessons: the exercises' solutions removed with nbgrader's tooling.

Usage: python tools/student_copies.py --notebooks notebooks --out student [--force]

`make student-copies` runs it (`make student` too, then opens JupyterLab in student/).  A copy that
is already there holds the student's answers and is kept; `--force` (`make student-copies FORCE=1`)
writes it anew and first copies the answers it replaces to ``<out>/backups/<date-time>/``.  The
output folder can never be the lessons' folder.

How a lesson marks its exercises (nbgrader's conventions, schema 3, as the "Create Assignment"
toolbar writes them):
- one locked cell with ``grade_id: exercises-setup`` near the top: everything the exercises need, built
  from the library alone, so that the exercise cells (spread over the sections they practise) run by
  themselves after a kernel restart;
- per exercise, a *solution* cell (``nbgrader.solution: true``) whose answer sits between
  ``### BEGIN SOLUTION`` and ``### END SOLUTION``.  Above the markers the cell sets a placeholder
  of the right type and a wrong value (``kl = torch.zeros(len(mu))``), so a student copy runs and
  its check fails on the value, not on a NameError;
- per exercise, an autograded *test* cell (``nbgrader.grade: true``, ``points``, locked) holding
  the check: it compares computed values and raises AssertionError when they differ.

The copy is made by nbgrader's preprocessors, in the order ``nbgrader generate_assignment`` runs
them: ClearSolutions (the region between the markers becomes ``# YOUR CODE HERE``: nbgrader's stub
without its ``raise NotImplementedError()``, so that the placeholder reaches the check), LockCells,
ClearOutput, ComputeChecksums (``nbgrader autograde`` can then tell whether a test cell was
edited).  ``generate_assignment`` itself wants a course folder and a gradebook database, which a
self-study course does not have.  Lessons without nbgrader cells are skipped and named.
tests/test_student_copies.py runs each exercise section with the stubs (every check must fail
with AssertionError) and with the solutions (every check must pass).
"""

from __future__ import annotations

import argparse
import copy
import shutil
import time
from pathlib import Path

import nbformat
from nbgrader.preprocessors import ClearOutput, ClearSolutions, ComputeChecksums, LockCells

CODE_STUB = {"python": "# YOUR CODE HERE"}
SETUP_ID = "exercises-setup"


def nbgrader_meta(cell) -> dict:
    """The cell's nbgrader metadata ({} for a plain cell)."""
    return cell.get("metadata", {}).get("nbgrader", {})


def is_solution(cell) -> bool:
    return bool(nbgrader_meta(cell).get("solution"))


def is_check(cell) -> bool:
    return bool(nbgrader_meta(cell).get("grade")) and cell.cell_type == "code"


def has_exercises(nb) -> bool:
    return any(is_check(c) for c in nb.cells)


def exercise_section(nb) -> list:
    """The `exercises-setup` cell, then every solution and check cell in order: what runs on its own.

    Exercises sit in the sections they practise, so other cells lie between them; a solution and its
    check need only the setup cell and the exercise cells before them (tests/test_student_copies.py
    runs exactly these cells in a fresh kernel)."""
    ids = [nbgrader_meta(c).get("grade_id") for c in nb.cells]
    if SETUP_ID not in ids:
        raise ValueError(f"no cell with nbgrader grade_id {SETUP_ID!r}")
    start = ids.index(SETUP_ID)
    early = [nbgrader_meta(c)["grade_id"] for c in nb.cells[:start] if is_solution(c) or is_check(c)]
    if early:
        raise ValueError(f"exercise cells {early} come before the {SETUP_ID!r} cell")
    return [c for c in nb.cells[start:] if c.cell_type == "code" and (is_solution(c) or is_check(c)
                                                                      or nbgrader_meta(c).get("grade_id") == SETUP_ID)]


def exercises(nb) -> list[tuple[str, str]]:
    """(solution grade_id, check grade_id) per exercise, in order: each check follows its solution cell."""
    pairs, pending = [], None
    for c in nb.cells:
        if is_solution(c) and c.cell_type == "code":
            pending = nbgrader_meta(c)["grade_id"]
        elif is_check(c):
            if pending is None:
                raise ValueError(f"check {nbgrader_meta(c)['grade_id']!r} has no solution cell before it")
            pairs.append((pending, nbgrader_meta(c)["grade_id"]))
            pending = None
    return pairs


def student_copy(nb):
    """A release notebook -> its student copy (a new notebook; the argument is left as it is)."""
    nb = copy.deepcopy(nb)
    resources: dict = {}
    for pre in (ClearSolutions(code_stub=CODE_STUB, enforce_metadata=True), LockCells(), ClearOutput(),
                ComputeChecksums()):
        nb, resources = pre.preprocess(nb, resources)
    return nb


def main(argv=None) -> list[Path]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--notebooks", type=Path, default=Path("notebooks"))
    ap.add_argument("--out", type=Path, default=Path("student"))
    ap.add_argument("--force", action="store_true", help="overwrite copies that exist (and the answers in them)")
    args = ap.parse_args(argv)
    if not args.notebooks.is_dir():
        ap.error(f"--notebooks {args.notebooks} is not a folder of lessons")
    if args.out.resolve() == args.notebooks.resolve() or (args.out.exists() and args.out.samefile(args.notebooks)):
        ap.error(f"--out {args.out} is the --notebooks folder: the copies would replace the lessons' solutions "
                 "(--force does not change this); choose another --out")
    args.out.mkdir(parents=True, exist_ok=True)
    stamp = time.strftime("%Y%m%d-%H%M%S")
    written, skipped = [], []
    for path in sorted(args.notebooks.glob("[0-9]*.ipynb")):
        nb = nbformat.read(path, as_version=4)
        if not has_exercises(nb):
            skipped.append(path.name)
            continue
        out = args.out / path.name
        if out.exists() and not args.force:
            print(f"student copy: {out} kept (it holds your answers; --force writes it anew)")
            continue
        if out.exists():  # --force: the answers it replaces are kept in a timestamped backup
            backup = args.out / "backups" / stamp / path.name
            backup.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(out, backup)
            print(f"student copy: your answers in {out} are kept in {backup}")
        nbformat.write(student_copy(nb), out)
        written.append(out)
        print(f"student copy: {out} ({len(exercises(nb))} exercises, solutions removed)")
    if skipped:
        print("no nbgrader exercises yet (not copied; work in notebooks/):", ", ".join(skipped))
    return written


if __name__ == "__main__":
    main()
