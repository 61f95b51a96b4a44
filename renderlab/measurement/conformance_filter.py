r"""Conformance check of a navigation filter (:class:`~renderlab.contracts.navigation.NavigationFilter`).

The case is the contract's *linear-Gaussian case* for a LOS filter: truth follows the filter's own model
exactly and every noise is the declared Gaussian, so a correct filter is consistent and its NEES/NIS are χ².

- Truth: a 1000-km, 45° circular orbit propagated by the onboard two-body model itself
  (:func:`estimators.coastline.dynamics.propagate_state_stm`, RK4, 10-s steps: the coastline filter's own
  discretisation), images every ``cadence_s``.
- Measurements: k landmarks per image on the Earth sphere around nadir, seen by a nadir camera whose attitude
  (``R_cam_from_eci``) is given. :math:`\mathbf z_i = T\mathbf e_i(\mathbf r) + \sigma_\theta(n_1\mathbf a_i
  + n_2\mathbf b_i) + \sigma_{att}[\mathbf e_i\times]\boldsymbol n_{att}` with standard normals n and
  :math:`\mathbf a_i, \mathbf b_i \perp \mathbf e_i`: *exactly* Gaussian with the declared covariance
  :math:`R = \sigma_\theta^2\,\mathrm{blkdiag}(I-\mathbf e_i\mathbf e_i^T) + \sigma_{att}^2 GG^T` (eq. 18 plus a
  star-tracker error shared by the image; the attitude error is carried as LOS noise, which to first order is
  what a rotated star-tracker attitude does). The only departure from linear-Gaussian is the curvature of the
  LOS function over the estimation error: its second-order term is ~|δr|/ρ ≤ 5e-4 of the first-order one
  (500 m at 1000 km), far below what the χ² bands (±8 % for 200 runs) resolve. With small LOS noise the
  measurement is, for this check, linear.
- Initial estimate: truth + a draw from N(0, P0).

:func:`check_filter` runs N seeded runs through the contract (``initialize``/``propagate``/``update``) and
returns what fails: ANEES (6 dof) inside its two-sided 95 % band χ²(6N)/N at the final time and at
≥ ``min_fraction_inside`` of the image times; ANIS inside its band χ²(N·2k)/N at that fraction of the times and
summed over all times (band χ²(N·2kK)/N); ``dof = 2k``, finite NIS, symmetric positive-definite P, inputs
unmodified. The 95 % bands are applied several times and ANEES is strongly correlated in time, so a *correct*
filter fails this criterion on ~30 % of seeds (measured over 200 seeds, N = 200): use it with a fixed seed on
which the built-in filters pass; a filter over-confident by 2× fails on every seed tried.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from estimators.coastline.dynamics import MU_EARTH, propagate_state_stm
from estimators.coastline.los import los_predict, skew_batch, stacked_measurement_covariance
from estimators.coastline.sqrt_ekf import tangent_basis
from renderlab.contracts.navigation import FilterMeasurement, NavigationFilter

__all__ = ["ConformanceCase", "make_case", "measurement", "run_filter", "chi2_band", "score", "check_filter"]

R_EARTH_M = 6378137.0


@dataclass(frozen=True)
class ConformanceCase:
    """N runs on one truth: times (K+1,), truth (K+1, 6), landmarks (K+1, k, 3), attitudes (K+1, 3, 3),
    declared R per image (K+1, 3k, 3k), measured LOS (N, K+1, k, 3), initial estimates (N, 6) and P0 (6, 6).
    Index 0 is the prior time (no image)."""

    t_s: np.ndarray
    x_true: np.ndarray
    points_eci_m: np.ndarray
    R_cam_from_eci: np.ndarray
    R: np.ndarray
    z: np.ndarray
    x0: np.ndarray
    P0: np.ndarray
    sigma_theta_rad: float
    sigma_attitude_rad: float

    @property
    def n_runs(self) -> int:
        return self.x0.shape[0]

    @property
    def n_images(self) -> int:
        return len(self.t_s) - 1


def _nadir_frame(x: np.ndarray) -> np.ndarray:
    """Camera-from-ECI rows (in-track, cross × in-track, −r̂) of states x (K, 6)."""
    r, v = x[:, :3], x[:, 3:]
    zc = -r / np.linalg.norm(r, axis=1, keepdims=True)
    h = np.cross(r, v)
    xc = np.cross(h / np.linalg.norm(h, axis=1, keepdims=True), -zc)
    return np.stack([xc, np.cross(zc, xc), zc], axis=1)


def _landmarks(x: np.ndarray, T: np.ndarray, grid: int, half_angle: float) -> np.ndarray:
    """Points where a grid×grid fan of camera rays (±half_angle) meets the Earth sphere: (K, grid², 3)."""
    g = np.tan(np.linspace(-half_angle, half_angle, grid))
    u, w = np.meshgrid(g, g)
    d_cam = np.stack([u.ravel(), w.ravel(), np.ones(grid * grid)], -1)
    d = np.einsum("kji,mj->kmi", T, d_cam / np.linalg.norm(d_cam, axis=1, keepdims=True))   # Tᵀ d_cam
    r = x[:, None, :3]
    b = np.einsum("kmi,kmi->km", d, r)
    s = -b - np.sqrt(b**2 - (np.einsum("kmi,kmi->km", r, r) - R_EARTH_M**2))
    return r + s[..., None] * d


def make_case(seed: int, n_runs: int = 200, n_images: int = 20, cadence_s: float = 30.0, grid: int = 3,
              sigma_theta_rad: float = 2e-4, sigma_attitude_rad: float = 5e-5,
              sigma0: tuple[float, float] = (500.0, 0.5)) -> ConformanceCase:
    """The linear-Gaussian LOS case (module docstring), all random numbers from ``default_rng(seed)``.

    Parameters
    ----------
    seed : int
    n_runs, n_images : int
        N runs, K images after the prior time.
    cadence_s : float
        Time between images (s).
    grid : int
        k = grid² landmarks per image.
    sigma_theta_rad, sigma_attitude_rad : float
        Declared per-LOS and shared (star-tracker) angular noise, per axis.
    sigma0 : (float, float)
        Per-axis 1σ of the initial position (m) and velocity (m/s) error: P0 = diag.
    """
    rng = np.random.default_rng(seed)
    a = R_EARTH_M + 1.0e6
    v = math.sqrt(MU_EARTH / a)
    inc = math.radians(45.0)
    x = [np.array([a, 0.0, 0.0, 0.0, v * math.cos(inc), v * math.sin(inc)])]
    for _ in range(n_images):
        x.append(propagate_state_stm(x[-1][None], cadence_s, MU_EARTH, 10.0)[0][0])
    x = np.array(x)
    T = _nadir_frame(x)
    pts = _landmarks(x, T, grid, math.radians(8.0))
    k = grid * grid
    e = np.stack([los_predict(x[j:j + 1, :3], pts[j], T[j])[0][0] for j in range(n_images + 1)])   # (K+1, k, 3)
    R = stacked_measurement_covariance(e, sigma_theta_rad, sigma_attitude_rad)
    n_los = rng.standard_normal((n_runs, n_images + 1, k, 2))
    n_att = rng.standard_normal((n_runs, n_images + 1, 3))
    ab = tangent_basis(e)                                                     # (K+1, k, 2, 3)
    z = (e[None] + sigma_theta_rad * np.einsum("nkmj,kmji->nkmi", n_los, ab)
         + sigma_attitude_rad * np.einsum("kmij,nkj->nkmi", skew_batch(e), n_att))
    sd0 = np.r_[np.full(3, sigma0[0]), np.full(3, sigma0[1])]
    x0 = x[0] + rng.standard_normal((n_runs, 6)) * sd0
    return ConformanceCase(t_s=np.arange(n_images + 1) * cadence_s, x_true=x, points_eci_m=pts, R_cam_from_eci=T,
                           R=R, z=z, x0=x0, P0=np.diag(sd0**2), sigma_theta_rad=sigma_theta_rad,
                           sigma_attitude_rad=sigma_attitude_rad)


def measurement(case: ConformanceCase, run: int, j: int) -> FilterMeasurement:
    """The ``"los"`` measurement of run ``run`` at image ``j`` (1..K), on copies of the case's arrays."""
    return FilterMeasurement(kind="los", z=case.z[run, j].reshape(-1).copy(), R=case.R[j].copy(),
                             context={"points_eci_m": case.points_eci_m[j].copy(),
                                      "R_cam_from_eci": case.R_cam_from_eci[j].copy()})


