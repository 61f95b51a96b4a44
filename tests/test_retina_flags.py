"""Retina's rejections and the final output phase on images made by Retina's own synthetic-image tracer:
a shift beyond the search distance is flagged ``SEARCH_BORDER``, an image without the landmark
``LOW_CORRELATION`` (both: no shift returned); in a frame whose landmarks agree but one, the odd one is
flagged ``OUTLIER`` and keeps its shift (flagged, not dropped)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from estimators import flags as F
from estimators.retina import (
    CameraPoseEstimate,
    RetinaOptions,
    build_mesh,
    final_output_phase,
    measure_frame,
    measure_landmark,
    project_point,
    render_template,
)
from estimators.retina.landmarks import LandmarkMeasurement
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.maplet import Maplet

CAM = CameraModel.from_dict({"width": 200, "height": 200, "fx": 220.0, "fy": 220.0, "cx": 99.5, "cy": 99.5})
R_DOWN = np.diag([1.0, -1.0, -1.0])  # camera +x = maplet +x, +y = maplet −y, looking down
TRUE = CameraPoseEstimate(R_DOWN, np.array([0.0, 0.0, 12.0]))
SUN = np.array([0.5, 0.3, 0.8]) / np.linalg.norm([0.5, 0.3, 0.8])
CENTRES = [(-1.9, -1.8), (1.8, -1.9), (-1.8, 1.9), (1.9, 1.8), (0.0, 0.0), (0.1, -2.2)]


def _maplet(k, cx, cy, n=33, s=0.08):
    rng = np.random.default_rng(100 + k)
    h = gaussian_filter(rng.normal(0, 0.4, (n, n)), 1.5)
    a = np.clip(1 + 0.3 * gaussian_filter(rng.normal(size=(n, n)), 1.0) / 0.28, 0.3, 3)
    return Maplet(k, np.array([cx, cy, 0.0]), np.eye(3), s, h, a)


def _scene(displace=None):
    """Meshes and a background-filled image of every maplet rendered at the true pose; ``displace``:
    {landmark: (ds, dl) whole px} pastes that landmark's patch displaced (a mis-mapped landmark)."""
    meshes = [build_mesh(_maplet(k, cx, cy)) for k, (cx, cy) in enumerate(CENTRES)]
    img = np.full((CAM.height, CAM.width), 0.2)
    for m in meshes:
        t = render_template(m, CAM, TRUE, SUN)
        ds, dl = (displace or {}).get(int(m.maplet.landmark_id), (0, 0))
        sl = np.s_[t.l0 + dl:t.l0 + dl + t.image.shape[0], t.s0 + ds:t.s0 + ds + t.image.shape[1]]
        img[sl] = np.where(t.valid, t.image, img[sl])
    return meshes, img


@pytest.fixture(scope="module")
def scene():
    return _scene()


def _apriori(dx, dy):
    """The a-priori camera translated parallel to the image plane by (dx, dy) m."""
    return CameraPoseEstimate(R_DOWN, TRUE.position_m + np.array([dx, dy, 0.0]))


def test_shift_within_search_is_measured_beyond_it_flagged_border(scene):
    meshes, img = scene
    m = meshes[4]
    ap = _apriori(0.25, -0.15)  # moves the prediction by ≈ (−4.6, −2.8) px
    truth = project_point(CAM, TRUE, m.maplet.center_m)
    ok = measure_landmark(img, m, CAM, ap, SUN, 8)
    assert ok.has_result and ok.flags == 0, F.describe(ok.flags)
    assert np.hypot(ok.meas_s - truth[0], ok.meas_l - truth[1]) < 0.2
    assert np.hypot(ok.pred_s - truth[0], ok.pred_l - truth[1]) > 4.0
    near = measure_landmark(img, m, CAM, ap, SUN, 3)  # the true shift lies outside ±3 px
    assert near.flags & F.SEARCH_BORDER and not near.has_result
    assert np.isnan(near.ds) and np.isnan(near.dl) and np.isfinite(near.score)
    assert near.search_px == 3


def test_image_without_the_landmark_is_flagged_low_correlation(scene):
    meshes, _ = scene
    rng = np.random.default_rng(9)
    noise = gaussian_filter(rng.normal(size=(CAM.height, CAM.width)), 1.0)
    m = meshes[4]
    r = measure_landmark(noise, m, CAM, TRUE, SUN, 4)
    assert r.flags & F.LOW_CORRELATION and not r.has_result, (F.describe(r.flags), r.score)
    assert r.score < 0.3 and np.isnan(r.ds)
    # the threshold is what rejects it: with none, the same peak is returned as a shift
    loose = measure_landmark(noise, m, CAM, TRUE, SUN, 4, RetinaOptions(min_correlation=-1.0))
    assert not loose.flags & F.LOW_CORRELATION and loose.score == pytest.approx(r.score)


def test_final_output_phase_flags_the_odd_landmark_and_keeps_its_shift():
    meshes, img = _scene(displace={2: (3, -2)})  # landmark 2 appears 3 px right, 2 px up of the others
    ap = _apriori(0.06, 0.04)  # every landmark's prediction off by ≈ (−1.1, +0.7) px
    res = measure_frame(img, meshes, CAM, ap, SUN, [6] * len(meshes))
    assert all(r.has_result for r in res), [F.describe(r.flags) for r in res]
    truth = [project_point(CAM, TRUE, m.maplet.center_m) for m in meshes]
    err = [np.hypot(r.meas_s - t[0] - (3 if k == 2 else 0), r.meas_l - t[1] + (2 if k == 2 else 0))
           for k, (r, t) in enumerate(zip(res, truth))]
    assert max(err) < 0.3, np.round(err, 3)  # every landmark measured where its patch is
    odd = res[2]
    assert odd.flags & F.OUTLIER
    assert odd.has_result and np.isfinite(odd.ds)  # flagged, not dropped
    assert [k for k, r in enumerate(res) if r.flags & F.OUTLIER] == [2]


def test_final_output_phase_rules():
    """Median and MAD threshold (``max(floor, k · 1.4826 · MAD)``); no-result rows are ignored; with
    fewer than three results nothing is flagged."""
    def rows(shifts, flags=None):
        return [LandmarkMeasurement(k, 0.0, 0.0, ds=s[0], dl=s[1], flags=(flags or {}).get(k, 0))
                for k, s in enumerate(shifts)]

    ms = rows([(1.0, 0.5), (1.1, 0.4), (0.9, 0.6), (1.05, 0.45), (2.5, 0.5), (9.0, 9.0)], {5: F.LOW_CORRELATION})
    med = final_output_phase(ms, k=5.0, floor_px=1.0)
    np.testing.assert_allclose(med, [1.05, 0.5])  # the no-result row (9, 9) does not count
    assert [bool(m.flags & F.OUTLIER) for m in ms] == [False, False, False, False, True, False]
    assert ms[4].ds == 2.5  # kept
    few = rows([(0.0, 0.0), (5.0, 5.0)])
    assert np.all(np.isnan(final_output_phase(few))) and not any(m.flags for m in few)
