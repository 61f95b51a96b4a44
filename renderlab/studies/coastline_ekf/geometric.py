"""Geometric coastline-navigation Monte Carlo, the way Straub & Christian simulated it (Section III.B): the truth
orbit, a nadir camera and the GSHHG points it sees (shared by all runs), then N seeded runs of the EKF in lock-step
(LOS tilted by σθ, eq. 18; star-tracker noise). Output: the filter table of :data:`FILTER_COLUMNS`, RIC axes of the
true state. The simulation in full: docs/coastline_ekf.md.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np

from estimators.coastline.ekf import BatchCoastlineEKF, EKFOptions, nees
from estimators.coastline.los import los_predict, perturb_unit_vectors, small_rotation_matrices
from estimators.coastline.sqrt_ekf import SqrtBatchCoastlineEKF
from renderlab.dynamics.orbits import MU_EARTH, nadir_attitude, ric_axes, state_from_elements
from renderlab.dynamics.truth_orbit import propagate_for  # RK4 two-body/J2, or zonal_dop853 if asked
from renderlab.errors import UserError
from renderlab.worlds.earth.coast_points import coastline_points, points_in_view, spread_pick, view_query_radius_m

__all__ = ["CoastlineGeometricOptions", "Geometry", "PAPER_ORBITS", "paper_orbit", "truth_geometry",
           "draws_for_runs", "measurements", "run_batch", "FILTER_COLUMNS", "TRUTH_FIELDS", "filter_table"]

R_EARTH_M = 6378137.0
OMEGA_EARTH = 7.292115e-5

#: the coastline filter table (then ``has_result``, ``reason``: :data:`renderlab.contracts.schemas.FILTER_CORE`)
FILTER_COLUMNS = ["run", "t_s", "err_r_m", "err_i_m", "err_c_m", "err_vr_mps", "err_vi_mps", "err_vc_mps",
                  "sig_r_m", "sig_i_m", "sig_c_m", "sig_vr_mps", "sig_vi_mps", "sig_vc_mps", "nees", "nis",
                  "n_meas"]
#: the truth propagator's settings (``trajectory.truth_model`` and its force options; the filter keeps its own model)
TRUTH_FIELDS = ("truth_model", "zonal_degree", "drag", "srp", "third_body", "drag_cd", "srp_cr",
                "area_to_mass_m2_kg")


@dataclass(frozen=True)
class CoastlineGeometricOptions:
    """Options of one geometric coastline-EKF study (SI units; angles in rad); the paper's defaults where it states
    them, stated assumptions otherwise (docs/coastline_ekf.md). ``truth_model = "zonal_dop853"``: DOP853 with
    EGM2008 zonals J2..J``zonal_degree`` (+ optional drag, SRP, Sun/Moon) as truth; ``"j2_rk4"``: the filter's class."""

    altitude_m: float = 1.0e6
    inclination_rad: float = 0.0
    raan_rad: float = 0.0
    argp_rad: float = 0.0
    nu0_rad: float = 0.0
    gmst0_rad: float = 0.0
    truth_j2: bool = False
    duration_s: float | None = None          # None: one orbital period
    cadence_s: float = 30.0
    fov_rad: float = math.radians(30.0)
    points_per_image: int = 16
    db_spacing_m: float = 2000.0
    sigma_theta_rad: float = 5.0e-4
    sigma_star_tracker_rad: float = 2.424e-5  # 5 arcsec per axis
    sigma_r0_m: float | tuple[float, float, float] = 500.0      # per ECI axis (one value: all three)
    sigma_v0_mps: float | tuple[float, float, float] = 0.005
    q_acc_m2_s3: float = 0.0
    filter_step_s: float = 10.0
    t0_s: float = 0.0                         # filter start (prior) time after the elements' epoch
    filter_form: str = "joseph"               # "joseph" (eq. 7) or "sqrt" (array-form QR square root)
    truth_model: str = "j2_rk4"
    zonal_degree: int = 6
    drag: bool = False
    srp: bool = False
    third_body: bool = False
    drag_cd: float = 2.2
    srp_cr: float = 1.3
    area_to_mass_m2_kg: float = 0.01

    def validate(self) -> "CoastlineGeometricOptions":
        checks = [("altitude_m", 1.0e5 <= self.altitude_m <= 5.0e7, "between 100 km and 50000 km"),
                  ("cadence_s", self.cadence_s > 0, "> 0"), ("points_per_image", self.points_per_image >= 1, ">= 1"),
                  ("fov_rad", 0 < self.fov_rad < math.radians(120), "in (0, 120°)"),
                  ("db_spacing_m", self.db_spacing_m >= 100.0, ">= 100 m"),
                  ("sigma_theta_rad", self.sigma_theta_rad > 0, "> 0 (the filter needs R, eq. 18)"),
                  ("sigma_star_tracker_rad", self.sigma_star_tracker_rad >= 0, ">= 0"),
                  ("q_acc_m2_s3", self.q_acc_m2_s3 >= 0, ">= 0"), ("filter_step_s", self.filter_step_s > 0, "> 0"),
                  ("t0_s", self.t0_s >= 0, ">= 0")]
        if self.filter_form not in ("joseph", "sqrt"):
            raise UserError(f"coastline study option filter_form = {self.filter_form!r} must be 'joseph' or 'sqrt'")
        if self.duration_s is not None:
            checks.append(("duration_s", self.duration_s >= self.cadence_s, ">= cadence_s"))
        for name, ok, what in checks:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and ok):
                raise UserError(f"coastline study option {name} = {value!r} must be {what}")
        for name in ("sigma_r0_m", "sigma_v0_mps"):
            v = np.atleast_1d(np.asarray(getattr(self, name), dtype=float))
            if v.shape not in ((1,), (3,)) or not np.all(np.isfinite(v) & (v > 0)):
                raise UserError(f"coastline study option {name} = {getattr(self, name)!r} must be > 0 "
                                "(one value or one per axis)")
        return self

    def initial_sigmas(self) -> np.ndarray:
        """Per-axis 1σ of the initial estimate, (6,): [σ_r (m) x3, σ_v (m/s) x3]."""
        return np.concatenate([np.broadcast_to(np.asarray(self.sigma_r0_m, float), 3),
                               np.broadcast_to(np.asarray(self.sigma_v0_mps, float), 3)])

    @property
    def period_s(self) -> float:
        a = R_EARTH_M + self.altitude_m
        return 2.0 * math.pi * math.sqrt(a**3 / MU_EARTH)


