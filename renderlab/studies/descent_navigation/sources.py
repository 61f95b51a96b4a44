r"""Measurement sources of the descent study: what turns image k of a run into the filter's landmark measurement —
a registered landmark method on the image (:class:`LandmarkMethodSource`) or a registered source kind such as
``geometric`` (:class:`GeometricSource`, true pixel + injected error, eq. G1 of docs/descent_navigation.md)."""

from __future__ import annotations

import math

import numpy as np

from estimators.descent_nav import pixel_covariance
from renderlab.contracts.landmark import CameraPose, LandmarkResult
from renderlab.contracts.navigation import FilterMeasurement
from renderlab.measurement.runner import _frame_record, run_method_on_image


def select_landmarks(cam, pose, centres, spacing, cfg) -> np.ndarray:
    """Indices of the landmarks to attempt, deterministic: those the a-priori ``pose`` predicts inside the image
    whose GSD ratio (predicted range / fx / maplet spacing) lies in ``cfg.gsd_ratio_range``, at most
    ``cfg.max_landmarks``, GSD ratio closest to 1 first."""
    xc = pose.to_camera(centres)
    sl = cam.project(xc)
    ok = cam.in_image(sl) & (xc[:, 2] > 0)
    ratio = np.where(ok, xc[:, 2] / cam.fx / spacing, np.nan)
    lo, hi = cfg.gsd_ratio_range
    cand = np.flatnonzero(ok & (ratio >= lo) & (ratio <= hi))
    order = np.lexsort((cand, np.abs(np.log(ratio[cand]))))
    return cand[order][: cfg.max_landmarks]


def map_context(maplets, sigma_h_m, sigma_v_m) -> dict:
    """Landmark ids and the declared map covariance of each (body frame, m²): R_bm diag(σ_h², σ_h², σ_v²) R_bmᵀ
    (σ per landmark, (k,))."""
    h, v = np.broadcast_to(sigma_h_m, (len(maplets),)), np.broadcast_to(sigma_v_m, (len(maplets),))
    return {"landmark_ids": np.array([int(m.landmark_id) for m in maplets], int),
            "landmark_cov_m2": np.stack([m.R_body_from_maplet @ np.diag([a**2, a**2, b**2]) @ m.R_body_from_maplet.T
                                         for m, a, b in zip(maplets, h, v)])}


def declared_sigma(cfg, name: str, spacing, gsd) -> np.ndarray:
    """Each landmark's declared pixel σ of the filter (k,): σ_px (per tier) and the ground term (eq. M3's input)."""
    s_px = cfg.landmark_sigmas(name, spacing)[0]
    sg = cfg.ground_sigma_for(name)
    return np.sqrt(s_px**2 + (sg / gsd) ** 2) if sg > 0 else s_px


def _filter_measurement(inp, k, cfg, name, sel_ok, z, x, cam, flagged) -> FilterMeasurement:
    """The FilterMeasurement of the landmarks ``sel_ok`` measured at ``z`` (k, 2): R of eq. M3 with the declared σ."""
    pts = inp.centres[sel_ok]
    gsd = ((pts - x[:3]) @ inp.R_star[k])[:, 2] / cam.fx
    sig = declared_sigma(cfg, name, inp.spacing[sel_ok], gsd)
    R = pixel_covariance(cam, pts, x[:3], inp.R_star[k], sig, inp.sigma_st_rad)
    ctx = {"points_body_m": pts, "R_body_from_cam": inp.R_star[k], "camera": cam, "flagged": flagged}
    if cfg.map_states != "off":
        _, s_mh, s_mv = cfg.landmark_sigmas(name, inp.spacing[sel_ok])
        ctx.update(map_context([inp.maplets[i] for i in sel_ok], s_mh, s_mv))
    return FilterMeasurement("pixel", np.asarray(z, float).reshape(-1), R, ctx)


class LandmarkMethodSource:
    """A registered image-based landmark method as a measurement source (the study's ``methods``)."""

    needs_images = True

    def __init__(self, impl, cfg, mopts):
        self.impl, self.cfg, self.mopts, self.name = impl, cfg, mopts, impl.name

    def prepare(self, inp, seed_sequence) -> None:
        """Nothing to draw: the method sees the run's image."""

    def columns(self) -> dict:
        return {}

    def measure(self, inp, k, filt):
        """(selected, results, FilterMeasurement or None) of image k at the filter's a-priori pose."""
        fr = _frame_record(inp.ts, k)
        x, P = filt.x, filt.P
        pose = CameraPose(inp.R_star[k], x[:3])
        sel = select_landmarks(fr.camera, pose, inp.centres, inp.spacing, self.cfg)
        if sel.size == 0:
            return sel, [], None
        cov_r = np.eye(3) * inp.sigma_st_rad**2
        _, results = run_method_on_image(self.impl, inp.image(k), fr.adc_max, fr.camera, pose, fr.sun,
                                         [inp.maplets[i] for i in sel], inp.centres[sel], P[:3, :3], cov_r,
                                         self.mopts, k)
        good = [i for i, r in enumerate(results) if r.has_result]
        if not good:
            return sel, results, None
        z = np.array([[results[i].meas_s, results[i].meas_l] for i in good])
        flagged = np.array([results[i].outlier for i in good], bool)
        return sel, results, _filter_measurement(inp, k, self.cfg, self.name, sel[good], z, x, fr.camera, flagged)


