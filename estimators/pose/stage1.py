r"""Stage 1 (Ivanov et al. 2018, §4): reference points, initial conditions and inertia by batch least squares.

Description
-----------
Parameter vector (eq. 5, the attitude as a rotation-vector correction of a reference attitude, the inertia as
log-ratios): ``θ = [r0 (3), v0 (3), δφ0 (3), ω0 (3), ln(I1/I3), ln(I2/I3), p_1 … p_M (3 each)]``. r0, v0: target
centre of mass relative to the chaser, LVLH, at the first database frame; ``R_lvlh_from_body(0) = R_ref ·
exp([δφ0]×)``; ω0 the absolute body rate; p_j the body coordinates of the database's points. Given θ, eqs. 1-2 are
integrated (:mod:`.onboard_model`, :mod:`.variational`) and eqs. 3-4 predict every database measurement; the error
function (eq. 6) Φ(θ) = Σ_k Σ_j ‖z_jk − ẑ_jk(θ)‖² / σ² (+ a range prior, below) is minimised with
``scipy.optimize.least_squares`` (LM by default) and the analytic Jacobian: CW (eq. 1) is linear in (r0, v0), the
points enter through R_k p_j, and ∂R_k/∂(δφ0, ω0, ln I) comes from the variational equations integrated alongside
eq. 2 (:mod:`.variational`). The old finite-difference Jacobian (``jacobian = "fd"``) is kept as the benchmark
baseline and as the tests' independent check of the analytic one.

Monocular scale — what the paper does and what is done here. The paper's §5 starts from chosen initial values of θ
(listed in an equation lost in our text copy) with random initial point coordinates, and does not discuss scale.
With images alone, scaling (r0 − d, v0, p_j) by a common factor changes the predictions only through O(n·t) CW
(Coriolis) terms — over seconds a null direction of the Fisher matrix (eq. 7; :mod:`.observability` reports it,
relative singular value ~1e-11). LM does not move along such a direction, so in the paper the scale is that of the
initial r0: the separation geometry (the target leaves a known place on the chaser with the separation mechanism's
known speed; ref. [28]). Here that assumption is explicit and weighted: a prior on the initial range ‖r0 − d‖
(``range_prior_m``, σ = ``range_prior_sigma_m``, the a-priori uncertainty of the separation geometry). Points start,
unlike the paper's random values, from back-projection of their first measurement to the a-priori range (same
minimum, fewer iterations). Inertia: the free log-ratios can leave the set of physical bodies (I_i + I_j < I_k)
where the arc is short; ``inertia_param = "fallback"`` re-solves such a result in the parametrisation of
:mod:`.inertia`, where every value is physical.

Tuning
------
=======================  =========  ========================================================================
Stage1Options            default    turn it when
=======================  =========  ========================================================================
``sigma_px``             0.3        whitening σ of eq. 6: the centroid noise, px (it also scales the CRLB σ)
``range_prior_sigma_m``  0.05       σ of the range prior, m; None or 0 drops it (scale then barely observed)
``inertia_param``        fallback   ``physical``: always solve in u; ``log_ratio``: free, may end unphysical
``loss``, ``f_scale``    linear, 3  a robust loss (``cauchy``, …; implies ``trf``) against bad tracks
``method``               lm         ``trf``: bounded (attitude ±π/2, rate ±1 rad/s, ratios 0.2–5)
``max_nfev``             300        evaluation budget; when spent, status 0 (``converged`` is False)
``ftol``, ``xtol``       1e-12      least_squares stopping tolerances (``gtol`` = 1e-10)
``substeps``             2          RK4 steps per frame interval: raise for fast tumbles or sparse frames
``min_points``           4          fewer database points raise :class:`EstimationError`
``jacobian``             analytic   ``fd``: finite differences (the benchmark baseline, the tests' check)
``integrator``           numba      ``python``: the baseline onboard propagation
=======================  =========  ========================================================================

Use
---
::

    db = build_database(track_points(detections, TrackOptions()), TrackOptions())     # detections: detect_points
    prob = Stage1Problem(camera, R_lvlh_from_cam, d_lvlh, n_rad_s, times_s, db, R_ref, range_prior_m, Stage1Options())
    res = solve_stage1(prob, r0_guess, v0_guess, w0_guess, ratios_guess)       # from an a-priori guess
    res.converged, res.inertia_ratios, res.points_body, res.sigma_theta       # 1σ from (JᵀJ)⁻¹

References
----------
D. Ivanov et al., "Relative Pose and Inertia Determination of Unknown Satellite Using Monocular Vision",
International Journal of Aerospace Engineering, vol. 2018, Article ID 9731512, 9 pages, 2018.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .features import MeasurementDatabase
from .onboard_model import cw_transition, exp_so3, propagate_rotation, propagate_rotation_python
from .variational import propagate_with_sensitivities


class EstimationError(ValueError):
    """Input the estimator cannot work with (too few points, coplanar points, empty database)."""


@dataclass(frozen=True)
class Stage1Options:
    sigma_px: float = 0.3                 # measurement noise used to whiten residuals (eq. 6)
    range_prior_sigma_m: float | None = 0.05
    substeps: int = 2                     # RK4 steps per frame interval in the onboard model
    max_nfev: int = 300                   # evaluation budget (each Jacobian costs one propagation here)
    min_points: int = 4
    jacobian: str = "analytic"            # "analytic" (variational equations) or "fd" (baseline)
    integrator: str = "numba"             # "numba" or "python" (the baseline onboard propagation)
    ftol: float = 1e-12
    xtol: float = 1e-12
    gtol: float = 1e-10
    method: str = "lm"                    # least_squares method: "lm" (MINPACK, unbounded) or "trf" (bounded)
    inertia_param: str = "fallback"       # "physical": solve in u (every value obeys I_i + I_j ≥ I_k,
    #   :mod:`.inertia`); "log_ratio": ln(I1/I3), ln(I2/I3) free (may leave that set); "fallback":
    #   log_ratio, and if the result is unphysical re-solve in u from it (Stage1Result.inertia_fallback)
    loss: str = "linear"                  # least_squares loss; a robust one ("cauchy", ...) implies "trf"
    f_scale: float = 3.0                  # robust-loss scale, in whitened units (σ)

    def __post_init__(self):
        if self.inertia_param not in ("physical", "log_ratio", "fallback"):
            raise ValueError(f"Stage1Options.inertia_param must be 'physical', 'log_ratio' or 'fallback', "
                             f"got {self.inertia_param!r}")
        if self.jacobian not in ("analytic", "fd") or self.integrator not in ("numba", "python"):
            raise ValueError(f"Stage1Options: jacobian must be 'analytic'/'fd' and integrator 'numba'/'python', "
                             f"got {self.jacobian!r}, {self.integrator!r}")


@dataclass
class Stage1Problem:
    """Everything stage 1 knows: camera, mounting, orbit rate, frame times and the database."""

    camera: object                 # renderlab.geometry.CameraModel
    R_lvlh_from_cam: np.ndarray
    d_lvlh: np.ndarray             # camera position in LVLH (chaser CM at the origin)
    n: float                       # orbit mean motion, rad/s
    times_s: np.ndarray            # time of every frame index (frame k at times_s[k])
    db: MeasurementDatabase
    R_ref: np.ndarray              # reference attitude R_lvlh_from_body for δφ0 = 0
    range_prior_m: float | None = None
    opts: Stage1Options = field(default_factory=Stage1Options)

    def __post_init__(self):
        if self.db.n_points < self.opts.min_points:
            raise EstimationError(f"stage 1 needs at least {self.opts.min_points} tracked reference points, "
                                  f"the database has {self.db.n_points}")
        self.frames = np.unique(self.db.frame)
        self.t = self.times_s[self.frames] - self.times_s[self.frames[0]]
        self.phi = np.array([cw_transition(self.n, t) for t in self.t])
        self.row = np.searchsorted(self.frames, self.db.frame)

    # ------------------------------------------------------------------ model
    def unpack(self, theta: np.ndarray, inertia_mode: str = "ratios"):
        ni = 2 if inertia_mode == "ratios" else 3
        r0, v0, dphi, w0 = theta[0:3], theta[3:6], theta[6:9], theta[9:12]
        li = theta[12:12 + ni]
        inertia = np.exp(np.r_[li, 0.0]) if ni == 2 else np.exp(li)
        pts = theta[12 + ni:].reshape(-1, 3)
        return r0, v0, dphi, w0, inertia, pts

    def states(self, theta: np.ndarray, inertia_mode: str = "ratios"):
        """(r (F,3), v (F,3), R_lvlh_from_body (F,3,3), ω (F,3)) at the database frames."""
        r0, v0, dphi, w0, inertia, _ = self.unpack(theta, inertia_mode)
        rv = self.phi @ np.r_[r0, v0]
        prop = propagate_rotation if self.opts.integrator == "numba" else propagate_rotation_python
        R, W = prop(self.R_ref @ exp_so3(dphi), w0, inertia, self.n, self.t, self.opts.substeps)
        return rv[:, :3], rv[:, 3:], R, W

    def predict(self, theta: np.ndarray, inertia_mode: str = "ratios") -> np.ndarray:
        r, _, R, _ = self.states(theta, inertia_mode)
        pts = self.unpack(theta, inertia_mode)[5]
        k, j = self.row, self.db.point
        p_lvlh = r[k] + np.einsum("nab,nb->na", R[k], pts[j])
        rho = (p_lvlh - self.d_lvlh) @ self.R_lvlh_from_cam
        return self.camera.project(rho)

    def residuals(self, theta: np.ndarray, inertia_mode: str = "ratios", prior: bool = True) -> np.ndarray:
        """Whitened residuals of eq. 6 (2 per measurement, then the range prior if any)."""
        with np.errstate(all="ignore"):
            try:
                pred = self.predict(theta, inertia_mode)
            except (np.linalg.LinAlgError, ValueError, OverflowError):  # a wild trial step
                pred = np.full(self.db.sl.shape, np.nan)
        res = ((pred - self.db.sl) / self.opts.sigma_px).ravel()
        res = np.where(np.isfinite(res), res, 1e4)  # behind the camera: a large, finite penalty
        if prior and self.range_prior_m is not None and self.opts.range_prior_sigma_m:
            rng = np.linalg.norm(theta[:3] - self.d_lvlh)
            res = np.r_[res, (rng - self.range_prior_m) / self.opts.range_prior_sigma_m]
        return res

    def jacobian(self, theta: np.ndarray, inertia_mode: str = "ratios", prior: bool = True,
                 central: bool = False) -> np.ndarray:
        """Jacobian of :meth:`residuals`: analytic (default) or finite differences (``opts.jacobian``)."""
        if self.opts.jacobian == "fd":
            return self.jacobian_fd(theta, inertia_mode, prior, central)
        return self.jacobian_analytic(theta, inertia_mode, prior)

    def jacobian_analytic(self, theta: np.ndarray, inertia_mode: str = "ratios", prior: bool = True) -> np.ndarray:
        """∂(whitened residuals)/∂θ from CW (eq. 1), the variational equations of eq. 2 and eqs. 3-4."""
        ni = 2 if inertia_mode == "ratios" else 3
        nd = 12 + ni
        r0, v0, dphi, w0, _, pts = self.unpack(theta, inertia_mode)
        li = np.r_[theta[12:12 + ni], 0.0] if ni == 2 else theta[12:15]
        with np.errstate(all="ignore"):
            try:
                R, _, SR, _ = propagate_with_sensitivities(self.R_ref, dphi, w0, li, self.n, self.t,
                                                           self.opts.substeps, ni)
            except (ValueError, OverflowError):
                return np.zeros((len(self.residuals(theta, inertia_mode, prior)), len(theta)))
            k, j = self.row, self.db.point
            r = (self.phi[:, :3] @ np.r_[r0, v0])[k]
            Rk = R[k]
            rho = (r + np.einsum("nab,nb->na", Rk, pts[j]) - self.d_lvlh) @ self.R_lvlh_from_cam
            A = self.camera.project_jacobian(rho) @ self.R_lvlh_from_cam.T / self.opts.sigma_px  # (N, 2, 3)
        ok = np.all(np.isfinite(A), axis=(1, 2))
        A[~ok] = 0.0                       # behind the camera: constant penalty, zero slope
        N = len(k)
        J = np.zeros((2 * N + self._n_prior(prior), len(theta)))
        Jm = J[:2 * N].reshape(N, 2, -1)
        Jm[:, :, 0:6] = A @ self.phi[k, :3, :]                           # r0, v0
        dp = np.einsum("npab,nb->npa", SR[k], pts[j])                      # (N, 6+ni, 3)
        Jm[:, :, 6:nd] = np.einsum("nia,npa->nip", A, dp)                   # δφ0, ω0, ln I
        Ap = A @ Rk                                                        # (N, 2, 3)
        for g in range(3):
            Jm[np.arange(N), :, nd + 3 * j + g] = Ap[:, :, g]
        if self._n_prior(prior):
            u = theta[:3] - self.d_lvlh
            J[-1, :3] = u / np.linalg.norm(u) / self.opts.range_prior_sigma_m
        return J

    def _n_prior(self, prior: bool) -> int:
        return int(bool(prior and self.range_prior_m is not None and self.opts.range_prior_sigma_m))

    def jacobian_fd(self, theta: np.ndarray, inertia_mode: str = "ratios", prior: bool = True,
                    central: bool = False) -> np.ndarray:
        """Finite-difference Jacobian of :meth:`residuals`; point columns grouped 3 at a time (the baseline)."""
        ni = 2 if inertia_mode == "ratios" else 3
        nd = 12 + ni
        f0 = self.residuals(theta, inertia_mode, prior)
        J = np.zeros((len(f0), len(theta)))

        def diff(delta):
            fp = self.residuals(theta + delta, inertia_mode, prior)
            if central:
                return (fp - self.residuals(theta - delta, inertia_mode, prior)) / 2
            return fp - f0

        for c in range(nd):
            h = (1e-5 if central else 1e-7) * max(1.0, abs(theta[c]))
            e = np.zeros_like(theta)
            e[c] = h
            J[:, c] = diff(e) / h
        n_meas = 2 * len(self.db.frame)
        rows_point = np.repeat(self.db.point, 2)
        for g in range(3):
            e = np.zeros_like(theta)
            cols = nd + 3 * np.arange(self.db.n_points) + g
            h = (1e-5 if central else 1e-7) * np.maximum(1.0, np.abs(theta[cols]))
            e[cols] = h
            dcol = diff(e)
            J[np.arange(n_meas), nd + 3 * rows_point + g] = dcol[:n_meas] / h[rows_point]  # prior row: 0
        return J

    def initial_points(self, theta_dyn: np.ndarray) -> np.ndarray:
        """Back-project each point's first measurement to the guessed range of the target centre."""
        theta = np.r_[theta_dyn, np.zeros(3 * self.db.n_points)]
        r, _, R, _ = self.states(theta)
        pts = np.zeros((self.db.n_points, 3))
        for j in range(self.db.n_points):
            m = np.nonzero(self.db.point == j)[0][0]
            k = self.row[m]
            ray_cam = self.camera.unproject(self.db.sl[m])
            u = self.R_lvlh_from_cam @ ray_cam
            depth = np.linalg.norm(r[k] - self.d_lvlh)
            pts[j] = R[k].T @ (self.d_lvlh + depth * u - r[k])
        return pts


