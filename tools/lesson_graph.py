"""The lessons' dependency graph, read from each lesson header's **Prerequisites:** line.

    python tools/lesson_graph.py                 # print the edges and draw tools/site/_static/lesson_graph.png
    python tools/lesson_graph.py --out FILE.png  # draw it elsewhere (the site build draws its own copy)

The README shows the picture and lists each lesson's prerequisites in its lesson table;
tests/test_lesson_rules.py checks both against the headers.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PICTURE = REPO / "tools" / "site" / "_static" / "lesson_graph.png"
PREREQ = re.compile(r"\*\*Prerequisites:\*\*([^\n]*)")
LESSON_REF = re.compile(r"\b(\d\d[a-z]?)\b")


def _first_cell(path: Path) -> str:
    cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
    s = cells[0].get("source", "") if cells else ""
    return "".join(s) if isinstance(s, list) else s


def lesson_id(path: Path) -> str:
    return path.name.split("_")[0]


def prerequisites_of(header: str) -> list[str] | None:
    """Lesson numbers a header's **Prerequisites:** line names (None when the line is missing)."""
    m = PREREQ.search(header)
    return None if m is None else LESSON_REF.findall(m.group(1))


def title_of(header: str) -> str:
    line = next((ln for ln in header.splitlines() if ln.startswith("# ")), "")
    return re.split(r"\s+[—-]\s+", line[2:], maxsplit=1)[-1].split(" (")[0].strip()


def graph(notebooks: list[Path] | None = None) -> dict[str, dict]:
    """{lesson id: {"title", "needs": [ids]}} in the lessons' order."""
    paths = notebooks or sorted((REPO / "notebooks").glob("[0-9]*.ipynb"))
    out = {}
    for p in paths:
        head = _first_cell(p)
        out[lesson_id(p)] = {"title": title_of(head), "needs": prerequisites_of(head) or []}
    return out


def direct(g: dict[str, dict]) -> dict[str, list[str]]:
    """The needs without those implied by another need (the transitive reduction): what the picture draws."""
    def ancestors(k, seen=None):
        seen = set() if seen is None else seen
        for n in g.get(k, {}).get("needs", []):
            if n not in seen:
                seen.add(n)
                ancestors(n, seen)
        return seen
    return {k: [n for n in v["needs"] if not any(n in ancestors(m) for m in v["needs"] if m != n)]
            for k, v in g.items()}


def draw(g: dict[str, dict], out: Path) -> Path:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    edges = direct(g)
    depth: dict[str, int] = {}
    for k in g:  # lessons come in order, so every need has its depth already
        depth[k] = 1 + max((depth[n] for n in edges[k] if n in depth), default=-1)
    rows: dict[int, list[str]] = {}
    for k, d in depth.items():
        rows.setdefault(d, []).append(k)
    pos = {k: (d, -(i - (len(ks) - 1) / 2)) for d, ks in rows.items() for i, k in enumerate(ks)}
    fig, ax = plt.subplots(figsize=(2.2 * (max(rows) + 1), 1.5 * max(map(len, rows.values())) + 0.8), dpi=110)
    boxes = {}
    for k, (x, y) in pos.items():
        words, lines = g[k]["title"].split(":")[0].split(), [""]
        for w in words:  # wrap the title at about 18 characters
            lines[-1:] = [lines[-1] + " " + w] if len(lines[-1] + w) < 19 else [lines[-1], w]
        boxes[k] = ax.text(x, y, f"{k}\n" + "\n".join(s.strip() for s in lines[:4]), ha="center", va="center",
                           fontsize=9, bbox=dict(boxstyle="round,pad=0.4", fc="#eef3fb", ec="#3b6db3"))
    fig.canvas.draw()  # the boxes' patches get their size
    for k, needs in edges.items():
        for n in needs:
            ax.annotate("", xy=pos[k], xytext=pos[n], arrowprops=dict(
                arrowstyle="-|>", color="0.4", lw=1.2, patchA=boxes[n].get_bbox_patch(),
                patchB=boxes[k].get_bbox_patch(), connectionstyle="arc3,rad=0.05"))
    ax.set_xlim(-0.6, max(rows) + 0.6)
    ax.set_ylim(min(y for _, y in pos.values()) - 0.6, max(y for _, y in pos.values()) + 0.6)
    ax.axis("off")
    ax.set_title("Lessons and what each needs first (an arrow: read this one before)", fontsize=10)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, bbox_inches="tight")
    plt.close(fig)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=PICTURE)
    args = ap.parse_args(argv)
    g = graph()
    for k, v in g.items():
        print(f"{k:4s} {v['title']:48s} needs {', '.join(v['needs']) or '-'}")
    print("drew", draw(g, args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