PAPER_ORBITS = {  # name -> (altitude_m, inclination_deg), Table 1
    "i00_h1000": (1.0e6, 0.0), "i45_h1000": (1.0e6, 45.0), "i90_h1000": (1.0e6, 90.0),
    "i45_h500": (5.0e5, 45.0), "i90_h500": (5.0e5, 90.0),
}


def paper_orbit(name: str, **overrides) -> CoastlineGeometricOptions:
    """Options for one of the paper's five orbits (``PAPER_ORBITS``) with any option overridden."""
    if name not in PAPER_ORBITS:
        raise UserError(f"unknown coastline orbit {name!r}; choose one of {', '.join(PAPER_ORBITS)}")
    h, inc = PAPER_ORBITS[name]
    return replace(CoastlineGeometricOptions(altitude_m=h, inclination_rad=math.radians(inc)), **overrides).validate()


@dataclass
class Geometry:
    """Truth shared by all runs: times (K,), states (K, 6), T_cam_from_eci (K, 3, 3), matched points per time."""

    t_s: np.ndarray
    x_true: np.ndarray
    T_cam_from_eci: np.ndarray
    points_eci: list[np.ndarray]     # per time (m_k, 3); m_0 = 0 (initial estimate only)
    n_meas: np.ndarray               # (K,)


def _R3(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])   # ECEF = R3(θ) ECI


def _geometry_key(o: CoastlineGeometricOptions) -> CoastlineGeometricOptions:
    """Options with the per-run noise fields reset, so runs differing only in noise share the truth."""
    return replace(o, sigma_theta_rad=1.0, sigma_star_tracker_rad=0.0, sigma_r0_m=1.0, sigma_v0_mps=1.0,
                   q_acc_m2_s3=0.0, filter_step_s=1.0, filter_form="joseph")


def truth_geometry(options: CoastlineGeometricOptions) -> Geometry:
    """Truth orbit (:func:`~renderlab.dynamics.truth_orbit.propagate_for`), attitude, matched points (cached)."""
    return _truth_geometry_cached(_geometry_key(options.validate()))


