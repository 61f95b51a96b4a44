r"""The error budget's contribution to navigation error: each source's landmark errors flown through the descent EKF.

Description
-----------
A GN&C error budget of the onboard descent filter (``descent_ekf``, :mod:`estimators.descent_nav`, default
options of :func:`renderlab.studies.descent_navigation.run.filter_options` and the descent scenario's
``[descent_navigation]`` section) flown along the descent study's truth (:mod:`renderlab.studies.descent_navigation
.truth`: the 15 images 200 → 50 m of ``results/descent_navigation/scenario.toml``) with **geometric**
measurements: no rendering; landmark i in image k is measured at its true pixel (the maplet centre projected
through the true camera, Wright et al. eqs. 1–4) plus an injected error drawn from one budget configuration's
measured error model (:func:`error_models`, from ``tables/budget_measurements.parquet``):

.. math::

    \mathbf z_{ik} = \pi(\mathbf T_k, \mathbf c_i) + \boldsymbol\mu(R_{ik}) + \boldsymbol\sigma_b(R_{ik})
    \odot \boldsymbol\beta_i + \boldsymbol\sigma_n(R_{ik}) \odot \boldsymbol\epsilon_{ik}     \quad (N1)

with β_i, ε_ik ~ N(0, I₂) (β_i constant for landmark i over the descent: its per-landmark bias; ε white),
per image axis (s, l): μ the configuration's mean error (common to every landmark), σ_b = √(b_rms² − μ²) the
landmark-to-landmark spread of the per-landmark bias (so the per-landmark bias has the budget's rms b_rms), σ_n
the budget's per-landmark noise sd (pooled within landmark-frames over runs). R_ik is the landmark's depth in
the camera. The budget measures these at three frames (217, 105, 50 m); three **mappings** onto the descent's
altitudes bracket how they scale:

* ``altitude`` (primary): the per-frame pixel statistics, interpolated linearly in log R between the three
  frames' median depths (held constant outside) — what the budget measured at each altitude;
* ``ground``: pooled over the frames in metres on the ground (error × GSD, GSD = R / f_x), then
  σ_px = σ_m · f_x / R — errors constant on the ground (what the descent campaign measured:
  ``results/descent_navigation/README.md``);
* ``pixel``: pooled over the frames in pixels, constant at every altitude.

Statistics on the budget rows the descent would attempt (GSD ratio in the descent's ``gsd_ratio_range``), with a
truth pixel and |err| ≤ 1 px (the budget's per-landmark decomposition; gross errors are left to the filter's
gate and not injected). Everything else is the descent study's run i exactly — the filter's initial estimate,
the star tracker's attitude error per image and the accelerometer's noise come from ``SeedSequence(campaign
seed, spawn_key=(i,))`` spawned as :func:`renderlab.studies.descent_navigation.run.run` does, so run i pairs
with run i of the rendered campaign — and the landmarks are selected as there
(:func:`renderlab.studies.descent_navigation.loop.select_landmarks`, at the filter's a-priori pose), with the
filter's declared σ_px and the star tracker's σ in R (eq. M3). The draws β, ε come from
``SeedSequence(nav seed, spawn_key=(i,))``, the same for every configuration and method (common random numbers:
contributions are paired differences). Not modelled: the search window (a measurement is never lost because
the truth lies outside it), no-result rates, gross errors, and the correlation across landmarks of a run of the
per-run knowledge errors (camera, Sun, spacing, a-priori pose: injected as white noise).

Configuration ``no_landmark_error`` (method ``none``) injects nothing: the floor set by the initial estimate,
the star tracker, the accelerometer and the gravity model the filter lacks.

Tuning
------
``runs`` (200: the touchdown rms to ± 10 % at 95 %), ``seed`` of the landmark draws, ``mappings``.

Use
---
``python -m renderlab.studies.retina_vs_spc.budget navigation results/error_budget --runs 200`` (``--only
CONFIG ...``: just those configurations, replacing their rows) writes
``tables/budget_navigation.parquet`` (one row per mapping, configuration, method and run: touchdown-proxy error
at the last image, east / north / up in the site frame, the filter's 1σ, NEES, track loss, the injected model)
and ``tables/budget_navigation_rendered.parquet`` (the rendered campaign's touchdown rows, for the validation),
then the report (:mod:`.budget_navigation_report`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from renderlab.errors import UserError

MAPPINGS = ("altitude", "ground", "pixel")
NONE_CONFIG, NONE_METHOD = "no_landmark_error", "none"
TABLE, RENDERED = "budget_navigation", "budget_navigation_rendered"


@dataclass(frozen=True)
class NavBudgetOptions:
    """Options of the navigation budget (module docstring)."""

    runs: int = 200
    seed: int = 2027
    mappings: tuple = MAPPINGS
    gross_px: float = 1.0


@dataclass(frozen=True)
class ErrorModel:
    """One configuration × method × mapping: eq. N1's μ, σ_b, σ_n per axis (s, l) at knots of depth R.

    ``unit`` is ``"px"`` (values in px at each knot of ``knots_m``; ``altitude`` has three knots, ``pixel`` one)
    or ``"m"`` (metres on the ground, one knot; σ_px = σ_m f_x / R)."""

    config: str
    method: str
    mapping: str
    unit: str
    knots_m: np.ndarray      # (K,) median depth of each knot's rows
    mu: np.ndarray           # (K, 2)
    sd_bias: np.ndarray      # (K, 2)
    sd_noise: np.ndarray     # (K, 2)
    bias_rms: np.ndarray     # (K, 2) the budget's per-landmark bias rms
    landmark_frames: int

    def at(self, depth_m: np.ndarray, fx: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(μ, σ_b, σ_n), each (n, 2) px, at depths ``depth_m`` (n,)."""
        d = np.asarray(depth_m, float)
        if self.unit == "m":
            f = (fx / d)[:, None]
            return self.mu[0] * f, self.sd_bias[0] * f, self.sd_noise[0] * f
        if len(self.knots_m) == 1:
            return tuple(np.broadcast_to(a[0], (d.size, 2)).copy() for a in (self.mu, self.sd_bias, self.sd_noise))
        o = np.argsort(self.knots_m)
        x = np.log(d)

        def interp(a):
            return np.stack([np.interp(x, np.log(self.knots_m[o]), a[o, j]) for j in range(2)], axis=1)

        return interp(self.mu), interp(self.sd_bias), interp(self.sd_noise)


