"""The course site in a real browser: headless Debian chromium with the network cut.

A one-lesson site is built the way `make course` / `make site` build the whole course
(tools/build_site.py: Sphinx + MyST-NB + the book theme) from a small notebook made here: a first
cell with objectives, prerequisites and time, inline and display equations, an image output, an
MP4 player output (`render.video_html`), internal links and a summary saying what holds.
Chromium opens the pages with every host name unresolvable; a probe script, added to the test's
copy of a page, waits for MathJax and the videos and reports what a reader sees.  Checks: MathJax
typeset every equation and no raw TeX is left in the text; every image loaded (naturalWidth > 0);
every video decoded its first frame (H.264, videoWidth > 0) and has controls; every internal link
(file and #anchor) resolves; the landing page shows the lesson's objectives, time, prerequisites
and what holds of its paper; the search page finds a word of the lesson, offline.
The known answer the other way: nbconvert's own page, MathJax from the CDN, shows its $...$ raw.

.ci/run installs chromium; without it (and without CI=true) the tests skip.
"""

from __future__ import annotations

import base64
import io
import json
import os
import re
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tools"))
import build_site  # noqa: E402

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = [pytest.mark.slow,  # make test-slow
              pytest.mark.skipif(CHROMIUM is None and os.environ.get("CI") != "true",
                                 reason="needs Debian's chromium (.ci/run installs it)")]

PROBE = """<script>
window.addEventListener('load', function () {
  function report() {
    var md = Array.from(document.querySelectorAll('.jp-MarkdownCell .jp-RenderedMarkdown, article.bd-article'));
    var text = md.map(function (e) { return e.innerText; }).join('\\n');
    var imgs = Array.from(document.images);
    var vids = Array.from(document.querySelectorAll('video'));
    var pre = document.createElement('pre');
    pre.id = 'course-probe';
    pre.textContent = JSON.stringify({
      mathjax: !!(window.MathJax && window.MathJax.Hub),
      typeset: document.querySelectorAll('.MathJax, .MathJax_Display, .MathJax_SVG').length,
      fonts: Array.from(document.fonts).filter(function (f) { return f.status === 'loaded'; }).map(function (f) {
        return f.family; }),
      raw: (text.match(/\\$[^$\\n]+\\$/g) || []).concat(text.match(/\\\\[(\\[][^\\n]*/g) || []),
      images: imgs.length,
      broken: imgs.filter(function (i) { return !(i.complete && i.naturalWidth > 0); }).map(function (i) {
        return i.src.slice(0, 60); }),
      videos: vids.map(function (v) { return {controls: v.controls, width: v.videoWidth, ready: v.readyState,
        error: v.error ? v.error.code : null}; }),
      search: Array.from(document.querySelectorAll('#search-results li a')).map(function (a) {
        return a.getAttribute('href'); })
    });
    document.body.appendChild(pre);
  }
  function media() {  // resolves when every video has its first frame (or failed), at most 8 s
    var vids = Array.from(document.querySelectorAll('video'));
    return Promise.race([Promise.all(vids.map(function (v) {
      return v.readyState >= 2 ? null : new Promise(function (ok) {
        v.addEventListener('loadeddata', ok); v.addEventListener('error', ok); v.load(); }); })),
      new Promise(function (ok) { setTimeout(ok, 8000); })]);
  }
  function after(ms) { return new Promise(function (ok) { setTimeout(ok, ms); }); }
  var typeset = (window.MathJax && window.MathJax.Hub) ?
    new Promise(function (ok) { window.MathJax.Hub.Queue(ok); }) : Promise.resolve();
  var searching = document.getElementById('search-results') ? after(3000) : Promise.resolve();
  Promise.all([typeset, media(), searching]).then(report);
});
</script>
"""


def _png() -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(2, 1.5))
    ax.plot([0, 1], [0, 1])
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode()


