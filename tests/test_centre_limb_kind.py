"""The centre/limb observable kind as registered: its parts load, its scorer against numpy/scipy on a table of known
errors, its runner's rows, its report section, and the conformance harness on every method registered for it.

Oracles: numpy means and standard deviations of the errors the table was built with; scipy's χ² quantiles; the
harness's exact ray-cast disc.
"""

from __future__ import annotations

import math

import numpy as np
import pyarrow as pa
import pytest

from renderlab import plugins
from renderlab.contracts.centre_limb import CENTRE_LIMB, CentreLimbResult
from renderlab.contracts.centre_limb_table import CENTRE_LIMB_CORE, CENTRE_LIMB_KNOWN
from renderlab.contracts.schemas import table_from_rows
from renderlab.measurement.centre_limb_runner import MeasuredImage, result_row, runner, truth_columns
from renderlab.measurement.conformance_centre_limb import check_centre_limb_method, disc_case

#: methods that fail the harness, and the rule: measured (see the tests of each)
EXPECTED_FAILURES = {"centroid_raw": "(a) centroid_raw: centre", "bsk_limb_horizon": "(a) bsk_limb_horizon: centre"}


def test_the_kind_is_registered_with_every_part():
    kind = plugins.observables.get("centre_limb")
    assert kind is CENTRE_LIMB
    assert kind.core_schema() == CENTRE_LIMB_CORE and kind.known_columns() == CENTRE_LIMB_KNOWN
    for part in ("runner", "scorer", "report_section", "conformance"):
        assert callable(kind.part(part)), part
    assert plugins.method_registry("centre_limb").group == kind.method_group


@pytest.mark.parametrize("name", plugins.method_registry("centre_limb").names())
def test_conformance_of_every_registered_method(name):
    if name.startswith("bsk_"):
        pytest.importorskip("Basilisk")
    fails = check_centre_limb_method(plugins.method_registry("centre_limb").get(name))
    if name in EXPECTED_FAILURES:
        assert len(fails) == 1 and fails[0].startswith(EXPECTED_FAILURES[name]), fails
    else:
        assert fails == [], fails


def _table(bias, sigma, claimed_sigma, n_draws=40, seed=3):
    """Rows of known errors: cell c has centre bias bias[c] (px, both axes), N(0, sigma²) noise, a claimed covariance
    claimed_sigma² I, and a range error of 1e-3 + N(0, 1e-4²) relative with a matching position covariance."""
    rng = np.random.default_rng(seed)
    truth = {"centre_s": 100.0, "centre_l": 80.0, "limb_centre_s": 100.1, "limb_centre_l": 80.1,
             "apparent_radius_px": 40.0, "range_m": 1.0e7, "los_cam_x": 0.0, "los_cam_y": 0.0, "los_cam_z": 1.0,
             "phase_deg": 30.0}
    cam = type("Cam", (), {"fx": 500.0})()
    rows, errs = [], []
    for c, b in enumerate(bias):
        for k in range(n_draws):
            e = b + sigma * rng.standard_normal(2)
            dr = 1e-3 + 1e-4 * rng.standard_normal()
            res = CentreLimbResult(centre_s=100.0 + e[0], centre_l=80.0 + e[1],
                                   cov_centre_px2=np.eye(2) * claimed_sigma**2,
                                   r_cam_m=np.array([0.0, 0.0, 1.0e7 * (1 + dr)]),
                                   cov_r_cam_m2=np.diag([1e6, 1e6, (1e3 + 0.0) ** 2]))
            rows.append({"campaign": "t", "run": k, "frame": 0, "cell": c, "method": "m", **result_row(res),
                         **truth_columns(truth, cam), "law": "lambert" if c % 2 else "lommel_seeliger",
                         "range_nominal_m": 1e7, "phase_nominal_deg": 30.0, "draw": k})
            errs.append((c, e, dr))
    return table_from_rows(rows, CENTRE_LIMB_KNOWN, "centre_limb"), errs


def test_scorer_against_numpy_on_known_errors():
    scorer = CENTRE_LIMB.part("scorer")
    t, errs = _table(bias=[0.3, -0.1, 0.2, 0.0, 0.5, 0.1], sigma=0.2, claimed_sigma=0.2)
    q = {r["quantity"]: r for r in scorer(t) if r["group"] == "all"}
    e = np.array([x[1] for x in errs])
    cells = np.array([x[0] for x in errs])
    assert q["bias_s"]["estimate"] == pytest.approx(e[:, 0].mean(), abs=1e-12)
    assert q["bias_s"]["lo"] < q["bias_s"]["estimate"] < q["bias_s"]["hi"]
    resid = np.concatenate([e[cells == c, 0] - e[cells == c, 0].mean() for c in range(6)])
    assert q["noise_s"]["estimate"] == pytest.approx(np.sqrt(np.mean(resid**2) * 40 / 39), rel=1e-9)
    assert q["noise_s"]["lo"] < 0.2 < q["noise_s"]["hi"]                      # the σ the rows were drawn with
    dr = np.array([x[2] for x in errs])
    assert q["bias_range_rel"]["estimate"] == pytest.approx(dr.mean(), rel=1e-6)
    assert q["los_rms_urad"]["estimate"] == pytest.approx(1e6 * np.sqrt(np.mean(np.sum(e**2, 1))) / 500.0, rel=1e-9)
    nees = np.sum(e**2, 1) / 0.04
    assert q["anees_centre"]["estimate"] == pytest.approx(nees.mean(), rel=1e-9)
    from scipy.stats import chi2

    n = len(nees)
    assert q["anees_centre"]["band_hi"] == pytest.approx(chi2.ppf(0.975, 2 * n) / n)
    assert q["anees_centre"]["inside"] is False                  # the biases make the claimed σ over-confident
    assert q["result_rate"]["estimate"] == 1.0
    groups = {r["group"] for r in scorer(t)}
    assert groups == {"all", "lambert", "lommel_seeliger"}


