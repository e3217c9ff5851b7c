"""A lesson is a class session a student can finish (DESIGN.md "Notebooks", STYLE.md).

Checked on every lesson notebook, each rule with a planted example that it must catch:

* no project vocabulary in prose or printed output (`JARGON`);
* prose under 25,000 characters, no markdown cell over 1,500, no sentence over `MAX_SENTENCE_WORDS` words;
* a header naming earlier lessons as prerequisites (the dependency graph the README and the site draw)
  and a time within a factor 1.5 of `tools/lesson_time.py`'s estimate (prose, code, exercises and the
  recorded class-mode run time in results/lesson_times.json);
* at least four exercises, inside the sections they practise (no "Exercises" section), one of them a
  derivation, a prediction or a design choice, each followed by its solution and its check;
* one claims table (`| claim | paper | ours | holds | study |`) in each paper lesson, failing claims
  linking a study note that exists;
* no code cell that reads a study's stored result (lessons read `results/` through course_lib.results).
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tools"))
import lesson_graph as LG  # noqa: E402
import lesson_time as LT  # noqa: E402

NOTEBOOKS = sorted((REPO / "notebooks").glob("[0-9]*.ipynb"))
PAPER_LESSONS = ("02_", "03_", "04_", "05_", "06_")
MAX_PROSE = 25_000
MAX_CELL = 1_500
MAX_SENTENCE_WORDS = 45  # "about 40"
MIN_EXERCISES = 4
CLAIMS_HEADER = re.compile(r"^\|\s*claim\s*\|\s*paper\s*\|\s*ours\s*\|\s*holds\s*\|\s*study\s*\|", re.I | re.M)

# words of the team's work, not of the subject: a student cannot know them
JARGON = {
    "issue": r"\bissues?\b",
    "must-show": r"\bmust[- ]show\b",
    "shipped": r"\bshipped\b",
    "lent": r"\blent\b",
    "H100": r"\bH[12]00\b",
    "git checkout": r"\bgit checkout\b",
    "the lead": r"\bthe lead\b",
    "widths-128": r"\bwidths-128\b",
    "former preset": r"\bformer preset\b",
    "AVX": r"\bAVX",
    "not rerun": r"\bnot rerun\b",
}


def load(path: Path) -> dict:
    return json.loads(path.read_text(encoding="utf-8"))


def src(cell: dict) -> str:
    s = cell.get("source", "")
    return "".join(s) if isinstance(s, list) else s


def output_text(cell: dict) -> str:
    parts = []
    for o in cell.get("outputs", []):
        if o.get("output_type") == "stream":
            parts.append("".join(o.get("text", "")))
        for mime in ("text/plain", "text/markdown", "text/html"):
            value = o.get("data", {}).get(mime)
            if value:
                parts.append("".join(value) if isinstance(value, list) else value)
    return "\n".join(parts)


def jargon_found(nb: dict) -> list[str]:
    found = []
    for i, c in enumerate(nb["cells"]):
        text = src(c) if c["cell_type"] == "markdown" else output_text(c)
        text = re.sub(r"https?://\S+", "", text)
        text = re.sub(r"[A-Za-z0-9+/=]{80,}", "", text)  # embedded images and videos (base64) are not words
        for word, pattern in JARGON.items():
            if re.search(pattern, text, re.I if word != "H100" else 0):
                found.append(f"cell {i}: {word!r}")
    return found


def prose(text: str) -> str:
    """A markdown cell's sentences: code, math, tables, headings, links' targets and HTML dropped."""
    text = re.sub(r"```.*?```", " ", text, flags=re.S)
    text = re.sub(r"\$\$.*?\$\$", " MATH ", text, flags=re.S)
    text = re.sub(r"\$[^$]*\$", " MATH ", text)
    text = re.sub(r"`[^`]*`", " CODE ", text)
    text = re.sub(r"\]\([^)]*\)", "]", text)
    text = re.sub(r"<[^>]+>", " ", text)
    lines = [ln for ln in text.splitlines() if not ln.lstrip().startswith(("|", "#"))]
    return "\n".join(lines)


def long_sentences(text: str) -> list[str]:
    out = []
    for block in re.split(r"\n\s*\n|\n\s*[*\-]\s+|\n\s*\d+\.\s+", prose(text)):
        for sentence in re.split(r"(?<=[.?!:;])\s+(?=[A-Z(*])|(?<=[.?!:;]\*\*)\s+", " ".join(block.split())):
            words = [w for w in sentence.split() if re.search(r"\w", w)]
            if len(words) > MAX_SENTENCE_WORDS:
                out.append(f"{len(words)} words: {sentence[:80]}...")
    return out


def heading_of(nb: dict, index: int) -> str:
    """The `## ` section heading a cell sits under ('' before the first one)."""
    for c in reversed(nb["cells"][:index + 1]):
        if c["cell_type"] == "markdown":
            for line in reversed(src(c).splitlines()):
                if line.startswith("## "):
                    return line
    return ""


def exercise_problems(nb: dict) -> list[str]:
    problems, cells = [], nb["cells"]
    stated = LT.exercise_cells(nb)
    graded = [i for i in stated if "(open" not in src(cells[i]).splitlines()[0]]
    if len(graded) < MIN_EXERCISES:
        problems.append(f"{len(graded)} graded exercises (at least {MIN_EXERCISES})")
    for i in stated:
        if re.search(r"\bexercises\b", heading_of(nb, i), re.I):
            problems.append(f"cell {i}: an exercise under {heading_of(nb, i)!r}: put it in the section it practises")
    for i in graded:
        meta = [c.get("metadata", {}).get("nbgrader", {}) for c in cells[i + 1:i + 3]]
        if len(meta) < 2 or not meta[0].get("solution") or not meta[1].get("grade"):
            problems.append(f"cell {i}: an exercise not followed by its solution cell and its check cell")
    if not any(LT.exercise_kind(src(cells[i])) for i in graded):
        problems.append("no exercise is marked (derivation), (prediction) or (design)")
    return problems


def prerequisites(nb: dict) -> list[str] | None:
    """Lesson numbers the header's **Prerequisites:** line names (None when the line is missing)."""
    return LG.prerequisites_of(src(nb["cells"][0])) if nb["cells"] else None


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_no_project_vocabulary(path):
    found = jargon_found(load(path))
    assert not found, f"{path.name}: words a student cannot know: {found}"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_prose_is_a_class_session_long(path):
    nb = load(path)
    md = [src(c) for c in nb["cells"] if c["cell_type"] == "markdown"]
    total = sum(map(len, md))
    assert total < MAX_PROSE, f"{path.name}: {total} characters of prose (under {MAX_PROSE})"
    big = [f"cell {i}: {len(src(c))}" for i, c in enumerate(nb["cells"])
           if c["cell_type"] == "markdown" and len(src(c)) > MAX_CELL]
    assert not big, f"{path.name}: markdown cells over {MAX_CELL} characters: {big}"
    long = [s for text in md for s in long_sentences(text)]
    assert not long, f"{path.name}: sentences over {MAX_SENTENCE_WORDS} words: {long}"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_exercises_sit_in_their_sections(path):
    problems = exercise_problems(load(path))
    assert not problems, f"{path.name}: {problems}"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_header_names_earlier_lessons_and_a_measured_time(path):
    nb = load(path)
    prereq = prerequisites(nb)
    assert prereq is not None, f"{path.name}: no **Prerequisites:** line in the header"
    ids = [LG.lesson_id(p) for p in NOTEBOOKS]
    for ref in prereq:
        assert ref in ids, f"{path.name}: prerequisite {ref} is not a lesson"
        assert ids.index(ref) < ids.index(LG.lesson_id(path)), f"{path.name}: prerequisite {ref} comes later"
    head = LT.header_minutes(nb)
    assert head is not None, f"{path.name}: no '**Time:** about N hours|minutes' line in the header"
    run = LT.recorded_seconds(path.stem)
    assert run is not None, f"{path.name}: no class-mode run time in results/lesson_times.json (make course)"
    est = LT.estimate(nb, run)["estimate_min"]
    assert 1 / LT.TOLERANCE <= head / est <= LT.TOLERANCE, \
        f"{path.name}: header says {head:.0f} min, the estimate is {est:.0f} min (python tools/lesson_time.py)"
    assert est <= LT.MAX_MINUTES, f"{path.name}: {est:.0f} min estimated: split the lesson"


