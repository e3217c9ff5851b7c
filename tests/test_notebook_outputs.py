"""The committed notebooks' outputs: no progress-bar warning (ipywidgets is installed, so tqdm.auto draws bars)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("[0-9]*.ipynb"))


def output_texts(path: Path) -> list[str]:
    """Every text a code cell printed or displayed (streams, errors, text/plain and text/html data)."""
    texts = []
    for cell in json.loads(path.read_text(encoding="utf-8"))["cells"]:
        for out in cell.get("outputs", []):
            texts.append("".join(out.get("text", "")))
            texts.append("".join(out.get("traceback", [])))
            for mime in ("text/plain", "text/html"):
                texts.append("".join(out.get("data", {}).get(mime, "")))
    return texts


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_no_iprogress_warning_in_outputs(path):
    hits = [t for t in output_texts(path) if "IProgress not found" in t]
    assert not hits, f"{path.name}: re-execute it (ipywidgets is pinned): {hits[0][:200]}"


def test_the_scan_sees_a_planted_warning(tmp_path):
    nb = {"cells": [{"cell_type": "code", "outputs": [{"output_type": "stream", "name": "stderr",
                                                       "text": ["TqdmWarning: IProgress not found. Please update"]}]}]}
    path = tmp_path / "x.ipynb"
    path.write_text(json.dumps(nb))
    assert any("IProgress not found" in t for t in output_texts(path))