def _video_html() -> str:
    import numpy as np

    from course_lib import render

    frames = np.zeros((6, 64, 96, 3), np.uint8)
    frames[:, :, :, 0] = np.linspace(40, 220, 6, dtype=np.uint8)[:, None, None]  # a fade, in H.264
    return render.video_html(render.write_mp4(frames, fps=6)).data


def _notebook(path: Path) -> None:
    import nbformat

    nb = nbformat.v4.new_notebook()
    nb.metadata = {"kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"},
                   "language_info": {"name": "python"}}
    nb.cells = [
        nbformat.v4.new_markdown_cell(
            "# Lesson 00 — Browser check\n\n"
            "**Prerequisites:** lesson zero and a browser.  \n**Time:** about 5 minutes.\n\n"
            "**Objectives.** After this lesson you can\n\n1. read an equation;\n2. watch a video.\n\n"
            "Inline $p(y \\mid x) = \\sum_{i=1}^{M} w_i\\, \\mathcal{N}(y \\mid \\mu_i, \\sigma_i^2)$"
            " and a display equation\n\n"
            "$$\\mathcal{L} = -\\log D(R(x)) + \\lambda \\lVert x \\rVert^2 \\qquad (13)$$\n\n"
            "[back to the index](index.md), [to the image](#an-image)."),
        nbformat.v4.new_markdown_cell("## An image\n\nA figure output, embedded as a PNG."),
        nbformat.v4.new_code_cell("plot()", outputs=[nbformat.v4.new_output(
            "display_data", data={"image/png": _png(), "text/plain": "<Figure>"})]),
        nbformat.v4.new_markdown_cell("## A video\n\nAn MP4 in a player: the word quaternionsearchprobe is here."),
        nbformat.v4.new_code_cell("display(render.video_html(video))", outputs=[nbformat.v4.new_output(
            "display_data", data={"text/html": _video_html(), "text/plain": "<HTML>"})]),
        nbformat.v4.new_markdown_cell("## Summary\n\n* **Built:** a page.\n"
                                      "* **What holds:** equations render offline.\n"),
    ]
    path.write_text(nbformat.writes(nb), encoding="utf-8")


class _Links(HTMLParser):
    def __init__(self):
        super().__init__()
        self.hrefs, self.ids = [], set()

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if a.get("id"):
            self.ids.add(a["id"])
        if tag == "a" and a.get("href"):
            self.hrefs.append(a["href"])


def _dump(page: Path, tmp: Path, query: str = "") -> str:
    """The DOM of a file page after its scripts ran, from headless chromium with no name resolution."""
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
           f"--user-data-dir={tmp / 'profile'}", "--host-resolver-rules=MAP * ~NOTFOUND",
           "--virtual-time-budget=20000", "--dump-dom", page.as_uri() + query]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout


def _probe(dom: str) -> dict:
    m = re.search(r'<pre id="course-probe"[^>]*>(.*?)</pre>', dom, re.S)
    assert m, "the probe script did not report (page scripts did not run)"
    import html

    return json.loads(html.unescape(m.group(1)))


def _broken_links(page: Path, dom: str) -> list[str]:
    links = _Links()
    links.feed(dom)
    bad = []
    for href in links.hrefs:
        if re.match(r"^[a-z]+:", href) and not href.startswith("file:"):
            continue  # external (http, mailto, data): not the site's
        target, _, anchor = href.partition("#")
        target = target.partition("?")[0]  # search.html?q=...: the file is search.html
        file = page if not target else (page.parent / target)
        if not file.is_file():
            bad.append(href)
        elif anchor:
            ids = links.ids if file == page else _ids(file)
            if anchor not in ids:
                bad.append(href)
    return bad


def _ids(file: Path) -> set[str]:
    p = _Links()
    p.feed(file.read_text(encoding="utf-8"))
    return p.ids


