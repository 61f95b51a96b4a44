"""The geometric coastline study as a campaign: the ``[coastline]`` scenario section, the mapping of the
scenario onto the study, ``renderlab campaign`` + ``renderlab report``, and the ``truth_j2`` option.

Oracles: the Earth world's own orbit (Kepler, independent of the study's RK4) and astropy's GCRS → ITRS for the
mapping; Vallado's secular J2 nodal rate (eq. 9-41) for ``truth_j2``; the χ²
band for the inconsistency a J2 truth causes in a two-body filter without process noise.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from renderlab.errors import UserError

SHORT = ["coastline.duration_s=900"]


def _scenario(repo, *overrides):
    from renderlab.scenario import load_scenario

    return load_scenario(repo / "scenes/coastline_ekf.toml", list(overrides))


@pytest.mark.parametrize("override, message", [
    ("coastline.mode=sideways", "coastline.mode"),
    ("coastline.sigma_theta_mrad=0", "coastline.sigma_theta_mrad"),
    ("coastline.points_per_image=0", "coastline.points_per_image"),
    ("coastline.cadence=3", "unknown key 'coastline.cadence'"),
])
def test_bad_section_values_are_user_errors(repo, override, message):
    with pytest.raises(UserError, match=message.replace(".", r"\.")):
        _scenario(repo, override)


def test_study_refuses_what_it_does_not_model(repo):
    from renderlab.studies.coastline_ekf.study import geometric_options

    for override, key in (("perturbations.attitude_sigma_deg=0.1", "perturbations.attitude_sigma_deg"),
                          ("perturbations.focal_length_sigma_frac=0.01", "perturbations.focal_length_sigma_frac"),
                          ("perturbations.apriori_position_sigma_m=[0,0,0]", "apriori_position_sigma_m"),
                          ("trajectory.eccentricity=0.01", "eccentricity")):
        sc, _ = _scenario(repo, override)
        with pytest.raises(UserError, match=key.replace(".", r"\.")):
            geometric_options(sc)


def test_scenario_maps_onto_the_earth_worlds_orbit(repo):
    """The study's truth orbit (RK4 two-body) is the Earth world's (GCRF, Kepler) to < 1 m; the world's ITRF position
    is astropy's GCRS → ITRS of it (< 0.5 m); the study's simplified Earth (a uniform rotation gmst0 + ω⊕t about the
    inertial z axis) is off the real GCRF → ITRF by the precession-nutation since J2000 (< 0.4°: 0.30° measured)."""
    import astropy.units as u
    from astropy.coordinates import GCRS, ITRS, CartesianRepresentation

    from renderlab.studies.coastline_ekf.geometric import _R3, OMEGA_EARTH, truth_geometry
    from renderlab.studies.coastline_ekf.study import geometric_options
    from renderlab.worlds.earth import orientation, wgs84
    from renderlab.worlds.earth.plan import EarthPlan

    sc, _ = _scenario(repo, *SHORT, "trajectory.start_s=600", "trajectory.raan_deg=30", "trajectory.true_anomaly_deg=10")
    o = geometric_options(sc)
    assert (o.cadence_s, o.t0_s, o.duration_s) == (30.0, 600.0, 900.0)
    assert o.sigma_theta_rad == pytest.approx(5e-4) and o.sigma_star_tracker_rad == pytest.approx(math.radians(5 / 3600))
    geo = truth_geometry(o)
    world_sc = sc.model_copy(update={"trajectory": sc.trajectory.model_copy(update={"frames": len(geo.t_s)})})
    plan = EarthPlan.from_scenario(world_sc)
    times = orientation.utc_times(wgs84.parse_epoch(sc.trajectory.epoch_utc), geo.t_s)
    for k in (0, len(geo.t_s) // 2, len(geo.t_s) - 1):
        st = plan.states[k]
        assert st["t"] == pytest.approx(geo.t_s[k])
        assert np.linalg.norm(geo.x_true[k, :3] - st["r_eci"]) < 1.0                      # m
        gcrs = GCRS(CartesianRepresentation(np.asarray(st["r_eci"]) * u.m), obstime=times[k])
        r_itrs = gcrs.transform_to(ITRS(obstime=times[k])).cartesian.xyz.to_value(u.m)
        assert np.linalg.norm(r_itrs - st["r_ecef"]) < 0.5                                 # world = astropy
        r_study = _R3(o.gmst0_rad + OMEGA_EARTH * geo.t_s[k]) @ geo.x_true[k, :3]
        off = math.degrees(math.acos(np.dot(r_study, r_itrs) / np.linalg.norm(r_study) / np.linalg.norm(r_itrs)))
        print(f"t = {geo.t_s[k]:.0f} s: study's simplified Earth vs GCRF→ITRF: {off:.3f}° "
              f"({np.linalg.norm(r_study - r_itrs) / 1e3:.1f} km)")
        assert off < 0.4
    assert geo.n_meas.sum() > 0


def test_campaign_and_report(repo, tmp_path):
    from renderlab.campaign.plan import make_plan, run_seed_sequence
    from renderlab.campaign.runner import run_campaign_file
    from renderlab.report.campaign_report import make_report
    from renderlab.studies.coastline_ekf.study import run

    out = tmp_path / "camp"
    res = run_campaign_file(repo / "scenes/coastline_ekf.toml", out, 3, overrides=SHORT, workers=0, progress=False)
    assert res.executed == 3 and not res.failed
    t = pq.read_table(out / "runs/000002/coastline_filter.parquet")
    assert t.num_rows == 31 and t["n_meas"].to_numpy().sum() > 0
    sc, base = _scenario(repo, *SHORT)
    again = run(sc, base, 2, run_seed_sequence(sc.campaign.seed, 2), tmp_path)["coastline_filter"]
    for name in again.column_names:                                  # run 2 replays alone, bit for bit
        np.testing.assert_array_equal(again[name].to_numpy(), t[name].to_numpy())
    page = make_report(out, tmp_path / "report").read_text()
    for f in ("coastline_filter_coastline_errors.png", "coastline_filter_coastline_consistency.png",
              "coastline_filter_coastline_steady_state.csv"):
        assert (tmp_path / "report" / f).is_file()
    assert not list((tmp_path / "report").glob("*.svg")), "SVG only under renderlab report --svg"
    # the study reports its filter table itself (Study.own_tables): no generic section duplicating it
    assert not (tmp_path / "report" / "coastline_filter_errors.png").exists() and "Filter: coastline_filter" not in page
    assert "ANEES inside its 99" in page and "χ² band low (99 %)</th><th" in page
    assert page.index("χ² band low") < page.index("χ² band high") and 'class="badge' in page
    section = page[page.index("Coastline EKF (Straub"):]
    assert "_m<" not in section and "_mps" not in section and "time (h)" not in page   # no raw column names; one unit
    earth_sc, earth_base = _scenario(repo)
    assert make_plan(earth_sc.model_copy(update={"campaign": earth_sc.campaign.model_copy(update={"study": ""})}),
                     earth_base, 1).study == "coastline_ekf"                # default study of world kind earth


def test_truth_j2_option(repo):
    """``truth_j2``: the truth's node drifts at Vallado's secular J2 rate; the two-body filter (q = 0) then
    fails its χ² test, which is what the option is for."""
    from renderlab.dynamics.orbits import OrbitElements, j2_nodal_rate, raan_of
    from renderlab.studies.coastline_ekf.geometric import R_EARTH_M, paper_orbit, run_batch, truth_geometry
    from renderlab.studies.coastline_ekf.scoring import chi2_band

    o = paper_orbit("i45_h1000", cadence_s=60.0)
    o = replace(o, truth_j2=True, duration_s=3 * o.period_s).validate()
    geo = truth_geometry(o)
    raan = np.unwrap(raan_of(geo.x_true[:, :3], geo.x_true[:, 3:]))
    rate = np.polyfit(geo.t_s, raan, 1)[0]
    expected = j2_nodal_rate(OrbitElements(R_EARTH_M + o.altitude_m, 0.0, o.inclination_rad))
    assert rate == pytest.approx(expected, rel=0.03)            # measured 1.2 % (short-period terms)
    seeds = np.random.SeedSequence(7).spawn(20)
    short = replace(o, duration_s=1200.0, cadence_s=30.0).validate()
    def anees_at_end(opts):
        tbl = run_batch(opts, seeds)["table"]
        t = tbl["t_s"].to_numpy()
        return float(np.mean(tbl["nees"].to_numpy()[t == t.max()]))

    anees_j2, anees_2b = anees_at_end(short), anees_at_end(replace(short, truth_j2=False))
    print(f"ANEES at 1200 s: J2 truth {anees_j2:.1f}, two-body truth {anees_2b:.2f}")
    lo, hi = chi2_band(6.0, 20)
    assert lo <= anees_2b <= hi
    assert anees_j2 > 10 * hi



def test_demo_piece(tmp_path):
    """``run_demo_coastline`` (wired into ``renderlab demo``): campaign, report with figures, one summary line."""
    from renderlab.studies.coastline_ekf.study import run_demo_coastline

    r = run_demo_coastline(tmp_path, progress=False, runs=3)
    assert r["runs"] == 3 and r["failed"] == 0 and r["report"].is_file()
    for f in ("coastline_filter_coastline_errors.png", "coastline_filter_coastline_consistency.png"):
        assert (tmp_path / "coastline_report" / f).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert r["summary"].startswith("coastline EKF, 90°/1000 km, 3 runs") and "\n" not in r["summary"]
    ss = {k: float(v) for k, v in r["steady_state"].items() if k.startswith(("mc_", "filter_"))}
    for a in ("r", "i", "c"):                 # the images shrank the prior's 3σ = 1500 m (16 runs: 136/278/116 m)
        assert ss[f"filter_3sig_{a}_m"] < 500.0 and ss[f"mc_3sig_{a}_m"] < 3 * ss[f"filter_3sig_{a}_m"]


def test_report_section_flags_the_published_image_in_the_loop_inconsistency(repo, tmp_path):
    """On the published image-in-the-loop tables: ANEES at the end (8.95) and the total NIS per dof (0.60) are
    outside their 99 % bands → two FAIL badges, each with the study's known reason; units in the tables, the
    χ² bands low then high, the figure says how many runs are drawn of how many."""
    from renderlab.studies.coastline_ekf.study import report_sections

    d = repo / "results/coastline_ekf/image_in_the_loop"
    tables = {n: pq.read_table(d / "tables" / f"{n}.parquet") for n in ("coastline_filter", "coastline_frames")}
    [(title, body)] = report_sections(tables, tmp_path)
    assert "Straub" in title
    assert body.count('<span class="badge fail">FAIL</span>') == 2 and "badge pass" not in body
    assert "ANEES 8.95 is above its band [4.54, 7.69]" in body and "map error" in body
    assert "Total NIS / dof 0.597 is below its band" in body
    assert "<th class=\"l\">unit</th>" in body and ">mm/s<" in body
    assert body.index("χ² band low") < body.index("χ² band high")
    assert "25 of 32 runs drawn" in body and "time (s)" in body
    for f in ("errors", "consistency"):
        assert (tmp_path / f"coastline_filter_coastline_{f}.png").stat().st_size > 10_000
        assert not (tmp_path / f"coastline_filter_coastline_{f}.svg").exists()


def test_truth_model_from_the_scenario_reaches_the_geometric_study():
    """trajectory.truth_model = "zonal_dop853" makes the study's truth J2–J6 (DOP853) while the filter stays
    two-body: the truth orbit departs from the two-body one by kilometres within an orbit."""
    import numpy as np

    from renderlab.scenario import load_scenario
    from renderlab.studies.coastline_ekf.geometric import truth_geometry
    from renderlab.studies.coastline_ekf.study import geometric_options

    repo = Path(__file__).resolve().parents[1]
    sc, _ = load_scenario(repo / "scenes" / "coastline_ekf.toml", ["trajectory.truth_model=zonal_dop853"])
    o = geometric_options(sc)
    assert o.truth_model == "zonal_dop853" and o.zonal_degree == 6
    sc0, _ = load_scenario(repo / "scenes" / "coastline_ekf.toml")
    o0 = geometric_options(sc0)
    assert o0.truth_model == "j2_rk4"
    d = np.linalg.norm(truth_geometry(o).x_true[:, :3] - truth_geometry(o0).x_true[:, :3], axis=1)
    assert d[0] < 1e-6 and d.max() > 1e3


def test_reduced_filter_tables_give_the_report_of_the_raw_ones(repo, tmp_path):
    """A published campaign folder in the image folder's layout (the campaign's filter table and its geometric twin):
    its report from the raw tables and from the study's ``publish_tables`` of them (``renderlab publish`` and
    ``compact_folder`` apply it) write the same CSVs (steady state per table, the comparison of the modes)."""
    import json
    import shutil

    from renderlab.campaign import store
    from renderlab.campaign.compact import compact_folder
    from renderlab.campaign.runner import run_campaign_file
    from renderlab.cli import main as cli
    from renderlab.studies.coastline_ekf.publish import publish_tables

    camp, raw, red = tmp_path / "camp", tmp_path / "raw", tmp_path / "reduced"
    run_campaign_file(repo / "scenes/coastline_ekf.toml", camp, 3, overrides=SHORT, workers=0, progress=False)
    assert cli(["publish", str(camp), "--out", str(raw)]) == 0
    assert "coastline_filter" in json.loads((raw / "tables" / "raw_tables.json").read_text())["tables"]
    full = store.load_tables(camp)["coastline_filter"]
    assert {"campaign", "has_result", "reason"} <= set(full.column_names)
    (raw / "tables" / "raw_tables.json").unlink()
    for name in ("coastline_filter", "geometric_filter"):
        pq.write_table(full, raw / "tables" / f"{name}.parquet")
    shutil.copytree(raw, red)
    compact_folder(red, publish_tables)
    assert "has_result" not in pq.read_table(red / "tables" / "geometric_filter.parquet").column_names
    for folder in (raw, red):
        shutil.rmtree(folder / "report", ignore_errors=True)
        assert cli(["report", str(folder), "--tables-only"]) == 0
    names = sorted(p.name for p in (raw / "report").glob("*.csv"))
    assert names == ["coastline_filter_coastline_steady_state.csv", "comparison.csv"]
    for name in names:
        assert (red / "report" / name).read_text() == (raw / "report" / name).read_text(), name