def _axis_stats(e: np.ndarray, cluster: np.ndarray, runs: int) -> tuple[float, float, float]:
    """(mean, per-landmark bias rms, pooled within-landmark noise sd) of errors e grouped by cluster."""
    u, inv = np.unique(cluster, return_inverse=True)
    n = np.bincount(inv).astype(float)
    sx, sxx = np.bincount(inv, e), np.bincount(inv, e * e)
    mean_k = sx / n
    two = n >= 2
    noise = 0.0
    if runs >= 2 and two.any():
        noise = math.sqrt(max(float(np.sum(sxx[two] - sx[two] ** 2 / n[two])), 0.0) / float(np.sum(n[two] - 1)))
    return float(np.mean(e)), float(np.sqrt(np.mean(mean_k ** 2))), noise


def error_models(meas, configs, fx: float, gsd_range: tuple, mapping: str, gross_px: float = 1.0) -> list:
    """The :class:`ErrorModel` of every configuration × method of a budget's tables under ``mapping``."""
    from renderlab.studies.retina_vs_spc import budget_stats as S

    if mapping not in MAPPINGS:
        raise UserError(f"navigation budget: mapping must be one of {', '.join(MAPPINGS)}, got {mapping!r}")
    cols = S.columns(meas)
    depth = np.asarray(meas.column("range_m").to_numpy(zero_copy_only=False), float)
    runs = dict(zip(configs.column("config").to_pylist(), configs.column("runs").to_pylist()))
    g = cols["gsd_ratio"]
    base = cols["truth_visible"] & (g >= gsd_range[0]) & (g <= gsd_range[1])
    frames = np.unique(cols["frame"][base])
    out = []
    for c in runs:
        for m in sorted(set(cols["method"][cols["config"] == c])):
            sel = base & (cols["config"] == c) & (cols["method"] == m)
            groups = [sel & (cols["frame"] == f) for f in frames] if mapping == "altitude" else [sel]
            scale = depth / fx if mapping == "ground" else np.ones_like(depth)
            knots, stats = [], []
            for rows in groups:
                per_axis = []
                for a in "sl":
                    ok = rows & np.isfinite(cols[f"err_{a}"]) & (np.abs(cols[f"err_{a}"]) <= gross_px)
                    if ok.sum() < 2:
                        raise UserError(f"navigation budget: configuration {c}, method {m} has fewer than 2 "
                                        f"results in the GSD-ratio range {gsd_range}")
                    per_axis.append(_axis_stats(cols[f"err_{a}"][ok] * scale[ok], cols["cluster"][ok], runs[c]))
                knots.append(float(np.median(depth[rows])))
                stats.append(per_axis)
            st = np.array(stats)                                  # (K, 2 axes, 3)
            mu, brms, noise = st[..., 0], st[..., 1], st[..., 2]
            out.append(ErrorModel(c, m, mapping, "m" if mapping == "ground" else "px", np.array(knots), mu,
                                  np.sqrt(np.clip(brms ** 2 - mu ** 2, 0, None)), noise, brms,
                                  int(np.unique(cols["cluster"][sel]).size)))
    return out


