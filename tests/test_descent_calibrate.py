"""The landmark error model fit (renderlab.studies.descent_navigation.calibrate) and the common-share / N_eff scores
(renderlab.stats.independence) on synthetic errors drawn from the models they assume, with
known parameters (seeded)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from renderlab.stats.independence import common_share, n_effective, state_common_share
from renderlab.studies.descent_navigation.calibrate import fit_method


def test_fit_recovers_a_known_ground_offset_and_pixel_noise():
    rng = np.random.default_rng(1)
    s_map, s_px, bias = 0.02, 0.08, np.array([0.01, -0.05])
    run, item, es, el, gsd = [], [], [], [], []
    for r in range(200):
        for i in range(12):
            g = rng.uniform(0.04, 0.16) * np.linspace(1.0, 0.85, 5)      # one track: 5 images, GSD shrinking
            b = rng.normal(0, s_map, 2)
            e = b[None] / g[:, None] + rng.normal(0, s_px, (5, 2)) + bias
            run += [r] * 5
            item += [i] * 5
            es += e[:, 0].tolist()
            el += e[:, 1].tolist()
            gsd += g.tolist()
    f = fit_method(np.array(run), np.array(item), np.array(es), np.array(el), np.array(gsd))
    assert f["sigma_map_h_m"] == pytest.approx(s_map, rel=0.05)
    assert f["sigma_px"] == pytest.approx(s_px, rel=0.1)
    assert f["bias_s_px"] == pytest.approx(bias[0], abs=0.02) and f["bias_l_px"] == pytest.approx(bias[1], abs=0.02)
    assert f["n_tracks"] == 2400


def test_common_share_and_effective_band():
    rng = np.random.default_rng(2)
    N, rho = 100, 0.5
    # errors of 30 landmarks over N runs: a common part (variance rho) and an independent part (1 - rho)
    c = rng.normal(0, np.sqrt(rho), 30)
    v = c[None] + rng.normal(0, np.sqrt(1 - rho), (N, 30))
    assert common_share(v.ravel(), np.tile(np.arange(30), N)) == pytest.approx(rho, abs=0.15)
    assert common_share(rng.normal(size=3000), np.tile(np.arange(30), 100)) < 0.05
    # ANEES/6 of correlated runs: its spread over many campaigns matches the N_eff band, not the plain one
    a = []
    for _ in range(2000):
        y = rng.normal(0, np.sqrt(rho), 6)[None] + rng.normal(0, np.sqrt(1 - rho), (N, 6))
        a.append(np.mean(np.sum(y**2, 1)) / 6)
    ne = n_effective(N, rho)
    lo, hi = chi2.ppf([0.025, 0.975], 6 * ne) / (6 * ne)
    inside = np.mean((np.array(a) >= lo) & (np.array(a) <= hi))
    plain = np.mean((np.array(a) >= chi2.ppf(0.025, 6 * N) / (6 * N)) & (np.array(a) <= chi2.ppf(0.975, 6 * N) / (6 * N)))
    assert 0.92 <= inside <= 0.98 and plain < 0.5
    assert state_common_share(y) == pytest.approx(rho, abs=0.35)
