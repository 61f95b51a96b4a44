"""``renderlab measure --images``: a user's own images (written by OpenCV, and by astropy as FITS) + an a-priori file +
a maplet catalogue, no truth set. An imposed integer shift of the image comes back as the measured shift."""

from __future__ import annotations

import json

import numpy as np
import pyarrow.parquet as pq
import pytest
from terrain_fixtures import truthset  # noqa: F401  (the tiny rendered terrain truth set, fixture)
from terrain_fixtures import write_inputs as _write_inputs

from renderlab.cli import main

SHIFT = (2, 1)  # imposed (sample, line) shift, px


def _measure(tmp_path, ts_path, apriori, name, method="retina"):
    out = tmp_path / f"{name}.parquet"
    assert main(["measure", "--images", str(apriori), "--catalog", str(ts_path), "--method", method, "--out", str(out),
                 "--quiet"]) == 0
    return pq.read_table(out).to_pydict()


@pytest.mark.parametrize("method", ["retina", "ncc_baseline"])
def test_imposed_shift_is_measured(truthset, tmp_path, capsys, method):  # noqa: F811
    path, _ = truthset
    if not (path / "landmarks.parquet").is_file():
        pytest.skip("no catalog writer")
    a0 = _measure(tmp_path, path, _write_inputs(tmp_path, path, (0, 0), name="plain"), "plain", method)
    a1 = _measure(tmp_path, path, _write_inputs(tmp_path, path, SHIFT, name="shifted"), "shifted", method)
    assert np.all(np.isnan(a0["truth_s"])) and np.all(np.isnan(a0["err_s"]))  # no truth: unknown, not invented
    ok = np.array(a0["has_result"]) & np.array(a1["has_result"])
    assert ok.sum() >= 2 and a0["item"] == a1["item"] and a0["pred_s"] == a1["pred_s"]
    ds = np.array(a1["meas_s"])[ok] - np.array(a0["meas_s"])[ok]
    dl = np.array(a1["meas_l"])[ok] - np.array(a0["meas_l"])[ok]
    np.testing.assert_allclose(ds, SHIFT[0], atol=0.05)
    np.testing.assert_allclose(dl, SHIFT[1], atol=0.05)
    # the unshifted image measured at its true pose lands on the truth table of the set it came from
    from renderlab.files.truthset import TruthSet

    t = TruthSet.open(path).read_table("landmark_truth").to_pydict()
    truth = {i: (s, l) for f, i, s, l in zip(t["frame"], t["landmark_id"], t["s"], t["l"]) if f == 0}
    err = [np.hypot(ms - truth[i][0], ml - truth[i][1]) for i, ms, ml, h in
           zip(a0["item"], a0["meas_s"], a0["meas_l"], a0["has_result"]) if h]
    assert max(err) < 0.45


def test_fits_equals_png(truthset, tmp_path):  # noqa: F811
    path, _ = truthset
    if not (path / "landmarks.parquet").is_file():
        pytest.skip("no catalog writer")
    a = _measure(tmp_path, path, _write_inputs(tmp_path, path, SHIFT, "png", "p"), "p")
    b = _measure(tmp_path, path, _write_inputs(tmp_path, path, SHIFT, "fits", "f"), "f")
    assert a["meas_s"] == b["meas_s"] and a["meas_l"] == b["meas_l"]


def test_bad_inputs_one_line_and_nothing_written(truthset, tmp_path, capsys):  # noqa: F811
    path, _ = truthset
    good = _write_inputs(tmp_path, path, name="g")
    data = json.loads(good.read_text())
    cases = {"missing image": {**data, "images": [{**data["images"][0], "file": "nope.png"}]},
             "bad covariance": {**data, "images": [{**data["images"][0], "covariance": [[1, 0], [0, 1]]}]},
             "no images": {**data, "images": []},
             "nan position": {**data, "images": [{**data["images"][0], "position_m": [0, "nan", 0]}]}}
    for what, d in cases.items():
        f = tmp_path / f"bad_{what.replace(' ', '_')}.json"
        f.write_text(json.dumps(d))
        out = tmp_path / "out.parquet"
        assert main(["measure", "--images", str(f), "--catalog", str(path), "--method", "retina", "--out", str(out),
                     "--quiet"]) == 2, what
        err = capsys.readouterr().err
        assert err.startswith("renderlab: error:") and err.count("\n") == 1, (what, err)
        assert not out.exists(), what
    assert main(["measure", "--images", str(good), "--method", "retina", "--quiet"]) == 2
    assert "--catalog" in capsys.readouterr().err
