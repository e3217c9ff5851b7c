"""tools/build_site.py's lesson links into the lab: a lesson's `../studies/...` links become links to the site's
reproduction-notes pages (the notebook in the repository keeps its own links, which work on GitHub and in Jupyter)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))

import build_site  # noqa: E402


def test_relink_lesson_points_study_links_at_the_site_pages_and_keeps_anchors():
    text = ("[why](../studies/02_vae_lstm/README.md#table-1s-two-rows-are-close), "
            "[feet](../studies/05_hierarchical_vrnn/README.md), [all](../studies/README.md), "
            "[folders](../studies/README.md#the-folders), [paper](https://example.org/studies/a/README.md)")
    assert build_site.relink_lesson(text) == (
        "[why](studies_02_vae_lstm.md#table-1s-two-rows-are-close), [feet](studies_05_hierarchical_vrnn.md), "
        "[all](reproduction_notes.md), [folders](reproduction_notes.md#the-folders), "
        "[paper](https://example.org/studies/a/README.md)")


def test_copy_lesson_relinks_markdown_cells_only(tmp_path):
    link = "[n](../studies/06_moglow/README.md#moglow_noise_blind)"
    book = {"cells": [{"cell_type": "markdown", "metadata": {}, "source": [f"See {link}.\n", "Next line."]},
                      {"cell_type": "code", "metadata": {}, "source": [f"# {link}"], "outputs": [],
                       "execution_count": 1}],
            "metadata": {}, "nbformat": 4, "nbformat_minor": 5}
    src, dest = tmp_path / "a.ipynb", tmp_path / "out.ipynb"
    src.write_text(json.dumps(book))
    build_site.copy_lesson(src, dest)
    cells = json.loads(dest.read_text())["cells"]
    assert cells[0]["source"] == "See [n](studies_06_moglow.md#moglow_noise_blind).\nNext line."
    assert cells[1]["source"] == [f"# {link}"]
    assert json.loads(src.read_text()) == book  # the input is untouched
