r"""Geometric coastline-navigation Monte Carlo, the way Straub & Christian simulated it (Section III.B).

Truth: a circular orbit from classical elements (RAAN, ω, ν = 0 in the paper), propagated by
:func:`renderlab.dynamics.orbits.propagate` (two-body, eq. 10-12, optionally + J2); a nadir-pointing
camera with a square field of view (30° in the paper; ground footprint eq. 1); the Earth turning at
ω⊕ from GMST ``gmst0_rad`` at t = 0. At every measurement time the database coastline points
(:mod:`.coastline_database`, real GSHHG) that lie inside the camera's field of view and face the
camera are found; the image is cut into a g×g grid (g² ≤ ``points_per_image``) and the point nearest each
occupied cell's centre is taken, so matched points spread over the image. All of this depends on the
truth only and is shared by every run.

Per run (its own ``numpy.random.Generator`` from one spawned ``SeedSequence``, draws in a fixed layout so
run k replays alone bit-identically): the initial estimate is the truth plus N(0, diag(σ_r², σ_v²))
(500 m / 5 mm/s per axis in the paper); each LOS is the true camera-frame unit vector tilted by σθ
(eq. 18 noise model); the star tracker reports the attitude rotated by N(0, σ_att² I). The filter is
:class:`estimators.coastline.ekf.BatchCoastlineEKF`, all runs in lock-step (``filter_form = "sqrt"``: the
square-root form :class:`estimators.coastline.sqrt_ekf.SqrtBatchCoastlineEKF`, same model). The prior is at
``t0_s`` (after the elements' epoch), images every ``cadence_s`` after it.

Output (design's filter-study schema), one row per run and time: ``run, t_s, err_r_m, err_i_m, err_c_m,
err_vr_mps, err_vi_mps, err_vc_mps, sig_r_m, sig_i_m, sig_c_m, sig_vr_mps, sig_vi_mps, sig_vc_mps, nees,
nis, n_meas``. RIC = radial, in-track (ĥ × r̂), cross-track (ĥ = r × v/|r × v|) of the *true* state; velocity
errors are the inertial velocity error resolved on those axes. ``nees`` has 6 degrees of freedom, ``nis``
2·n_meas (NaN where n_meas = 0; row t = 0 is the initial estimate, before any image).
"""

from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass, fields, replace

import numpy as np

from estimators.coastline.ekf import BatchCoastlineEKF, EKFOptions, nees
from estimators.coastline.los import los_predict, perturb_unit_vectors, small_rotation_matrices
from estimators.coastline.sqrt_ekf import SqrtBatchCoastlineEKF
from renderlab.dynamics.orbits import MU_EARTH, nadir_attitude, state_from_elements
from renderlab.dynamics.truth_orbit import propagate_for  # RK4 two-body/J2, or zonal_dop853 if asked
from renderlab.errors import UserError
from renderlab.worlds.earth.coast_points import coastline_points

__all__ = ["CoastlineGeometricOptions", "Geometry", "PAPER_ORBITS", "paper_orbit", "truth_geometry",
           "draws_for_runs", "measurements", "run_batch", "run", "ric_axes", "FILTER_COLUMNS"]

R_EARTH_M = 6378137.0
OMEGA_EARTH = 7.292115e-5

#: the coastline filter table (then ``has_result``, ``reason``: :data:`renderlab.contracts.schemas.FILTER_CORE`)
FILTER_COLUMNS = ["run", "t_s", "err_r_m", "err_i_m", "err_c_m", "err_vr_mps", "err_vi_mps", "err_vc_mps",
                  "sig_r_m", "sig_i_m", "sig_c_m", "sig_vr_mps", "sig_vi_mps", "sig_vc_mps", "nees", "nis",
                  "n_meas"]


@dataclass(frozen=True)
class CoastlineGeometricOptions:
    """Options of one geometric coastline-EKF study (SI units; angles in rad).

    The defaults are the paper's where it states them (30° FOV, 500 m / 5 mm/s dispersion, RAAN = ω = ν = 0,
    two-body truth, 30 s cadence from Section III.A); the rest are stated assumptions: σθ = 0.5 mrad (one pixel
    of a 1024-px, 30° camera), a 5″ star tracker, 16 matched points per image, no process noise, one orbit.
    """

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

    def validate(self) -> "CoastlineGeometricOptions":
        checks = [
            ("altitude_m", 1.0e5 <= self.altitude_m <= 5.0e7, "between 100 km and 50000 km"),
            ("cadence_s", self.cadence_s > 0, "> 0"),
            ("fov_rad", 0 < self.fov_rad < math.radians(120), "in (0, 120°)"),
            ("points_per_image", self.points_per_image >= 1, ">= 1"),
            ("db_spacing_m", self.db_spacing_m >= 100.0, ">= 100 m"),
            ("sigma_theta_rad", self.sigma_theta_rad > 0, "> 0 (the filter needs R, eq. 18)"),
            ("sigma_star_tracker_rad", self.sigma_star_tracker_rad >= 0, ">= 0"),
            ("q_acc_m2_s3", self.q_acc_m2_s3 >= 0, ">= 0"),
            ("filter_step_s", self.filter_step_s > 0, "> 0"),
            ("t0_s", self.t0_s >= 0, ">= 0"),
        ]
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
    n_visible: np.ndarray            # (K,) database points in the field of view before the grid pick