class GeometricSource:
    """True pixel + injected error, eq. G1 (module docstring); ``spec`` a
    :class:`~renderlab.studies.descent_navigation.config.MeasurementSourceConfig`."""

    needs_images = False

    def __init__(self, spec, cfg):
        self.spec, self.cfg, self.name = spec, cfg, spec.name
        self._beta = self._eps = self._delta = None

    def columns(self) -> dict:
        """The injected error of eq. G1, constant over the run (NaN σ_n: the declared σ per landmark)."""
        s = self.spec
        return {"src_kind": s.kind, "inj_bias_s_px": float(s.bias_px[0]), "inj_bias_l_px": float(s.bias_px[1]),
                "inj_sigma_bias_px": float(s.sigma_bias_px), "inj_scale": float(s.scale),
                "inj_sigma_noise_px": math.nan if s.sigma_noise_px is None else float(s.sigma_noise_px),
                "inj_map_offset_h_m": float(s.map_offset_h_m),
                "inj_map_offset_v_m": float(s.map_offset_h_m if s.map_offset_v_m is None else s.map_offset_v_m)}

    def prepare(self, inp, seed_sequence) -> None:
        """Draw β (L, 2), ε (K, L, 2), γ (L, 3) → δ (L, 3) from ``seed_sequence`` (the same for every source)."""
        rng = np.random.default_rng(seed_sequence)
        n_l, n_k = len(inp.centres), len(inp.times)
        self._beta = rng.standard_normal((n_l, 2))
        self._eps = rng.standard_normal((n_k, n_l, 2))
        gamma = rng.standard_normal((n_l, 3))
        c = self.columns()
        sd = np.array([c["inj_map_offset_h_m"], c["inj_map_offset_h_m"], c["inj_map_offset_v_m"]])
        self._delta = np.stack([m.R_body_from_maplet @ (sd * g) for m, g in zip(inp.maplets, gamma)]) \
            if n_l else np.zeros((0, 3))

    def measure(self, inp, k, filt):
        """(selected, results, FilterMeasurement or None) of image k: eq. G1 at the selected landmarks."""

        s, cam, x = self.spec, inp.cameras[k], filt.x
        pose = CameraPose(inp.R_star[k], x[:3])
        sel = select_landmarks(cam, pose, inp.centres, inp.spacing, self.cfg)
        if sel.size == 0:
            return sel, [], None
        pred = cam.project(pose.to_camera(inp.centres[sel]))
        xc = CameraPose(inp.R_true[k], inp.pos_true[k]).to_camera(inp.centres[sel] + self._delta[sel])
        true_px = cam.project(xc)
        ok = cam.in_image(true_px) & (xc[:, 2] > 0)
        gsd = ((inp.centres[sel] - x[:3]) @ inp.R_star[k])[:, 2] / cam.fx
        sn = declared_sigma(self.cfg, self.name, inp.spacing[sel], gsd) if s.sigma_noise_px is None \
            else np.full(len(sel), float(s.sigma_noise_px))
        pp = np.array([cam.cx, cam.cy])
        z = pp + (1.0 + s.scale) * (true_px - pp) + np.asarray(s.bias_px, float) \
            + s.sigma_bias_px * self._beta[sel] + sn[:, None] * self._eps[k, sel]
        results = []
        for j, i in enumerate(sel):
            lid, (ps, pl) = int(inp.maplets[i].landmark_id), pred[j]
            results.append(LandmarkResult(lid, float(ps), float(pl), float(z[j, 0] - ps), float(z[j, 1] - pl))
                           if ok[j] else LandmarkResult(lid, float(ps), float(pl), reason="off_image"))
        if not ok.any():
            return sel, results, None
        return sel, results, _filter_measurement(inp, k, self.cfg, self.name, sel[ok], z[ok], x, cam,
                                                 np.zeros(int(ok.sum()), bool))
