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


# animations are H.264 videos in a player (render.render_mp4 + video_html); a GIF has no play/scrub controls.
# Lesson 03 still shows a GIF until it is re-executed with render_mp4.
GIF_ALLOWED = {"03_gmm_rnn_refiner"}
MAX_VIDEO_BYTES = 400_000  # each inline MP4: small H.264, not a movie
MAX_NOTEBOOK_BYTES = 5_000_000


def animations(path: Path) -> tuple[int, list[str]]:
    """(number of GIF outputs, the HTML of every output holding an inline MP4)."""
    gifs, videos = 0, []
    for cell in json.loads(path.read_text(encoding="utf-8"))["cells"]:
        for out in cell.get("outputs", []):
            data = out.get("data", {})
            gifs += "image/gif" in data
            html = "".join(data.get("text/html", ""))
            if "video/mp4" in html:
                videos.append(html)
    return gifs, videos


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_animations_are_small_videos_with_controls(path):
    import base64
    import re

    gifs, videos = animations(path)
    assert path.stat().st_size < MAX_NOTEBOOK_BYTES, f"{path.name}: {path.stat().st_size / 1e6:.1f} MB"
    if path.stem not in GIF_ALLOWED:
        assert gifs == 0, f"{path.name}: {gifs} GIF output(s): use render.render_mp4 and render.video_html"
    for html in videos:
        assert re.search(r"<video controls", html), "a video without play/scrub controls"
        data = base64.b64decode(re.search(r"base64,([^\"]+)\"", html).group(1))
        assert b"avc1" in data, "not H.264"
        assert len(data) < MAX_VIDEO_BYTES, f"{path.name}: a {len(data) / 1e3:.0f} kB video"


def test_the_animation_scan_sees_a_planted_gif_and_video(tmp_path):
    video = '<video controls><source src="data:video/mp4;base64,QUJD" type="video/mp4"></video>'
    nb = {"cells": [{"cell_type": "code", "outputs": [
        {"output_type": "display_data", "data": {"image/gif": "R0lGOD", "text/plain": "<Image>"}},
        {"output_type": "display_data", "data": {"text/html": video}}]}]}
    path = tmp_path / "x.ipynb"
    path.write_text(json.dumps(nb))
    assert animations(path) == (1, [video])