def ric_axes(x: np.ndarray) -> np.ndarray:
    """Rows r̂, î, ĉ of the RIC frame of states x (..., 6) → C_ric_from_eci (..., 3, 3)."""
    r, v = x[..., :3], x[..., 3:]
    rh = r / np.linalg.norm(r, axis=-1, keepdims=True)
    h = np.cross(r, v)
    ch = h / np.linalg.norm(h, axis=-1, keepdims=True)
    ih = np.cross(ch, rh)
    return np.stack([rh, ih, ch], axis=-2)


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
    # footprint radius: Earth central angle of the FOV's corner ray (sphere of radius R_EARTH_M)
    a_d = math.atan(math.sqrt(2.0) * tan_half)
    rs = R_EARTH_M + o.altitude_m
    lam = math.asin(min(1.0, rs / R_EARTH_M * math.sin(a_d))) - a_d
    query_r = 2.0 * R_EARTH_M * math.sin(0.5 * lam) * 1.1 + 30e3
    g = max(1, int(math.isqrt(o.points_per_image)))
    points, n_meas, n_vis = [np.zeros((0, 3))], [0], [0]
    for k in range(1, K):
        R_ecef_from_eci = _R3(o.gmst0_rad + OMEGA_EARTH * t[k])
        r_ecef = R_ecef_from_eci @ x[k, :3]
        sub = r_ecef / np.linalg.norm(r_ecef) * R_EARTH_M
        idx = np.asarray(db.tree.query_ball_point(sub, query_r), dtype=np.int64)
        if idx.size:
            p_ecef = db.ecef_m[idx]
            facing = np.einsum("ij,ij->i", db.normal[idx], r_ecef - p_ecef) > 0
            p_eci = (p_ecef @ R_ecef_from_eci)                               # Rᵀ p
            pc = (p_eci - x[k, :3]) @ T[k].T
            u, w = pc[:, 0] / pc[:, 2], pc[:, 1] / pc[:, 2]
            inside = facing & (pc[:, 2] > 0) & (np.abs(u) <= tan_half) & (np.abs(w) <= tan_half)
            p_eci, u, w = p_eci[inside], u[inside], w[inside]
        else:
            p_eci, u, w = np.zeros((0, 3)), np.zeros(0), np.zeros(0)
        n_vis.append(len(p_eci))
        if len(p_eci):
            cu = np.clip(((u / tan_half + 1.0) * 0.5 * g).astype(int), 0, g - 1)
            cw = np.clip(((w / tan_half + 1.0) * 0.5 * g).astype(int), 0, g - 1)
            cell = cw * g + cu
            centre_u = ((cu + 0.5) / g * 2.0 - 1.0) * tan_half
            centre_w = ((cw + 0.5) / g * 2.0 - 1.0) * tan_half
            d2 = (u - centre_u) ** 2 + (w - centre_w) ** 2
            order = np.lexsort((d2, cell))                                   # by cell, then distance
            first = order[np.r_[True, cell[order][1:] != cell[order][:-1]]]
            p_eci = p_eci[first]
        points.append(p_eci)
        n_meas.append(len(p_eci))
    return Geometry(t, x, T, points, np.asarray(n_meas), np.asarray(n_vis))


def _draws(seed_sequence: np.random.SeedSequence, K: int, m_max: int) -> dict[str, np.ndarray]:
    """All random numbers of one run, in a fixed layout (independent of the batch it runs in)."""
    rng = np.random.Generator(np.random.PCG64(seed_sequence))
    return {"x0": rng.standard_normal(6), "los": rng.standard_normal((K, m_max, 2)),
            "att": rng.standard_normal((K, 3))}


