"""Build the course site: Sphinx + MyST-NB + the book theme, from executed notebooks, working offline.

Usage: python tools/build_site.py --notebooks notebooks --site site --mode ci [--only 00_skeletons_and_rotations ...]

`make course` executes every lesson (COURSE_MODE=class) into build/executed/ and calls this on that
folder; `make site` calls it on notebooks/ (the committed notebooks, executed in CI mode: fast).

Why Sphinx + MyST-NB (and not MkDocs + mkdocs-jupyter): it reads the executed notebooks as they are
(outputs, images, the MP4 players of `render.video_html`), numbers and cross-links pages, and its
search is a local index (searchindex.js) that works from file:// with no server and no network; the
book theme gives the lesson navigation.  mkdocs-jupyter embeds nbconvert's own page (MathJax and
require.js from CDNs) and Material's search needs a web worker, which file:// pages cannot start.

What this script adds around sphinx-build:
- a landing page (index.md) with each lesson's objectives, time and prerequisites and what holds or
  fails of its paper, all read from the lesson itself (its first cell and its summary), so it cannot
  drift from the notebooks;
- MathJax 2.7 served from the site (_static/mathjax), copied from the PyPI package
  jupyter-server-mathjax (pinned in pyproject.toml: no root, no apt, the same on every machine).
tests/test_site_browser.py builds a one-lesson site with this script and opens it in headless
chromium with the network cut.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import lesson_graph  # noqa: E402  (tools/lesson_graph.py: the lessons' dependency graph)

CONF_DIR = Path(__file__).resolve().parent / "site"  # conf.py


# ----------------------------------------------------------------------------- reading a lesson


def _markdown_cells(notebook: Path) -> list[str]:
    cells = json.loads(notebook.read_text(encoding="utf-8")).get("cells", [])
    out = []
    for cell in cells:
        if cell.get("cell_type") == "markdown":
            source = cell.get("source", "")
            out.append("".join(source) if isinstance(source, list) else source)
    return out


def lesson_title(notebook: Path) -> str:
    """The first Markdown heading of the notebook, or its file name when it has none."""
    for text in _markdown_cells(notebook):
        for line in text.splitlines():
            if line.lstrip().startswith("#"):
                return line.lstrip("# \t").strip()
    return notebook.stem


def _field(text: str, name: str) -> str | None:
    """The text after **name:** up to the next bold field or blank line (one paragraph), or None."""
    m = re.search(rf"\*\*{name}:\*\*\s*(.*?)(?=\s*\*\*[A-Z][a-z]+:\*\*|\n\s*\n|\Z)", text, re.S)
    return " ".join(m.group(1).split()) if m else None


def _objectives(text: str) -> str | None:
    """The **Objectives.** paragraph with its list (up to the first blank line after the list)."""
    lines = text.splitlines()
    start = next((i for i, line in enumerate(lines) if line.lstrip().startswith("**Objectives.**")), None)
    if start is None:
        return None
    out, in_list = [lines[start].replace("**Objectives.**", "").strip()], False
    for line in lines[start + 1:]:
        if not line.strip():
            if in_list:
                break
            continue
        in_list = in_list or bool(re.match(r"\s*(\d+\.|[-*])\s", line))
        out.append(line.rstrip())
    return "\n".join(out).strip() or None


def _bullets(text: str) -> list[str]:
    """Top-level bullets of a Markdown list, each joined onto one line."""
    items: list[str] = []
    for line in text.splitlines():
        if re.match(r"[*-] ", line):
            items.append(line[2:].strip())
        elif items and line.startswith(" ") and line.strip():
            items[-1] += " " + line.strip()
    return items


def lesson_info(notebook: Path) -> dict:
    """What the landing page says about a lesson, read from the lesson: name, title, objectives, prerequisites,
    time (None where the lesson does not state them) and the summary's bullets on what holds and fails."""
    cells = _markdown_cells(notebook)
    head = cells[0] if cells else ""
    summary = next((c for c in cells if re.match(r"\s*#+ .*Summary", c)), "")
    verdicts = [b for b in _bullets(summary) if re.match(r"\*\*What (holds|fails|does not hold)", b)]
    return {"name": notebook.stem, "title": lesson_title(notebook), "objectives": _objectives(head),
            "prerequisites": _field(head, "Prerequisites"), "time": _field(head, "Time"), "paper": verdicts}


STUDIES = CONF_DIR.parents[1] / "studies"  # the lab: studies/README.md and one README.md per lesson folder


