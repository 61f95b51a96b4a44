"""Reports say what their numbers show: a sentence of conclusion per method built by fixed rules from the summary
rows, a section title without the repeated table name, no empty no-result plot and no reason drawn in a method's
colour, and the analytic-pointing report opening with what it measures (the lit-limb offset of a blob centre),
whose Lambert-sphere photocentre formula is checked against a direct integration over the disc."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from renderlab.report import conclusions, landmark_figures, style


def _row(axis, bias, lo, hi, rsig=0.2, gross=0.01, nores=0.0, n=100, ratio=None):
    r = {"method": "m", "axis": axis, "n_rows": n, "n_result": n, "bias_px": bias, "bias_px_lo": lo,
         "bias_px_hi": hi, "robust_sigma_px": rsig, "gross_rate": gross, "no_result_rate": nores}
    if ratio is not None:
        r["robust_sigma_over_crlb"] = ratio
    return r


def test_sentence_rules():
    zero = conclusions.landmark_sentence("retina", _row("s", 0.01, -0.02, 0.04, ratio=2.13),
                                         _row("l", -0.01, -0.03, 0.01, ratio=1.9), 1.0)
    assert "zero within its 95 % interval on both axes" in zero and "2.1× / 1.9× the registration CRLB" in zero
    assert "every row has a result" in zero and "1.0 % / 1.0 % of results beyond the 1 px" in zero
    biased = conclusions.landmark_sentence("spc", _row("s", 0.01, -0.02, 0.04), _row("l", 0.3, 0.2, 0.4, nores=0.1),
                                           1.0)
    assert "biased (+0.010, +0.300) px: the 95 % interval excludes zero on line" in biased
    assert "CRLB" not in biased  # no CRLB column, no ratio
    none = conclusions.landmark_sentence("x", {**_row("s", math.nan, math.nan, math.nan), "n_result": 0},
                                         _row("l", math.nan, math.nan, math.nan), 1.0)
    assert "no result on any of its 100 rows" in none
    assert conclusions.times(3983.2) == "3983×" and conclusions.times(2.13) == "2.1×"


def test_filter_sentence_words_follow_the_band():
    rows = [{"quantity": "anees", "mean": 7.0e7, "chi2_lo": 0.9, "chi2_hi": 1.1, "fraction_inside": 0.0},
            {"quantity": "anis", "mean": 1.0, "chi2_lo": 0.9, "chi2_hi": 1.1, "fraction_inside": 0.93},
            {"quantity": "err_r_m", "rms": 12.0}, {"quantity": "err_v_mps", "rms": 0.1}]
    s = conclusions.filter_sentence(rows)
    assert "ANEES 7e+07 is outside its 95 % χ² band [0.9, 1.1]: over-confident" in s
    assert "ANIS 1 is inside its 95 % χ² band [0.9, 1.1]: consistent (93 %" in s
    assert "largest RMS error is in r (m): 12" in s


def test_reason_colours_are_never_method_colours():
    faces = {landmark_figures.reason_style(j) for j in range(24)}
    assert len(faces) == 24  # 24 reasons before a style repeats
    assert not {f.lower() for f, _ in faces} & {c.lower() for c in style.OKABE_ITO}


def test_lambert_photocentre_against_integration():
    from estimators.centre_limb.phase import lambert_offset

    x = np.linspace(-1, 1, 1601)
    X, Y = np.meshgrid(x, x)
    inside = X ** 2 + Y ** 2 < 1
    Z = np.sqrt(np.clip(1 - X ** 2 - Y ** 2, 0, None))
    for deg in (0.0, 20.0, 45.0, 90.0, 135.0):
        a = math.radians(deg)
        mu0 = X * math.sin(a) + Z * math.cos(a)  # cos(incidence), Sun in the x-z plane, view along z
        w = np.where(inside & (mu0 > 0), mu0, 0.0)  # Lambert radiance ∝ cos(incidence)
        assert abs(float(lambert_offset(a)) - (w * X).sum() / w.sum()) < 2e-4, deg


@pytest.fixture(scope="module")
def analytic_report(tmp_path_factory):
    from campaign_fixtures import SCENE

    from renderlab.cli import main

    d = tmp_path_factory.mktemp("concl")
    tiny = ["camera.width=128", "camera.height=96", "camera.fx=131", "camera.fy=129", "camera.cx=65.6",
            "camera.cy=46.9", "render.spp=4", "trajectory.frames=2", "perturbations.attitude_sigma_deg=0.1"]
    assert main(["campaign", str(SCENE), "--runs", "2", "--out", str(d / "camp"), "--workers", "0", "--quiet",
                 *[a for kv in tiny for a in ("--set", kv)]]) == 0
    assert main(["report", str(d / "camp"), "--out", str(d / "rep")]) == 0
    return d


def test_analytic_report_opens_with_what_it_measures(analytic_report):
    import pyarrow as pa
    import pyarrow.parquet as pq

    from estimators.centre_limb.phase import lambert_offset

    page = (analytic_report / "rep" / "index.html").read_text()
    h2 = re.findall(r"<h2[^>]*>([^<]+)</h2>", page)
    assert h2[0] == "What this campaign measures" and "Landmark measurements" in h2
    assert "Landmark measurements: measurements" not in page
    assert "lit-limb offset" in page and page.count("Conclusion") >= 2
    t = pa.concat_tables([pq.read_table(p) for p in sorted((analytic_report / "camp").glob("runs/*/measurements.parquet"))])
    d = t.to_pydict()
    light = np.hypot(np.subtract(d["centre_of_light_s"], d["truth_s"]), np.subtract(d["centre_of_light_l"], d["truth_l"]))
    pred = lambert_offset(np.radians(d["phase_deg"])) * np.asarray(d["target_radius_px"])
    # the rendered truth's centre of light is the Lambert sphere's photocentre up to perspective, the box's shadow
    # and pixel sampling (11 px radius here)
    assert np.all(np.abs(light / pred - 1) < 0.25), light / pred
    if all(d["has_result"]):
        assert "Every row of every method has a result" in page
        assert not list((analytic_report / "rep").glob("*_reasons.png"))


def test_crlb_note_says_which_bound_the_table_carries():
    import pyarrow as pa

    from renderlab.report.conclusions import CRLB_NOTE_CONTINUOUS, CRLB_NOTE_FINITE_DIFFERENCE, crlb_note

    old = pa.table({"crlb_s": [0.01, 0.02], "crlb_l": [0.01, 0.02]})
    assert crlb_note(old) == CRLB_NOTE_FINITE_DIFFERENCE and "finite-difference" in crlb_note(old)
    new = old.append_column("crlb_bound", pa.array(["continuous", "continuous"]))
    assert crlb_note(new) == CRLB_NOTE_CONTINUOUS and "continuous truth" in crlb_note(new)
    mixed = old.append_column("crlb_bound", pa.array(["continuous", "finite_difference"]))
    assert crlb_note(mixed) == CRLB_NOTE_FINITE_DIFFERENCE  # one note per table: the mixed one is not continuous