def draws_for_runs(seed_sequences, K: int, points_per_image: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stacked per-run draws: initial-state (N, 6), LOS (N, K, m_max, 2), attitude (N, K, 3) standard normals."""
    m_max = max(1, int(math.isqrt(points_per_image)) ** 2)
    draws = [_draws(s, K, m_max) for s in seed_sequences]
    return (np.stack([d["x0"] for d in draws]), np.stack([d["los"] for d in draws]),
            np.stack([d["att"] for d in draws]))


def measurements(geo: Geometry, k: int, z_los_k: np.ndarray, z_att_k: np.ndarray, sigma_los: float,
                 sigma_att: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Image k for N runs: measured camera-frame LOS (N, m, 3), database points (m, 3), star-tracker T̂ (N, 3, 3).

    The camera truly points with ``geo.T_cam_from_eci[k]``; the LOS to each matched point from the true position
    is tilted by σ_los (eq. 18); the star tracker reports exp([σ_att z×]) T_true.
    """
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
    """Propagate and update the N filters through every time of ``geo`` → x̂ (N, K, 6), P (N, K, 6, 6), NIS and
    NEES (N, K); NIS is NaN at times without a matched point."""
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


def _filter_table(geo: Geometry, runs: np.ndarray, xs, Ps, nis, nees_v):
    """The :data:`FILTER_COLUMNS` table (then ``has_result``, ``reason``) of N runs: RIC errors and 1σ, NEES, NIS."""
    import pyarrow as pa

    N, K = xs.shape[:2]
    err = xs - geo.x_true[None]
    C = ric_axes(geo.x_true)                                                  # (K, 3, 3)
    e_r = np.einsum("kij,nkj->nki", C, err[..., :3])
    e_v = np.einsum("kij,nkj->nki", C, err[..., 3:])
    C6 = np.zeros((K, 6, 6))
    C6[:, :3, :3] = C
    C6[:, 3:, 3:] = C
    sig = np.sqrt(np.sum(np.matmul(C6[None], Ps) * C6[None], axis=-1))      # sqrt diag(C P Cᵀ)
    cols = {"run": np.repeat(runs, K), "t_s": np.tile(geo.t_s, N)}
    vals = np.concatenate([e_r, e_v], axis=-1)
    for j, name in enumerate(FILTER_COLUMNS[2:8]):                            # err_r_m ... err_vc_mps
        cols[name] = vals[..., j].ravel()
    for j, name in enumerate(FILTER_COLUMNS[8:14]):                           # sig_r_m ... sig_vc_mps
        cols[name] = sig[..., j].ravel()
    cols["nees"] = nees_v.ravel()
    cols["nis"] = nis.ravel()
    cols["n_meas"] = np.tile(geo.n_meas.astype(np.int32), N)
    cols.update(filter_status(cols["n_meas"], np.tile(np.arange(K) == 0, N)))
    return pa.table(cols)


def run_batch(options: CoastlineGeometricOptions, seed_sequences, run_indices=None, *, noise_free: bool = False,
              progress: bool = False, keep_history: bool = False) -> dict:
    """Run N filters (one per seed sequence) through the same truth, vectorised across runs.

    Parameters
    ----------
    options : CoastlineGeometricOptions
    seed_sequences : sequence of numpy.random.SeedSequence
        One spawned child per run (``SeedSequence(seed).spawn(N)``).
    run_indices : sequence of int, optional
        Values of the ``run`` column (default 0..N-1).
    noise_free : bool
        Measurements and attitude exact (the filter still assumes σθ, σ_att); the initial dispersion stays.
    progress : bool
        Show a tqdm bar over measurement times.
    keep_history : bool
        Also return ``x_hat`` (N, K, 6) and ``P`` (N, K, 6, 6).

    Returns
    -------
    dict with ``table`` (pyarrow.Table, :data:`FILTER_COLUMNS`), ``geometry`` (:class:`Geometry`) and, when asked,
    the histories.
    """
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
    out = {"table": _filter_table(geo, runs, xs, Ps, nis, nees_v), "geometry": geo}
    if keep_history:
        out.update(x_hat=xs, P=Ps)
    return out


def filter_status(n_meas, is_prior) -> dict:
    """``has_result`` (an update with ≥ 1 measurement) and ``reason`` (:class:`renderlab.contracts.reasons.FilterReason`:
    ``prior`` for the initial estimate, ``no_measurement`` for a time without line of sight) of filter rows."""
    import pyarrow as pa

    n = np.asarray(n_meas)
    prior = np.asarray(is_prior, bool)
    has = (n > 0) & ~prior
    reason = np.where(prior, "prior", np.where(has, "ok", "no_measurement"))
    return {"has_result": has, "reason": pa.array(reason.tolist(), pa.string()).dictionary_encode()}


def options_from_mapping(scenario) -> CoastlineGeometricOptions:
    """Options from a dataclass or a mapping of option names (unknown names → UserError)."""
    if isinstance(scenario, CoastlineGeometricOptions):
        return scenario.validate()
    if not hasattr(scenario, "keys"):
        raise UserError("coastline geometric study: expected CoastlineGeometricOptions or a mapping of its fields, "
                        f"got {type(scenario).__name__} (scenario files: study coastline_ekf)")
    known = {f.name for f in fields(CoastlineGeometricOptions)}
    unknown = sorted(set(scenario) - known)
    if unknown:
        raise UserError(f"unknown coastline study option(s): {', '.join(unknown)}")
    return CoastlineGeometricOptions(**dict(scenario)).validate()


def run(scenario, base_dir, run_index: int, seed_sequence, workdir) -> dict:
    """Campaign-engine study function: one run → ``{"coastline_filter": pyarrow.Table}``.

    ``scenario`` is a :class:`CoastlineGeometricOptions` or a mapping of its fields; ``base_dir`` and ``workdir``
    are unused (the study writes no files). Scenario files go through study ``coastline_ekf``
    (:func:`renderlab.studies.coastline_ekf.study.run`), which maps the scenario onto these options.
    """
    o = options_from_mapping(scenario)
    return {"coastline_filter": run_batch(o, [seed_sequence], [run_index])["table"]}


def options_dict(o: CoastlineGeometricOptions) -> dict:
    """JSON-friendly options (for README/summary files)."""
    return asdict(o)
