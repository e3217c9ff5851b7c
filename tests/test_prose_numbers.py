"""Every measured number a lesson's prose quotes is printed by a code cell above it.

The rule, applied to each markdown cell of a notebook:

* **Which numbers are checked (measured values).** A number with a decimal point or an exponent
  (``0.482``, ``2.1x``, ``5e-4``) or an integer of three or more digits (``317``, ``1,136``).  Integers of
  one or two digits are counts and settings (21 joints, 30 fps, 8 clips) and are not checked.  Signs are
  ignored (prose says "falls by 0.3" where a cell prints ``-0.3``).
* **Which text is not prose.** Fenced code blocks and inline code spans (they quote code and its
  arguments, not results), LaTeX math (``$...$``, ``$$...$$``: its numbers are an equation's constants),
  link targets and HTML tags, and tokens glued to letters, underscores or dots in front (``H.264``,
  ``07_01``, ``MP4``, ``v1.2``).
* **References are not values.** A number right after eq./eqs./equation, sec./section/§, figure/fig.,
  table, lesson, issue, cell, exercise, part, appendix, page/p., line, # (and a list or range of them:
  "eqs. 14-15", "sec. 4.1.3", "cells 15 and 24"); a year (1990-2029) after "et al.", a name or a
  comma, or in parentheses.
  The lesson header's **Time:** and **Prerequisites:** lines are estimates, not measurements.
* **The paper's numbers are not ours.** A number in a sentence that cites the paper ("the paper", "paper's",
  "(paper", "paper,", "reported", "reports") and a number in a table column whose header says "paper".
* **Allowlist.** `ALLOWED` below: per notebook, a few numbers with the reason each one is fine (a
  data-spec constant or a setting of `course_lib` that no cell prints).  Kept short on purpose.

A checked number matches when some code cell *above* the markdown cell printed it: in its stream
text, in a ``text/plain`` result, or in the visible text of a ``text/html`` result (a table the
notebook displays; tags, attributes and embedded data dropped).  Matching is by value, tolerant of
formatting: thousands commas and thin spaces are dropped ("1,136" = "1136"), trailing zeros do not
count ("0.50" = "0.5"), units are not part of the number ("0.482 m" = "0.482").  **Rounding is
accepted**: prose with d decimals matches a printed number with more decimals that rounds to it
(printed 0.4821 supports "0.48"; printed 0.48 does not support "0.482"); a rounding to fewer
significant figures ("38,000" for 38469) is not.  A percentage may quote a printed fraction
("127 %" for 1.27).  A number also matches when it is a literal in the source of a code cell above,
comments dropped (a setting the reader sees set: ``frame = 100``); `violations` counts the two
routes apart.

"""

from __future__ import annotations

import json
import re
from decimal import ROUND_HALF_EVEN, ROUND_HALF_UP, Decimal, InvalidOperation
from pathlib import Path

import pytest

NOTEBOOK_DIR = Path(__file__).resolve().parents[1] / "notebooks"
CHECKED = sorted(p.stem for p in (Path(__file__).resolve().parents[1] / "notebooks").glob("[0-9]*.ipynb"))

# notebook -> {number as written in the prose: why it needs no printing cell}
ALLOWED: dict[str, dict[str, str]] = {
    "00_skeletons_and_rotations": {
        "0.45": "the CMU BVH length unit (inches / 0.45): a data-spec constant of the CMU files",
        "0.056444": "course_lib.bvh.CMU_SCALE, that unit in metres: a data-spec constant"},
    "00b_synthetic_data": {
        "2.2": "random_control_program's segment lengths (0.8-2.2 s): a data-spec constant of the generator",
        "125": "the walk cadence bounds, CADENCE_BOUNDS['walk'] = (1.6, 2.08) steps/s, in steps/min (95-125)"},
    "02_vae_lstm": {
        "0.05": "lesson 01's collapse threshold (KL per dimension, nats), quoted before the cells using it: a setting",
        "480": "Exercise 1's clip length, set by the exercise's own cells below its text"},
    "03_gmm_rnn_refiner": {
        "0.002": "RefinerConfig's RMSProp learning rate of R: a setting of the recipe",
        "0.005": "RefinerConfig's RMSProp learning rate of D: a setting of the recipe",
        "2500": "Lesson03Spec.refiner_updates, the refiners' training length: a setting",
        "128": "the LSTM widths of GmmRnnConfig and RefinerConfig, in the paper-vs-here table: settings"},
    "04_map_control": {
        "128": "Lesson03Spec.rnn_width before the RNN was widened, naming the model a study ran on"},
    "05_hierarchical_vrnn": {
        "0.05": "the shipped classifiers' scale floor (course_lib.evaluation.classifiers): a setting",
        "1100": "the end step of the classifier-loss ramp (HvrnnConfig), in the paper-vs-here table: a setting"},
    "06_moglow": {
        "0.25": "E.STEP_LAG = 5 frames at 20 fps, the lag of the stepping measure: a setting"},
    "07_benchmark": {
        "400": "lesson 02's training-set size: a data-spec constant, printed in lesson 02",
        "1800": "lesson 06's training-set size: a data-spec constant, printed in lesson 06"},
}