def run_filter(factory, case: ConformanceCase, runs) -> dict:
    """Drive ``factory()`` filters through ``case`` for the given runs via the contract.

    Returns
    -------
    dict with ``x`` (n, K+1, 6), ``P`` (n, K+1, 6, 6), ``nis`` (n, K+1; NaN at 0), ``dof`` (n, K+1),
    ``problems`` (list of str: contract violations seen on the way).
    """
    runs = list(runs)
    K = case.n_images
    xs, Ps = np.empty((len(runs), K + 1, 6)), np.empty((len(runs), K + 1, 6, 6))
    nis, dof = np.full((len(runs), K + 1), np.nan), np.zeros((len(runs), K + 1), dtype=int)
    problems: list[str] = []
    for i, n in enumerate(runs):
        f = factory()
        if i == 0 and not isinstance(f, NavigationFilter):
            problems.append(f"{type(f).__name__} does not implement NavigationFilter")
        f.initialize(float(case.t_s[0]), case.x0[n], case.P0)
        xs[i, 0], Ps[i, 0] = f.x, f.P
        for j in range(1, K + 1):
            f.propagate(float(case.t_s[j]))
            res = f.update(float(case.t_s[j]), measurement(case, n, j))
            nis[i, j], dof[i, j] = res.nis, res.dof
            xs[i, j], Ps[i, j] = f.x, f.P
    return {"x": xs, "P": Ps, "nis": nis, "dof": dof, "problems": problems}