@dataclass(frozen=True)
class Geometry:
    """The descent the filter flies: truth, images' true poses and camera, the landmark catalog."""

    truth: object              # TrueDescent
    times: np.ndarray          # (K,)
    R_true: np.ndarray         # (K, 3, 3) body ← camera
    pos_true: np.ndarray       # (K, 3)
    camera: object             # CameraModel (every image)
    centres: np.ndarray        # (L, 3)
    spacing: np.ndarray        # (L,)
    ids: np.ndarray            # (L,) landmark ids
    R_site: np.ndarray         # body ← site (east, north, up)
    cfg: object                # DescentNavigationConfig
    campaign_seed: int


def descent_geometry(scenario_path) -> Geometry:
    """The :class:`Geometry` of a descent-navigation scenario, built without rendering (the world's plan)."""
    from pathlib import Path

    from renderlab.geometry.camera import CameraModel
    from renderlab.scenario import load_scenario
    from renderlab.studies.descent_navigation.run import check, section
    from renderlab.studies.descent_navigation.truth import TrueDescent
    from renderlab.worlds.base import make_plan
    from renderlab.worlds.ev5.descent import DescentProfile

    scenario, base = load_scenario(Path(scenario_path))
    check(scenario)
    cfg = section(scenario)
    plan = make_plan(scenario, base)
    model, states = plan.model, plan.states
    site = model.site
    truth = TrueDescent(DescentProfile(scenario.trajectory), 2.0 * math.pi / model.spin.period_s,
                        np.asarray(site.origin_m, float), np.asarray(site.R_body_from_site, float)[:, 2],
                        float(cfg.gm_true_m3_s2), float(cfg.j2_true), float(cfg.r_ref_m))
    ms = sorted(model.maplets, key=lambda m: m.landmark_id)
    return Geometry(truth, np.array([s.time_s for s in states]),
                    np.stack([s.pose.rotation.as_matrix() for s in states]),
                    np.stack([np.asarray(s.pose.position_m, float) for s in states]),
                    CameraModel.from_dict(scenario.camera.model_dump()), np.array([m.center_m for m in ms], float),
                    np.array([m.spacing_m for m in ms], float), np.array([m.landmark_id for m in ms], np.int64),
                    np.asarray(site.R_body_from_site, float), cfg, int(scenario.campaign.seed))


def run_draws(geom: Geometry, run: int) -> dict:
    """Run ``run``'s initial estimate, star tracker and accelerometer, drawn as the descent study draws them."""
    from scipy.spatial.transform import Rotation

    from renderlab.campaign.plan import run_seed_sequence

    cfg = geom.cfg
    _, ss_x0, ss_st, ss_acc = run_seed_sequence(geom.campaign_seed, run).spawn(4)
    sig_st = math.radians(cfg.star_tracker_sigma_arcsec / 3600.0)
    dth = np.random.default_rng(ss_st).standard_normal((len(geom.times), 3)) * sig_st
    R_star = np.einsum("kij,kjl->kil", geom.R_true, Rotation.from_rotvec(dth).as_matrix())
    sd0 = np.r_[np.full(3, cfg.initial_position_sigma_m), np.full(3, cfg.initial_velocity_sigma_mps)]
    x0 = geom.truth.state(geom.times[0]) + np.random.default_rng(ss_x0).standard_normal(6) * sd0
    spans = []
    for a, b in zip(geom.times[:-1], geom.times[1:]):
        n = max(1, int(math.ceil((b - a) * cfg.accel_rate_hz - 1e-9)))
        e = np.linspace(a, b, n + 1)
        spans.append(np.stack([e[:-1], e[1:]], 1))
    allsp = np.concatenate(spans)
    u = geom.truth.accelerometer(allsp[:, 0], allsp[:, 1], cfg.accel_sigma_mps2, np.random.default_rng(ss_acc))
    accel, j = [[]], 0
    for sp in spans:
        accel.append([(float(t0), float(t1), u[j + i]) for i, (t0, t1) in enumerate(sp)])
        j += len(sp)
    return {"x0": x0, "P0": np.diag(sd0 ** 2), "R_star": R_star, "accel": accel, "sigma_st": sig_st}