NUMBER = re.compile(r"(?<![\w.])(\d{1,3}(?:[,\u2009\u202f]\d{3})+(?:\.\d+)?|\d*\.\d+|\d+)(?:[eE]([-+]?\d+))?(?![\d_])")
REF_WORDS = (r"eqs?\.|equations?|secs?\.|sections?|§|figures?|figs?\.|tables?|lessons?|issues?|cells?|"
             r"exercises?|parts?|appendix|pages?|pp?\.|lines?|#")
_REF_NUM = r"\(?\d+(?:\.\d+)*[a-z]?\)?"
REF = re.compile(rf"(?i)(?:\b|(?<=§)|(?<=#))(?:{REF_WORDS})\s*{_REF_NUM}(?:\s*(?:[-–,]|and|to|&)\s*{_REF_NUM})*")
# a year in a citation (1990-2029): after "et al.", a capitalised word or a comma, or alone in parentheses
_Y = r"(?:199\d|20[0-2]\d)"
YEAR = re.compile(rf"(?:et al\.|\b[A-Z][a-z]+|,)\s*{_Y}\b|\(\s*{_Y}\s*\)|{_Y}(?=\))")
HEADER = re.compile(r"(?im)^\s*\*\*(?:time|prerequisites):\*\*.*$")  # the lesson's estimates, not measurements
PAPER = re.compile(r"(?i)\bthe paper\b|\bpaper's\b|\(paper\b|\bpaper,|\breport(?:s|ed)\b")


def _strip_non_prose(md: str) -> str:
    md = re.sub(r"```.*?```", " ", md, flags=re.S)  # fenced code
    md = re.sub(r"`[^`]*`", " ", md)  # inline code
    md = re.sub(r"\$\$.*?\$\$", " ", md, flags=re.S)  # display math
    md = re.sub(r"\\\[.*?\\\]", " ", md, flags=re.S)
    md = re.sub(r"(?<!\\)\$[^$]*?(?<!\\)\$", " ", md)  # inline math
    md = re.sub(r"\]\([^)]*\)", "]", md)  # link targets
    md = re.sub(r"<[^>]+>", " ", md)  # HTML tags
    md = HEADER.sub(" ", md)
    md = REF.sub(" ", md)
    md = YEAR.sub(" ", md)
    return md


def _paper_columns(md: str) -> str:
    """Blank the cells of markdown-table columns whose header says 'paper'."""
    lines, out, paper_cols = md.split("\n"), [], set()
    for i, line in enumerate(lines):
        if line.lstrip().startswith("|"):
            cells = line.split("|")
            nxt = lines[i + 1] if i + 1 < len(lines) else ""
            if re.match(r"^\s*\|[\s:|-]+\|?\s*$", nxt):  # a header row
                paper_cols = {k for k, c in enumerate(cells) if re.search(r"(?i)paper", c)}
            elif paper_cols:
                cells = [" " if k in paper_cols else c for k, c in enumerate(cells)]
            out.append("|".join(cells))
        else:
            paper_cols = set()
            out.append(line)
    return "\n".join(out)


def _sentences(md: str) -> list[str]:
    return re.split(r"(?<=[.;!?])\s+(?=[A-Z(*])|\n\s*\n|\n\s*[-*|]", md)


