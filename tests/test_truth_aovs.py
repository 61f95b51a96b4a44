"""The truth-AOV pass (renderlab.render.truth_aovs) against the numpy expressions it replaced, byte for byte, with
hits and misses, registry ids out of the table's range, and a far render origin."""

from __future__ import annotations

import numpy as np

from renderlab.render.truth_aovs import truth_aovs


def test_truth_aovs_equal_the_numpy_expressions_byte_for_byte():
    rng = np.random.default_rng(0)
    n = 5000
    valid = rng.random(n) > 0.2
    P = (rng.normal(size=(3, n)) * 300).astype(np.float32)
    N = rng.normal(size=(3, n)).astype(np.float32)
    reg = rng.integers(-3, 9, n)
    lut = np.array([-1, 0, 1, 2, -1, 5], np.int32)
    cam, origin = rng.normal(size=3) * 200, np.array([6.4e6, -2.1e5, 3.3e4])
    pos, nrm, rng_m, ids = truth_aovs(valid, P, N, reg, lut, cam, origin)

    miss = ~valid
    want_ids = lut[np.clip(reg, 0, len(lut) - 1)].astype(np.int32)
    want_ids[miss] = -1
    P64 = P.T.astype(np.float64)
    d = P64 - cam
    want_rng = np.sqrt(np.einsum("ij,ij->i", d, d))
    P64 += origin
    want_nrm = N.T.copy()
    P64[miss], want_nrm[miss], want_rng[miss] = np.nan, np.nan, np.nan
    for got, want in ((pos, P64.astype(np.float32)), (nrm, want_nrm), (rng_m, want_rng), (ids, want_ids)):
        assert got.dtype == want.dtype and got.shape == want.shape and got.tobytes() == want.tobytes()
    assert np.isnan(pos[miss]).all() and (ids[miss] == -1).all() and miss.any()
    # the range is the float64 distance of the float32 hit: compare a few with math.dist
    import math
    k = np.flatnonzero(valid)[:20]
    assert all(rng_m[i] == math.dist([float(v) for v in P[:, i]], list(cam)) or
               abs(rng_m[i] - math.dist([float(v) for v in P[:, i]], list(cam))) <= 1e-12 * rng_m[i] for i in k)
