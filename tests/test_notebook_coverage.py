"""Coverage (Pyro's test_coverage): every notebook is committed executed, small, runs in a COURSE_MODE
and is picked up by the Makefile; every data script answers --help and is run by `make data`."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MAX_NOTEBOOK_BYTES = 5 * 1024 * 1024
NOTEBOOK_NAME = re.compile(r"^\d\d[a-z]?_[a-z0-9_]+\.ipynb$")  # 00_, 00b_, 01_: run in name order
MODE_WORDS = ("COURSE_MODE", "course_mode", "by_mode")


def code_source(cell: dict) -> str:
    source = cell.get("source", "")
    return "".join(source) if isinstance(source, list) else source


def notebook_problems(path: Path) -> list[str]:
    """Why `path` is not a committed, executed, small, mode-aware lesson notebook (empty list: it is)."""
    problems = []
    if not NOTEBOOK_NAME.match(path.name):
        problems.append(f"name {path.name!r} is not NN_lower_case.ipynb (or NNb_...)")
    size = path.stat().st_size
    if size >= MAX_NOTEBOOK_BYTES:
        problems.append(f"{size / 2**20:.1f} MB, the limit is {MAX_NOTEBOOK_BYTES / 2**20:.0f} MB")
    nb = json.loads(path.read_text(encoding="utf-8"))
    if nb.get("metadata", {}).get("kernelspec", {}).get("name") != "python3":
        problems.append("kernelspec name is not 'python3' (the kernel nbconvert and nbval start)")
    code = [c for c in nb.get("cells", []) if c.get("cell_type") == "code" and code_source(c).strip()]
    counts = [c.get("execution_count") for c in code]
    if counts != list(range(1, len(code) + 1)):
        problems.append(f"not executed top to bottom in a fresh kernel: execution counts {counts}")
    outputs = [out for c in code for out in c.get("outputs", [])]
    if not outputs:
        problems.append("committed without outputs")
    errors = [out.get("ename", "?") for out in outputs if out.get("output_type") == "error"]
    if errors:
        problems.append(f"committed with error outputs: {errors}")
    if not any(word in code_source(c) for c in code for word in MODE_WORDS):
        problems.append("never reads COURSE_MODE (course_lib.modes.course_mode / by_mode)")
    return problems


def lesson_notebooks() -> list[Path]:
    return sorted((REPO / "notebooks").glob("*.ipynb"))


def data_scripts() -> list[Path]:
    return sorted((REPO / "data_scripts").glob("*.py"))


def fake_notebook(path: Path, cells: list[dict], kernel: str = "python3") -> Path:
    meta = {"kernelspec": {"name": kernel, "display_name": "Python 3", "language": "python"}}
    path.write_text(json.dumps({"cells": cells, "metadata": meta, "nbformat": 4, "nbformat_minor": 5}))
    return path


def code_cell(source: str, count: int | None, outputs: list[dict] | None = None) -> dict:
    return {"cell_type": "code", "source": source, "execution_count": count, "metadata": {}, "outputs": outputs or []}


STREAM = {"output_type": "stream", "name": "stdout", "text": "0.12\n"}


def test_checker_accepts_a_good_notebook_and_names_each_fault(tmp_path):
    good = [code_cell("from course_lib.modes import by_mode\nn = by_mode(ci=1, class_=2, full=3)", 1),
            code_cell("", None), code_cell("print(n)", 2, [STREAM])]
    assert notebook_problems(fake_notebook(tmp_path / "03_gmm_rnn.ipynb", good)) == []
    bad = [code_cell("import os", 2), code_cell("print(1)", 1, [{"output_type": "error", "ename": "NameError"}])]
    found = notebook_problems(fake_notebook(tmp_path / "Lesson.ipynb", bad, kernel="venv"))
    assert len(found) == 5, found
    for words in ["is not NN_lower_case", "kernelspec", "execution counts [2, 1]", "['NameError']", "COURSE_MODE"]:
        assert any(words in problem for problem in found), (words, found)
    unexecuted = fake_notebook(tmp_path / "04_x.ipynb", [code_cell("course_mode()", None)])
    assert notebook_problems(unexecuted) == ["not executed top to bottom in a fresh kernel: execution counts [None]",
                                             "committed without outputs"]
    big = fake_notebook(tmp_path / "05_big.ipynb", [code_cell("by_mode", 1, [{**STREAM, "text": "x" * 6_000_000}])])
    assert notebook_problems(big) == ["5.7 MB, the limit is 5 MB"]


def test_every_notebook_is_an_executed_small_mode_aware_lesson():
    problems = {nb.name: notebook_problems(nb) for nb in lesson_notebooks()}
    assert {name: p for name, p in problems.items() if p} == {}


def test_every_notebook_is_in_the_readme_lesson_list():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    missing = [nb.name for nb in lesson_notebooks() if f"| {nb.name.split('_')[0]} |" not in readme]
    assert missing == [], "give these lessons a row `| NN | ...` in README.md's lesson table"


# One interpreter runs every script's --help (each would otherwise spend seconds importing torch):
# {script: [exit status, stdout, stderr]} as JSON.
HELP_PROBE = r"""
import contextlib, io, json, runpy, sys
results = {}
for script in sys.argv[1:]:
    out, err, status = io.StringIO(), io.StringIO(), None
    sys.argv = [script, "--help"]
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            runpy.run_path(script, run_name="__main__")
        except SystemExit as stop:
            status = stop.code or 0
        except Exception as exc:  # reported, not raised: the test names the script
            status, _ = 1, err.write(repr(exc))
    results[script] = [status, out.getvalue(), err.getvalue()]
print(json.dumps(results))
"""


def test_every_data_script_answers_help_and_is_run_by_make_data():
    makefile = (REPO / "Makefile").read_text(encoding="utf-8")
    scripts = [str(path) for path in data_scripts()]
    for script in scripts:
        assert f"data_scripts/{Path(script).name}" in makefile, f"{script} is not run by the Makefile"
    proc = subprocess.run([sys.executable, "-c", HELP_PROBE, *scripts], capture_output=True, text=True, timeout=180,
                          cwd=REPO, env=dict(os.environ, OMP_NUM_THREADS="1"))
    assert proc.returncode == 0, proc.stderr[-2000:]
    for script, (status, out, err) in json.loads(proc.stdout.splitlines()[-1]).items():
        assert status == 0, f"{script} --help exited with {status}:\n{err[-2000:]}"
        assert out.startswith("usage:") and "--out" in out, f"{script} --help printed:\n{out}"