@functools.lru_cache(maxsize=8)
def _truth_geometry_cached(o: CoastlineGeometricOptions) -> Geometry:
    duration = o.period_s if o.duration_s is None else o.duration_s
    K = int(math.floor(duration / o.cadence_s + 1e-9)) + 1
    t = o.t0_s + np.arange(K) * o.cadence_s
    r0, v0 = state_from_elements(R_EARTH_M + o.altitude_m, 0.0, o.inclination_rad, o.raan_rad, o.argp_rad,
                                 o.nu0_rad)
    x = propagate_for(o, np.concatenate([r0, v0]), t, pole="+z", rk4_step_s=1.0)  # the study's ECI: equator of date
    T = np.swapaxes(nadir_attitude(x[:, :3], x[:, 3:]), -1, -2)          # cam_from_eci
    db = coastline_points(o.db_spacing_m)
    tan_half = math.tan(0.5 * o.fov_rad)
    query_r = view_query_radius_m(R_EARTH_M, o.altitude_m, o.fov_rad)
    g = max(1, int(math.isqrt(o.points_per_image)))
    points, n_meas = [np.zeros((0, 3))], [0]
    for k in range(1, K):
        p_eci, u, w = points_in_view(db, x[k, :3], _R3(o.gmst0_rad + OMEGA_EARTH * t[k]), T[k], tan_half, R_EARTH_M,
                                     query_r)
        if len(p_eci):
            p_eci = p_eci[spread_pick(u, w, tan_half, g)]
        points.append(p_eci)
        n_meas.append(len(p_eci))
    return Geometry(t, x, T, points, np.asarray(n_meas))