def _value(text: str, exp: str | None = None) -> Decimal | None:
    try:
        d = Decimal(re.sub(r"[,\u2009\u202f]", "", text))
    except InvalidOperation:
        return None
    return d.scaleb(int(exp)) if exp else d


def is_measured(token: str, exp: str | None) -> bool:
    digits = re.sub(r"[,\u2009\u202f]", "", token)
    return "." in digits or exp is not None or len(digits.lstrip("0") or "0") >= 3


def prose_numbers(md: str) -> list[tuple[str, str]]:
    """-> [(number as written, its sentence)] for the measured numbers of a markdown cell's prose."""
    found = []
    for sentence in _sentences(_paper_columns(md)):
        if PAPER.search(sentence):
            continue
        prose = _strip_non_prose(sentence)
        for m in NUMBER.finditer(prose):
            if is_measured(m.group(1), m.group(2)):
                percent = "%" if re.match(r"\s*%", prose[m.end():]) else ""
                found.append((m.group(0) + percent, " ".join(sentence.split())[:160]))
    return found


def printed_numbers(text: str) -> set[Decimal]:
    """Every number in a cell's text (absolute values), formatting dropped."""
    values = set()
    for m in re.finditer(r"(\d{1,3}(?:,\d{3})+(?:\.\d+)?|\d*\.\d+|\d+)(?:[eE]([-+]?\d+))?", text):
        v = _value(m.group(1), m.group(2))
        if v is not None:
            values.add(abs(v))
    return values


def matches(written: str, printed: set[Decimal]) -> bool:
    """Is the prose number `written` printed: equal by value, or (no exponent) a rounding of a printed number with
    more decimals?  A percentage ("127%") may also be 100 x a printed fraction (1.27)."""
    if written.endswith("%"):
        written, printed = written[:-1], printed | {100 * p for p in printed}
    m = NUMBER.fullmatch(written)
    v = abs(_value(m.group(1), m.group(2)))
    if v in printed:
        return True
    if m.group(2) is not None:
        return False
    decimals = -min(_value(m.group(1)).as_tuple().exponent, 0)
    quantum = Decimal(1).scaleb(-decimals)
    return any(p.quantize(quantum, rounding=r) == v for p in printed if p.as_tuple().exponent < -decimals
               for r in (ROUND_HALF_UP, ROUND_HALF_EVEN))


def _html_text(html: str) -> str:
    """The visible text of an HTML output: tags (with their attributes: data: URIs, styles) and scripts dropped."""
    html = re.sub(r"(?is)<(script|style)\b.*?</\1>", " ", html)
    return re.sub(r"<[^>]*>", " ", html).replace("&nbsp;", " ").replace("&plusmn;", "±")


def _cell_texts(cell: dict) -> str:
    """What a code cell printed or displayed as text: stream text, text/plain, and the visible text of text/html."""
    texts = []
    for out in cell.get("outputs", []):
        data = out.get("data", {})
        texts += ["".join(out.get("text", "")), "".join(data.get("text/plain", "")),
                  _html_text("".join(data.get("text/html", "")))]
    return "\n".join(texts)


def violations(nb: dict, allowed: dict[str, str] | None = None) -> tuple[dict[str, int], list[tuple[int, str, str]]]:
    """-> (counts: checked / printed / set in code / allowed, [(cell index, number, context)] of the unmatched)."""
    allowed = allowed or {}
    printed: set[Decimal] = set()
    in_code: set[Decimal] = set()
    counts, bad = dict.fromkeys(("checked", "printed", "set in code", "allowed"), 0), []
    for i, cell in enumerate(nb["cells"]):
        source = "".join(cell["source"])
        if cell["cell_type"] == "code":
            printed |= printed_numbers(_cell_texts(cell))
            in_code |= printed_numbers(re.sub(r"#.*", "", source))  # literals set in the code, not its comments
        elif cell["cell_type"] == "markdown":
            for written, context in prose_numbers(source):
                counts["checked"] += 1
                if matches(written, printed):
                    counts["printed"] += 1
                elif matches(written, in_code):
                    counts["set in code"] += 1
                elif written.rstrip("%") in allowed:
                    counts["allowed"] += 1
                else:
                    bad.append((i, written, context))
    return counts, bad


def _load(stem: str) -> dict:
    return json.loads((NOTEBOOK_DIR / f"{stem}.ipynb").read_text(encoding="utf-8"))


