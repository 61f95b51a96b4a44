"""The navigation error budget: the budget's error models (renderlab.studies.retina_vs_spc.budget.navigation) flown
through the descent filter with geometric landmark measurements (renderlab.studies.descent_navigation.error_flights)
by ``renderlab navigation-budget`` (renderlab.commands.navigation_budget), checked against the rendered campaign's
truth, the χ² distribution, the geometry of a uniform image shift and direct numpy statistics."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from scipy import stats

from renderlab.cli import main
from renderlab.contracts.error_model import LandmarkErrorModel
from renderlab.stats import oat_budget as S
from renderlab.studies.descent_navigation import error_flights as F
from renderlab.studies.retina_vs_spc.budget import navigation as N
from renderlab.studies.retina_vs_spc.budget import navigation_report as NR

REPO = Path(__file__).resolve().parents[1]
DESCENT = REPO / "results" / "descent_navigation"
BUDGET = REPO / "results" / "error_budget" / "tables"


@pytest.fixture(scope="module")
def geom():
    return F.descent_geometry(DESCENT / "scenario.toml")


def _model(mu=(0.0, 0.0), sd_bias=0.0, sd_noise=0.0):
    one = np.ones((1, 2))
    return N.ErrorModel("test", "retina", "pixel", "px", np.array([100.0]), np.array([mu], float), sd_bias * one,
                        sd_noise * one, sd_bias * one, 0)


def test_geometry_reproduces_the_rendered_campaign_truth_and_draws(geom):
    """True pixels (no rendering) equal the rendered campaign's truth_s/l (its full landmark table, recovered by the
    git command raw_tables.json records); run 3's initial estimate minus the truth, in site axes, equals its prior's
    error (position and velocity)."""
    from renderlab.campaign.compact import recover_raw_table
    from renderlab.contracts.landmark import CameraPose

    raw = recover_raw_table(DESCENT / "tables", "descent_landmarks")
    if raw is None:
        pytest.skip("the full landmark table is not recoverable in this checkout (no git history)")
    lm = raw.select(["frame", "item", "truth_s", "truth_l"]).slice(0, 300).to_pydict()
    idx = {int(i): j for j, i in enumerate(geom.ids)}
    for k, it, s, l in zip(lm["frame"], lm["item"], lm["truth_s"], lm["truth_l"]):
        p = geom.camera.project(CameraPose(geom.R_true[k], geom.pos_true[k]).to_camera(geom.centres[idx[it]]))
        assert p == pytest.approx([s, l], abs=1e-9)
    f = pq.read_table(DESCENT / "tables" / "descent_filter.parquet").to_pydict()
    j = next(i for i in range(len(f["run"])) if f["run"][i] == 3 and f["frame"][i] == -1)
    d = F.run_draws(geom, 3)["x0"][:6] - geom.truth.state(geom.times[0])[:6]
    err = np.r_[geom.R_site.T @ d[:3], geom.R_site.T @ d[3:]]
    names = ("e_m", "n_m", "u_m", "ve_mps", "vn_mps", "vu_mps")
    assert err == pytest.approx([f[f"err_{a}"][j] for a in names], abs=1e-6)


def test_budget_error_models_are_what_the_flights_take():
    assert isinstance(_model(), LandmarkErrorModel)
    with pytest.raises(TypeError, match="not a LandmarkErrorModel"):
        F.fly_models(DESCENT / "scenario.toml", [object()], 2, 0, workers=1)


def test_zero_error_model_flies_the_floor(geom):
    d, (b, e) = F.run_draws(geom, 1), F.landmark_draws(geom, 9, 1)
    assert F.fly(geom, d, _model(), b, e, "retina") == F.fly(geom, d, None, b, e, "retina")


def test_a_uniform_image_shift_moves_the_estimate_by_its_ground_size(geom):
    """Every landmark shifted by +b px in s (star-tracker attitude known) is a camera shift of −b·z/f_x along the
    camera's x axis (site east here) at the last image: the touchdown offset against the floor, and linear in b."""
    d, (bb, e) = F.run_draws(geom, 2), F.landmark_draws(geom, 9, 2)
    floor = F.fly(geom, d, None, bb, e, "retina")
    z_last = (geom.centres.mean(0) - geom.pos_true[-1]) @ geom.R_true[-1][:, 2]
    east = (geom.R_site.T @ geom.R_true[-1][:, 0])[0]
    assert east == pytest.approx(1.0, abs=1e-3)
    shift = {b: F.fly(geom, d, _model(mu=(b, 0.0)), bb, e, "retina")["err_e_m"] - floor["err_e_m"]
             for b in (0.05, 0.1, -0.05)}
    assert shift[0.05] == pytest.approx(-0.05 * z_last / geom.camera.fx, rel=0.1)
    assert shift[0.1] == pytest.approx(2 * shift[0.05], rel=1e-3)
    assert shift[-0.05] == pytest.approx(-shift[0.05], rel=1e-3)