@pytest.mark.parametrize("path", [p for p in NOTEBOOKS if p.name.startswith(PAPER_LESSONS)], ids=lambda p: p.stem)
def test_one_claims_table_linking_its_studies(path):
    nb = load(path)
    tables = [(i, src(c)) for i, c in enumerate(nb["cells"])
              if c["cell_type"] == "markdown" and CLAIMS_HEADER.search(src(c))]
    assert len(tables) == 1, f"{path.name}: {len(tables)} claims tables (| claim | paper | ours | holds | study |)"
    for target in re.findall(r"\]\((\.\./studies/[^)#]+)", tables[0][1]):
        assert (path.parent / target).resolve().exists(), f"{path.name}: the claims table links a missing {target}"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_no_cell_prints_a_stored_study(path):
    reads = [i for i, c in enumerate(load(path)["cells"]) if c["cell_type"] == "code"
             and re.search(r"study_result\(|studies/", src(c))]
    assert not reads, f"{path.name}: code cells {reads} read a study's stored result"


# ---- each rule catches a planted fault ------------------------------------------------------------
def _nb(*cells) -> dict:
    return {"cells": list(cells)}


def _md(text: str) -> dict:
    return {"cell_type": "markdown", "source": text}


def _code(text: str, out: str = "", **nbgrader) -> dict:
    meta = {"nbgrader": nbgrader} if nbgrader else {}
    return {"cell_type": "code", "source": text, "metadata": meta,
            "outputs": [{"output_type": "stream", "name": "stdout", "text": out}] if out else []}