def chi2_band(dof_per_run: float, n_runs: int, p: float = 0.95) -> tuple[float, float]:
    """Two-sided ``p`` band of the average of ``n_runs`` χ²(dof_per_run) variables: χ²_{(1∓p)/2}(N·dof)/N."""
    from scipy.stats import chi2

    a = 0.5 * (1.0 - p)
    d = dof_per_run * n_runs
    return float(chi2.ppf(a, d) / n_runs), float(chi2.ppf(1.0 - a, d) / n_runs)


def _inputs_unchanged(factory, case: ConformanceCase) -> list[str]:
    """Run one filter on copies-checked inputs; report any input it modified."""
    m = measurement(case, 0, 1)
    keep = {"x0": case.x0[0].copy(), "P0": case.P0.copy(), "z": m.z.copy(), "R": m.R.copy(),
            "points_eci_m": m.context["points_eci_m"].copy(), "R_cam_from_eci": m.context["R_cam_from_eci"].copy()}
    x0, P0 = case.x0[0].copy(), case.P0.copy()
    f = factory()
    f.initialize(0.0, x0, P0)
    f.update(float(case.t_s[1]), m)
    now = {"x0": x0, "P0": P0, "z": m.z, "R": m.R, **m.context}
    return [f"the filter modified its input {k}" for k in keep if not np.array_equal(keep[k], now[k])]


def _band_report(what: str, series: np.ndarray, lo: float, hi: float, min_fraction: float) -> list[str]:
    inside = (series >= lo) & (series <= hi)
    out = []
    if not inside[-1]:
        out.append(f"{what} at the final time {series[-1]:.3f} outside its 95 % band [{lo:.3f}, {hi:.3f}]")
    if inside.mean() < min_fraction:
        out.append(f"{what} inside its 95 % band [{lo:.3f}, {hi:.3f}] at {inside.mean():.0%} of the times "
                   f"(< {min_fraction:.0%}; range {series.min():.3f}..{series.max():.3f})")
    return out


