"""Write site/index.html: the course's lessons in order, each linked to its executed HTML.

Usage: python tools/build_site.py --notebooks notebooks --site site --mode class

`make course` runs it after executing every notebook into site/<name>.html.  A lesson whose
HTML is missing (its execution failed) is listed as "not built" instead of linked.
"""

from __future__ import annotations

import argparse
import html
import json
from pathlib import Path


def lesson_title(notebook: Path) -> str:
    """The first Markdown heading of the notebook, or its file name when it has none."""
    cells = json.loads(notebook.read_text(encoding="utf-8")).get("cells", [])
    for cell in cells:
        if cell.get("cell_type") != "markdown":
            continue
        source = cell.get("source", "")
        text = "".join(source) if isinstance(source, list) else source
        for line in text.splitlines():
            if line.lstrip().startswith("#"):
                return line.lstrip("# \t").strip()
    return notebook.stem


def lessons(notebooks_dir: Path, site_dir: Path) -> list[dict]:
    """One dict per notebook, in file-name order: name, title, html (file name or None)."""
    rows = []
    for nb in sorted(notebooks_dir.glob("[0-9]*.ipynb")):
        page = site_dir / f"{nb.stem}.html"
        rows.append({"name": nb.stem, "title": lesson_title(nb), "html": page.name if page.exists() else None})
    return rows


def render_index(rows: list[dict], mode: str) -> str:
    """The index page's HTML for the given lessons."""
    items = []
    for row in rows:
        title = html.escape(row["title"])
        if row["html"]:
            items.append(f'<li><a href="{html.escape(row["html"])}">{title}</a> <code>{row["name"]}</code></li>')
        else:
            items.append(f"<li>{title} <code>{row['name']}</code> &mdash; <em>not built</em></li>")
    body = "\n".join(items) if items else "<li><em>no notebooks yet</em></li>"
    return (
        "<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>Data-driven human motion synthesis</title>"
        "</head>\n<body>\n<h1>Data-driven human motion synthesis &mdash; lessons</h1>\n"
        f"<p>Executed with <code>COURSE_MODE={html.escape(mode)}</code> by <code>make course</code>.</p>\n"
        f"<ol start='0'>\n{body}\n</ol>\n</body></html>\n"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--notebooks", type=Path, default=Path("notebooks"), help="folder of the lesson notebooks")
    parser.add_argument("--site", type=Path, default=Path("site"), help="folder of the executed HTML pages")
    parser.add_argument("--mode", default="class", help="COURSE_MODE the pages were executed in")
    args = parser.parse_args(argv)
    if not args.notebooks.is_dir():
        parser.error(f"--notebooks {args.notebooks} is not a folder")
    args.site.mkdir(parents=True, exist_ok=True)
    rows = lessons(args.notebooks, args.site)
    index = args.site / "index.html"
    index.write_text(render_index(rows, args.mode), encoding="utf-8")
    built = sum(row["html"] is not None for row in rows)
    print(f"build_site: {index} lists {len(rows)} lessons, {built} built")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