def landmark_draws(geom: Geometry, seed: int, run: int) -> tuple[np.ndarray, np.ndarray]:
    """(β (L, 2), ε (K, L, 2)) of eq. N1 for run ``run``: standard normals, shared by every configuration."""
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(int(run),)))
    return rng.standard_normal((len(geom.ids), 2)), rng.standard_normal((len(geom.times), len(geom.ids), 2))


def fly(geom: Geometry, draws: dict, model: ErrorModel | None, beta: np.ndarray, eps: np.ndarray,
        method: str) -> dict:
    """One descent of the filter with eq. N1's measurements (``model`` None: no landmark error) → the
    touchdown-proxy row: error and 1σ at the last image (site east, north, up), NEES there, ANEES over the
    images, landmarks kept, track loss (``track_loss_frames`` images in a row without a kept landmark)."""
    from estimators.descent_nav import pixel_covariance
    from renderlab import plugins
    from renderlab.contracts.landmark import CameraPose
    from renderlab.contracts.navigation import FilterMeasurement
    from renderlab.studies.descent_navigation.loop import select_landmarks
    from renderlab.studies.descent_navigation.run import filter_options

    cfg, cam = geom.cfg, geom.camera
    filt = plugins.filters.get("descent_ekf")(filter_options(cfg, geom.truth.omega_rad_s))
    filt.initialize(float(geom.times[0]), draws["x0"], draws["P0"])
    sig_px = cfg.sigma_for(method)
    nees, kept_total, misses, lost, diverged = [], 0, 0, False, False
    for k, t in enumerate(geom.times):
        for t0, t1, u in draws["accel"][k]:
            filt.set_input(u)
            filt.propagate(t1)
        x = filt.x
        R_st = draws["R_star"][k]
        sel = select_landmarks(cam, CameraPose(R_st, x[:3]), geom.centres, geom.spacing, cfg)
        xc = CameraPose(geom.R_true[k], geom.pos_true[k]).to_camera(geom.centres[sel])
        true_px = cam.project(xc)
        sel, xc, true_px = sel[cam.in_image(true_px)], xc[cam.in_image(true_px)], true_px[cam.in_image(true_px)]
        kept = 0
        if sel.size:
            z = true_px.copy()
            if model is not None:
                mu, sb, sn = model.at(xc[:, 2], cam.fx)
                z += mu + sb * beta[sel] + sn * eps[k, sel]
            pts = geom.centres[sel]
            gsd = ((pts - x[:3]) @ R_st)[:, 2] / cam.fx
            sg = cfg.ground_sigma_for(method)
            sig = np.sqrt(sig_px ** 2 + (sg / gsd) ** 2) if sg > 0 else sig_px
            R = pixel_covariance(cam, pts, x[:3], R_st, sig, draws["sigma_st"])
            meas = FilterMeasurement("pixel", z.reshape(-1), R, {"points_body_m": pts, "R_body_from_cam": R_st,
                                                                  "camera": cam, "flagged": np.zeros(len(sel), bool)})
            try:
                filt.update(float(t), meas)
                kept = int(filt.last.kept.sum())
            except UserError:
                diverged = True
                break
        kept_total += kept
        misses = misses + 1 if kept == 0 else 0
        lost = lost or misses >= cfg.track_loss_frames
        d = filt.x[:6] - geom.truth.state(t)
        nees.append(float(d @ np.linalg.solve(filt.P[:6, :6], d)))
    return _touchdown(geom, filt, nees, kept_total, lost, diverged)


def _touchdown(geom, filt, nees, kept_total, lost, diverged) -> dict:
    nan = float("nan")
    out = {"track_lost": bool(lost or diverged), "diverged": bool(diverged), "n_kept": int(kept_total)}
    if diverged:
        return {**out, **{f"{p}_{a}_m": nan for p in ("err", "sig") for a in "enu"}, "err_norm_m": nan,
                "nees_td": nan, "anees": nan}
    e = geom.R_site.T @ (filt.x[:3] - geom.truth.position(geom.times[-1]))
    sig = np.sqrt(np.diag(geom.R_site.T @ filt.P[:3, :3] @ geom.R_site))
    return {**out, **{f"err_{a}_m": float(v) for a, v in zip("enu", e)},
            **{f"sig_{a}_m": float(v) for a, v in zip("enu", sig)}, "err_norm_m": float(np.linalg.norm(e)),
            "nees_td": nees[-1], "anees": float(np.mean(nees))}