@dataclass
class Stage1Result:
    theta: np.ndarray
    r0_lvlh: np.ndarray
    v0_lvlh: np.ndarray
    R0_lvlh_from_body: np.ndarray
    omega0_body: np.ndarray
    inertia_ratios: np.ndarray     # (I1/I3, I2/I3)
    points_body: np.ndarray        # (M, 3), row j ↔ db.track_ids[j]
    track_ids: np.ndarray
    rms_px: float
    nfev: int
    status: int                    # scipy least_squares status (0: evaluation budget spent, > 0: converged)
    sigma_theta: np.ndarray        # 1σ from (JᵀJ)⁻¹ of the whitened problem
    history: list = field(default_factory=list)   # accepted iterates θ_i (convergence, Figs 5-7)
    epoch_frame: int = 0
    njev: int = 0
    cost: float = float("nan")     # ½ Σ whitened residual² at the solution
    cost0: float = float("nan")    # ... at the start
    optimality: float = float("nan")  # ‖∇Φ‖∞ scaled as scipy reports it (first-order optimality)
    message: str = ""
    seconds: float = float("nan")
    inertia_fallback: bool = False  # the free solve left the physical set and was re-solved in u

    @property
    def converged(self) -> bool:
        return self.status > 0

    def report(self) -> dict:
        """Convergence report for summaries."""
        return {"status": self.status, "converged": self.converged, "message": self.message,
                "nfev": self.nfev, "njev": self.njev, "cost0": self.cost0, "cost": self.cost,
                "gradient_inf_norm": self.optimality, "rms_px": self.rms_px, "seconds": self.seconds}


