"""Study ``descent_gnc`` end to end on the tiny EV5 world: ``renderlab campaign`` → ``renderlab report``.

Real Mitsuba renders (64², 2 spp, an image every 300 s from the 200 m waypoint to touchdown), two landmark methods
each flying its own closed loop and the open-loop replay beside them, 2 runs. Checked against what the study does
not compute itself:

* contact is on the surface: the touchdown point's height above the target equals the site DEM's
  (``Site.height_at``) at its east/north offset;
* paired draws: within a run every method and mode starts from the same initial estimate; runs differ;
* the replay's true path does not depend on the method (one flight), the closed loops' paths do;
* the same seed gives the same tables byte for byte (an in-process run vs the campaign's, timings set apart);
* the summary's touchdown median and track-loss count are the numpy median / count of the run table;
* a filter told a pixel noise 1000× too small rejects images on their NIS, widens its search ×2, ×4 and records
  a track loss with that cause.
"""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from gnc_fixtures import TINY_GNC_SCENARIO as TINY

from renderlab.cli import main

RUNS = 2


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    d = tmp_path_factory.mktemp("gnc")
    (d / "tiny.toml").write_text(TINY)
    assert main(["campaign", str(d / "tiny.toml"), "--runs", str(RUNS), "--out", str(d / "camp"), "--workers", "0",
                 "--timings", "separate", "--quiet"]) == 0
    assert main(["report", str(d / "camp"), "--out", str(d / "report")]) == 0
    runs = sorted((d / "camp" / "runs").iterdir())
    return d, [pq.read_table(r / "gnc_runs.parquet") for r in runs], [pq.read_table(r / "gnc_images.parquet")
                                                                      for r in runs]


def _scenario(d, overrides=()):
    from renderlab.scenario import load_scenario

    return load_scenario(d / "tiny.toml", list(overrides))


def test_flights_touch_down_on_the_dem_with_paired_draws(campaign):
    from renderlab.campaign.cache import loaded_world
    from renderlab.scenario import scenario_from_dict, truth_dict

    d, run_tabs, _ = campaign
    sc, base = _scenario(d)
    site = loaded_world(scenario_from_dict(truth_dict(sc.to_dict())), base).plan.model.site
    starts = []
    for t in run_tabs:
        r = t.to_pydict()
        assert sorted(zip(r["method"], r["mode"])) == sorted((m, mo) for m in ("spc", "ncc_baseline")
                                                             for mo in ("closed", "replay"))
        assert all(td for td, lost in zip(r["touchdown"], r["track_lost"]) if not lost)
        for e, n, u, lost in zip(r["td_e_m"], r["td_n_m"], r["td_u_m"], r["track_lost"]):
            if not lost:                             # contact on the DEM (the target at 0, 0; a lost flight may
                assert abs(u - (site.height_at(e, n) - site.height_at(0.0, 0.0))) < 1e-6   # land off the site)
        kept = [math.hypot(e, n) for e, n, lost in zip(r["td_e_m"], r["td_n_m"], r["track_lost"]) if not lost]
        assert kept and max(kept) < 3.0
        assert len(set(r["init_pos_err_max_sigma"])) == 1 and len(set(r["init_vel_err_max_sigma"])) == 1
        starts.append(r["init_vel_err_max_sigma"][0])
        rep = [i for i, mo in enumerate(r["mode"]) if mo == "replay"]
        clo = [i for i, mo in enumerate(r["mode"]) if mo == "closed"]
        assert len({(r["td_e_m"][i], r["t_end_s"][i]) for i in rep}) == 1          # one replay flight
        assert len({(r["td_e_m"][i], r["t_end_s"][i]) for i in clo}) == len(clo)   # each method its own flight
        assert all(dv > 0 and p > 0 for dv, p in zip(r["delta_v_mps"], r["propellant_kg"]))
    assert starts[0] != starts[1]


def test_same_seed_reproduces_the_run_byte_for_byte(campaign):
    from renderlab.campaign.executors import split_timings
    from renderlab.studies.descent_gnc.study import run

    d, run_tabs, img_tabs = campaign
    sc, base = _scenario(d)
    plan = json.loads((d / "camp" / "campaign.json").read_text())["plan"]
    ss = np.random.SeedSequence(plan["seed"]["entropy"]).spawn(RUNS)[1]      # the campaign's run 1
    again, _ = split_timings(run(sc, base, 1, ss, d / "work"))
    for name, committed in (("gnc_runs", run_tabs[1]), ("gnc_images", img_tabs[1])):
        mine = again[name]
        for c in committed.column_names:
            a, b = committed.column(c), mine.column(c)
            if pa.types.is_floating(a.type) or pa.types.is_integer(a.type):
                assert np.asarray(a).tobytes() == np.asarray(b).tobytes(), c
            else:
                assert a.to_pylist() == b.to_pylist(), c