def study_pages() -> dict[str, str]:
    """The "Reproduction notes": page name -> Markdown, from studies/README.md (the index) and each
    studies/<lesson>/README.md, links between them pointed at the pages."""
    if not (STUDIES / "README.md").is_file():
        return {}
    folders = sorted(p.parent.name for p in STUDIES.glob("*/README.md"))

    def relink(text: str) -> str:
        for name in folders:
            text = re.sub(rf"\]\((?:\.\./)?(?:studies/)?{name}/(?:README\.md)?\)", f"](studies_{name}.md)", text)
        return re.sub(r"\]\((?:\.\./)?README\.md\)", "](reproduction_notes.md)", text)

    pages = {"reproduction_notes": relink((STUDIES / "README.md").read_text(encoding="utf-8"))}
    for name in folders:
        pages[f"studies_{name}"] = relink((STUDIES / name / "README.md").read_text(encoding="utf-8"))
    return pages


def relink_lesson(text: str) -> str:
    """A lesson's Markdown with its links into the lab (`../studies/<lesson>/README.md#anchor`, `../studies/README.md`)
    pointed at the site's reproduction-notes pages, anchors kept."""
    text = re.sub(r"\]\(\.\./studies/([^/)#]+)/(?:README\.md)?(#[^)]*)?\)",
                  lambda m: f"](studies_{m.group(1)}.md{m.group(2) or ''})", text)
    return re.sub(r"\]\(\.\./studies/(?:README\.md)?(#[^)]*)?\)",
                  lambda m: f"](reproduction_notes.md{m.group(1) or ''})", text)