def test_white_noise_at_the_declared_sigma_gives_a_consistent_filter(geom):
    """Injected white noise equal to the filter's declared σ_px: the touchdown NEES (6 dof) averaged over the runs
    lies in the 99.9 % χ² band; twice that σ lies above it."""
    n = 40
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], 6 * n) / (6 * n)
    sig = geom.cfg.sigma_for("retina")
    anees = {}
    for k in (1.0, 2.0):
        nees = [F.fly(geom, F.run_draws(geom, r), _model(sd_noise=k * sig), *F.landmark_draws(geom, 5, r),
                      "retina")["nees_td"] for r in range(n)]
        anees[k] = np.mean(nees) / 6
    assert lo < anees[1.0] < hi, (anees, lo, hi)
    assert anees[2.0] > hi


def test_error_models_match_the_budget_statistics():
    """Pixel mapping = the budget's own per-landmark statistics on the descent's GSD range; ground mapping = the same
    on err × range / f_x (direct numpy); altitude mapping: one knot per budget frame, log-linear between."""
    meas, configs = pq.read_table(BUDGET / "budget_measurements.parquet"), pq.read_table(BUDGET / "budget_configs.parquet")
    rng = (0.4, 2.5)
    px = {(m.config, m.method): m for m in N.error_models(meas, configs, 1218.0, rng, "pixel")}
    cols = S.columns(meas)
    sub = (cols["gsd_ratio"] >= rng[0]) & (cols["gsd_ratio"] <= rng[1])
    s = S.sample(cols, "sensor_noise", "spc", sub, "l", 10)
    ones = np.ones(cols["n_clusters"])
    m = px[("sensor_noise", "spc")]
    assert m.bias_rms[0, 1] == pytest.approx(S.weighted_stat("bias_rms", s, ones, 1.0), rel=1e-12)
    assert m.sd_noise[0, 1] == pytest.approx(S.weighted_stat("noise_sd", s, ones, 1.0), rel=1e-12)
    assert m.sd_bias[0, 1] ** 2 + m.mu[0, 1] ** 2 == pytest.approx(m.bias_rms[0, 1] ** 2, rel=1e-12)
    g = {(m.config, m.method): m for m in N.error_models(meas, configs, 1218.0, rng, "ground")}[("all_off", "retina")]
    rows = (cols["config"] == "all_off") & (cols["method"] == "retina") & sub & cols["truth_visible"]
    e = cols["err_s"][rows]
    ok = np.isfinite(e) & (np.abs(e) <= 1)
    em = e[ok] * np.asarray(meas.column("range_m").to_numpy(zero_copy_only=False))[rows][ok] / 1218.0
    assert g.mu[0, 0] == pytest.approx(em.mean(), rel=1e-12)
    assert g.bias_rms[0, 0] == pytest.approx(np.sqrt(np.mean(em ** 2)), rel=1e-12)  # one run: one row per landmark-frame
    assert g.at(np.array([50.0, 100.0]), 1218.0)[1][:, 0] == pytest.approx(g.sd_bias[0, 0] * 1218.0 / np.array([50, 100.0]))
    a = {(m.config, m.method): m for m in N.error_models(meas, configs, 1218.0, rng, "altitude")}[("all_on", "spc")]
    assert len(a.knots_m) == 3
    mid = np.sqrt(a.knots_m[0] * a.knots_m[1])
    val = a.at(np.r_[a.knots_m, mid, 10.0, 1e4], 1218.0)[2][:, 0]
    assert val[:3] == pytest.approx(a.sd_noise[:, 0])
    assert val[3] == pytest.approx(0.5 * (a.sd_noise[0, 0] + a.sd_noise[1, 0]))
    assert val[4] == pytest.approx(a.sd_noise[np.argmin(a.knots_m), 0])   # held outside the knots
    assert val[5] == pytest.approx(a.sd_noise[np.argmax(a.knots_m), 0])


def _table(errs: dict, n: int) -> pa.Table:
    rows = []
    for (mp, c, m), e in errs.items():
        for r in range(n):
            rows.append({"mapping": mp, "config": c, "method": m, "run": r, "err_e_m": float(e[r, 0]),
                         "err_n_m": float(e[r, 1]), "err_u_m": float(e[r, 2]), "err_norm_m": float(np.linalg.norm(e[r])),
                         "track_lost": False, "diverged": False})
    return pa.table({k: [x[k] for x in rows] for k in rows[0]})