_WORKER: dict = {}


def _init_worker(scenario_path: str, models: list) -> None:
    _WORKER["geom"], _WORKER["models"] = descent_geometry(scenario_path), models


def _injected(model: ErrorModel | None, fx: float, depth_m: float) -> dict:
    """eq. N1's μ, σ_b, σ_n (px, per axis) at depth ``depth_m`` (the last image's), for the table."""
    if model is None:
        return {f"inj_{q}_{a}_px": 0.0 for q in ("mu", "sd_bias", "sd_noise") for a in "sl"}
    vals = model.at(np.array([depth_m]), fx)
    return {f"inj_{q}_{a}_px": float(v[0, j]) for q, v in zip(("mu", "sd_bias", "sd_noise"), vals)
            for j, a in enumerate("sl")}


def _fly_run(args) -> list[dict]:
    """Worker: every (mapping, configuration, method) of run ``run`` (and, with ``floor``, the descent without
    landmark error) → rows."""
    run, seed, floor = args
    geom, models = _WORKER["geom"], _WORKER["models"]
    draws = run_draws(geom, run)
    beta, eps = landmark_draws(geom, seed, run)
    depth = float(np.linalg.norm(geom.pos_true[-1] - geom.truth.origin_m))
    rows = [{"mapping": "", "config": NONE_CONFIG, "method": NONE_METHOD, "run": run,
             **_injected(None, geom.camera.fx, depth), **fly(geom, draws, None, beta, eps, "retina")}] if floor else []
    for m in models:
        rows.append({"mapping": m.mapping, "config": m.config, "method": m.method, "run": run,
                     **_injected(m, geom.camera.fx, depth), **fly(geom, draws, m, beta, eps, m.method)})
    return rows


def navigation_tables(folder, scenario_path, opts: NavBudgetOptions, workers: int = 2, only=None) -> tuple:
    """(navigation table, rendered touchdown table) of a budget folder's tables flown along ``scenario_path``'s
    descent (module docstring); progress on stderr. ``only``: fly just these configurations (no floor) — the
    same seeds give the rows a full run would, so they can replace those of an existing table."""
    import concurrent.futures as cf
    import sys
    import time

    import pyarrow as pa

    from renderlab.studies.retina_vs_spc.budget_tables import read_tables

    if opts.runs < 2:
        raise UserError(f"--runs must be >= 2, got {opts.runs}")
    bad = sorted(set(opts.mappings) - set(MAPPINGS))
    if bad:
        raise UserError(f"--mappings: {bad[0]!r} is not one of {', '.join(MAPPINGS)}")
    meas, configs = read_tables(folder)
    geom = descent_geometry(scenario_path)
    models = [m for mp in opts.mappings
              for m in error_models(meas, configs, geom.camera.fx, geom.cfg.gsd_ratio_range, mp, opts.gross_px)]
    if only:
        unknown = sorted(set(only) - {m.config for m in models})
        if unknown:
            raise UserError(f"--only: the budget has no configuration {unknown[0]!r}")
        models = [m for m in models if m.config in only]
    rows, t0 = [], time.perf_counter()
    with cf.ProcessPoolExecutor(max_workers=max(1, workers), initializer=_init_worker,
                                initargs=(str(scenario_path), models)) as pool:
        for i, r in enumerate(pool.map(_fly_run, [(run, opts.seed, not only) for run in range(opts.runs)])):
            rows += r
            if (i + 1) % 10 == 0 or i + 1 == opts.runs:
                print(f"[{i + 1}/{opts.runs}] runs flown ({len(r)} descents each, "
                      f"{time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    table = pa.table({k: [r[k] for r in rows] for k in rows[0]})
    return table, rendered_touchdown(scenario_path)


def rendered_touchdown(scenario_path):
    """The rendered campaign's touchdown rows (last image) from ``<scenario folder>/tables/descent_filter.parquet``:
    run, method, error and 1σ (east, north, up), NEES, track loss."""
    from pathlib import Path

    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    p = Path(scenario_path).parent / "tables" / "descent_filter.parquet"
    if not p.is_file():
        raise UserError(f"navigation budget: no rendered campaign table {p} beside the scenario")
    t = pq.read_table(p)
    last = pc.max(t.column("frame")).as_py()
    t = t.filter(pc.equal(t.column("frame"), last))
    keep = ["run", "method", "frame", "t_s", "err_e_m", "err_n_m", "err_u_m", "sig_e_m", "sig_n_m", "sig_u_m",
            "nees", "track_lost", "n_kept"]
    return t.select(keep)