CDN_MATHJAX = re.compile(r'<script src="https?://[^"]*mathjax[^"]*"', re.IGNORECASE)


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("site")
    notebooks, site = tmp / "notebooks", tmp / "site"
    notebooks.mkdir()
    _notebook(notebooks / "00_browser_check.ipynb")
    assert build_site.main(["--notebooks", str(notebooks), "--site", str(site), "--work", str(tmp / "work"),
                            "--mode", "ci"]) == 0
    return tmp, site


def _probed(page: Path, tmp: Path, query: str = "") -> tuple[dict, str, Path]:
    """Open a copy of `page` with the probe (same folder: relative URLs hold) -> (report, DOM, the copy)."""
    probed = page.with_name("probe_" + page.name)
    probed.write_text(page.read_text(encoding="utf-8").replace("</body>", PROBE + "</body>"), encoding="utf-8")
    dom = _dump(probed, tmp, query)
    return _probe(dom), dom, probed


def test_lesson_page_renders_equations_images_videos_and_links_offline(site):
    tmp, site_dir = site
    page = site_dir / "00_browser_check.html"
    text = page.read_text(encoding="utf-8")
    assert "_static/mathjax/MathJax.js" in text and not CDN_MATHJAX.search(text)
    assert not re.search(r'<(script|link)[^>]+(src|href)="https?://', text), "the page loads something from the web"
    report, dom, probed = _probed(page, tmp)
    assert report["mathjax"], "MathJax did not load from _static/mathjax"
    assert report["raw"] == [], f"raw TeX left in the visible text: {report['raw']}"
    assert report["typeset"] >= 2  # the inline and the display equation
    assert any("STIX" in f for f in report["fonts"]), report["fonts"]  # MathJax's web fonts came from the site
    assert report["images"] >= 1 and report["broken"] == []
    assert report["videos"] == [{"controls": True, "width": 96, "ready": report["videos"][0]["ready"], "error": None}]
    assert report["videos"][0]["ready"] >= 2  # its first frame is decoded: H.264 plays here
    assert _broken_links(probed, dom) == []


def test_landing_page_shows_each_lessons_objectives_time_prerequisites_and_paper(site):
    tmp, site_dir = site
    report, dom, probed = _probed(site_dir / "index.html", tmp)
    for words in ("Open the lesson", "lesson zero and a browser", "about 5 minutes", "read an equation",
                  "watch a video", "equations render offline"):
        assert words in dom, words
    assert 'href="00_browser_check.html"' in dom  # the navigation and the lesson's link
    assert _broken_links(probed, dom) == []


def test_search_finds_a_word_of_the_lesson_offline(site):
    tmp, site_dir = site
    report, _, _ = _probed(site_dir / "search.html", tmp, "?q=quaternionsearchprobe")
    assert any(h.startswith("00_browser_check.html") for h in report["search"]), report["search"]


def test_cdn_page_shows_raw_tex_without_network(site, tmp_path):
    # the known answer the other way: nbconvert's own page, MathJax from the CDN, no network
    from nbconvert import HTMLExporter

    tmp, _ = site
    body, _ = HTMLExporter().from_filename(str(tmp / "notebooks" / "00_browser_check.ipynb"))
    assert CDN_MATHJAX.search(body)
    page = tmp_path / "cdn.html"
    page.write_text(body, encoding="utf-8")
    report, _, _ = _probed(page, tmp_path)
    assert not report["mathjax"]
    assert any("\\sum_{i=1}^{M}" in r for r in report["raw"]), report["raw"]


def test_link_checker_finds_a_broken_link(tmp_path):
    page = tmp_path / "a.html"
    dom = '<a id="here" href="#here">ok</a><a href="missing.html">x</a><a href="a.html#nowhere">y</a>' \
          '<a href="https://example.org/">ext</a>'
    page.write_text(dom, encoding="utf-8")
    assert _broken_links(page, dom) == ["missing.html", "a.html#nowhere"]
