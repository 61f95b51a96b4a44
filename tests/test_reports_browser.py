"""The HTML reports in a real browser (headless Chromium): every figure is there, decodes and is
displayed, every local link resolves; a screenshot of each report is kept in ``tests/artifacts/``.

Without Chromium the tests skip locally and fail in CI (``CI=true``). The checker itself is tested on
a small page with known faults, so a clean report is a finding, not a blind spot.
"""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from browser import check_report, find_chromium, screenshot
from campaign_fixtures import SCENE, TINY

from renderlab.cli import main

ARTIFACTS = Path(__file__).resolve().parent / "artifacts"


@pytest.fixture(scope="module", autouse=True)
def chromium():
    exe = find_chromium()
    if exe is None:
        msg = "headless Chromium is not installed (apt-get install -y chromium, or set $CHROMIUM)"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"CI=true but {msg}", pytrace=False)
        pytest.skip(msg)
    return exe


def _png(w: int, h: int) -> bytes:
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    raw = b"".join(b"\x00" + bytes([(x * 40) % 256 for x in range(w)]) for _ in range(h))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def test_checker_finds_known_faults(tmp_path):
    """Oracle for the checker: a page with one fault of each kind, and its clean twin."""
    (tmp_path / "good.png").write_bytes(_png(6, 4))
    (tmp_path / "trunc.png").write_bytes(_png(6, 4)[:30])
    (tmp_path / "fig.svg").write_text('<?xml version="1.0"?><svg xmlns="http://www.w3.org/2000/svg" '
                                      'width="10" height="10"><rect width="10" height="10"/></svg>')
    (tmp_path / "data.csv").write_text("a\n1\n")
    good = ('<html><head><title>t</title></head><body><h2 id="top">x</h2><img src="good.png">'
            '<img src="fig.svg"><a href="data.csv">csv</a><a href="#top">top</a></body></html>')
    (tmp_path / "good.html").write_text(good)
    assert check_report(tmp_path / "good.html") == []
    bad = good.replace("</body>", '<img src="missing.png"><img src="trunc.png"><a href="nope.csv">x</a>'
                                  '<a href="#nowhere">y</a><img src="../escape.png"></body>')
    (tmp_path / "bad.html").write_text(bad)
    problems = check_report(tmp_path / "bad.html")
    text = "\n".join(problems)
    for expected in ("missing.png'>: missing file", "trunc.png'>: does not decode", "nope.csv'>: missing file",
                     "no element with id 'nowhere'", "escape.png'>: points outside the report folder",
                     "browser: <img src='trunc.png'> has naturalWidth 0",
                     "browser: <img src='missing.png'> has naturalWidth 0", "browser: cannot load missing.png"):
        assert expected in text, f"{expected!r} not in:\n{text}"
    assert not any("good.png" in p or "fig.svg" in p for p in problems)


@pytest.fixture(scope="module")
def campaign_report(tmp_path_factory):
    """The analytic campaign report (as tests/test_report_campaign.py builds it, 4 tiny runs)."""
    d = tmp_path_factory.mktemp("browser_campaign")
    args = ["campaign", str(SCENE), "--runs", "4", "--out", str(d / "camp"), "--workers", "0", "--quiet",
            "--seed", "2", *[a for kv in TINY for a in ("--set", kv)]]
    assert main(args) == 0
    assert main(["report", str(d / "camp"), "--out", str(d / "rep")]) == 0
    return d / "rep" / "index.html"


def test_campaign_report_in_browser(campaign_report):
    import cv2

    assert check_report(campaign_report) == []
    shot = screenshot(campaign_report, ARTIFACTS / "campaign_report.png", width=1280, height=2400)
    img = cv2.imread(str(shot))
    assert img is not None and img.shape[:2] == (2400, 1280)
    assert np.std(img) > 5, "the screenshot is blank"


REPO = Path(__file__).resolve().parents[1]
PUBLISHED = sorted(p.relative_to(REPO).as_posix() for p in (REPO / "results").rglob("report/index.html"))


def test_every_published_result_has_a_report():
    assert len(PUBLISHED) >= 8, PUBLISHED


@pytest.mark.parametrize("page", PUBLISHED)
def test_published_report_in_browser(page):
    """Every committed report under results/ opens in Chromium with every figure loaded; screenshot kept."""
    import cv2

    html = REPO / page
    assert check_report(html) == []
    name = page.removeprefix("results/").removesuffix("/report/index.html").replace("/", "__")
    shot = screenshot(html, ARTIFACTS / f"published_{name}.png", width=1280, height=2400)
    img = cv2.imread(str(shot))
    assert img is not None and np.std(img) > 5, "the screenshot is blank"
