"""Coastline EKF (Straub & Christian eq. 3-19): Jacobians vs finite differences, dynamics vs solve_ivp,
the eq. 19 gain vs a numpy pseudo-inverse, noise-free convergence, χ² consistency over seeded runs on the
real GSHHG coastline, and bit-identical replay of one run."""

from __future__ import annotations

import math

import numpy as np
import pytest
from coastline_fixtures import A_1000, circular_state, random_filter_problem
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from estimators.coastline.dynamics import MU_EARTH, dynamics_jacobian, propagate_state_stm, two_body_rhs
from estimators.coastline.los import los_jacobian_position, los_predict, small_rotation_matrices
from renderlab.errors import UserError


def test_dynamics_jacobian_eq13_matches_central_differences():
    rng = np.random.default_rng(3)
    x = circular_state() + np.r_[rng.normal(0, 5e4, 3), rng.normal(0, 50, 3)]
    F = dynamics_jacobian(x)
    Ffd = np.empty((6, 6))
    steps = np.r_[np.full(3, 1.0), np.full(3, 1e-3)]
    for j in range(6):
        d = np.zeros(6)
        d[j] = steps[j]
        Ffd[:, j] = (two_body_rhs(x + d) - two_body_rhs(x - d)) / (2 * steps[j])
    scale = np.abs(F).max(axis=1, keepdims=True)
    assert np.allclose(F, Ffd, rtol=0, atol=1e-7 * scale.max())
    assert np.allclose(F[3:, :3], Ffd[3:, :3], rtol=1e-6, atol=1e-15)


def test_los_jacobian_eq17_matches_central_differences():
    rng = np.random.default_rng(4)
    r = circular_state()[:3]
    o = r * (6378137.0 / np.linalg.norm(r)) + rng.normal(0, 2e5, (5, 3))
    T = Rotation.from_rotvec(rng.normal(0, 1, 3)).as_matrix()
    e_c, e_i, rho = los_predict(r[None], o, T)
    H = los_jacobian_position(e_i, rho, T)[0]                 # (m, 3, 3)
    for j in range(3):
        d = np.zeros(3)
        d[j] = 1.0
        fd = (los_predict((r + d)[None], o, T)[0] - los_predict((r - d)[None], o, T)[0])[0] / 2.0
        assert np.allclose(H[:, :, j], fd, rtol=1e-6, atol=1e-15)
    # eq. 20: Hᵢᵀ eᵢ = 0 — the LOS direction carries no information
    assert np.max(np.abs(np.einsum("mij,mi->mj", H, e_c[0]))) < 1e-18