def copy_lesson(nb: Path, dest: Path) -> None:
    """Copy an executed notebook into the site's source with its Markdown cells' lab links relinked."""
    book = json.loads(nb.read_text(encoding="utf-8"))
    for cell in book["cells"]:
        if cell["cell_type"] == "markdown":
            source = "".join(cell["source"]) if isinstance(cell["source"], list) else cell["source"]
            cell["source"] = relink_lesson(source)
    dest.write_text(json.dumps(book, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")


def extra_pages() -> list[Path]:
    """The site's pages beyond the lessons (tools/site/pages/*.md: troubleshooting, ...), in name order."""
    return sorted((CONF_DIR / "pages").glob("*.md"))


def landing_page(rows: list[dict], mode: str, demo: bool = False) -> str:
    """index.md (MyST) for the given lessons: a hidden toctree for the navigation, one section per lesson."""
    out = ["# Data-driven human motion synthesis", "",
           "A Jupyter course that builds and reproduces four papers on human motion synthesis on a laptop CPU: the "
           "VAE-LSTM of Habibie et al. (lesson 02), the GMM-RNN with an adversarial refiner of Wang, Chai et al. "
           "(03, 04), the hierarchical VRNN of Ghorbani et al. (05) and MoGlow of Henter et al. (06), after the "
           "foundations (00, 00b, 00c, 01), and compares them all in one benchmark (07). Each lesson page below "
           "is the executed notebook "
           f"(`COURSE_MODE={mode}`); the notebooks themselves are in `notebooks/`, the student copies "
           "with the exercises to solve come from `make student`. Search is at the top left; it works offline.",
           "", "## The order of the lessons", "",
           "Each lesson names its prerequisites in its header; an arrow points from a lesson to one that needs it.",
           "", "![The lessons' dependency graph](lesson_graph.png)", ""]
    if demo:  # make site / make course build site/demo/ right after (make demo)
        out += [
            "## Steer the model in your browser", "",
            "Lesson 06's pretrained MoGlow runs in a web page, offline: arrow keys or WASD set the speed and turn "
            "(<a href=\"demo/index.html\">open the demo</a>; `make site` and `make course` build it into "
            "`site/demo/`; `make serve` serves the site at http://localhost:8000).", "",
            "![The demo page after its self-test (?selftest=1)](demo_page.png)", "",
        ]
    out += ["```{toctree}", ":hidden:", ":maxdepth: 1", ""]
    out += [r["name"] for r in rows] + list(study_pages()) + [page.stem for page in extra_pages()] + ["```", ""]
    for r in rows:
        out += [f"## {r['title']}", "", f"{{doc}}`Open the lesson <{r['name']}>` (`{r['name']}.ipynb`)", ""]
        out += [f"**Prerequisites:** {r['prerequisites'] or '(not stated in the lesson)'}", "",
                f"**Time:** {r['time'] or '(not stated in the lesson)'}", ""]
        if r["objectives"]:
            out += ["**Objectives.** " + r["objectives"], ""]
        if r["paper"]:
            out += ["**Its paper, on our data:**", ""] + [f"* {b}" for b in r["paper"]] + [""]
        else:
            out += ["**Its paper, on our data:** no paper is reproduced in this lesson (foundations).", ""]
    return "\n".join(out)


# ----------------------------------------------------------------------------- MathJax


def mathjax_source() -> Path:
    """The folder holding MathJax.js in the installed jupyter-server-mathjax package."""
    import jupyter_server_mathjax

    folder = Path(jupyter_server_mathjax.__file__).parent / "static"
    if not (folder / "MathJax.js").is_file():
        raise FileNotFoundError(f"no MathJax.js in {folder}: reinstall jupyter-server-mathjax (make setup)")
    return folder


def copy_mathjax(static_dir: Path) -> Path:
    """Copy MathJax into static_dir/mathjax (kept when its MathJax.js is already the same size) -> that folder."""
    src, dst = mathjax_source(), static_dir / "mathjax"
    have, want = dst / "MathJax.js", src / "MathJax.js"
    if not (have.is_file() and have.stat().st_size == want.stat().st_size):
        shutil.rmtree(dst, ignore_errors=True)
        shutil.copytree(src, dst)
    return dst


# ----------------------------------------------------------------------------- the build


def prepare_source(notebooks: list[Path], src: Path, mode: str, demo: bool = False) -> list[dict]:
    """Fill src/ with the notebooks and the landing page -> the lessons' info."""
    shutil.rmtree(src, ignore_errors=True)
    src.mkdir(parents=True)
    rows = []
    for nb in notebooks:
        copy_lesson(nb, src / nb.name)
        rows.append(lesson_info(nb))
    for page in extra_pages():
        shutil.copy2(page, src / page.name)
    for name, text in study_pages().items():
        (src / f"{name}.md").write_text(text, encoding="utf-8")
    (src / "index.md").write_text(landing_page(rows, mode, demo), encoding="utf-8")
    lesson_graph.draw(lesson_graph.graph(notebooks), src / "lesson_graph.png")
    if demo:
        shutil.copy2(CONF_DIR / "_static" / "demo_page.png", src / "demo_page.png")  # a screenshot of site/demo/
    return rows


def build(notebooks: list[Path], site: Path, mode: str, work: Path, demo: bool = False) -> list[dict]:
    """sphinx-build the notebooks into site/ (html), MathJax included -> the lessons' info."""
    rows = prepare_source(notebooks, work / "src", mode, demo)
    html = work / "html"  # MyST-NB writes its jupyter_execute/ beside the output folder: keep both in work/
    cmd = [sys.executable, "-m", "sphinx", "-b", "html", "-q", "-c", str(CONF_DIR), "-d", str(work / "doctrees"),
           str(work / "src"), str(html)]
    subprocess.run(cmd, check=True)
    copy_mathjax(html / "_static")
    shutil.copytree(html, site, dirs_exist_ok=True)  # site/ may hold other files (the lessons' BVH samples)
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--notebooks", type=Path, default=Path("notebooks"), help="folder of the executed lessons")
    parser.add_argument("--site", type=Path, default=Path("site"), help="output folder (HTML)")
    parser.add_argument("--mode", default="ci", help="COURSE_MODE the notebooks were executed in")
    parser.add_argument("--work", type=Path, default=Path("build/site"), help="Sphinx source and cache folder")
    parser.add_argument("--only", nargs="*", help="lesson names to include (default: every [0-9]*.ipynb)")
    parser.add_argument("--demo", action="store_true", help="link the browser demo (make demo builds site/demo/)")
    args = parser.parse_args(argv)
    if not args.notebooks.is_dir():
        parser.error(f"--notebooks {args.notebooks} is not a folder")
    notebooks = sorted(args.notebooks.glob("[0-9]*.ipynb"))
    if args.only:
        notebooks = [nb for nb in notebooks if nb.stem in args.only]
        missing = set(args.only) - {nb.stem for nb in notebooks}
        if missing:
            parser.error(f"--only: no notebook {sorted(missing)} in {args.notebooks}")
    if not notebooks:
        parser.error(f"no lesson notebooks in {args.notebooks}")
    start = time.perf_counter()
    rows = build(notebooks, args.site, args.mode, args.work, args.demo)
    print(f"build_site: {args.site}/index.html, {len(rows)} lessons, MathJax served from "
          f"{args.site}/_static/mathjax ({time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
