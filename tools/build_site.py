"""Write site/index.html: the course's lessons in order, each linked to its executed HTML.

Usage: python tools/build_site.py --notebooks notebooks --site site --mode class

`make course` runs it after executing every notebook into site/<name>.html.  A lesson whose
HTML is missing (its execution failed) is listed as "not built" instead of linked.

Equations work with no network: nbconvert's pages load MathJax from a CDN, so this script copies
MathJax 2.7 into site/mathjax/ and points every page at that copy.  The copy comes from the PyPI
package jupyter-server-mathjax (pinned in pyproject.toml, installed by `make setup`: no root, no
apt, the same on every machine); it is MathJax 2.7, the major version whose configuration
(`MathJax.Hub.Config`) nbconvert's HTML template writes.  tests/test_site_browser.py opens a page
in headless chromium with the network cut and checks that no raw $...$ is left.
"""

from __future__ import annotations

import argparse
import html
import json
import re
import shutil
from pathlib import Path

# nbconvert's default <script src=...> for MathJax (any CDN URL of MathJax is replaced)
CDN_MATHJAX = re.compile(r'<script src="https?://[^"]*mathjax[^"]*"', re.IGNORECASE)
# the local copy: config "TeX-AMS-MML_HTMLorMML-full" (the package ships no CommonHTML-only config) + "Safe"
LOCAL_MATHJAX = "mathjax/MathJax.js?config=TeX-AMS-MML_HTMLorMML-full,Safe"
# the package ships only the STIX-Web web fonts (not MathJax's default TeX fonts): use them, never the
# reader's locally installed fonts or the image fonts, so every page looks the same everywhere
FONT_CONFIG = ('<script type="text/x-mathjax-config">MathJax.Hub.Config({"HTML-CSS": '
               '{availableFonts: [], preferredFont: null, webFont: "STIX-Web", imageFont: null}});</script>\n')


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


def mathjax_source() -> Path:
    """The folder holding MathJax.js in the installed jupyter-server-mathjax package."""
    import jupyter_server_mathjax

    folder = Path(jupyter_server_mathjax.__file__).parent / "static"
    if not (folder / "MathJax.js").is_file():
        raise FileNotFoundError(f"no MathJax.js in {folder}: reinstall jupyter-server-mathjax (make setup)")
    return folder


def copy_mathjax(site_dir: Path) -> Path:
    """Copy MathJax into site_dir/mathjax (kept when its MathJax.js is already the same size) -> that folder."""
    src, dst = mathjax_source(), site_dir / "mathjax"
    have, want = dst / "MathJax.js", src / "MathJax.js"
    if not (have.is_file() and have.stat().st_size == want.stat().st_size):
        shutil.rmtree(dst, ignore_errors=True)
        shutil.copytree(src, dst)
    return dst


def localise_mathjax(page: Path) -> bool:
    """Point one HTML page's MathJax <script> at the site's copy -> whether the page changed."""
    text = page.read_text(encoding="utf-8")
    new = CDN_MATHJAX.sub(lambda _: f'{FONT_CONFIG}<script src="{LOCAL_MATHJAX}"', text)
    if new != text:
        page.write_text(new, encoding="utf-8")
    return new != text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--notebooks", type=Path, default=Path("notebooks"), help="folder of the lesson notebooks")
    parser.add_argument("--site", type=Path, default=Path("site"), help="folder of the executed HTML pages")
    parser.add_argument("--mode", default="class", help="COURSE_MODE the pages were executed in")
    args = parser.parse_args(argv)
    if not args.notebooks.is_dir():
        parser.error(f"--notebooks {args.notebooks} is not a folder")
    args.site.mkdir(parents=True, exist_ok=True)
    copy_mathjax(args.site)
    changed = sum(localise_mathjax(page) for page in sorted(args.site.glob("*.html")))
    rows = lessons(args.notebooks, args.site)
    index = args.site / "index.html"
    index.write_text(render_index(rows, args.mode), encoding="utf-8")
    built = sum(row["html"] is not None for row in rows)
    print(f"build_site: {index} lists {len(rows)} lessons, {built} built; MathJax served from {args.site}/mathjax "
          f"({changed} pages re-pointed)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
