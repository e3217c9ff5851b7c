"""The course site in a real browser: headless Debian chromium with the network cut.

One small page is built the way `make course` builds every lesson (nbconvert's HTML exporter,
then tools/build_site.py), from a notebook made here with inline and display equations, an
image output and internal links.  Chromium opens it with every host name unresolvable; a probe
script, added to the test's copy of the page, waits for MathJax to finish and reports what a
reader sees.  Checks: MathJax typeset every equation and no raw $...$ is left in the Markdown
text; every image loaded (naturalWidth > 0); every internal link (file and #anchor) resolves.
The known answer the other way: the same page left pointing at the CDN shows its $...$ raw.

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
pytestmark = pytest.mark.skipif(CHROMIUM is None and os.environ.get("CI") != "true",
                                reason="needs Debian's chromium (.ci/run installs it)")

PROBE = """<script>
window.addEventListener('load', function () {
  function report() {
    var md = Array.from(document.querySelectorAll('.jp-MarkdownCell .jp-RenderedMarkdown'));
    var text = md.map(function (e) { return e.innerText; }).join('\\n');
    var imgs = Array.from(document.images);
    var pre = document.createElement('pre');
    pre.id = 'course-probe';
    pre.textContent = JSON.stringify({
      mathjax: !!(window.MathJax && window.MathJax.Hub),
      typeset: document.querySelectorAll('.MathJax, .MathJax_Display, .MathJax_SVG').length,
      fonts: Array.from(document.fonts).filter(function (f) { return f.status === 'loaded'; }).map(function (f) {
        return f.family; }),
      raw: text.match(/\\$[^$\\n]+\\$/g) || [],
      images: imgs.length,
      broken: imgs.filter(function (i) { return !(i.complete && i.naturalWidth > 0); }).map(function (i) {
        return i.src.slice(0, 60); })
    });
    document.body.appendChild(pre);
  }
  if (window.MathJax && window.MathJax.Hub) { window.MathJax.Hub.Queue(report); } else { report(); }
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


def _notebook(path: Path) -> None:
    import nbformat

    nb = nbformat.v4.new_notebook()
    nb.cells = [
        nbformat.v4.new_markdown_cell(
            "# 00 Browser check\n\n"
            "Inline $p(y \\mid x) = \\sum_{i=1}^{M} w_i\\, \\mathcal{N}(y \\mid \\mu_i, \\sigma_i^2)$"
            " and a display equation\n\n"
            "$$\\mathcal{L} = -\\log D(R(x)) + \\lambda \\lVert x \\rVert^2 \\qquad (13)$$\n\n"
            "[back to the index](index.html), [to the image](#An-image)."),
        nbformat.v4.new_markdown_cell("## An image\n\nA figure output, embedded as a PNG."),
        nbformat.v4.new_code_cell("plot()", outputs=[nbformat.v4.new_output(
            "display_data", data={"image/png": _png(), "text/plain": "<Figure>"})]),
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


def _dump(page: Path, tmp: Path) -> str:
    """The DOM of a file page after its scripts ran, from headless chromium with no name resolution."""
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
           f"--user-data-dir={tmp / 'profile'}", "--host-resolver-rules=MAP * ~NOTFOUND",
           "--virtual-time-budget=15000", "--dump-dom", page.as_uri()]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout


def _probe(dom: str) -> dict:
    m = re.search(r'<pre id="course-probe">(.*?)</pre>', dom, re.S)
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


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    from nbconvert import HTMLExporter

    tmp = tmp_path_factory.mktemp("site")
    notebooks, site = tmp / "notebooks", tmp / "site"
    notebooks.mkdir()
    site.mkdir()
    nb = notebooks / "00_browser_check.ipynb"
    _notebook(nb)
    body, _ = HTMLExporter().from_filename(str(nb))  # the exporter `make course` uses, default (CDN) MathJax
    assert build_site.CDN_MATHJAX.search(body), "nbconvert's template changed: its MathJax <script> is not matched"
    (site / "00_browser_check.html").write_text(body, encoding="utf-8")
    (tmp / "cdn.html").write_text(body.replace("</body>", PROBE + "</body>"), encoding="utf-8")
    assert build_site.main(["--notebooks", str(notebooks), "--site", str(site), "--mode", "ci"]) == 0
    return tmp, site


def test_built_page_renders_equations_images_and_links_offline(site):
    tmp, site_dir = site
    page = site_dir / "00_browser_check.html"
    html_text = page.read_text(encoding="utf-8")
    assert build_site.LOCAL_MATHJAX in html_text and not build_site.CDN_MATHJAX.search(html_text)
    probed = site_dir / "probe.html"  # the page plus the probe, in the same folder so relative URLs hold
    probed.write_text(html_text.replace("</body>", PROBE + "</body>"), encoding="utf-8")
    dom = _dump(probed, tmp)
    report = _probe(dom)
    assert report["mathjax"], "MathJax did not load from site/mathjax"
    assert report["raw"] == [], f"raw TeX left in the visible text: {report['raw']}"
    assert report["typeset"] >= 2  # the inline and the display equation
    assert any("STIX" in f for f in report["fonts"]), report["fonts"]  # MathJax's web fonts came from site/mathjax
    assert report["images"] >= 1 and report["broken"] == []
    assert _broken_links(probed, dom) == []


def test_index_links_resolve(site):
    tmp, site_dir = site
    index = site_dir / "index.html"
    dom = _dump(index, tmp)
    assert "00_browser_check.html" in dom
    assert _broken_links(index, dom) == []


def test_cdn_page_shows_raw_tex_without_network(site):
    # the known answer the other way: nbconvert's own page, MathJax from the CDN, no network
    tmp, _ = site
    report = _probe(_dump(tmp / "cdn.html", tmp))
    assert not report["mathjax"]
    assert any("\\sum_{i=1}^{M}" in r for r in report["raw"]), report["raw"]


def test_link_checker_finds_a_broken_link(tmp_path):
    page = tmp_path / "a.html"
    dom = '<a id="here" href="#here">ok</a><a href="missing.html">x</a><a href="a.html#nowhere">y</a>' \
          '<a href="https://example.org/">ext</a>'
    page.write_text(dom, encoding="utf-8")
    assert _broken_links(page, dom) == ["missing.html", "a.html#nowhere"]