def test_nees_passes_for_an_honest_covariance_and_fails_for_a_tight_one():
    scorer = CENTRE_LIMB.part("scorer")
    honest, _ = _table(bias=[0.0] * 6, sigma=0.2, claimed_sigma=0.2)
    tight, _ = _table(bias=[0.0] * 6, sigma=0.2, claimed_sigma=0.1)
    a = {r["quantity"]: r for r in scorer(honest) if r["group"] == "all"}
    b = {r["quantity"]: r for r in scorer(tight) if r["group"] == "all"}
    assert a["anees_centre"]["inside"] is True and b["anees_centre"]["inside"] is False
    assert b["anees_centre"]["estimate"] == pytest.approx(4 * a["anees_centre"]["estimate"], rel=1e-9)


def test_runner_rows_and_method_errors():
    truth_sl, rng, frame = disc_case()
    truth = {"centre_s": truth_sl[0], "centre_l": truth_sl[1], "limb_centre_s": math.nan,
             "limb_centre_l": math.nan, "apparent_radius_px": 44.7, "range_m": rng, "los_cam_x": 0.0,
             "los_cam_y": 0.0, "los_cam_z": 1.0, "phase_deg": 0.0}

    class Raises:
        name = "raises"

        def measure(self, frame):
            raise RuntimeError("boom")

    run = CENTRE_LIMB.part("runner")
    good = run(plugins.method_registry("centre_limb").get("horizon_opnav")(),
               [MeasuredImage(frame, truth, {"cell": 7})])
    bad = run(Raises(), [MeasuredImage(frame, truth, {"cell": 7})])
    assert good[0]["reason"] == "ok" and good[0]["cell"] == 7 and abs(good[0]["range_m"] / rng - 1) < 1e-3
    assert bad[0]["reason"] == "method_error" and "boom" in bad[0]["diagnostics"] and math.isnan(bad[0]["centre_s"])
    t = table_from_rows(good + bad, pa.schema([f for f in CENTRE_LIMB_CORE if f.name not in ("campaign", "run")]),
                        "centre_limb")
    assert set(CENTRE_LIMB_CORE.names) - {"campaign", "run"} <= set(t.column_names)
    assert runner is run


def test_report_section_writes_figures_tables_and_verdicts(tmp_path):
    from renderlab.contracts.observable import ReportContext

    t, _ = _table(bias=[0.3, -0.1, 0.2, 0.0], sigma=0.2, claimed_sigma=0.2, n_draws=10)
    section, rows, head = CENTRE_LIMB.part("report_section")("centre_limb", t, tmp_path, ReportContext())
    assert {"centre_limb_bias.png", "centre_limb_nees.png", "centre_limb_cells.csv",
            "centre_limb_summary.csv"} <= {p.name for p in tmp_path.iterdir()}
    text = " ".join(b.get("html", "") + b.get("text", "") for b in section["blocks"])
    assert "FAIL" in text and "<b>m</b>" in text and "cluster bootstrap over the 4 grid cells" in text
    assert rows == [] and head.startswith("centre_limb: 1 centre/limb methods")   # the rows are in the CSV


def test_the_generic_path_measures_the_kind_by_name():
    from renderlab.campaign.scoring import table_kind
    from renderlab.measurement.kinds import measure_frames

    truth_sl, rng, frame = disc_case()
    truth = {"centre_s": truth_sl[0], "centre_l": truth_sl[1], "limb_centre_s": math.nan,
             "limb_centre_l": math.nan, "apparent_radius_px": 44.7, "range_m": rng, "los_cam_x": 0.0,
             "los_cam_y": 0.0, "los_cam_z": 1.0, "phase_deg": 0.0}
    t = measure_frames("centre_limb", "limb_ellipse", [MeasuredImage(frame, truth, {"cell": 3, "law": "lambert"})],
                       campaign="c", run=2)
    assert table_kind(t) == "centre_limb" and t.num_rows == 1
    row = t.to_pylist()[0]
    assert row["campaign"] == "c" and row["run"] == 2 and row["cell"] == 3 and row["law"] == "lambert"
    assert math.hypot(row["centre_s"] - truth_sl[0], row["centre_l"] - truth_sl[1]) < 0.05