def test_state_and_stm_match_solve_ivp_and_finite_differences():
    x0 = circular_state()
    period = 2 * math.pi * math.sqrt(A_1000**3 / MU_EARTH)
    x1, phi = propagate_state_stm(x0[None], period, max_step_s=10.0)
    ref = solve_ivp(lambda t, x: two_body_rhs(x), (0, period), x0, method="DOP853", rtol=1e-13, atol=1e-8)
    assert np.linalg.norm(x1[0, :3] - ref.y[:3, -1]) < 0.05          # metres after one 105-min orbit
    assert np.linalg.norm(x1[0, 3:] - ref.y[3:, -1]) < 5e-5
    # STM over 600 s vs central differences of solve_ivp (the oracle)
    def flow(x):
        return solve_ivp(lambda t, y: two_body_rhs(y), (0, 600.0), x, method="DOP853", rtol=1e-13, atol=1e-9).y[:, -1]
    _, phi600 = propagate_state_stm(x0[None], 600.0, max_step_s=10.0)
    steps = np.r_[np.full(3, 10.0), np.full(3, 0.01)]
    fd = np.column_stack([(flow(x0 + np.eye(6)[j] * steps[j]) - flow(x0 - np.eye(6)[j] * steps[j])) / (2 * steps[j])
                          for j in range(6)])
    assert np.allclose(phi600[0], fd, rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("sigma_att", [0.0, 3e-5])
def test_modified_gain_eq19_equals_pseudo_inverse_update(sigma_att):
    """Both implementations of eq. 19 give the gain P Hᵀ S⁺, the Joseph covariance and the NIS νᵀS⁺ν that a
    plain numpy.linalg.pinv computation gives."""
    fw, y, o, T = random_filter_problem(7, sigma_att=sigma_att)
    fd, *_ = random_filter_problem(7, sigma_att=sigma_att, method="direct")
    x_prior, P_prior = fw.x.copy(), fw.P.copy()
    rw, rd = fw.update(y, o, T), fd.update(y, o, T)
    m = len(o)
    for n in range(fw.n_runs):
        e_c, e_i, rho = los_predict(x_prior[n:n + 1, :3], o, T[n])
        H = np.zeros((3 * m, 6))
        H[:, :3] = los_jacobian_position(e_i, rho, T[n]).reshape(3 * m, 3)
        R = np.zeros((3 * m, 3 * m))
        G = np.zeros((3 * m, 3))
        for i, e in enumerate(e_c[0]):
            R[3 * i:3 * i + 3, 3 * i:3 * i + 3] = 4e-4**2 * (np.eye(3) - np.outer(e, e))
            G[3 * i:3 * i + 3] = np.cross(np.eye(3), e)        # rows of [e×] up to sign
        R += sigma_att**2 * G @ G.T
        S = H @ P_prior[n] @ H.T + R
        Sp = np.linalg.pinv(S, rcond=1e-9, hermitian=True)
        K = P_prior[n] @ H.T @ Sp
        nu = (y[n] - e_c[0]).ravel()
        IKH = np.eye(6) - K @ H
        P_ref = IKH @ P_prior[n] @ IKH.T + K @ R @ K.T
        assert np.allclose(fw.x[n], x_prior[n] + K @ nu, rtol=0, atol=1e-6)
        assert np.allclose(fd.x[n], x_prior[n] + K @ nu, rtol=0, atol=1e-6)
        for P in (fw.P[n], fd.P[n]):
            assert np.allclose(P, P_ref, rtol=1e-7, atol=1e-12 * np.abs(P_ref).max())
        assert rw.nis[n] == pytest.approx(nu @ Sp @ nu, rel=1e-6)
        assert rd.nis[n] == pytest.approx(nu @ Sp @ nu, rel=1e-6)
    assert rw.dof == 2 * m


def test_star_tracker_rotation_is_small_and_orthonormal():
    R = small_rotation_matrices(np.array([[1e-4, -2e-4, 3e-4], [0.0, 0.0, 0.0]]))
    assert np.allclose(R @ np.swapaxes(R, 1, 2), np.eye(3), atol=1e-14)
    assert np.allclose(R[0], Rotation.from_rotvec([1e-4, -2e-4, 3e-4]).as_matrix(), atol=1e-15)


# --- Monte Carlo on the real GSHHG coastline (geometry loaded once for this module) -----------------------

@pytest.fixture(scope="module")
def polar_1000():
    from renderlab.studies.coastline_ekf.geometric import paper_orbit, truth_geometry

    o = paper_orbit("i90_h1000")
    geo = truth_geometry(o)
    assert (geo.n_meas > 0).sum() > 50, "a polar orbit should see coastline in many images"
    return o, geo


def test_matched_points_are_inside_the_camera_footprint(polar_1000):
    from renderlab.geometry import CameraModel

    o, geo = polar_1000
    W = 1024
    f = (W / 2) / math.tan(o.fov_rad / 2)
    cam = CameraModel(width=W, height=W, fx=f, fy=f, cx=(W - 1) / 2, cy=(W - 1) / 2)
    for k in np.flatnonzero(geo.n_meas)[::10]:
        p_cam = (geo.points_eci[k] - geo.x_true[k, :3]) @ geo.T_cam_from_eci[k].T
        sl = cam.project(p_cam)
        assert np.all((sl > -0.5 - 1.0) & (sl < W - 0.5 + 1.0))
        # ground distance from nadir within the footprint's half-diagonal (eq. 1 gives the flat-Earth side)
        nadir = -geo.x_true[k, :3] / np.linalg.norm(geo.x_true[k, :3])
        ang = np.arccos(np.clip((p_cam / np.linalg.norm(p_cam, axis=1, keepdims=True)) @ (geo.T_cam_from_eci[k] @ nadir),
                                -1, 1))
        assert np.all(ang <= math.atan(math.sqrt(2) * math.tan(o.fov_rad / 2)) + 1e-9)
        # every matched point is on the WGS-84 surface and in front of the Earth's limb
        lat_scale = np.array([1.0, 1.0, 1.0 / (1.0 - 1.0 / 298.257223563)])
        assert np.allclose(np.linalg.norm(geo.points_eci[k] * lat_scale, axis=1), 6378137.0, rtol=0, atol=1e-3)
        assert np.all(np.linalg.norm(geo.points_eci[k] - geo.x_true[k, :3], axis=1) < math.sqrt(
            np.linalg.norm(geo.x_true[k, :3]) ** 2 - 6356752.0**2))


def test_noise_free_stream_converges_to_truth(polar_1000):
    """Noise-free LOS, dispersed start: the error shrinks to the linear-theory value
    x̂_K − x_K = P_K Φ(t_K, t_0)⁻ᵀ P_0⁻¹ (x̂_0 − x_0) (information form, Q = 0)."""
    from renderlab.studies.coastline_ekf.geometric import run_batch

    o, geo = polar_1000
    N = 6
    out = run_batch(o, np.random.SeedSequence(11).spawn(N), noise_free=True, keep_history=True)
    err = out["x_hat"] - geo.x_true[None]
    e0, eK = err[:, 0], err[:, -1]
    _, phi = propagate_state_stm(geo.x_true[:1], geo.t_s[-1] - geo.t_s[0], max_step_s=10.0)
    P0inv = np.linalg.inv(out["P"][0, 0])
    lin = np.einsum("nij,nj->ni", out["P"][:, -1], (np.linalg.inv(phi[0]).T @ P0inv @ e0.T).T)
    pos0, posK = np.linalg.norm(e0[:, :3], axis=1), np.linalg.norm(eK[:, :3], axis=1)
    assert np.all(posK < 0.1 * pos0)
    assert np.all(np.linalg.norm(eK[:, :3] - lin[:, :3], axis=1) < 0.05 * np.linalg.norm(lin[:, :3], axis=1) + 0.5)


def test_anees_and_anis_inside_99_percent_chi2_band(polar_1000):
    """200 seeded runs, one orbit: ANEES at four times inside [χ²₀.₀₀₅(6N)/N, χ²₀.₉₉₅(6N)/N] and the summed
    NIS of all images inside the 99 % band of χ²(N Σ 2mₖ); the MC RMS does not beat the PCRB."""
    from renderlab.studies.coastline_ekf.geometric import run_batch
    from renderlab.studies.coastline_ekf.scoring import chi2_band, nis_total_test, pcrb_ric_sigma, per_time_summary

    o, geo = polar_1000
    N = 200
    table = run_batch(o, np.random.SeedSequence(2026).spawn(N))["table"]
    s = per_time_summary(table, pcrb_ric_sigma(geo, o))
    lo, hi = chi2_band(6.0, N)
    assert s["anees_lo"].to_numpy()[0] == pytest.approx(lo) and lo == pytest.approx(5.388, abs=1e-3)
    K = len(geo.t_s)
    anees = s["anees"].to_numpy()
    for k in (K // 4, K // 2, 3 * K // 4, K - 1):
        assert lo <= anees[k] <= hi, (k, anees[k], lo, hi)
    nis = nis_total_test(table)
    assert nis["inside"], nis
    for ax in ("r_m", "i_m", "c_m", "vr_mps", "vi_mps", "vc_mps"):
        mc, pcrb, filt = (s[f"{p}{ax}"].to_numpy()[-1] for p in ("mc_rms_", "pcrb_sig_", "filter_sig_"))
        assert mc > 0.8 * pcrb                       # sampling scatter of an RMS over 200 runs is ~5 %
        assert filt == pytest.approx(pcrb, rel=0.02)  # EKF linearised at the estimate vs PCRB at the truth


def test_run_k_replays_alone_bit_identically(polar_1000):
    from renderlab.studies.coastline_ekf.geometric import run_batch

    o, _ = polar_1000
    seeds = np.random.SeedSequence(99).spawn(5)
    batch = run_batch(o, seeds)["table"]
    again = run_batch(o, np.random.SeedSequence(99).spawn(5))["table"]
    def same(a, b):  # NaN-aware for numbers (nis is NaN without an image), plain equality for the reason strings
        a, b = np.asarray(a.to_pylist(), dtype=object), np.asarray(b.to_pylist(), dtype=object)
        num = a.dtype.kind == "O" and all(isinstance(v, float) for v in a)
        return np.array_equal(a.astype(float), b.astype(float), equal_nan=True) if num else bool(np.all(a == b))

    for c in batch.column_names:                   # same seed → same numbers
        assert same(batch[c], again[c]), c
    k = 3
    alone = run_batch(o, [seeds[k]], [k])["table"]
    rows = batch.filter(batch["run"].to_numpy() == k)
    for c in batch.column_names:
        assert same(rows[c], alone[c]), c


@pytest.mark.parametrize("bad", [{"sigma_theta_rad": 0.0}, {"cadence_s": -1.0}, {"altitude_m": float("nan")}])
def test_bad_options_raise_one_line_user_error(bad):
    from renderlab.studies.coastline_ekf.geometric import CoastlineGeometricOptions

    with pytest.raises(UserError) as ei:
        CoastlineGeometricOptions(**bad).validate()
    assert "\n" not in str(ei.value) and next(iter(bad)) in str(ei.value)


def _tiny_publication(out):
    """``publish --keep-runs`` of 12 runs of a quarter orbit, and those runs' rows made again directly (every run is
    its own seed: the batches of ``--chunk`` do not change them)."""
    from dataclasses import replace

    from renderlab.studies.coastline_ekf.geometric import paper_orbit, run_batch
    from renderlab.studies.coastline_ekf.publish import PAPER_TABLE1, main

    assert main(["--out", str(out), "--runs", "12", "--orbits", "i45_h500", "--revolutions", "0.25",
                 "--chunk", "5", "--keep-runs"]) == 0
    o = paper_orbit("i45_h500")
    o = replace(o, duration_s=0.25 * o.period_s).validate()
    seeds = np.random.SeedSequence([2026, list(PAPER_TABLE1).index("i45_h500")]).spawn(12)
    return o, run_batch(o, seeds)


def test_publish_writes_the_published_layout_and_its_report(tmp_path):
    """The publication command on a tiny case: the published layout (tables/, campaign.json, runs.json), a report
    made from those tables (figures PNG, summary numbers equal to a direct computation from every run's rows, which
    ``--keep-runs`` records in raw_tables.json and reduces to what the report reads)."""
    import csv
    import json

    import pyarrow.parquet as pq

    from renderlab.campaign.publish import is_published
    from renderlab.studies.coastline_ekf.scoring import nis_total_test, per_time_summary, steady_state

    _, direct_runs = _tiny_publication(tmp_path)
    runs = direct_runs["table"]
    assert is_published(tmp_path)
    rep = tmp_path / "report"
    for name in ("summary.csv", "table1.md", "index.html", "i45_h500_coastline_errors.png",
                 "i45_h500_coastline_consistency.png"):
        assert (rep / name).stat().st_size > 0, name
    assert (rep / "i45_h500_coastline_errors.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    row = next(csv.DictReader(open(rep / "summary.csv")))
    assert row["case"] == "i45_h500" and int(row["runs"]) == 12
    ts = pq.read_table(tmp_path / "tables" / "coastline_timeseries.parquet")
    assert ts.num_rows == int(row["images"]) + 1 and int(ts["n_runs"][0].as_py()) == 12
    raw = json.loads((tmp_path / "tables" / "raw_tables.json").read_text())["tables"]
    assert raw["coastline_runs"]["rows"] == runs.num_rows == 12 * ts.num_rows
    assert not (tmp_path / "tables" / "coastline_runs.parquet").exists()
    direct = steady_state(per_time_summary(runs))
    for key in ("mc_3sig_r_m", "mc_3sig_i_m", "filter_3sig_c_m", "anees_mean"):
        assert float(row[key]) == pytest.approx(direct[key], rel=1e-5), key
    assert float(row["nis_total_over_dof"]) == pytest.approx(nis_total_test(runs)["ratio"], rel=1e-5)
    sample = pq.read_table(tmp_path / "tables" / "coastline_sample_runs.parquet")
    assert sorted(set(sample["run"].to_pylist())) == list(range(12))
    in_order = runs.sort_by([("run", "ascending"), ("t_s", "ascending")])        # the sample: float64, all 12 runs
    np.testing.assert_array_equal(sample["err_i_m"].to_numpy(), in_order["err_i_m"].to_numpy())


def test_reduced_geometric_tables_give_the_report_of_the_raw_ones(tmp_path):
    """``publish_tables`` is a pure function raw → published: the report of a folder holding every raw table (every
    run's rows, per-run totals, the run means) and the report of its reduction write the same CSV and Markdown."""
    import shutil

    import pyarrow.parquet as pq

    from renderlab.campaign.compact import compact_bytes
    from renderlab.cli import main as cli
    from renderlab.studies.coastline_ekf.geometric import truth_geometry
    from renderlab.studies.coastline_ekf.publish import orbit_tables, publish_tables
    from renderlab.studies.coastline_ekf.scoring import pcrb_ric_sigma, per_time_summary

    pub = tmp_path / "pub"
    o, direct = _tiny_publication(pub)
    runs = direct["table"]
    summary = per_time_summary(runs, pcrb_ric_sigma(truth_geometry(o), o))
    raw = orbit_tables("i45_h500", o, direct["geometry"], runs, summary, {"geometry": 0.0, "monte_carlo": 0.0},
                       keep_runs=True)
    raw["coastline_orbits"] = pq.read_table(pub / "tables" / "coastline_orbits.parquet")   # its wall times
    assert {"coastline_runs", "coastline_run_totals"} <= set(raw) and "run" in raw["coastline_run_totals"].column_names
    reduced = publish_tables(dict(raw))
    assert "coastline_runs" not in reduced and reduced["coastline_run_totals"].num_rows == 1
    for name, t in reduced.items():              # what publish wrote is the reduction of the raw tables, byte for byte
        assert compact_bytes(t) == (pub / "tables" / f"{name}.parquet").read_bytes(), name
    copy = tmp_path / "raw"
    shutil.copytree(pub, copy, ignore=shutil.ignore_patterns("report", "raw_tables.json", "*.parquet"))
    for name, t in raw.items():
        pq.write_table(t, copy / "tables" / f"{name}.parquet")
    for folder in (pub, copy):
        shutil.rmtree(folder / "report", ignore_errors=True)
        assert cli(["report", str(folder), "--tables-only"]) == 0
    for name in ("summary.csv", "table1.md"):
        assert (copy / "report" / name).read_text() == (pub / "report" / name).read_text(), name


@pytest.mark.parametrize("argv, message", [(["--orbits", "i45_h700"], "unknown orbit 'i45_h700'"),
                                          (["--runs", "0"], "--runs and --chunk must be >= 1")])
def test_publish_refuses_bad_input_in_one_line_and_writes_nothing(tmp_path, capsys, argv, message):
    from renderlab.errors import run_main
    from renderlab.studies.coastline_ekf.publish import main

    out = tmp_path / "pub"
    assert run_main(main, ["--out", str(out), *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("renderlab: error: ") and message in err and "\n" not in err
    assert not out.exists()
