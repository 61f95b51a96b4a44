"""The a-priori file of ``renderlab measure --images``: a pydantic schema with a generated reference
(docs/apriori_file.md), ``frame`` checked against the catalogue's, image size checked against the camera, and an
exporter (``renderlab export TRUTHSET --apriori FILE``) whose file measures exactly what ``renderlab measure
TRUTHSET`` measures with the same seed (same a-priori draws, same images)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pyarrow.parquet as pq
import pytest
from terrain_fixtures import truthset  # noqa: F401  (the tiny rendered terrain truth set, fixture)
from terrain_fixtures import write_inputs as _write_inputs

from renderlab.cli import main
from renderlab.measurement import apriori


def test_committed_reference_is_fresh_and_its_example_reads():
    assert apriori.DOC.read_text(encoding="utf-8") == apriori.render(), (
        f"{apriori.DOC} is stale; regenerate it with `{apriori.REGENERATE}`")
    apriori.AprioriFile.model_validate(json.loads(apriori.EXAMPLE))
    text = apriori.render()
    for key in apriori.AprioriImageEntry.model_fields:
        assert f"| `{key}` |" in text


def _run_measure(apriori_path, catalog, out):
    return main(["measure", "--images", str(apriori_path), "--catalog", str(catalog), "--method", "retina",
                 "--out", str(out), "--quiet"])


def _one_line(capsys, *needles):
    err = capsys.readouterr().err
    assert err.startswith("renderlab: error:") and err.count("\n") == 1, err
    for n in needles:
        assert n in err, err


def test_frame_must_be_given_and_be_the_catalogues(truthset, tmp_path, capsys):  # noqa: F811
    path, _ = truthset
    good = _write_inputs(tmp_path, path, name="g")
    data = json.loads(good.read_text())
    out = tmp_path / "out.parquet"
    missing = tmp_path / "no_frame.json"
    missing.write_text(json.dumps({k: v for k, v in data.items() if k != "frame"}))
    assert _run_measure(missing, path, out) == 2  # the former reader took "BODY" silently
    _one_line(capsys, "missing key 'frame'")
    catalog = tmp_path / "catalog_ev5"  # a catalogue folder that records its frame, as an EV5 truth set does
    shutil.copytree(path, catalog)
    man = json.loads((catalog / "manifest.json").read_text())
    (catalog / "manifest.json").write_text(json.dumps({**man, "render_frame": {"name": "EV5_FIXED"}}))
    assert _run_measure(good, catalog, out) == 2
    _one_line(capsys, "frame is 'BODY'", "'EV5_FIXED'")
    assert not out.exists()
    right = tmp_path / "right.json"
    right.write_text(json.dumps({**data, "frame": "EV5_FIXED"}))
    assert _run_measure(right, catalog, out) == 0 and out.is_file()


def test_image_size_must_be_the_cameras(truthset, tmp_path, capsys):  # noqa: F811
    import cv2

    path, _ = truthset
    good = _write_inputs(tmp_path, path, name="g")
    data = json.loads(good.read_text())
    img = cv2.imread(str(tmp_path / "g.png"), cv2.IMREAD_UNCHANGED)
    assert cv2.imwrite(str(tmp_path / "crop.png"), img[:, :-4])  # 4 columns short
    bad = tmp_path / "crop.json"
    bad.write_text(json.dumps({**data, "images": [{**data["images"][0], "file": "crop.png"}]}))
    out = tmp_path / "out.parquet"
    assert _run_measure(bad, path, out) == 2
    w, h = data["camera"]["width"], data["camera"]["height"]
    _one_line(capsys, f"crop.png is {w - 4}x{h} px but the a-priori camera is {w}x{h} px")
    assert not out.exists()


@pytest.mark.parametrize("case, change, needle", [
    ("both uncertainties", {"covariance": np.eye(6).tolist()}, "not both"),
    ("no uncertainty", {"position_sigma_m": None}, "needs covariance"),
    ("asymmetric covariance", {"covariance": (np.eye(6) + np.triu(np.ones((6, 6)), 1)).tolist(),
                               "position_sigma_m": None, "attitude_sigma_deg": None}, "symmetric"),
    ("unknown key", {"sun_dir": [1, 0, 0]}, "unknown key 'images.0.sun_dir'"),
    ("boolean bits", "bits", "bits"),
])
def test_schema_refusals_are_one_line(truthset, tmp_path, capsys, case, change, needle):  # noqa: F811
    path, _ = truthset
    data = json.loads(_write_inputs(tmp_path, path, name="g").read_text())
    if change == "bits":
        data["bits"] = True
    else:
        entry = {**data["images"][0], **change}
        data["images"] = [{k: v for k, v in entry.items() if v is not None}]
    f = tmp_path / "bad.json"
    f.write_text(json.dumps(data))
    assert _run_measure(f, path, tmp_path / "out.parquet") == 2, case
    _one_line(capsys, needle)


def test_exported_apriori_measures_what_the_truthset_measures(truthset, tmp_path, capsys):  # noqa: F811
    from renderlab.files.truthset import TruthSet

    path, _ = truthset
    if not (path / "landmarks.parquet").is_file():
        pytest.skip("no catalog writer")
    ts = TruthSet.open(path)
    plain = tmp_path / "sub" / "plain.json"
    plain.parent.mkdir()
    assert main(["export", str(path), "--apriori", str(plain)]) == 0
    doc = json.loads(plain.read_text())
    assert doc["camera"] == ts.frames[0]["camera"] and doc["bits"] == 10 and len(doc["images"]) == len(ts)
    for rec, im in zip(ts.frames, doc["images"]):  # no seed: the true pose, image paths relative to the file
        assert (plain.parent / im["file"]).resolve() == (path / rec["dn"]).resolve()
        assert im["position_m"] == rec["pose"]["position_m"]
        q, qt = np.array(im["quat_body_from_cam_xyzw"]), np.array(rec["pose"]["quat_render_from_cam_xyzw"])
        assert min(np.abs(q - qt).max(), np.abs(q + qt).max()) < 1e-12
    assert main(["export", str(path), "--apriori", str(plain)]) == 2  # no silent overwrite
    capsys.readouterr()
    drawn = tmp_path / "drawn.json"
    common = ["--photometry", "fixed", "--quiet", "--method", "retina"]
    assert main(["export", str(path), "--apriori", str(drawn), "--apriori-seed", "7", "--apriori-sigma-pos-m", "0.2",
                 "--apriori-sigma-att-deg", "0.02"]) == 0
    assert main(["measure", "--images", str(drawn), "--catalog", str(path), "--out", str(tmp_path / "a.parquet"),
                 *common]) == 0
    assert main(["measure", str(path), "--seed", "7", "--sigma-pos-m", "0.2", "--sigma-att-deg", "0.02",
                 "--out", str(tmp_path / "b.parquet"), *common]) == 0
    a, b = (pq.read_table(tmp_path / f"{n}.parquet").to_pydict() for n in "ab")
    assert a["item"] == b["item"] and a["frame"] == b["frame"] and sum(a["has_result"]) >= 5
    for col in ("pred_s", "pred_l", "meas_s", "meas_l"):
        np.testing.assert_allclose(a[col], b[col], atol=1e-6, equal_nan=True)
    assert a["has_result"] == b["has_result"]
