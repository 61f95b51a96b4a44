"""The registration CRLB from noisy renders (cross-product Fisher) and the error budget's CRLB probe (its report rows;
the probe itself is ``investigations/error_budget/crlb_probe.py``)."""

from __future__ import annotations

import math

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from renderlab.campaign.scoring import fisher_information, registration_crlb, template_shift_covariance
from renderlab.studies.retina_vs_spc.budget import crlb as BC


def _analytic_image(n: int = 48):
    """A smooth image and its exact gradients: I = 200 + 60 sin(a x + b y) + 40 cos(c x − d y)."""
    y, x = np.mgrid[0:n, 0:n].astype(float)
    a, b, c, d = 0.31, 0.17, 0.12, 0.27
    img = 200 + 60 * np.sin(a * x + b * y) + 40 * np.cos(c * x - d * y)
    gs = 60 * a * np.cos(a * x + b * y) - 40 * c * np.sin(c * x - d * y)
    gl = 60 * b * np.cos(a * x + b * y) + 40 * d * np.sin(c * x - d * y)
    return img, gs, gl


def _analytic_crlb(gs, gl, var):
    """√diag J⁻¹ with J from the exact gradients over the pixels the stencil keeps (two each border left out)."""
    k = (slice(2, -2), slice(2, -2))
    J = np.array([[np.sum(gs[k] ** 2), np.sum(gs[k] * gl[k])], [np.sum(gs[k] * gl[k]), np.sum(gl[k] ** 2)]]) / var
    C = np.linalg.inv(J)
    return math.sqrt(C[0, 0]), math.sqrt(C[1, 1])


def test_cross_product_matches_the_analytic_crlb_where_one_noisy_copy_is_biased_low():
    img, gs, gl = _analytic_image()
    var = 4.0  # the sensor noise the bound is for (DN²)
    truth = _analytic_crlb(gs, gl, var)
    assert registration_crlb(img, var) == pytest.approx(truth, rel=2e-3)  # the stencil on the clean image
    rng = np.random.default_rng(11)
    sd_mc = 12.0  # render noise, fixed in each copy
    cross, single = [], []
    for _ in range(20):
        a, b = img + rng.normal(0, sd_mc, img.shape), img + rng.normal(0, sd_mc, img.shape)
        cross.append(registration_crlb(a, var, independent=b))
        single.append(registration_crlb(a, var))
    cross, single = np.array(cross), np.array(single)
    assert cross.mean(0) == pytest.approx(truth, rel=0.02)
    # one copy adds Σ c² σ_mc² = (130/144)·144 DN² per pixel and axis to the gradient energy: predicted bias
    k = (slice(2, -2), slice(2, -2))
    extra = 130 / 144 * sd_mc ** 2
    pred = (math.sqrt(var / (np.sum(gs[k] ** 2) + extra * gs[k].size)), math.sqrt(var / (np.sum(gl[k] ** 2) + extra * gl[k].size)))
    single_axis = np.array([registration_crlb(img + rng.normal(0, sd_mc, img.shape), var, full=False) for _ in range(20)])
    assert single_axis.mean(0) == pytest.approx(pred, rel=0.02)
    assert np.all(single.mean(0) < 0.85 * np.array(truth))  # biased low by > 15 %
    assert np.all(cross.mean(0) > 0.95 * np.array(truth))


def test_cross_product_of_one_image_with_itself_is_the_single_image_bound():
    img, _, _ = _analytic_image(32)
    noisy = img + np.random.default_rng(2).normal(0, 3.0, img.shape)
    var = np.full(img.shape, 2.5)
    assert registration_crlb(noisy, var, independent=noisy) == pytest.approx(registration_crlb(noisy, var), rel=1e-12)
    J = fisher_information(noisy, var, independent=img)
    assert J[0, 1] == pytest.approx(J[1, 0])


def test_cross_product_of_pure_noise_is_not_positive_definite():
    """Two independent noise images carry no shift information: the cross-product J is about 0 (either sign)
    and the bound infinite; one noise image alone would claim a finite bound."""
    rng = np.random.default_rng(5)
    flat = np.full((40, 40), 100.0)
    a, b = flat + rng.normal(0, 5, flat.shape), flat + rng.normal(0, 5, flat.shape)
    one = registration_crlb(a, 1.0)
    assert np.all(np.isfinite(one))
    J = fisher_information(a, 1.0, independent=b)
    J_one = fisher_information(a, 1.0)
    assert abs(J[0, 0]) < 0.1 * J_one[0, 0] and abs(J[1, 1]) < 0.1 * J_one[1, 1]
    assert registration_crlb(a, 1.0, independent=flat) == (math.inf, math.inf)  # J = 0 exactly