def solve_stage1(problem: Stage1Problem, r0, v0, w0, inertia_ratios, points0=None, dphi0=None) -> Stage1Result:
    """Minimise eq. 6 from an initial guess of the dynamics (attitude guess ``problem.R_ref·exp([dphi0]×)``,
    dphi0 = 0 by default); the points start from ``points0`` (M, 3) if given, else from
    :meth:`Stage1Problem.initial_points`. With ``inertia_param = "fallback"`` an unphysical free solution
    (I_i + I_j < I_k) is re-solved in the physical parametrisation from where the free solve stopped."""
    import dataclasses

    from .inertia import is_physical

    if problem.opts.inertia_param != "fallback":
        return _solve(problem, r0, v0, w0, inertia_ratios, points0, dphi0)
    free = dataclasses.replace(problem, opts=dataclasses.replace(problem.opts, inertia_param="log_ratio"))
    res = _solve(free, r0, v0, w0, inertia_ratios, points0, dphi0)
    if is_physical(np.r_[res.inertia_ratios, 1.0]):
        return res
    phys = dataclasses.replace(problem, opts=dataclasses.replace(problem.opts, inertia_param="physical"))
    res2 = _solve(phys, res.r0_lvlh, res.v0_lvlh, res.omega0_body, res.inertia_ratios, res.points_body,
                  res.theta[6:9])
    res2.inertia_fallback = True
    res2.history = res.history + res2.history
    res2.nfev += res.nfev
    res2.njev += res.njev
    res2.cost0 = res.cost0
    res2.seconds += res.seconds
    res2.message = f"free solve unphysical (I1/I3, I2/I3 = {res.inertia_ratios.round(3).tolist()}); " + res2.message
    return res2