def score(case: ConformanceCase, out: dict, min_fraction_inside: float = 0.9) -> tuple[list[str], dict]:
    """χ² consistency of filter outputs on ``case`` (``out`` as from :func:`run_filter`, all N runs).

    Returns
    -------
    failures : list of str
    stats : dict
        ``anees``/``anis`` (K,) per image time, their bands, ``anis_total`` (sum over times) and its band.
    """
    N = case.n_runs
    k = case.points_eci_m.shape[1]
    problems: list[str] = []
    if not np.all(out["dof"][:, 1:] == 2 * k):
        problems.append(f"update returned dof {np.unique(out['dof'][:, 1:]).tolist()}, expected 2k = {2 * k}")
    if not np.all(np.isfinite(out["nis"][:, 1:])):
        problems.append("update returned a non-finite NIS")
    P = out["P"][:, 1:]
    if not np.allclose(P, np.swapaxes(P, -1, -2), rtol=1e-9, atol=0) or np.any(np.linalg.eigvalsh(P)[..., 0] <= 0):
        return problems + ["P is not symmetric positive definite"], {}
    err = out["x"][:, 1:] - case.x_true[None, 1:]
    nees = np.einsum("nki,nki->nk", err, np.linalg.solve(P, err[..., None])[..., 0])
    anees, anis = nees.mean(axis=0), out["nis"][:, 1:].mean(axis=0)
    stats = {"anees": anees, "anis": anis, "anees_band": chi2_band(6.0, N), "anis_band": chi2_band(2.0 * k, N),
             "anis_total": float(anis.sum()), "anis_total_band": chi2_band(2.0 * k * case.n_images, N)}
    problems += _band_report("ANEES", anees, *stats["anees_band"], min_fraction_inside)
    problems += _band_report("ANIS", anis, *stats["anis_band"], min_fraction_inside)
    lo_t, hi_t = stats["anis_total_band"]
    if not lo_t <= stats["anis_total"] <= hi_t:
        problems.append(f"summed ANIS {stats['anis_total']:.2f} over {case.n_images} images outside its 95 % band "
                        f"[{lo_t:.2f}, {hi_t:.2f}]")
    return problems, stats


def check_filter(factory, seed: int, n_runs: int = 200, min_fraction_inside: float = 0.9,
                 case: ConformanceCase | None = None, return_stats: bool = False):
    """Conformance check of a filter factory on the linear-Gaussian LOS case (module docstring).

    Parameters
    ----------
    factory : callable
        ``factory() -> NavigationFilter`` (e.g. ``renderlab.plugins.filters.get(name)``, called with no options).
    seed : int
        Seed of the case (:func:`make_case`).
    n_runs : int
        N Monte Carlo runs (≥ 100 for the bands to mean something).
    min_fraction_inside : float
        Fraction of the image times at which ANEES and ANIS must be inside their 95 % bands.
    case : ConformanceCase, optional
        A prepared case (overrides ``seed``/``n_runs``).
    return_stats : bool
        Also return the statistics of :func:`score`.

    Returns
    -------
    list of str
        What fails (empty: conforms); with ``return_stats``, ``(failures, stats)``.
    """
    case = make_case(seed, n_runs) if case is None else case
    modified = _inputs_unchanged(factory, case)
    out = run_filter(factory, case, range(case.n_runs))
    problems, stats = score(case, out, min_fraction_inside)
    problems = list(out["problems"]) + modified + problems
    return (problems, stats) if return_stats else problems


def check_filter_method(factory) -> list[str]:
    """The filter kind's ``conformance`` (:mod:`renderlab.contracts.observable`, ``renderlab check-method filter
    NAME``): :func:`check_filter` of ``factory()`` on the case of seed 0 with its default runs and bands."""
    return check_filter(factory, 0)
