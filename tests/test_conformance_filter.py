"""Navigation-filter contract (:mod:`renderlab.contracts.navigation`) for every registered filter.

The conformance case (:mod:`renderlab.measurement.conformance_filter`) is the contract's linear-Gaussian case:
truth propagated by the filter's own two-body model, LOS noise exactly the declared Gaussian R (small, so the LOS
function is linear to ~5e-4 relative over the errors), initial estimate drawn from P0. 200 seeded runs through
``initialize``/``propagate``/``update``: ANEES in its 95 % χ² band at the final time and at ≥ 90 % of the times,
ANIS likewise and summed over the times. A correct filter fails that criterion on about 30 % of the seeds
(the 95 % bands are applied several times, and ANEES is strongly correlated in time; measured with the batch
estimator over 200 seeds), so the seed is fixed; the over-confident filters below fail it on every seed tried.

Also: an over-confident filter (P shrunk 10× after each update), one that reports P/2, and one that writes
into its inputs fail with a message; the two built-in adapters agree with each other; the contract path equals
the batch estimators driven directly.
"""

from __future__ import annotations

import numpy as np
import pytest

from renderlab import plugins
from renderlab.contracts.navigation import FilterMeasurement, FilterUpdate, NavigationFilter
from renderlab.measurement.builtin_filters import CoastlineEKF, CoastlineSqrtEKF, los_noise_from_R
from renderlab.measurement.conformance_filter import check_filter, make_case, measurement, run_filter

SEED = 0
#: filters whose model is not the case's Earth two-body one; each is checked on its model-matched options elsewhere
#: (descent_ekf, an asteroid-fixed-frame filter: tests/test_descent_nav.py with GM = Earth's, no rotation)
OWN_MATCHED_CASE = ("descent_ekf",)
FILTER_NAMES = [n for n in plugins.filters.names() if n not in OWN_MATCHED_CASE]


@pytest.fixture(scope="module")
def case():
    return make_case(SEED, n_runs=200)


@pytest.mark.parametrize("name", FILTER_NAMES)
def test_registered_filter_is_consistent_on_the_linear_gaussian_case(name, case):
    factory = plugins.filters.get(name)
    problems, stats = check_filter(factory, SEED, case=case, return_stats=True)
    assert problems == [], (name, problems)
    lo, hi = stats["anees_band"]
    assert lo < stats["anees"].mean() < hi
    assert factory().name == name


class _Overconfident:
    """Wraps a filter and divides P by 10 after every update (restarting the inner filter from x, P/10)."""

    name = "overconfident"

    def __init__(self, inner):
        self._inner = inner

    x = property(lambda self: self._inner.x)
    P = property(lambda self: self._inner.P)

    def initialize(self, t0_s, x0, P0):
        self._inner.initialize(t0_s, x0, P0)

    def propagate(self, t_s):
        self._inner.propagate(t_s)

    def update(self, t_s, m):
        res = self._inner.update(t_s, m)
        self._inner.initialize(t_s, self._inner.x, self._inner.P / 10.0)
        return res


class _Mutating(CoastlineEKF):
    """Writes into the measurement it is given (forbidden by the contract)."""

    def update(self, t_s, m):
        res = super().update(t_s, m)
        m.z[:] = 0.0
        return res


class _ReportsHalfP(CoastlineEKF):
    """A correct recursion that reports P/2 (over-confident by 2× in what it tells the lab; NIS unaffected)."""

    P = property(lambda self: CoastlineEKF.P.fget(self) / 2.0)


def test_overconfident_filter_fails_with_a_message(case):
    problems = check_filter(lambda: _Overconfident(CoastlineEKF()), SEED, case=case)
    assert any(p.startswith("ANEES at the final time") for p in problems), problems
    assert any(p.startswith("ANIS") or p.startswith("summed ANIS") for p in problems), problems
    assert isinstance(_Overconfident(CoastlineEKF()), NavigationFilter)


def test_filter_reporting_half_its_covariance_fails_on_nees_only(case):
    problems = check_filter(_ReportsHalfP, SEED, case=case)
    assert problems and all(p.startswith("ANEES") for p in problems), problems


def test_filter_that_modifies_its_inputs_fails():
    problems = check_filter(_Mutating, SEED, case=make_case(SEED, n_runs=3, n_images=3))
    assert "the filter modified its input z" in problems, problems


def test_two_adapters_agree(case):
    runs = range(5)
    a, b = (run_filter(f, case, runs) for f in (CoastlineEKF, CoastlineSqrtEKF))
    sig = np.sqrt(np.diagonal(a["P"], axis1=-2, axis2=-1))
    assert np.max(np.abs(a["x"] - b["x"]) / sig) < 1e-9                 # measured 6e-12
    assert np.max(np.abs(a["P"] - b["P"]) / (sig[..., :, None] * sig[..., None, :])) < 1e-9   # 3e-15
    assert np.allclose(a["nis"][:, 1:], b["nis"][:, 1:], rtol=1e-9, atol=0)                   # 8e-13


