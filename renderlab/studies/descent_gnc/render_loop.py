"""The closed GN&C loop with images: each camera time renders the world where the vehicle really is.

:func:`fly_closed_loop` flies :func:`renderlab.dynamics.closed_loop.fly` on :class:`ImageNavigation`: the descent EKF
(``descent_ekf``) propagated on the accelerometer, and at every camera time the true pose rendered in memory
(``renderer.spec_at`` + ``render_spec``, a seed child per image), the landmark method run at the filter's a-priori
pose, the filter updated unless the image's NIS fails; misses widen the search, consecutive misses are a track loss.
Steps, noise model and robustness rules: ``docs/descent_gnc.md``; options: :mod:`.config`.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from estimators.descent_nav import pixel_covariance
from renderlab import plugins
from renderlab.contracts.landmark import CameraPose
from renderlab.contracts.navigation import FilterMeasurement
from renderlab.dynamics.closed_loop import fly
from renderlab.errors import UserError
from renderlab.geometry.rotations import look_at
from renderlab.measurement.runner import MeasureOptions, make_method, run_method_on_image
from renderlab.studies.descent_gnc.tables import MISSES


@dataclass
class ClosedLoopRun:
    """A flown run: the :class:`~renderlab.dynamics.closed_loop.Flight`, one record per image (counts, NIS, status,
    filter state after it, wall times), DN images if kept, initial estimate, end state, first track loss or None."""

    flight: object
    images: list = field(default_factory=list)
    dn: list = field(default_factory=list)
    x0_est: np.ndarray | None = None
    x_end: np.ndarray | None = None
    P_end: np.ndarray | None = None
    loss: dict | None = None


def _select(cam, pose, centres, spacing, cfg) -> np.ndarray:
    """Landmarks predicted inside the image with GSD ratio in range, ratio closest to 1 first."""
    xc = pose.to_camera(centres)
    ok = cam.in_image(cam.project(xc)) & (xc[:, 2] > 0)
    ratio = np.where(ok, xc[:, 2] / cam.fx / spacing, np.nan)
    lo, hi = cfg.gsd_ratio_range
    cand = np.flatnonzero(ok & (ratio >= lo) & (ratio <= hi))
    return cand[np.lexsort((cand, np.abs(np.log(ratio[cand]))))][: cfg.max_landmarks]


class ImageNavigation:
    """The descent EKF fed by rendered images at the camera times (module docstring); ``cfg`` a
    :class:`~renderlab.studies.descent_gnc.config.DescentGncConfig`."""

    def __init__(self, renderer, method, cfg, t0_s: float, x0, seed: int, look_at_m, *, spp=None,
                 keep_images: bool = False):
        self.r, self.cfg, self.spp, self.keep = renderer, cfg, spp, keep_images
        self.look_at_m = np.asarray(look_at_m, float)
        self.sig_st = math.radians(cfg.star_tracker_sigma_arcsec / 3600.0)
        self.mopts = MeasureOptions(n_sigma=cfg.n_sigma, min_search_px=cfg.min_search_px,
                                    max_search_px=cfg.max_search_px, campaign="descent_gnc", run=int(seed))
        self.method = make_method(method, self.mopts)
        ss_x0, ss_st, ss_acc, self.ss_img = np.random.SeedSequence(int(seed)).spawn(4)
        self.rng_st, self.rng_acc = np.random.default_rng(ss_st), np.random.default_rng(ss_acc)
        sig0 = np.r_[np.full(3, cfg.initial_position_sigma_m), np.full(3, cfg.initial_velocity_sigma_mps)]
        self.x0_est = np.asarray(x0, float) + sig0 * np.random.default_rng(ss_x0).standard_normal(6)
        omega = 2.0 * math.pi / renderer.plan.model.spin.period_s
        self.filt = plugins.filters.get("descent_ekf")({"gm_m3_s2": cfg.gm_filter_m3_s2, "omega_rad_s": (0.0, 0.0, omega),
                                                       "q_acc_m2_s3": cfg.q_acc_m2_s3,
                                                       "sigma_input_mps2": cfg.accel_sigma_mps2})
        self.filt.initialize(float(t0_s), self.x0_est, np.diag(sig0**2))
        self.maplets = sorted(renderer.plan.model.maplets, key=lambda m: m.landmark_id)
        self.centres = np.array([m.center_m for m in self.maplets], float)
        self.spacing = np.array([m.spacing_m for m in self.maplets], float)
        self.frame_times = np.array([f.pose.time_s for f in renderer.plan.frames], float)
        self.t0, self.images, self.dn, self.n_img, self.misses, self.loss = float(t0_s), [], [], 0, 0, None
        self.adc_max = (1 << int(renderer.options.bits)) - 1
        renderer.reset_exposure()

    def after_step(self, t0: float, t1: float, a_delivered) -> None:
        """The accelerometer's reading of the held acceleration drives the filter to t1."""
        u = np.asarray(a_delivered, float) + self.cfg.accel_sigma_mps2 * self.rng_acc.standard_normal(3)
        self.filt.set_input(u)
        self.filt.propagate(float(t1))

    def is_camera_time(self, t_s: float) -> bool:
        j = (float(t_s) - self.t0) / self.cfg.camera_period_s
        return abs(j - round(j)) < 1e-6

    def estimate(self, t_s: float, x_true) -> np.ndarray:
        if self.is_camera_time(t_s):
            x_true = np.asarray(x_true, float)
            R_true, R_star = self.attitude(x_true)
            dn, spec, t_render = self.render(float(t_s), x_true, R_true)
            self.measure_update(float(t_s), x_true, dn, spec, R_star, t_render)
        return self.filt.x

    def attitude(self, x_true: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(true camera attitude: boresight at the site, body +z up the image; the star tracker's reading of it)."""
        from scipy.spatial.transform import Rotation

        up = np.array([0.0, 0.0, 1.0])
        bore = self.look_at_m - x_true[:3]
        if abs(bore @ up) > 0.99 * np.linalg.norm(bore):
            up = np.array([1.0, 0.0, 0.0])
        R_true = look_at(x_true[:3], self.look_at_m, up).as_matrix()
        return R_true, R_true @ Rotation.from_rotvec(self.sig_st * self.rng_st.standard_normal(3)).as_matrix()

    def render(self, t: float, x_true: np.ndarray, R_true: np.ndarray):
        """(DN image, frame spec, wall seconds) of the world at t from the true pose."""
        t_start = time.perf_counter()
        spec = self.r.spec_at(t, {"position_m": x_true[:3], "R": R_true, "time_s": t})
        img = self.r.render_spec(spec, self.ss_img.spawn(1)[0], outputs=("dn",), spp=self.spp)
        return img.dn, spec, time.perf_counter() - t_start

    def measure_update(self, t: float, x_true: np.ndarray, dn, spec, R_star, t_render: float = math.nan) -> None:
        """Measure one image at the filter's a-priori pose, update, record it, count misses and track loss."""
        rec = {"t_s": t, "frame": int(np.argmin(np.abs(self.frame_times - t))), "position_m": x_true[:3].copy(),
               "n_candidates": 0, "n_attempted": 0, "n_results": 0, "n_kept": 0, "nis": math.nan, "nis_dof": 0,
               "widen": 1.0, "search_px": math.nan, "t_render_s": float(t_render), "t_measure_s": 0.0,
               "t_filter_s": 0.0}
        status = self._update(t, dn, spec, R_star, rec)
        rec["status"] = status
        if status in MISSES:
            self.misses += 1
            if self.misses >= self.cfg.track_loss_images and self.loss is None:
                site = self.r.plan.model.site
                alt = float((x_true[:3] - site.origin_m) @ site.R_body_from_site[:, 2])
                self.loss = {"t_s": t, "cause": status, "altitude_m": alt, "reacquired": False,
                             "image": self.n_img}
        elif status == "ok":
            self.misses = 0
            if self.loss is not None:
                self.loss["reacquired"] = True
        rec["x_est"], rec["P"] = self.filt.x, self.filt.P
        rec["err_pos_m"] = float(np.linalg.norm(self.filt.x[:3] - x_true[:3]))
        self.images.append(rec)
        if self.keep:
            self.dn.append(dn)
        self.n_img += 1

    def _update(self, t: float, dn, spec, R_star, rec: dict) -> str:
        cam, x, P, cfg = spec.camera, self.filt.x, self.filt.P, self.cfg
        pose = CameraPose(R_star, x[:3])
        sel = _select(cam, pose, self.centres, self.spacing, cfg)
        rec["n_candidates"] = int(sel.size)
        if sel.size == 0:
            return "no_landmarks"
        w = float(cfg.widen_factors[min(self.misses, len(cfg.widen_factors) - 1)])
        mopts = dataclasses.replace(self.mopts, n_sigma=cfg.n_sigma * w,
                                    max_search_px=int(math.ceil(cfg.max_search_px * w)))
        rec["widen"] = w
        t_start = time.perf_counter()
        att, res = run_method_on_image(self.method, dn, self.adc_max, cam, pose, spec.sun.direction_render,
                                       [self.maplets[i] for i in sel], self.centres[sel], P[:3, :3],
                                       np.eye(3) * self.sig_st**2, mopts, self.n_img)
        rec["t_measure_s"] = time.perf_counter() - t_start
        good = [i for i, r in enumerate(res) if r.has_result]
        rec["n_attempted"], rec["n_results"] = int(len(att)), len(good)
        if len(res):
            rec["search_px"] = float(np.median([r.search_px for r in res]))
        if not good:
            return "no_match"
        t_start = time.perf_counter()
        try:
            return self._filter(t, cam, x, R_star, self.centres[sel[att[good]]], [res[i] for i in good], rec)
        finally:
            rec["t_filter_s"] = time.perf_counter() - t_start

    def _filter(self, t: float, cam, x, R_star, pts, res: list, rec: dict) -> str:
        """Pixel update with σ_i² = σ_px² + (σ_g / GSD_i)² (eq. M3 of the descent EKF), undone on a χ² NIS miss."""
        from scipy.stats import chi2

        z = np.array([[r.meas_s, r.meas_l] for r in res]).reshape(-1)
        gsd = ((pts - x[:3]) @ R_star)[:, 2] / cam.fx
        sig = np.sqrt(self.cfg.sigma_px**2 + (self.cfg.sigma_ground_m / gsd) ** 2)
        R = pixel_covariance(cam, pts, x[:3], R_star, sig, self.sig_st)
        ctx = {"points_body_m": pts, "R_body_from_cam": R_star, "camera": cam,
               "flagged": np.array([r.outlier for r in res], bool)}
        before = copy.deepcopy(self.filt)
        try:
            upd = self.filt.update(t, FilterMeasurement("pixel", z, R, ctx))
        except UserError:
            self.filt = before
            return "diverged"
        rec["n_kept"], rec["nis"], rec["nis_dof"] = int(self.filt.last.kept.sum()), float(upd.nis), int(upd.dof)
        if upd.dof == 0:
            return "all_gated"
        p = self.cfg.nis_reject_probability
        if p < 1.0 and upd.nis > chi2.ppf(p, upd.dof):
            self.filt = before
            return "nis_rejected"
        return "ok"


def fly_closed_loop(renderer, method, guidance, cfg, *, truth, t0_s: float, x0, t_max_s: float, seed: int,
                    thrusters=None, look_at_m=None, spp=None, keep_images: bool = False) -> ClosedLoopRun:
    """Fly ``guidance`` (a :class:`~renderlab.contracts.guidance.GuidanceLaw`) on the images of ``renderer`` (an EV5
    world) measured by ``method`` (a name or a made method) through ``truth`` (a ``DescentTruth``) from (t0, x0) to
    contact or ``t_max_s``; ``seed`` roots the run's draws; the camera looks at ``look_at_m`` (default the site)."""
    if getattr(renderer.plan, "model", None) is None or not hasattr(renderer.plan.model, "maplets"):
        raise UserError("fly_closed_loop needs an EV5 world (a landmark catalogue and a spin state)")
    target = renderer.plan.model.site.origin_m if look_at_m is None else look_at_m
    nav = ImageNavigation(renderer, method, cfg, t0_s, x0, seed, target, spp=spp, keep_images=keep_images)
    flight = fly(truth, guidance, t0_s, x0, control_period_s=cfg.control_period_s, t_max_s=t_max_s,
                 navigation=nav, thrusters=thrusters)
    return ClosedLoopRun(flight, nav.images, nav.dn, nav.x0_est, nav.filt.x, nav.filt.P, nav.loss)
