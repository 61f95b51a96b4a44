"""The published READMEs say what they measured and no more: each ends with a "What this shows / what it does not"
paragraph; every one that quotes a ratio to the registration CRLB restates it on the continuous bound; the
descent campaigns that share one map say that their intervals leave out map-to-map variation and what "touchdown"
means; the coastline truth-not-model README draws no inference about the paper's truth and says that its J2–J6 truth
omits the tesseral terms."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

RESULTS = Path(__file__).resolve().parents[1] / "results"
READMES = sorted(p for p in RESULTS.rglob("README.md") if "report" not in p.relative_to(RESULTS).parts)
CLOSING = "**What this shows / what it does not.**"


@pytest.mark.parametrize("path", READMES, ids=lambda p: p.relative_to(RESULTS).as_posix())
def test_ends_with_what_it_shows_and_what_it_does_not(path):
    paragraphs = [p for p in re.split(r"\n\s*\n", path.read_text(encoding="utf-8").strip()) if p.strip()]
    last = " ".join(paragraphs[-1].split())
    assert last.startswith(CLOSING), f"{path}: the last paragraph must start with {CLOSING!r}"
    assert "does not" in last[len(CLOSING):] and len(last) > 150


@pytest.mark.parametrize("path", READMES, ids=lambda p: p.relative_to(RESULTS).as_posix())
def test_crlb_ratios_are_restated_on_the_continuous_bound(path):
    text = path.read_text(encoding="utf-8")
    if re.search(r"× (the )?(tables' )?(registration )?(CRLB|Cramér–Rao bound)", text):
        assert "crlb_continuous" in text and "continuous bound" in text, (
            f"{path} quotes a ratio to the CRLB without its restatement on the continuous bound "
            "(investigations/error_budget/crlb_continuous.md)")


@pytest.mark.parametrize("name", ["descent_navigation", "descent_navigation_calibrated"])
def test_shared_map_campaigns_say_what_their_intervals_leave_out(name):
    text = (RESULTS / name / "README.md").read_text(encoding="utf-8")
    assert "map-to-map variation" in text
    assert re.search(r"[Tt]ouchdown[^.]*50 m[^.]*not contact with the surface", text.replace("\n", " "))


def test_truth_not_model_draws_no_inference_about_the_papers_truth():
    text = (RESULTS / "coastline_ekf" / "truth_not_model" / "README.md").read_text(encoding="utf-8")
    flat = " ".join(text.split())
    assert "points at the paper's truth" not in flat
    assert "*consistent* filter" in flat and "tesseral" in flat