def _exact_R_case(case):
    """The case with R declared at the measured directions (then the adapter reads σθ, σ_att off R exactly)."""
    from dataclasses import replace

    from estimators.coastline.los import stacked_measurement_covariance

    z = case.z[:5]
    y = z / np.linalg.norm(z, axis=-1, keepdims=True)
    R = np.stack([stacked_measurement_covariance(y[:, j], case.sigma_theta_rad, case.sigma_attitude_rad)
                  for j in range(y.shape[1])], axis=1)                                  # (5, K+1, 3k, 3k)
    return replace(case, z=z, x0=case.x0[:5]), R


@pytest.mark.parametrize("adapter, form", [(CoastlineEKF, "joseph"), (CoastlineSqrtEKF, "sqrt")])
def test_contract_path_equals_the_batch_estimator(adapter, form, case):
    """One run through the adapter = the same run in the batch estimator (N = 5 in lock-step)."""
    from estimators.coastline.ekf import BatchCoastlineEKF, EKFOptions
    from estimators.coastline.sqrt_ekf import SqrtBatchCoastlineEKF

    c, R = _exact_R_case(case)
    opts = EKFOptions(sigma_theta_rad=c.sigma_theta_rad, sigma_attitude_rad=c.sigma_attitude_rad)
    batch = (SqrtBatchCoastlineEKF if form == "sqrt" else BatchCoastlineEKF)(c.x0, c.P0, opts)
    filters = [adapter() for _ in range(5)]
    for n, f in enumerate(filters):
        f.initialize(0.0, c.x0[n], c.P0)
    for j in range(1, c.n_images + 1):
        batch.propagate(c.t_s[j] - c.t_s[j - 1])
        ref = batch.update(c.z[:, j], c.points_eci_m[j], c.R_cam_from_eci[j])
        for n, f in enumerate(filters):
            m = measurement(c, n, j)
            res = f.update(c.t_s[j], FilterMeasurement("los", m.z, R[n, j], m.context))   # propagates to t
            assert res == FilterUpdate(nis=pytest.approx(ref.nis[n], rel=1e-9), dof=ref.dof, accepted=True)
            np.testing.assert_allclose(f.x, batch.x[n], rtol=1e-12, atol=1e-9)
            np.testing.assert_allclose(f.P, batch.P[n], rtol=1e-9, atol=1e-12 * np.abs(batch.P[n]).max())


def test_noise_read_off_R_on_the_case(case):
    """R built at the true directions, the adapter's basis at the measured ones: σθ, σ_att to ~1e-4 relative."""
    for j in (1, case.n_images):
        s_th, s_att = los_noise_from_R(case.R[j], case.z[0, j])
        assert s_th == pytest.approx(case.sigma_theta_rad, rel=1e-4)
        assert s_att == pytest.approx(case.sigma_attitude_rad, rel=1e-3)


def test_adapter_errors_and_empty_image(case):
    f = CoastlineEKF({"sigma_theta_rad": 1e-4})
    assert f.options.sigma_theta_rad == 1e-4 and np.all(np.isnan(f.x))
    f.initialize(0.0, case.x0[0], case.P0)
    m = measurement(case, 0, 1)
    with pytest.raises(ValueError, match="kind 'position'"):
        f.update(30.0, FilterMeasurement("position", np.zeros(3), np.eye(3)))
    with pytest.raises(ValueError, match="R_cam_from_eci"):
        f.update(30.0, FilterMeasurement("los", m.z, m.R, {"points_eci_m": m.context["points_eci_m"]}))
    with pytest.raises(ValueError, match="is not"):
        f.update(30.0, FilterMeasurement("los", m.z, np.eye(m.z.size), m.context))
    with pytest.raises(ValueError, match="unknown coastline EKF option"):
        CoastlineEKF({"sigma": 1.0})
    x_before = f.x
    res = f.update(30.0, FilterMeasurement("los", np.zeros(0), np.zeros((0, 0)),
                                           {"points_eci_m": np.zeros((0, 3)), "R_cam_from_eci": np.eye(3)}))
    assert res.dof == 0 and not res.accepted and np.isnan(res.nis)
    assert f.t_s == 30.0 and not np.array_equal(f.x, x_before)      # propagated to t, not updated
    res = f.update(30.0, FilterMeasurement("los", m.z, None, m.context))    # R None: the options' σθ, σ_att
    assert res.dof == 2 * case.points_eci_m.shape[1] and np.isfinite(res.nis)
