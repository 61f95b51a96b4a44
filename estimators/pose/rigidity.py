r"""Rigid-feature database: keep only tracks that move like points fixed on one rigid body.

The paper's reference features are the antenna tips — isolated bright points (Ivanov et al. 2018, §4).
A thresholded image also yields blobs on lit edges whose photocentre slides over the body as the
lighting changes; no rigid-body θ (eq. 5) fits them, and a least-squares fit (eq. 6) with them is
biased. Shape gating at detection (:mod:`.features`) removes most; this module removes the rest with a
robust fit and a per-track χ² test, onboard-style (no truth):

1. Start: eq. 6 over all database tracks — plain least squares by default; a Cauchy loss
   (``robust_start``, scale ``f_scale`` σ) is available, but with a handful of tracks over a short arc
   it can "explain" a good track away (seen on the 8-frame test sequence), so it is not the default.
2. Per-track test, dynamics fixed: every track's body point p_j is re-fitted alone (3-parameter
   Gauss-Newton triangulation through eqs. 3-4) and its statistic T_j = Σ_k ‖z_jk − ẑ_jk‖² / σ_eff²
   is compared with χ²(2 n_j − 3); the track is kept when its p-value ≥ ``alpha``. σ_eff =
   max(σ_px, robust scale of the kept tracks' residuals) — rendered knobs are not ideal points (the
   sunlit photocentre moves by up to the knob radius), so the pixel noise is estimated, not assumed.
3. Backward elimination: while a kept track fails, drop the worst one (largest χ²/dof) and refit eq. 6
   (plain least squares) on the rest — one at a time, so that one bad track cannot get good ones
   rejected with it. When every kept track passes, rejected tracks that now pass are reinstated and
   the fit repeated; stop when the kept set no longer changes (or repeats, or ``max_rounds``).

Every rejected track is reported with its statistic (:class:`RigidityReport`), never silently dropped.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .features import MeasurementDatabase
from .stage1 import EstimationError, Stage1Problem, Stage1Result, solve_stage1


@dataclass(frozen=True)
class RigidityOptions:
    alpha: float = 1e-3           # per-track false-rejection probability of the χ² test
    max_rounds: int = 30
    f_scale: float = 3.0          # Cauchy-loss scale of the robust start, in σ
    robust_start: bool = False    # step 1 with a Cauchy loss (True) or plain least squares (False)
    robust_nfev: int = 100        # evaluation budget of the start
    round_nfev: int = 60          # budget of each elimination round's refit (the final fit gets the full one)


@dataclass
class TrackTest:
    track_id: int
    n_meas: int
    chi2: float
    dof: int
    p_value: float
    rms_px: float
    kept: bool


@dataclass
class RigidityReport:
    tests: list[TrackTest]
    sigma_eff_px: float
    rounds: int
    history: list[list[int]] = field(default_factory=list)   # kept track ids after each round

    @property
    def kept(self) -> np.ndarray:
        return np.array([t.track_id for t in self.tests if t.kept], int)

    @property
    def rejected(self) -> np.ndarray:
        return np.array([t.track_id for t in self.tests if not t.kept], int)

    def lines(self) -> list[str]:
        out = [f"rigidity test: kept {len(self.kept)} of {len(self.tests)} tracks after {self.rounds} rounds, "
               f"σ_eff = {self.sigma_eff_px:.2f} px"]
        for t in self.tests:
            if not t.kept:
                out.append(f"rejected track {t.track_id}: {t.n_meas} frames, rms {t.rms_px:.2f} px, "
                           f"χ² {t.chi2:.1f} / {t.dof} dof, p = {t.p_value:.1e}")
        return out


def subset(db: MeasurementDatabase, track_ids) -> MeasurementDatabase:
    """The database restricted to ``track_ids`` (points renumbered in that order)."""
    idx = {int(t): k for k, t in enumerate(track_ids)}
    old = {k: int(t) for k, t in enumerate(db.track_ids)}
    m = np.array([old[p] in idx for p in db.point], bool)
    point = np.array([idx[old[p]] for p in db.point[m]], int)
    return MeasurementDatabase(np.asarray(track_ids, int), db.frame[m], point, db.sl[m],
                               dropped_tracks=db.dropped_tracks)


def fit_points(problem: Stage1Problem, theta: np.ndarray, points0: np.ndarray, iters: int = 20,
               max_step_m: float = 0.3):
    """Body coordinates of every database point with the dynamics of ``theta`` fixed (Gauss-Newton on
    eqs. 3-4, all points at once). Returns (points (M, 3), residuals (N, 2) in px)."""
    r, _, R, _ = problem.states(theta)
    k, j = problem.row, problem.db.point
    cam, R_lc = problem.camera, problem.R_lvlh_from_cam
    p = np.array(points0, float)
    M = len(p)
    for _ in range(iters):
        rho = (r[k] + np.einsum("nab,nb->na", R[k], p[j]) - problem.d_lvlh) @ R_lc
        with np.errstate(all="ignore"):
            e = problem.db.sl - cam.project(rho)
            A = np.einsum("nij,njb->nib", cam.project_jacobian(rho) @ R_lc.T, R[k])   # ∂ẑ/∂p (N, 2, 3)
        ok = np.isfinite(e).all(1) & np.isfinite(A).all((1, 2))
        e, A = np.where(ok[:, None], e, 0.0), np.where(ok[:, None, None], A, 0.0)
        H = np.zeros((M, 3, 3))
        g = np.zeros((M, 3))
        np.add.at(H, j, np.einsum("nia,nib->nab", A, A))
        np.add.at(g, j, np.einsum("nia,ni->na", A, e))
        dp = np.linalg.solve(H + 1e-9 * np.eye(3), g[..., None])[..., 0]
        step = np.linalg.norm(dp, axis=1, keepdims=True)
        dp = dp * np.minimum(1.0, max_step_m / np.maximum(step, 1e-300))   # no wild Gauss-Newton jumps
        p = p + dp
        if np.max(np.abs(dp)) < 1e-9:
            break
    rho = (r[k] + np.einsum("nab,nb->na", R[k], p[j]) - problem.d_lvlh) @ R_lc
    with np.errstate(all="ignore"):
        res = problem.db.sl - cam.project(rho)
    return p, np.where(np.isfinite(res), res, 1e3)


def chi2_track_tests(problem: Stage1Problem, theta: np.ndarray, points0: np.ndarray, kept: np.ndarray,
                opts: RigidityOptions) -> tuple[list[TrackTest], float, np.ndarray]:
    """χ² test of every track of ``problem.db`` against the dynamics of ``theta`` (step 2)."""
    from scipy.stats import chi2

    pts, res = fit_points(problem, theta, points0)
    db = problem.db
    in_kept = np.isin(db.track_ids[db.point], kept)
    mad = 1.4826 * np.median(np.abs(res[in_kept])) if in_kept.any() else 0.0
    n_k = np.bincount(db.point[in_kept], minlength=db.n_points)
    # the median of |r| of fitted residuals underestimates σ by √((2n−3)/2n) on average over the tracks
    corr = np.sqrt(np.sum(2 * n_k[n_k > 0]) / max(np.sum(2 * n_k[n_k > 0] - 3), 1))
    sigma = max(problem.opts.sigma_px, float(mad * corr))
    tests = []
    for p in range(db.n_points):
        m = db.point == p
        n = int(m.sum())
        t = float(np.sum(res[m] ** 2) / sigma**2)
        dof = max(2 * n - 3, 1)
        pv = float(chi2.sf(t, dof))
        tests.append(TrackTest(int(db.track_ids[p]), n, t, dof, pv, float(np.sqrt(np.mean(res[m] ** 2))),
                               pv >= opts.alpha))
    return tests, sigma, pts


def _scatter(pts_all, idx, flat):
    p = pts_all.copy()
    p[idx] = flat.reshape(-1, 3)
    return p.ravel()


def solve_rigid(problem: Stage1Problem, r0, v0, w0, inertia_ratios,
                opts: RigidityOptions = RigidityOptions()) -> tuple[Stage1Result, Stage1Problem, RigidityReport]:
    """Stage 1 on the rigid subset of ``problem.db`` (steps 1-3). Returns the final solution, the problem
    on the kept tracks (for the FIM), and the report of every track's test."""
    full = problem
    robust = dataclasses.replace(full, opts=dataclasses.replace(
        full.opts, loss="cauchy" if opts.robust_start else "linear", f_scale=opts.f_scale, max_nfev=opts.robust_nfev))
    sol = solve_stage1(robust, r0, v0, w0, inertia_ratios)
    iterates = list(sol.history)
    pts_all = sol.points_body
    theta_full = sol.theta
    kept = full.db.track_ids
    history, prob, seen = [], full, set()
    for rnd in range(1, opts.max_rounds + 1):
        tests, sigma, pts_all = chi2_track_tests(full, theta_full, pts_all, kept, opts)
        failing = [t for t in tests if t.track_id in kept and not t.kept]
        if failing:       # backward elimination: the worst-fitting kept track goes
            worst = max(failing, key=lambda t: t.chi2 / t.dof)
            new = kept[kept != worst.track_id]
        else:             # every kept track passes: reinstate rejected tracks that pass too
            new = np.array(sorted(set(kept.tolist()) | {t.track_id for t in tests if t.kept}), int)
        for t in tests:
            t.kept = bool(np.isin(t.track_id, new))
        history.append(new.tolist())
        if np.array_equal(new, kept) and rnd > 1 or tuple(new) in seen:
            for t in tests:       # a repeated set ends the loop with the set last fitted
                t.kept = bool(np.isin(t.track_id, kept))
            break
        seen.add(tuple(new))
        if len(new) < full.opts.min_points:
            worst3 = "; ".join(RigidityReport(tests, sigma, rnd).lines()[1:4])
            raise EstimationError(f"rigidity test kept {len(new)} of {full.db.n_points} tracks, stage 1 needs "
                                  f"{full.opts.min_points}: {worst3}")
        kept = new
        prob = dataclasses.replace(full, db=subset(full.db, kept),
                                   opts=dataclasses.replace(full.opts, max_nfev=opts.round_nfev))
        if prob.frames[0] != full.frames[0]:
            raise EstimationError("no rigid track at the first database frame (the stage-1 epoch)")
        idx = np.searchsorted(full.db.track_ids, kept)
        sol = solve_stage1(prob, sol.r0_lvlh, sol.v0_lvlh, sol.omega0_body, sol.inertia_ratios,
                           pts_all[idx], dphi0=sol.theta[6:9])
        iterates += [np.r_[th[:14], _scatter(pts_all, idx, th[14:])] for th in sol.history]
        theta_full = np.r_[sol.theta[:14], np.zeros(3 * full.db.n_points)]
        pts_all = pts_all.copy()
        pts_all[idx] = sol.points_body
    prob = dataclasses.replace(prob, opts=full.opts)       # the final fit, with the caller's budget
    idx = np.searchsorted(full.db.track_ids, kept)
    sol = solve_stage1(prob, sol.r0_lvlh, sol.v0_lvlh, sol.omega0_body, sol.inertia_ratios, pts_all[idx],
                       dphi0=sol.theta[6:9])
    # the convergence history in the final problem's parameters (kept points only), start to end
    sel = np.r_[np.arange(14), 14 + (3 * idx[:, None] + np.arange(3)).ravel()]
    sol.history = [th[sel] for th in iterates if len(th) == 14 + 3 * full.db.n_points] + sol.history
    return sol, prob, RigidityReport(tests, sigma, len(history), history)