def test_the_jargon_scan_sees_planted_words():
    assert jargon_found(_nb(_md("The shipped checkpoint."), _code("x", out="trained on an H100"))) == \
        ["cell 0: 'shipped'", "cell 1: 'H100'"]
    assert jargon_found(_nb(_md("See the issue for this."))) == ["cell 0: 'issue'"]
    assert jargon_found(_nb(_md("A pretrained checkpoint; a silent failure."), _code("shipped = 1"))) == []


def test_the_sentence_scan_sees_a_long_sentence_and_ignores_tables_and_math():
    long = " ".join(["word"] * 50) + "."
    assert len(long_sentences(long)) == 1
    assert long_sentences("| " + " | ".join(["cell"] * 60) + " |") == []
    assert long_sentences("Short. " + "$" + " + ".join(["x"] * 60) + "$ is it.") == []
    assert long_sentences("* " + " ".join(["a"] * 30) + "\n* " + " ".join(["b"] * 30)) == []


def test_the_exercise_rules_catch_a_final_exercise_section():
    def ex(n, kind=""):
        return [_md(f"**Exercise {n}{kind}.** Do it."), _code("x = 0", solution=True),
                _code("check(x)", grade=True)]
    good = _nb(_md("## 1. A section"), *ex(1, " (prediction)"), *ex(2), *ex(3), _md("## 2. More"), *ex(4))
    assert exercise_problems(good) == []
    bad = _nb(_md("## 9. Exercises"), *ex(1), *ex(2), *ex(3), *ex(4))
    problems = exercise_problems(bad)
    assert sum("put it in the section" in p for p in problems) == 4
    assert "no exercise is marked (derivation), (prediction) or (design)" in problems
    assert exercise_problems(_nb(_md("## 1. S"), *ex(1, " (design)")))[0].startswith("1 graded exercises")


def test_header_parsing_on_known_headers():
    nb = _nb(_md("# L\n**Prerequisites:** lessons 00b and 01.  \n**Time:** about 2.5 hours."))
    assert prerequisites(nb) == ["00b", "01"] and LT.header_minutes(nb) == 150
    assert LT.header_minutes(_nb(_md("**Time:** about 45 minutes"))) == 45
    assert prerequisites(_nb(_md("# no header"))) is None


def test_readme_lists_each_lessons_prerequisites_and_time_as_the_headers_say():
    # README's lesson table: | # | lesson | needs | paper | run time | status |, one row per lesson
    rows = {}
    for line in (REPO / "README.md").read_text(encoding="utf-8").splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 5 and re.fullmatch(r"\d\d[a-z]?", cells[0]):
            rows[cells[0]] = cells
    for path in NOTEBOOKS:
        lesson = LG.lesson_id(path)
        assert lesson in rows, f"README.md has no row for lesson {lesson}"
        needs = LG.LESSON_REF.findall(rows[lesson][2])
        assert needs == prerequisites(load(path)), \
            f"README.md says lesson {lesson} needs {needs}; its header says {prerequisites(load(path))}"
        run = LT.recorded_seconds(path.stem)
        assert run is not None and rows[lesson][4] == f"{run:.0f} s", \
            f"README.md's run time for {lesson} is {rows[lesson][4]!r}; results/lesson_times.json says {run}"
