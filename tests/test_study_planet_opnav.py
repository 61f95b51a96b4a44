"""Study ``planet_opnav`` end to end at a tiny size: campaign → publish → report, through the real renderer, the
lab's and Basilisk's methods on the same images; same seed → the same table; its grid, kind and refusals.

Oracle for the geometry: each row's truth is the planet world's ``centre_truth`` of the rendered pose, and the range
and phase there are the cell's nominal ones (the camera is placed at them); the projected centre lies ``offset_deg``
off the principal point (``fx·tan``, the pinhole).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from renderlab.cli import main
from renderlab.errors import UserError

REPO = Path(__file__).resolve().parents[1]
SCENARIO = REPO / "results" / "planet_opnav" / "scenario.toml"
TINY = ["--set", "camera.width=96", "--set", "camera.height=96", "--set", "render.spp=2",
        "--set", "planet_opnav.ranges_m=[12.6e6]", "--set", "planet_opnav.phases_deg=[0.0, 90.0]"]


def _campaign(out: Path, seed: int, methods: str | None = None) -> Path:
    extra = ["--set", f"planet_opnav.methods={methods}"] if methods else []
    assert main(["campaign", str(SCENARIO), "--runs", "2", "--workers", "0", "--out", str(out), "--seed", str(seed),
                 "--quiet", *TINY, *extra]) == 0
    return out


def _table(folder: Path):
    import pyarrow as pa

    return pa.concat_tables([pq.read_table(p) for p in sorted((folder / "runs").glob("*/centre_limb.parquet"))])


@pytest.mark.skipif(not __import__("importlib").util.find_spec("Basilisk"), reason="the basilisk extra")
def test_tiny_campaign_publishes_and_reports(tmp_path, capsys):
    from renderlab.campaign.scoring import table_kind

    run = _campaign(tmp_path / "camp", 7)
    t = _table(run)
    assert table_kind(t) == "centre_limb"
    d = t.to_pandas()
    assert len(d) == 2 * 4 * 7 and set(d.method) == {"centroid_raw", "centroid_phase", "limb_ellipse", "horizon_opnav",
                                                   "bsk_hough_circles", "bsk_hough_pixel_line", "bsk_limb_horizon"}
    assert sorted(d.cell.unique()) == [0, 1, 2, 3] and set(d.law) == {"lambert", "lommel_seeliger"}
    assert np.allclose(d.true_range_m, d.range_nominal_m, rtol=1e-9)
    assert np.allclose(d.phase_deg, d.phase_nominal_deg, atol=1e-6)
    fx = 48.0 / math.tan(math.radians(10.0))
    assert np.allclose(d.true_centre_s - 47.5, fx * math.tan(math.radians(2.0)), atol=0.1)
    for _key, g in d.groupby(["run", "cell"]):             # every method saw the same image: the same truth row
        assert g.true_centre_s.nunique() == 1 and g.true_radius_px.nunique() == 1
    ok = d[d.reason == "ok"]
    assert (ok.groupby("method").size() >= 6).all()        # every method measures most of these images
    err = np.hypot(ok.centre_s - ok.true_centre_s, ok.centre_l - ok.true_centre_l) / ok.true_radius_px
    raw = (ok.method == "centroid_raw").to_numpy()
    assert float(err[~raw].max()) < 0.15                   # within 0.15 of the apparent radius (38 px here)
    assert float(err[raw & (ok.phase_nominal_deg == 90.0).to_numpy()].min()) > 0.2   # the uncorrected centroid
    assert main(["publish", str(run), "--out", str(tmp_path / "pub")]) == 0
    assert main(["report", str(tmp_path / "pub")]) == 0
    capsys.readouterr()
    page = (tmp_path / "pub" / "report" / "index.html").read_text()
    assert "Centre/limb: centre_limb" in page and "PASS/FAIL" in page and "bsk_limb_horizon" in page


def test_same_seed_same_table_other_seed_other_images(tmp_path):
    methods = '["horizon_opnav", "centroid_phase"]'
    a = _table(_campaign(tmp_path / "a", 3, methods)).drop(["t_ms"])
    b = _table(_campaign(tmp_path / "b", 3, methods)).drop(["t_ms"])
    c = _table(_campaign(tmp_path / "c", 4, methods)).drop(["t_ms"])
    assert a.schema == b.schema and a.to_pandas().equals(b.to_pandas())      # NaN where no value, in both
    assert not np.array_equal(a.column("centre_s").to_numpy(), c.column("centre_s").to_numpy())


def test_the_study_refuses_what_it_cannot_run(tmp_path):
    from renderlab.scenario import load_scenario
    from renderlab.studies.planet_opnav.run import check

    sc, _ = load_scenario(SCENARIO, ["planet_opnav.methods=[\"horizon_opnav\", \"hough\"]"])
    with pytest.raises(UserError, match="unknown centre_limb method 'hough'"):
        check(sc)
    for bad in ("planet_opnav.laws=[\"oren_nayar\"]", "planet_opnav.methods=[\"hough\"]", "world.kind=\"analytic\""):
        assert main(["campaign", str(SCENARIO), "--runs", "1", "--workers", "0", "--out", str(tmp_path / "x"),
                     "--set", bad]) == 2, bad
        assert not (tmp_path / "x").exists()
