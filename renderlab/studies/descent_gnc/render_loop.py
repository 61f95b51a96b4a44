r"""The closed GN&C loop with images: each camera time renders the world where the vehicle really is.

:func:`fly_closed_loop` flies :func:`renderlab.studies.descent_gnc.loop.fly` with an image-based navigation
(:class:`ImageNavigation`): the descent EKF (registered filter ``descent_ekf``, :mod:`estimators.descent_nav`)
propagated between control times with the accelerometer (the delivered acceleration + white noise), and at every
camera time t_j (every ``camera_period_s`` from the start, on the control ticks):

1. the true camera pose: at the vehicle's true position r(t_j), boresight at the site centre, body +z toward the
   top of the image (the attitude :mod:`renderlab.worlds.ev5.descent` plans); the star tracker reads it with
   N(0, σ_st²) per camera axis;
2. the image: ``renderer.spec_at(t_j, pose)`` + ``renderer.render_spec`` in memory — the world at the true time
   t_j (EV5: the sun of the nearest planned frame turned with the spin to t_j), the camera at the true pose; each
   image has its own seed (a child of the run's seed), so the same seed renders the same images and another seed
   other sensor noise; the exposure is chosen on the flight's first image (``renderer.reset_exposure`` at the
   start, so a flight does not depend on what the renderer rendered before);
3. the landmark method at the a-priori pose (the filter's position, the star tracker's attitude) on the landmarks
   predicted inside the image with GSD ratio in ``gsd_ratio_range`` (at most ``max_landmarks``, ratio closest to 1
   first), each with the search distance w·n_σ √λ_max of its projected covariance
   (:func:`renderlab.measurement.runner.run_method_on_image`), w the widening below;
4. the filter update with their pixels (kind ``"pixel"``, R of eq. M3 with σ_i² = σ_px² + (σ_g / GSD_i)² per
   landmark, GSD_i its predicted range / f_x, and σ_st), kept only when the image's NIS is inside the χ²
   quantile ``nis_reject_probability`` of its dof (else the filter is put back as it was before the image).

**Robustness.** An image is a *miss* when the method measured nothing (``no_match``), the filter's per-landmark
gate kept nothing (``all_gated``), the joint NIS failed (``nis_rejected``) or the update diverged (``diverged``);
an image with no landmark in range (below the camera's last useful altitude) is not a miss (``no_landmarks``).
After m consecutive misses the next search distance is widened by ``widen_factors[min(m, len − 1)]`` (re-
acquisition); ``track_loss_images`` consecutive misses are a track loss, recorded with its time, altitude and cause
(the first loss of the flight; later successes mark it re-acquired). Each image record carries its status and the
wall times of the render, the landmark measurement and the filter update.

The guidance flies on the filter's estimate; the seed draws the initial navigation error (N(0, P0)), the star
tracker, the accelerometer and the images from independent children. Heavy parts (the renderer) come in with
``renderer``.
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
from renderlab.errors import UserError
from renderlab.geometry.rotations import look_at
from renderlab.measurement.runner import MeasureOptions, make_method, run_method_on_image


@dataclass(frozen=True)
class ClosedLoopOptions:
    """Navigation and camera of :func:`fly_closed_loop` (SI; module docstring)."""

    control_period_s: float = 1.0
    camera_period_s: float = 1.0
    sigma_px: float = 0.3
    star_tracker_sigma_rad: float = 10.0 / 206264.806
    accel_sigma_mps2: float = 2e-5
    initial_position_sigma_m: float = 1.0
    initial_velocity_sigma_mps: float = 0.01
    gm_filter_m3_s2: float = 3.19
    q_acc_m2_s3: float = 1e-10
    max_landmarks: int = 8
    gsd_ratio_range: tuple = (0.4, 2.5)
    n_sigma: float = 3.0
    min_search_px: int = 2
    max_search_px: int = 32
    spp: int | None = None
    keep_images: bool = False
    sigma_ground_m: float = 0.0
    widen_factors: tuple = (1.0,)
    nis_reject_probability: float = 1.0
    track_loss_images: int = 2


@dataclass
class ClosedLoopRun:
    """A flown run: the flight (:class:`~renderlab.studies.descent_gnc.loop.Flight`), one record per image
    (``t_s``, ``frame`` the planned frame nearest in time, ``position_m`` true, ``n_candidates``, ``n_attempted``,
    ``n_results``, ``n_kept``, ``nis``, ``nis_dof``, ``status``, ``widen``, ``search_px`` (median), ``x_est`` and
    ``P`` of the filter after the image, ``err_pos_m``, ``t_render_s``, ``t_measure_s``, ``t_filter_s``), the DN
    images when kept, the initial estimate, the filter's state and covariance at the end (``x_end``, ``P_end``) and
    the first track loss (``loss``: ``t_s``, ``altitude_m``, ``cause``, ``reacquired``; None without)."""

    flight: object
    images: list = field(default_factory=list)
    dn: list = field(default_factory=list)
    x0_est: np.ndarray | None = None
    x_end: np.ndarray | None = None
    P_end: np.ndarray | None = None
    loss: dict | None = None


def _select(cam, pose, centres, spacing, opts) -> np.ndarray:
    """Landmarks predicted inside the image with GSD ratio in range, ratio closest to 1 first (module docstring)."""
    xc = pose.to_camera(centres)
    ok = cam.in_image(cam.project(xc)) & (xc[:, 2] > 0)
    ratio = np.where(ok, xc[:, 2] / cam.fx / spacing, np.nan)
    lo, hi = opts.gsd_ratio_range
    cand = np.flatnonzero(ok & (ratio >= lo) & (ratio <= hi))
    return cand[np.lexsort((cand, np.abs(np.log(ratio[cand]))))][: opts.max_landmarks]


class ImageNavigation:
    """The descent EKF fed by rendered images at the camera times (module docstring)."""

    def __init__(self, renderer, method, opts: ClosedLoopOptions, t0_s: float, x0, seed: int, look_at_m):
        self.r, self.opts, self.look_at_m = renderer, opts, np.asarray(look_at_m, float)
        self.mopts = MeasureOptions(n_sigma=opts.n_sigma, min_search_px=opts.min_search_px,
                                    max_search_px=opts.max_search_px, campaign="descent_gnc", run=int(seed))
        self.method = make_method(method, self.mopts)
        ss_x0, ss_st, ss_acc, self.ss_img = np.random.SeedSequence(int(seed)).spawn(4)
        self.rng_st, self.rng_acc = np.random.default_rng(ss_st), np.random.default_rng(ss_acc)
        sig0 = np.r_[np.full(3, opts.initial_position_sigma_m), np.full(3, opts.initial_velocity_sigma_mps)]
        self.x0_est = np.asarray(x0, float) + sig0 * np.random.default_rng(ss_x0).standard_normal(6)
        omega = 2.0 * math.pi / renderer.plan.model.spin.period_s
        self.filt = plugins.filters.get("descent_ekf")({"gm_m3_s2": opts.gm_filter_m3_s2,
                                                       "omega_rad_s": (0.0, 0.0, omega),
                                                       "q_acc_m2_s3": opts.q_acc_m2_s3,
                                                       "sigma_input_mps2": opts.accel_sigma_mps2})
        self.filt.initialize(float(t0_s), self.x0_est, np.diag(sig0**2))
        maplets = sorted(renderer.plan.model.maplets, key=lambda m: m.landmark_id)
        self.maplets = maplets
        self.centres = np.array([m.center_m for m in maplets], float)
        self.spacing = np.array([m.spacing_m for m in maplets], float)
        self.frame_times = np.array([f.pose.time_s for f in renderer.plan.frames], float)
        self.t0, self.images, self.dn, self.n_img = float(t0_s), [], [], 0
        self.misses, self.loss = 0, None
        self.adc_max = (1 << int(renderer.options.bits)) - 1
        renderer.reset_exposure()

    def after_step(self, t0: float, t1: float, a_delivered) -> None:
        """The accelerometer's reading of the held acceleration drives the filter to t1."""
        u = np.asarray(a_delivered, float) + self.opts.accel_sigma_mps2 * self.rng_acc.standard_normal(3)
        self.filt.set_input(u)
        self.filt.propagate(float(t1))

    def is_camera_time(self, t_s: float) -> bool:
        j = (float(t_s) - self.t0) / self.opts.camera_period_s
        return abs(j - round(j)) < 1e-6

    def estimate(self, t_s: float, x_true) -> np.ndarray:
        if self.is_camera_time(t_s):
            x_true = np.asarray(x_true, float)
            R_true, R_star = self.attitude(x_true)
            dn, spec, t_render = self.render(float(t_s), x_true, R_true)
            self.measure_update(float(t_s), x_true, dn, spec, R_star, t_render)
        return self.filt.x

    def attitude(self, x_true: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(true camera attitude, the star tracker's reading of it) at the true position."""
        from scipy.spatial.transform import Rotation

        up = np.array([0.0, 0.0, 1.0])
        bore = self.look_at_m - x_true[:3]
        if abs(bore @ up) > 0.99 * np.linalg.norm(bore):
            up = np.array([1.0, 0.0, 0.0])
        R_true = look_at(x_true[:3], self.look_at_m, up).as_matrix()
        return R_true, R_true @ Rotation.from_rotvec(self.opts.star_tracker_sigma_rad
                                                     * self.rng_st.standard_normal(3)).as_matrix()

    def render(self, t: float, x_true: np.ndarray, R_true: np.ndarray):
        """(DN image, frame spec, wall seconds) of the world at t from the true pose (module docstring, 2)."""
        t_start = time.perf_counter()
        spec = self.r.spec_at(t, {"position_m": x_true[:3], "R": R_true, "time_s": t})
        img = self.r.render_spec(spec, self.ss_img.spawn(1)[0], outputs=("dn",), spp=self.opts.spp)
        return img.dn, spec, time.perf_counter() - t_start

    def measure_update(self, t: float, x_true: np.ndarray, dn, spec, R_star, t_render: float = math.nan) -> None:
        """Measure one image at the filter's a-priori pose, update, and record it (module docstring, 3–4)."""
        rec = {"t_s": t, "frame": int(np.argmin(np.abs(self.frame_times - t))), "position_m": x_true[:3].copy(),
               "n_candidates": 0, "n_attempted": 0, "n_results": 0, "n_kept": 0, "nis": math.nan, "nis_dof": 0,
               "widen": 1.0, "search_px": math.nan, "t_render_s": float(t_render), "t_measure_s": 0.0,
               "t_filter_s": 0.0}
        status = self._update(t, dn, spec, R_star, rec)
        rec["status"] = status
        if status in ("no_match", "all_gated", "nis_rejected", "diverged"):
            self.misses += 1
            if self.misses >= self.opts.track_loss_images and self.loss is None:
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
        if self.opts.keep_images:
            self.dn.append(dn)
        self.n_img += 1

    def _update(self, t: float, dn, spec, R_star, rec: dict) -> str:
        cam, x, P = spec.camera, self.filt.x, self.filt.P
        pose = CameraPose(R_star, x[:3])
        sel = _select(cam, pose, self.centres, self.spacing, self.opts)
        rec["n_candidates"] = int(sel.size)
        if sel.size == 0:
            return "no_landmarks"
        w = float(self.opts.widen_factors[min(self.misses, len(self.opts.widen_factors) - 1)])
        mopts = dataclasses.replace(self.mopts, n_sigma=self.opts.n_sigma * w,
                                    max_search_px=int(math.ceil(self.opts.max_search_px * w)))
        rec["widen"] = w
        cov_r = np.eye(3) * self.opts.star_tracker_sigma_rad**2
        t_start = time.perf_counter()
        att, res = run_method_on_image(self.method, dn, self.adc_max, cam, pose, spec.sun.direction_render,
                                       [self.maplets[i] for i in sel], self.centres[sel], P[:3, :3], cov_r,
                                       mopts, self.n_img)
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
        from scipy.stats import chi2

        z = np.array([[r.meas_s, r.meas_l] for r in res]).reshape(-1)
        gsd = ((pts - x[:3]) @ R_star)[:, 2] / cam.fx
        sig = np.sqrt(self.opts.sigma_px**2 + (self.opts.sigma_ground_m / gsd) ** 2)
        R = pixel_covariance(cam, pts, x[:3], R_star, sig, self.opts.star_tracker_sigma_rad)
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
        if self.opts.nis_reject_probability < 1.0 and upd.nis > chi2.ppf(self.opts.nis_reject_probability, upd.dof):
            self.filt = before
            return "nis_rejected"
        return "ok"


def fly_closed_loop(renderer, method, guidance, *, truth, t0_s: float, x0, t_max_s: float, seed: int,
                    options: ClosedLoopOptions = ClosedLoopOptions(), thrusters=None,
                    look_at_m=None) -> ClosedLoopRun:
    """Fly ``guidance`` on the images of ``renderer`` measured by ``method`` (module docstring).

    Parameters
    ----------
    renderer : renderlab.Renderer
        An EV5 world (its plan gives the maplets, the spin and the planned frames).
    method : str or landmark method
        A registered landmark-method name or a made method.
    guidance : GuidanceLaw
        Made with the run's waypoints (:func:`renderlab.studies.descent_gnc.waypoints.arrm_waypoints`).
    truth : renderlab.dynamics.descent_truth.DescentTruth
        The truth dynamics (gravity, spin, contact surface).
    t0_s, x0 : float, array (6,)
        Start time and true state.
    t_max_s : float
        Flight ends here unless contact comes first.
    seed : int
        Root of the run's draws (initial error, star tracker, accelerometer, image noise).
    look_at_m : array (3,), optional
        Where the camera points (default: the site centre).
    """
    from renderlab.studies.descent_gnc.loop import fly

    if getattr(renderer.plan, "model", None) is None or not hasattr(renderer.plan.model, "maplets"):
        raise UserError("fly_closed_loop needs an EV5 world (a landmark catalogue and a spin state)")
    ratio = options.camera_period_s / options.control_period_s
    if not options.camera_period_s > 0 or abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
        raise UserError("fly_closed_loop: camera_period_s must be a whole multiple of control_period_s")
    target = renderer.plan.model.site.origin_m if look_at_m is None else look_at_m
    nav = ImageNavigation(renderer, method, options, t0_s, x0, seed, target)
    flight = fly(truth, guidance, t0_s, x0, control_period_s=options.control_period_s, t_max_s=t_max_s,
                 navigation=nav, thrusters=thrusters)
    return ClosedLoopRun(flight, nav.images, nav.dn, nav.x0_est, nav.filt.x, nav.filt.P, nav.loss)