def test_independent_image_of_another_shape_is_refused():
    with pytest.raises(ValueError, match="shape"):
        registration_crlb(np.ones((10, 10)), 1.0, independent=np.ones((10, 11)))


def test_template_equal_to_the_image_up_to_gain_and_offset_reaches_the_crlb():
    img, _, _ = _analytic_image(40)
    var = np.full(img.shape, 3.0)
    out = template_shift_covariance(0.02 * img - 1.5, img, var)
    assert out["sandwich"] == pytest.approx(registration_crlb(img, var), rel=1e-9)
    assert out["crlb"] == pytest.approx(registration_crlb(img, var), rel=1e-9)
    assert out["rho"] == pytest.approx((1.0, 1.0))


def test_template_missing_a_texture_component_matches_the_analytic_sandwich():
    """Image = three sinusoids, template = the first two: cov = H⁻¹ B H⁻ᵀ from the exact gradients."""
    n = 48
    y, x = np.mgrid[0:n, 0:n].astype(float)
    waves = [(60, 0.31, 0.17), (35, 0.09, -0.33), (40, 0.22, 0.05)]  # amplitude, x and y wavenumbers
    comp = [A * np.sin(p * x + q * y) for A, p, q in waves]
    grad = [np.stack([A * p * np.cos(p * x + q * y), A * q * np.cos(p * x + q * y)], -1) for A, p, q in waves]
    first = comp[0] + comp[1]
    img = 200 + first + comp[2]
    g1, g2 = grad[0] + grad[1], grad[2]
    k = (slice(2, -2), slice(2, -2))
    Gt, Gi = g1[k].reshape(-1, 2), (g1 + g2)[k].reshape(-1, 2)
    var = 4.0
    H, B, J = Gt.T @ Gi / var, Gt.T @ Gt / var, Gi.T @ Gi / var
    Hi = np.linalg.inv(H)
    want = np.sqrt(np.diag(Hi @ B @ Hi.T))
    out = template_shift_covariance(first, img, var)
    assert out["sandwich"] == pytest.approx(tuple(want), rel=0.01)
    assert out["crlb"] == pytest.approx(tuple(np.sqrt(np.diag(np.linalg.inv(J)))), rel=0.01)
    assert np.all(np.array(out["sandwich"]) >= np.array(out["crlb"]))  # Cauchy–Schwarz
    assert out["sandwich"][0] > 1.05 * out["crlb"][0]  # the missing (mostly s-directed) wave costs on s


def test_template_with_too_few_valid_pixels_gives_nan():
    img, _, _ = _analytic_image(20)
    mask = np.zeros(img.shape, bool)
    mask[5:9, 5:9] = True  # 4 x 4: nothing keeps ±2 valid neighbours
    out = template_shift_covariance(img, img, 1.0, mask)
    assert out["pixels"] == 0 and all(math.isnan(v) for v in out["sandwich"])


def _budget_like(noise_sd: float, bound: float, runs: int = 12, landmarks: int = 30):
    """A budget-shaped measurement table of the sensor-noise configuration: ``landmarks`` landmark-frames,
    errors N(bias, noise_sd²) per run, table CRLB ``bound`` px; and a probe table whose clean bound is 2 × it."""
    rng = np.random.default_rng(7)
    rows = {c: [] for c in ("config", "run", "frame", "item", "method", "reason", "err_s", "err_l", "crlb_s",
                            "crlb_l", "gsd_ratio", "shadow_fraction", "has_result", "truth_visible")}
    for i in range(landmarks):
        bias = rng.normal(0, 0.1, 2)
        for r in range(runs):
            e = bias + rng.normal(0, noise_sd, 2)
            for c, v in zip(rows, ("sensor_noise", r, i % 3, i, "retina", "", e[0], e[1], bound, bound,
                                   0.4 + 0.1 * (i % 20), 0.0, True, True)):
                rows[c].append(v)
    meas = pa.table(rows)
    configs = pa.table({"config": ["all_off", "sensor_noise"], "source": ["", "sensor_noise"], "runs": [1, runs]})
    probe = {c: [] for c in ("frame", "item", "estimate", "crlb_s", "crlb_l", "render_sd_dn", "sensor_sd_dn",
                             "gradient_rms_dn")}
    for i in range(landmarks):
        for est in BC.ESTIMATES:
            f = {"budget": 1.0, "second": 1.0, "cross": 2.0, "high_a": 1.9, "high_b": 1.99, "clean": 2.0,
                 "footprint": 2.5, "template": 4.0}[est]
            for c, v in zip(probe, (i % 3, i, est, f * bound, f * bound, 3.0, 5.0, 4.0)):
                probe[c].append(v)
    return meas, configs, pa.table(probe)


