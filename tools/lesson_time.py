"""How long a lesson takes a student, estimated from what it asks of them.

    python tools/lesson_time.py                      # every lesson: estimate vs the header's **Time:**
    python tools/lesson_time.py notebooks/03_*.ipynb --run-seconds 240
    python tools/lesson_time.py --record notebooks/03_gmm_rnn_refiner.ipynb 240 --mode class

The estimate: prose words at 150 a minute, code lines at 10 a minute, 10 minutes an exercise, plus the
lesson's run time in `class` mode (recorded by `make course` in results/lesson_times.json, or given with
--run-seconds).  A header within a factor of 1.5 of the estimate passes (tests/test_lesson_rules.py).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TIMES = REPO / "results" / "lesson_times.json"
WORDS_PER_MINUTE = 150
CODE_LINES_PER_MINUTE = 10
MINUTES_PER_EXERCISE = 10
TOLERANCE = 1.5
MAX_MINUTES = 150  # a lesson that needs more is split

# `**Exercise 3.**`, `**Exercise 3 — a title.**`, `**Exercise 3 (prediction).**`, `**Exercise 3 (design) — a title.**`
EXERCISE = re.compile(r"^\*\*Exercise (\d+[a-z]?)\b([^*\n]*)\*\*", re.M)
KINDS = ("derivation", "prediction", "design")
HEADER_TIME = re.compile(r"\*\*Time:\*\*\s*about\s+([0-9]+(?:\.[0-9]+)?)\s*(hours?|h\b|minutes?|min\b)", re.I)


def _source(cell: dict) -> str:
    s = cell.get("source", "")
    return "".join(s) if isinstance(s, list) else s


def load(path: str | Path) -> dict:
    return json.loads(Path(path).read_text(encoding="utf-8"))


def prose_words(nb: dict) -> int:
    return sum(len(_source(c).split()) for c in nb["cells"] if c["cell_type"] == "markdown")


def code_lines(nb: dict) -> int:
    """Non-blank, non-comment lines of code cells: what a student reads and runs."""
    return sum(1 for c in nb["cells"] if c["cell_type"] == "code"
               for line in _source(c).splitlines() if line.strip() and not line.strip().startswith("#"))


def exercise_cells(nb: dict) -> list[int]:
    """Indices of the markdown cells that state an exercise (`**Exercise N.**` at a line's start)."""
    return [i for i, c in enumerate(nb["cells"]) if c["cell_type"] == "markdown" and EXERCISE.search(_source(c))]


def exercise_kind(text: str) -> str | None:
    """'derivation', 'prediction' or 'design' when the exercise's heading says so, else None."""
    m = EXERCISE.search(text)
    kind = re.search(rf"\(({'|'.join(KINDS)})\b", m.group(2)) if m else None
    return kind.group(1) if kind else None


def header_minutes(nb: dict) -> float | None:
    """The first cell's `**Time:** about N hours|minutes`, in minutes (None when missing)."""
    m = HEADER_TIME.search(_source(nb["cells"][0])) if nb["cells"] else None
    if m is None:
        return None
    value, unit = float(m.group(1)), m.group(2).lower()
    return value * 60 if unit.startswith("h") else value


def recorded_seconds(name: str, mode: str = "class") -> float | None:
    if not TIMES.exists():
        return None
    return json.loads(TIMES.read_text()).get(mode, {}).get(name)


def estimate(nb: dict, run_seconds: float | None) -> dict:
    words, lines, n_ex = prose_words(nb), code_lines(nb), len(exercise_cells(nb))
    parts = {"reading": words / WORDS_PER_MINUTE, "code": lines / CODE_LINES_PER_MINUTE,
             "exercises": n_ex * MINUTES_PER_EXERCISE, "run": (run_seconds or 0.0) / 60}
    return {"words": words, "code_lines": lines, "exercises": n_ex, "run_seconds": run_seconds,
            "parts_min": {k: round(v, 1) for k, v in parts.items()}, "estimate_min": round(sum(parts.values()), 1)}


def record(notebook: str | Path, seconds: float, mode: str) -> None:
    """Keep one lesson's measured run time (make course calls this after each notebook)."""
    times = json.loads(TIMES.read_text()) if TIMES.exists() else {}
    times.setdefault(mode, {})[Path(notebook).stem] = round(float(seconds))
    times[mode] = dict(sorted(times[mode].items()))
    TIMES.parent.mkdir(exist_ok=True)
    TIMES.write_text(json.dumps(times, indent=1) + "\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("notebooks", nargs="*", help="lesson notebooks (default: every one in notebooks/)")
    ap.add_argument("--run-seconds", type=float, help="class-mode run time to use (default: the recorded one)")
    ap.add_argument("--record", nargs=2, metavar=("NOTEBOOK", "SECONDS"), help="record a measured run time")
    ap.add_argument("--mode", default="class", help="COURSE_MODE of a recorded time (default class)")
    args = ap.parse_args(argv)
    if args.record:
        record(args.record[0], float(args.record[1]), args.mode)
        return 0
    paths = [Path(p) for p in args.notebooks] or sorted((REPO / "notebooks").glob("[0-9]*.ipynb"))
    print(f"{'lesson':28s} {'words':>6s} {'code':>5s} {'ex':>3s} {'run s':>6s} {'estimate':>9s} {'header':>7s} ratio")
    bad = 0
    for p in paths:
        nb = load(p)
        run = args.run_seconds if args.run_seconds is not None else recorded_seconds(p.stem)
        e, head = estimate(nb, run), header_minutes(nb)
        ratio = head / e["estimate_min"] if head and e["estimate_min"] else float("nan")
        ok = head is not None and 1 / TOLERANCE <= ratio <= TOLERANCE
        bad += not ok
        print(f"{p.stem:28s} {e['words']:6d} {e['code_lines']:5d} {e['exercises']:3d} "
              f"{'-' if run is None else f'{run:.0f}':>6s} {e['estimate_min']:7.0f} m "
              f"{'-' if head is None else f'{head:.0f}':>5s} m {ratio:5.2f}{'' if ok else '  <- header off'}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