def test_report_numbers_follow_from_the_run_table(campaign):
    d, run_tabs, _ = campaign
    r = pa.concat_tables(run_tabs).to_pydict()
    rows = {(x["method"], x["mode"]): x for x in csv.DictReader(open(d / "report" / "gnc_summary.csv"))}
    assert len(rows) == 4
    for (m, mode), row in rows.items():
        sel = [i for i in range(len(r["run"])) if r["method"][i] == m and r["mode"][i] == mode]
        h = np.hypot(np.take(r["td_e_m"], sel), np.take(r["td_n_m"], sel))
        assert float(row["td_h_median_m"]) == pytest.approx(float(np.median(h)), rel=1e-5)
        assert int(row["track_lost_runs"]) == sum(r["track_lost"][i] for i in sel)
        assert row["anees_pass"] in ("True", "False")
    for f in ("gnc_landing_dispersion.png", "gnc_error_history.png", "gnc_consistency.png", "gnc_timeseries.csv",
              "gnc_track_loss.csv"):
        assert (d / "report" / f).is_file(), f
    assert "Conclusion" in (d / "report" / "index.html").read_text()


def test_an_overconfident_filter_rejects_images_widens_its_search_and_records_the_loss(campaign):
    from renderlab.studies.descent_gnc.study import run

    d, _, _ = campaign
    sc, base = _scenario(d, ['descent_gnc.methods=["spc"]', "descent_gnc.replay=false",
                             "descent_gnc.sigma_px=0.0003", "descent_gnc.sigma_ground_m=0.0",
                             "descent_gnc.star_tracker_sigma_arcsec=0.01", "descent_gnc.nis_reject_probability=0.9"])
    t = run(sc, base, 0, np.random.SeedSequence(5), d / "work")
    im, r = t["gnc_images"].to_pydict(), t["gnc_runs"].to_pydict()
    measured = [i for i, s in enumerate(im["status"]) if s != "no_landmarks"]
    assert [im["status"][i] for i in measured[:2]] == ["nis_rejected"] * 2
    assert [im["widen"][i] for i in measured[:3]] == [1.0, 2.0, 4.0][: len(measured[:3])]
    assert r["track_lost"] == [True] and r["loss_cause"] == ["nis_rejected"]
    assert r["loss_t_s"][0] == im["t_s"][measured[1]]


def test_published_folder_ships_the_columns_the_report_reads_and_reports_the_same(campaign):
    """``renderlab publish`` keeps only the columns the report reads (Study.publish_tables), records the full tables
    in raw_tables.json, and the report of the published folder writes the same CSVs as the raw campaign's."""
    import pyarrow.parquet as pq

    from renderlab.campaign.compact import read_raw_tables

    d, run_tabs, img_tabs = campaign
    assert main(["publish", "--out", str(d / "pub"), str(d / "camp")]) == 0
    assert main(["report", str(d / "pub"), "--tables-only"]) == 0
    raw = read_raw_tables(d / "pub" / "tables")
    for name, tabs in (("gnc_images", img_tabs), ("gnc_runs", run_tabs)):
        pub = pq.read_table(d / "pub" / "tables" / f"{name}.parquet")
        assert set(pub.column_names) < set(tabs[0].column_names) and "campaign" not in pub.column_names
        assert raw[name]["columns"] == tabs[0].column_names and raw[name]["rows"] == sum(t.num_rows for t in tabs)
        full = pa.concat_tables(tabs)
        for c in pub.column_names:                                       # the kept columns, bit for bit
            x, y = pub.column(c), full.column(c)
            if pa.types.is_floating(x.type):
                assert np.asarray(x).tobytes() == np.asarray(y).tobytes(), c
            else:
                assert x.to_pylist() == y.to_pylist(), c
    for f in ("gnc_summary.csv", "gnc_timeseries.csv", "gnc_track_loss.csv"):
        assert (d / "pub" / "report" / f).read_bytes() == (d / "report" / f).read_bytes(), f