def test_report_rows_give_the_noise_over_each_bound():
    noise_sd, bound = 0.02, 0.01
    meas, configs, probe = _budget_like(noise_sd, bound)
    rows = BC.report_rows(meas, configs, probe)
    ratio = {r["estimate"]: r for r in rows if r["kind"] == "crlb_ratio"}
    assert ratio["budget"]["median"] == pytest.approx(0.5) and ratio["cross"]["median"] == pytest.approx(1.0)
    nr = {r["estimate"]: r for r in rows if r["kind"] == "noise_over_crlb" and r["band"] == "all"}
    # rms of the sample sd / CRLB: noise_sd / bound = 2 with the table's bound, 1 with the clean (2 × bound)
    assert nr["table"]["value"] == pytest.approx(noise_sd / bound, rel=0.1)
    assert nr["clean"]["value"] == pytest.approx(noise_sd / (2 * bound), rel=0.1)
    assert nr["table"]["value"] / nr["clean"]["value"] == pytest.approx(2.0, rel=1e-9)
    assert nr["clean"]["lo"] < nr["clean"]["value"] < nr["clean"]["hi"]
    assert nr["template"]["value"] == pytest.approx(nr["table"]["value"] / 4, rel=1e-9)
    w = next(r for r in rows if r["kind"] == "window_noise")
    assert w["predicted_ratio"] == pytest.approx(math.sqrt(16 / (16 + 130 / 144 * 9)))
    assert "| retina | all |" in BC.markdown(rows)
    assert len({tuple(r) for r in rows}) == 1  # one CSV header


def test_crlb_probe_refuses_a_folder_that_is_no_budget(tmp_path):
    """The probe that makes the table (``investigations/error_budget/crlb_probe.py``, run, not imported): a folder
    without the budget's tables is one line, exit 2, nothing written."""
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    r = subprocess.run([sys.executable, "investigations/error_budget/crlb_probe.py", str(tmp_path)], cwd=repo,
                       capture_output=True, text=True, timeout=300)
    err = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(err) == 1 and err[0].startswith("renderlab: error:") and "budget_measurements" in err[0]
    assert not (tmp_path / "tables").exists()


def test_published_probe_table_reproduces_the_budget_bound():
    """The probe's ``budget`` estimate (its own 8-spp render, same seed) is the budget's CRLB column."""
    from pathlib import Path

    folder = Path(__file__).resolve().parents[1] / "results" / "error_budget"
    probe = BC.read_probe(folder)
    if probe is None:
        pytest.skip("results/error_budget has no budget_crlb table")
    meas = pq.read_table(folder / "tables" / "budget_measurements.parquet",
                         columns=["config", "frame", "item", "crlb_s", "crlb_l"]).to_pydict()
    table = {(f, i): (s, l) for c, f, i, s, l in zip(*meas.values()) if c == "sensor_noise" and np.isfinite(s)}
    mine = BC._bounds(probe)["budget"]
    common = [k for k in table if k in mine]
    assert len(common) >= 0.9 * len(table)
    a = np.array([table[k] for k in common])
    b = np.array([mine[k] for k in common])
    rel = np.abs(a / b - 1)
    # the same render up to a few pixels (the truth code changed since the budget's render, docstrings and the
    # shadow switch): 13 of 192 windows differ, by at most 0.6 %
    assert np.median(rel) < 1e-5 and rel.max() < 0.01
