"""Basilisk's OpNav modules as centre/limb methods (``renderlab.basilisk.opnav_methods``), unmodified.

Oracles: the conformance harness's exact ray-cast disc (no renderer); OpenCV's ``HoughCircles`` run directly on the
same 8-bit image with houghCircles' own pre-processing (the C++ source: grey, inverted threshold at 15, box blur);
``pixelLineConverter``'s published range formula ``ρ = R / sin(atan(X·r))`` evaluated here from the circle radius;
and the principal point horizonOpNav assumes, ``(W/2, H/2)`` on pixel indices (its C source), which explains its
measured half-pixel error.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("Basilisk")
cv2 = pytest.importorskip("cv2")

from renderlab import plugins  # noqa: E402
from renderlab.basilisk.opnav_methods import (  # noqa: E402
    BASILISK_METHODS,
    REQ_MARS_M,
    BskOptions,
    HoughCirclesMethod,
    HoughPixelLineMethod,
    LimbHorizonMethod,
    png8,
)
from renderlab.contracts.centre_limb import BodyModel, CentreLimbReason  # noqa: E402
from renderlab.contracts.landmark import CameraPose  # noqa: E402
from renderlab.measurement.conformance_centre_limb import check_centre_limb_method, disc_case  # noqa: E402


def test_wrappers_are_registered_for_the_centre_limb_kind():
    reg = plugins.method_registry("centre_limb")
    for name, cls in BASILISK_METHODS.items():
        assert reg.get(name) is cls and cls().name == name
        assert plugins.kind_of_method(cls).name == "centre_limb"


def test_limb_horizon_fails_rule_a_by_horizonopnavs_principal_point():
    """Measured finding: horizonOpNav takes the principal point at (W/2, H/2) on pixel indices, half a pixel from
    the detector centre ((W − 1)/2 in pixel-centre coordinates, which pixelLineConverter's ``u − W/2 + 0.5`` uses),
    so its centre is off by about (−0.5, −0.5) px, far outside its own claimed 3σ."""
    fails = check_centre_limb_method(LimbHorizonMethod)
    assert len(fails) == 1 and fails[0].startswith("(a) bsk_limb_horizon: centre"), fails
    truth, _, frame = disc_case()
    res = LimbHorizonMethod().measure(frame)
    err = np.array([res.centre_s - truth[0], res.centre_l - truth[1]])
    assert np.all(np.abs(err - (-0.5)) < 0.1), err                 # the half pixel, both axes
    cam = frame.camera                                             # its own principal point: the error goes away
    shifted = dataclasses.replace(cam, cx=cam.width / 2, cy=cam.height / 2)
    again = shifted.project(res.r_cam_m)
    assert np.hypot(*(again - truth)) < 0.1
    assert 3 * np.sqrt(np.max(np.linalg.eigvalsh(res.cov_centre_px2))) < 0.2   # what it claims


def test_hough_centre_equals_opencv_on_the_same_pixels():
    truth, _, frame = disc_case()
    res = HoughCirclesMethod().measure(frame)
    o = BskOptions()
    grey = cv2.imdecode(png8(frame.image, None), cv2.IMREAD_GRAYSCALE)
    _, binary = cv2.threshold(grey, 15, 255, cv2.THRESH_BINARY_INV)
    blurred = cv2.blur(binary, (o.hough_blur, o.hough_blur))
    circles = cv2.HoughCircles(blurred, cv2.HOUGH_GRADIENT, o.dp_value, o.hough_min_dist, param1=o.canny_thresh,
                               param2=o.vote_thresh, minRadius=int(o.min_radius_px), maxRadius=0)
    s, ll, r = circles[0, 0, :3]
    assert (res.centre_s, res.centre_l, res.limb_a_px) == pytest.approx((s, ll, r), abs=1e-4)


def test_pixel_line_range_is_basilisks_formula_with_the_body_radius():
    _, rng, frame = disc_case()
    res = HoughPixelLineMethod().measure(frame)
    R = float(frame.body.semi_axes_m[0])
    expected = R / np.sin(np.arctan(res.limb_a_px / frame.camera.fx))  # X = 1/fx for Basilisk's centred pinhole
    assert res.range_m == pytest.approx(expected, rel=1e-9)
    assert abs(res.range_m / rng - 1) < 0.01                       # Hough's radius: −0.6 % measured on this disc
    k = REQ_MARS_M / R              # the same picture of a body of Basilisk's own radius: no adapter at all
    mars = dataclasses.replace(frame, body=BodyModel(semi_axes_m=np.full(3, REQ_MARS_M)),
                               pose=CameraPose(frame.pose.R_body_from_cam, frame.pose.position_m * k))
    assert HoughPixelLineMethod().measure(mars).range_m == pytest.approx(res.range_m * k, rel=1e-12)


@pytest.mark.parametrize("name", sorted(BASILISK_METHODS))
def test_no_result_reasons(name):
    _, _, frame = disc_case()
    make = BASILISK_METHODS[name]
    dark = make().measure(dataclasses.replace(frame, image=np.zeros_like(frame.image)))
    assert not dark.has_result and dark.reason == CentreLimbReason.UNLIT.value, (dark.reason, dark.diagnostics)
    tiny = make().measure(dataclasses.replace(frame, body=BodyModel(semi_axes_m=np.full(3, 100.0))))
    assert tiny.reason == CentreLimbReason.TOO_SMALL.value                     # 4.5 px < houghMinRadius 20
    cam = dataclasses.replace(frame.camera, fx=frame.camera.fx * 1.01)
    odd = make().measure(dataclasses.replace(frame, camera=cam))
    assert odd.reason == CentreLimbReason.METHOD_ERROR.value and "square pixels" in odd.diagnostics