def _solve(problem: Stage1Problem, r0, v0, w0, inertia_ratios, points0=None, dphi0=None) -> Stage1Result:
    import time

    from scipy.optimize import least_squares

    t_start = time.perf_counter()
    dphi0 = np.zeros(3) if dphi0 is None else np.asarray(dphi0, float)
    dyn = np.r_[r0, v0, dphi0, w0, np.log(np.asarray(inertia_ratios, float))]
    pts0 = problem.initial_points(dyn) if points0 is None else np.asarray(points0, float)
    theta0 = np.r_[dyn, pts0.ravel()]
    history, best = [], [np.inf]

    def fun(th):
        res = problem.residuals(th)
        c = float(res @ res)
        if c < best[0]:
            best[0] = c
            history.append(th.copy())
        return res

    o = problem.opts
    physical = o.inertia_param == "physical"
    if physical:  # the solver's vector φ: θ with the log-ratios replaced by u (every u is a physical body)
        from .inertia import log_ratios_from_u, u_from_ratios

        def to_theta(ph):
            th = ph.copy()
            th[12:14] = log_ratios_from_u(ph[12:14])[0]
            return th

        phi0 = theta0.copy()
        phi0[12:14] = u_from_ratios(np.exp(theta0[12:14]))
        theta0 = to_theta(phi0)
    else:
        def to_theta(ph):
            return ph

        phi0 = theta0

    def jac(ph):
        J = problem.jacobian(to_theta(ph))
        if physical:
            J[:, 12:14] = J[:, 12:14] @ log_ratios_from_u(ph[12:14])[1]
        return J

    lb = np.full(len(phi0), -np.inf)
    ub = np.full(len(phi0), np.inf)
    lb[6:9], ub[6:9] = -np.pi / 2, np.pi / 2      # attitude correction
    lb[9:12], ub[9:12] = -1.0, 1.0                # body rate, rad/s
    if not physical:
        lb[12:14], ub[12:14] = np.log(0.2), np.log(5.0)  # inertia ratios
    method = "trf" if o.loss != "linear" else o.method
    bounded = method == "trf"
    if bounded:
        phi0 = np.clip(phi0, lb + 1e-9, ub - 1e-9)
        theta0 = to_theta(phi0)
    sol = least_squares(lambda ph: fun(to_theta(ph)), phi0, jac=jac, method=method,
                        bounds=(lb, ub) if bounded else (-np.inf, np.inf), loss=o.loss, f_scale=o.f_scale,
                        x_scale="jac", max_nfev=o.max_nfev, xtol=o.xtol, ftol=o.ftol, gtol=o.gtol)
    sol.x = to_theta(sol.x)
    if o.loss != "linear":
        sol.fun = problem.residuals(sol.x)
        sol.cost = 0.5 * float(sol.fun @ sol.fun)
    th = sol.x
    J = problem.jacobian(th)
    try:
        cov = np.linalg.inv(J.T @ J)
        sig = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:
        sig = np.full(len(th), np.nan)
    r0, v0, dphi, w0, inertia, pts = problem.unpack(th)
    n_meas = 2 * len(problem.db.frame)
    rms = float(np.sqrt(np.mean(sol.fun[:n_meas] ** 2)) * problem.opts.sigma_px)
    res0 = problem.residuals(theta0)
    return Stage1Result(th, r0, v0, problem.R_ref @ exp_so3(dphi), w0, inertia[:2] / inertia[2], pts,
                        problem.db.track_ids, rms, int(sol.nfev), int(sol.status), sig, history,
                        int(problem.frames[0]), njev=int(sol.njev or 0), cost=float(sol.cost),
                        cost0=0.5 * float(res0 @ res0), optimality=float(sol.optimality),
                        message=str(sol.message), seconds=time.perf_counter() - t_start)