def draws_for_runs(seed_sequences, K: int, points_per_image: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stacked per-run draws: initial-state (N, 6), LOS (N, K, m_max, 2), attitude (N, K, 3) standard normals; each
    run's from its own ``PCG64(seed_sequence)`` in that order (independent of the batch it runs in)."""
    m_max = max(1, int(math.isqrt(points_per_image)) ** 2)
    gens = [np.random.Generator(np.random.PCG64(s)) for s in seed_sequences]
    draws = [(g.standard_normal(6), g.standard_normal((K, m_max, 2)), g.standard_normal((K, 3))) for g in gens]
    return tuple(np.stack([d[j] for d in draws]) for j in range(3))


def measurements(geo: Geometry, k: int, z_los_k: np.ndarray, z_att_k: np.ndarray, sigma_los: float,
                 sigma_att: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Image k for N runs: camera-frame LOS from the true pose tilted by σ_los (N, m, 3; eq. 18), database points
    (m, 3), star-tracker T̂ = exp([σ_att z×]) T_true (N, 3, 3)."""
    pts = geo.points_eci[k]
    m, N = len(pts), len(z_los_k)
    e_true, _, _ = los_predict(geo.x_true[k:k + 1, :3], pts, geo.T_cam_from_eci[k])
    y = perturb_unit_vectors(np.broadcast_to(e_true, (N, m, 3)), sigma_los, z_los_k[:, :m])
    T_hat = np.matmul(small_rotation_matrices(sigma_att * z_att_k), geo.T_cam_from_eci[k])
    return y, pts, T_hat


def _make_filter(o: CoastlineGeometricOptions, x0_hat: np.ndarray, P0: np.ndarray):
    """The batch filter of ``o.filter_form`` started at x̂0 (N, 6), P0 (6, 6), and its NEES of errors (N, 6)."""
    filt = SqrtBatchCoastlineEKF if o.filter_form == "sqrt" else BatchCoastlineEKF
    ekf = filt(x0_hat, P0, EKFOptions(sigma_theta_rad=o.sigma_theta_rad, sigma_attitude_rad=o.sigma_star_tracker_rad,
                                      q_acc_m2_s3=o.q_acc_m2_s3, max_step_s=o.filter_step_s))
    nees_of = ekf.nees if o.filter_form == "sqrt" else (lambda e: nees(e, ekf.P))   # sqrt: ‖S⁻¹e‖²
    return ekf, nees_of


def _filter_images(geo: Geometry, ekf, nees_of, z_los, z_att, sig_los: float, sig_att: float, progress: bool):
    """The N filters through every time of ``geo`` → x̂, P, NIS (NaN without a matched point), NEES per run and time."""
    N, K = len(ekf.x), len(geo.t_s)
    xs, Ps = np.empty((N, K, 6)), np.empty((N, K, 6, 6))
    nis, nees_v = np.full((N, K), np.nan), np.empty((N, K))
    xs[:, 0], Ps[:, 0] = ekf.x, ekf.P
    nees_v[:, 0] = nees_of(ekf.x - geo.x_true[0])
    steps = range(1, K)
    if progress:
        from tqdm import tqdm

        steps = tqdm(steps, desc=f"coastline EKF x{N}", unit="image")
    for k in steps:
        ekf.propagate(geo.t_s[k] - geo.t_s[k - 1])
        if geo.n_meas[k]:
            y, pts, T_hat = measurements(geo, k, z_los[:, k], z_att[:, k], sig_los, sig_att)
            nis[:, k] = ekf.update(y, pts, T_hat).nis
        xs[:, k], Ps[:, k] = ekf.x, ekf.P
        nees_v[:, k] = nees_of(ekf.x - geo.x_true[k])
    return xs, Ps, nis, nees_v


def filter_table(t_s, x_true, runs, xs, Ps, nis, nees_v, n_meas):
    """The :data:`FILTER_COLUMNS` table (then ``has_result``, ``reason``) of N runs on K times: RIC errors and 1σ
    about the truth ``x_true`` (K, 6) of the estimates ``xs`` (N, K, 6) and covariances ``Ps`` (N, K, 6, 6), NEES,
    NIS (N, K), matched LOS ``n_meas`` (K,)."""
    import pyarrow as pa

    N, K = xs.shape[:2]
    err = xs - x_true[None]
    C = ric_axes(x_true)                                                      # (K, 3, 3)
    e_r = np.einsum("kij,nkj->nki", C, err[..., :3])
    e_v = np.einsum("kij,nkj->nki", C, err[..., 3:])
    C6 = np.zeros((K, 6, 6))
    C6[:, :3, :3] = C
    C6[:, 3:, 3:] = C
    sig = np.sqrt(np.sum(np.matmul(C6[None], Ps) * C6[None], axis=-1))      # sqrt diag(C P Cᵀ)
    cols = {"run": np.repeat(np.asarray(runs, dtype=np.int64), K), "t_s": np.tile(t_s, N)}
    vals = np.concatenate([e_r, e_v, sig], axis=-1)
    for j, name in enumerate(FILTER_COLUMNS[2:14]):                           # err_r_m ... sig_vc_mps
        cols[name] = vals[..., j].ravel()
    cols.update(nees=nees_v.ravel(), nis=nis.ravel(), n_meas=np.tile(np.asarray(n_meas).astype(np.int32), N))
    prior = np.tile(np.arange(K) == 0, N)        # reason (FilterReason): the prior, an update, or no line of sight
    cols["has_result"] = (cols["n_meas"] > 0) & ~prior
    reason = np.where(prior, "prior", np.where(cols["has_result"], "ok", "no_measurement"))
    cols["reason"] = pa.array(reason.tolist(), pa.string()).dictionary_encode()
    return pa.table(cols)


def run_batch(options: CoastlineGeometricOptions, seed_sequences, run_indices=None, *, noise_free: bool = False,
              progress: bool = False, keep_history: bool = False) -> dict:
    """Run N filters (one per spawned seed sequence) through the same truth, vectorised across runs →
    ``{"table": filter_table, "geometry": Geometry}`` (+ ``x_hat`` (N, K, 6), ``P`` with ``keep_history``).
    ``run_indices``: the ``run`` column (default 0..N-1); ``noise_free``: exact measurements and attitude (the filter
    still assumes σθ, σ_att; the initial dispersion stays); ``progress``: a tqdm bar over the images."""
    o = options.validate()
    geo = truth_geometry(o)
    seeds = list(seed_sequences)
    N, K = len(seeds), len(geo.t_s)
    if N == 0:
        raise UserError("coastline study: no runs requested")
    runs = np.arange(N) if run_indices is None else np.asarray(list(run_indices), dtype=np.int64)
    z_x0, z_los, z_att = draws_for_runs(seeds, K, o.points_per_image)
    sd0 = o.initial_sigmas()
    ekf, nees_of = _make_filter(o, geo.x_true[0] + z_x0 * sd0, np.diag(sd0**2))
    sig_los = 0.0 if noise_free else o.sigma_theta_rad
    sig_att = 0.0 if noise_free else o.sigma_star_tracker_rad
    xs, Ps, nis, nees_v = _filter_images(geo, ekf, nees_of, z_los, z_att, sig_los, sig_att, progress)
    out = {"table": filter_table(geo.t_s, geo.x_true, runs, xs, Ps, nis, nees_v, geo.n_meas), "geometry": geo}
    if keep_history:
        out.update(x_hat=xs, P=Ps)
    return out