@pytest.mark.parametrize("stem", CHECKED)
def test_prose_numbers_are_printed_above(stem):
    counts, bad = violations(_load(stem), ALLOWED.get(stem))
    assert counts["checked"] > 0
    assert not bad, f"{stem}: {len(bad)} of {counts['checked']} numbers not printed above:\n" + "\n".join(
        f"  cell {i}: {n!r} in: {c}" for i, n, c in bad)


def test_every_lesson_is_checked():
    lessons = sorted(p.stem for p in NOTEBOOK_DIR.glob("[0-9]*.ipynb"))
    assert sorted(CHECKED) == lessons, f"lessons not in CHECKED: {sorted(set(lessons) - set(CHECKED))}"


# ---- known answers: the extractor and the matcher on a made-up notebook ---------------------------------------------

def _md(text):
    return {"cell_type": "markdown", "source": text}


def _code(source, printed):
    return {"cell_type": "code", "source": source, "outputs": [{"output_type": "stream", "name": "stdout",
                                                                "text": printed}]}


SYNTHETIC = {"cells": [
    _md("Before any cell: the walk is 1.36 m/s."),  # nothing printed yet -> a violation
    _code("speed = walk.speed()\nframe = 100  # 250 in class mode",
          "speed 1.3612 m/s over 1136 frames, skate -0.0500\n"),
    _md("Printed: 1.36 m/s, 1.4 (rounded), 1,136 frames, skate 0.05 (sign and trailing zeros), 0.050 too; frame 100 "
        "(set in code). Not printed: 1.362 (more decimals than any print), 250 (only in a comment), 1,100 (the "
        "frame count rounded to fewer figures)."),
    _md("References, no values: eq. (13), eqs. 14-15, sec. 4.1.3, Table 2, lesson 03, cells 15 and 24, "
        "Habibie et al. 2017, (Graves 2013), H.264, CMU 07_01; 21 joints, 60 fps (two digits)."),
    _md("Code and math: `size=(352, 640)`, $\\sigma = 0.482$, $$x = 3.14159$$. The paper reports an FID of 10.45."),
    {"cell_type": "code", "source": "display(table)", "outputs": [{"output_type": "display_data", "data": {
        "text/plain": "<HTML>", "text/html": "<table><tr><td style='width: 120px'>0.862</td></tr></table>"}}]},
    _md("| | paper | here |\n|---|---|---|\n| skate | 0.731 | 0.862, 86.2 % |\n| FID | 92.31 | 120 |"),
    _md("**Time:** about 1.5 hours.\n\nLater prints do not count: 7.25."),
    _code("print(7.25)", "7.25\n"),
]}


def test_extractor_finds_measured_numbers_and_skips_references_code_math_and_the_paper():
    found = [n for cell in SYNTHETIC["cells"] if cell["cell_type"] == "markdown"
             for n, _ in prose_numbers(cell["source"])]
    assert found == ["1.36", "1.36", "1.4", "1,136", "0.05", "0.050", "100", "1.362", "250", "1,100",
                     "0.862", "86.2%", "120", "7.25"]


def test_matcher_on_a_synthetic_notebook():
    counts, bad = violations(SYNTHETIC)
    assert [(i, n) for i, n, _ in bad] == [(0, "1.36"), (2, "1.362"), (2, "250"), (2, "1,100"), (6, "120"),
                                           (7, "7.25")]
    assert counts == {"checked": 14, "printed": 7, "set in code": 1, "allowed": 0}
    counts, bad = violations(SYNTHETIC, {"120": "a made-up setting", "250": "a made-up setting"})
    assert counts["allowed"] == 2 and [n for _, n, _ in bad] == ["1.36", "1.362", "1,100", "7.25"]


def test_matcher_rounding_and_formatting():
    printed = printed_numbers("0.4821 m, 1136 s, 0.50, -3e-4, 1.27")
    assert matches("0.482", printed) and matches("0.48", printed) and matches("1,136", printed)
    assert matches("0.5", printed) and matches("3e-4", printed) and matches("127%", printed)
    assert not matches("0.4822", printed) and not matches("1,100", printed) and not matches("0.51", printed)
    assert not matches("0.48", printed_numbers("0.4")) and not matches("127", printed)