def test_navigation_terms_against_direct_numpy():
    """Contributions, quadrature sum and its check from a table with known errors (direct numpy)."""
    g = np.random.default_rng(4)
    n = 300
    base = g.standard_normal((n, 3)) * 0.01
    a, b = g.standard_normal((n, 3)) * 0.02, g.standard_normal((n, 3)) * 0.03
    errs = {("", N.NONE_CONFIG, N.NONE_METHOD): base * 0.5, ("pixel", "all_off", "spc"): base,
            ("pixel", "a", "spc"): base + a, ("pixel", "b", "spc"): base + b, ("pixel", "all_on", "spc"): base + a + b}
    rows = NR.terms(_table(errs, n), ["a", "b"])
    v = {r["term"]: r for r in rows if r["statistic"] == "rms_3d"}
    ms = {k[1]: np.mean(np.sum(e ** 2, 1)) for k, e in errs.items()}
    assert v["a"]["value"] == pytest.approx(np.sqrt(ms["a"] - ms["all_off"]), rel=1e-12)
    assert v["floor"]["value"] == pytest.approx(np.sqrt(ms[N.NONE_CONFIG]), rel=1e-12)
    q = np.sqrt(ms["a"] + ms["b"] - ms["all_off"])
    assert v["quadrature_sum"]["value"] == pytest.approx(q, rel=1e-12)
    assert v["sum_over_all_on"]["value"] == pytest.approx(q / np.sqrt(ms["all_on"]), rel=1e-12)
    assert v["sum_over_all_on"]["check"] == "PASS" and v["a"]["lo"] < v["a"]["value"] < v["a"]["hi"]
    errs[("pixel", "all_on", "spc")] = base + 2 * (a + b)          # an interaction: the sum falls short
    assert {r["term"]: r for r in NR.terms(_table(errs, n), ["a", "b"])
            if r["statistic"] == "rms_3d"}["sum_over_all_on"]["check"] == "FAIL"


def test_navigation_command_refuses_a_folder_without_tables(tmp_path, capsys):
    assert main(["navigation-budget", str(tmp_path), "--runs", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not an error-budget folder" in err[0]
    assert not any(tmp_path.iterdir())


def _small_budget(folder: Path, configs=("all_off", "sensor_noise", "all_on"), methods=("retina", "retina_ml")):
    """The published budget's tables cut to a few configurations and methods (every path of the command is still
    taken: a source, all off, all on, two methods): the flights and the report run in seconds."""
    import pyarrow.compute as pc

    (folder / "tables").mkdir(parents=True)
    meas = pq.read_table(BUDGET / "budget_measurements.parquet")
    keep = pc.and_(pc.is_in(meas.column("config"), value_set=pa.array(configs)),
                   pc.is_in(meas.column("method"), value_set=pa.array(methods)))
    pq.write_table(meas.filter(keep), folder / "tables" / "budget_measurements.parquet")
    cfg = pq.read_table(BUDGET / "budget_configs.parquet")
    pq.write_table(cfg.filter(pc.is_in(cfg.column("config"), value_set=pa.array(configs))),
                   folder / "tables" / "budget_configs.parquet")
    (folder / "budget.json").write_bytes((BUDGET.parent / "budget.json").read_bytes())
    return len(configs), len(methods)


def test_navigation_command_writes_tables_and_report_and_only_reproduces_rows(tmp_path):
    """Two runs end to end through the CLI, then ``--only all_on`` again: the same rows (same seeds), the rest kept."""
    folder = tmp_path / "budget"
    n_cfg, n_methods = _small_budget(folder)
    args = ["navigation-budget", str(folder), "--scenario", str(DESCENT / "scenario.toml"), "--runs", "2", "--workers", "1",
            "--mappings", "pixel"]
    assert main(args) == 0
    first = pq.read_table(folder / "tables" / "budget_navigation.parquet")
    assert first.num_rows == 2 * (1 + n_cfg * n_methods)
    assert main(args + ["--only", "all_on"]) == 0
    again = pq.read_table(folder / "tables" / "budget_navigation.parquet")
    def key(t):
        return sorted(zip(*[t.column(c).to_pylist() for c in ("mapping", "config", "method", "run", "err_norm_m")]))

    assert key(again) == key(first)
    assert main(args + ["--only", "all_on", "--methods", "retina_ml"]) == 0   # one method of one configuration
    assert key(pq.read_table(folder / "tables" / "budget_navigation.parquet")) == key(first)
    assert main(args + ["--methods", "nope"]) == 2
    report = {p.name for p in (folder / "report").iterdir()}
    assert {"budget_navigation.csv", "budget_navigation_validation.csv", "budget_navigation.png"} <= report
    assert "### navigation: geometric all-on vs the rendered" in (folder / "report" / "budget_table.md").read_text()
