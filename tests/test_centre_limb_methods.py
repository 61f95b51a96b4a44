"""The lab's centre/limb methods (``estimators.centre_limb``) through the centre/limb contract.

Oracles: scipy's ``dblquad`` of the centroid-offset integral (eq. 5 of ``estimators.centre_limb.phase``) for the phase
correction; ``cv2.fitEllipse`` and exact points for the direct ellipse fit; the harness's exact ray-cast disc
(:mod:`renderlab.measurement.conformance_centre_limb`, no renderer) for the known centre and range; and the
``centre_truth`` table of Mitsuba renders of the planet world at 30°–90° phase.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from renderlab.contracts.centre_limb import BodyModel, CentreLimbFrame, CentreLimbReason, CentreLimbResult
from renderlab.contracts.landmark import CameraPose
from renderlab.measurement.centre_limb_methods import BUILTIN
from renderlab.measurement.conformance_centre_limb import check_centre_limb_method

cv2 = pytest.importorskip("cv2")


def _dblquad_offset(alpha: float, law: str) -> float:
    """Eq. 5 over the visible hemisphere in (colatitude, azimuth) about the view axis, by scipy."""
    from scipy.integrate import dblquad

    s = np.array([np.sin(alpha), 0.0, np.cos(alpha)])

    def f(t, p, moment):
        n = np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])
        mu0 = n @ s
        if mu0 <= 0:
            return 0.0
        L = mu0 if law == "lambert" else mu0 / (mu0 + n[2])
        return L * n[2] * np.sin(t) * (n[0] if moment else 1.0)

    def lit(p):  # μ₀ = A sin t + B cos t = |·| sin(t + φ) > 0 on (−φ, π − φ): the colatitudes lit, clipped
        phi = np.arctan2(np.cos(alpha), np.cos(p) * np.sin(alpha))
        return float(np.clip(-phi, 0, np.pi / 2)), float(np.clip(np.pi - phi, 0, np.pi / 2))

    flux = dblquad(lambda t, p: f(t, p, False), 0, 2 * np.pi, lambda p: lit(p)[0], lambda p: lit(p)[1],
                   epsabs=1e-11)[0]
    return dblquad(lambda t, p: f(t, p, True), 0, 2 * np.pi, lambda p: lit(p)[0], lambda p: lit(p)[1],
                   epsabs=1e-11)[0] / flux


@pytest.mark.parametrize("deg", [20.0, 60.0, 120.0])
def test_phase_offset_equals_the_integral(deg):
    from estimators.centre_limb.phase import lambert_offset, offset

    a = np.radians(deg)
    ref_l, ref_ls = _dblquad_offset(a, "lambert"), _dblquad_offset(a, "lommel_seeliger")
    assert float(lambert_offset(a)) == pytest.approx(ref_l, abs=1e-9)           # eq. 6, the closed form
    assert offset(a, "lommel_seeliger") == pytest.approx(ref_ls, abs=1e-9)       # eq. 7, the 1-D quadrature
    assert ref_ls < ref_l                                                        # a brighter limb pulls it back


def test_direct_ellipse_fit_recovers_exact_points_on_a_partial_arc():
    from estimators.centre_limb import fit_ellipse_direct
    from renderlab.geometry.conic import ellipse_params

    c, a, b, ang = np.array([71.3, 40.8]), 33.0, 21.5, 0.6
    t = np.linspace(-1.2, 1.4, 60)                                               # 150° of arc
    R = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    pts = c + (np.column_stack([a * np.cos(t), b * np.sin(t)]) @ R.T)
    u0, fa, fb, fang = ellipse_params(fit_ellipse_direct(pts))
    assert np.hypot(*(u0 - c)) < 1e-8 and fa == pytest.approx(a, abs=1e-8) and fb == pytest.approx(b, abs=1e-8)
    assert fang == pytest.approx(ang, abs=1e-9)
    full = c + (np.column_stack([a * np.cos(t * 2.4), b * np.sin(t * 2.4)]) @ R.T)
    (cx, cy), (w, h), _ = cv2.fitEllipse(full.astype(np.float32))             # OpenCV, the baseline
    u0, fa, fb, _ = ellipse_params(fit_ellipse_direct(full))
    assert np.hypot(cx - u0[0], cy - u0[1]) < 1e-3 and sorted([w / 2, h / 2]) == pytest.approx([fb, fa], abs=1e-3)


@pytest.mark.parametrize("name", ["centroid_phase", "limb_ellipse", "horizon_opnav"])
def test_builtin_methods_conform_on_the_exact_disc(name):
    assert check_centre_limb_method(BUILTIN[name]) == []


def test_harness_names_the_rule_a_method_breaks():
    fails = check_centre_limb_method(BUILTIN["centroid_raw"])        # no perspective shift: 0.44 px off-axis
    assert len(fails) == 1 and fails[0].startswith("(a) centroid_raw: centre")

    class Broken:
        name = "broken"
        calls = 0

        def measure(self, frame):
            frame.image[0, 0] += 1.0                                   # (c) mutates its input
            Broken.calls += 1
            return CentreLimbResult(centre_s=float("nan"), centre_l=1.0 * Broken.calls, reason="ok")

    fails = check_centre_limb_method(Broken)
    assert any(f.startswith("(b) broken: rule 1") for f in fails)     # NaN centre with reason ok
    assert any(f.startswith("(c) broken") for f in fails) and any(f.startswith("(d) broken") for f in fails)


@pytest.fixture(scope="module")
def rendered():
    """Frames of the planet world (Moon, Lambert) at 30°, 60° and 90° phase with their truth rows."""
    from renderlab import Renderer
    from renderlab.scenario import scenario_from_dict

    sc = {"name": "planet_phases", "world": {"kind": "planet", "preset": "moon", "law": "lambert"},
          "sun": {"direction": [1.0, 0.0, 0.0]},
          "camera": {"width": 128, "height": 128, "fx": 400.0, "fy": 400.0, "cx": 63.5, "cy": 63.5},
          "trajectory": {"kind": "planet_approach", "frames": 3, "range_start_m": 2.0e7, "phase_start_deg": 30.0,
                         "phase_end_deg": 90.0, "offset_deg": [2.0, -1.5], "phase_plane_deg": 30.0},
          "render": {"spp": 16, "far_clip_m": 1e9}}
    with Renderer(scenario_from_dict(sc)) as r:
        return [r.frame(k) for k in range(r.n_frames)]


def _frame(f, rng) -> tuple[CentreLimbFrame, np.ndarray]:
    row = f.truth["centre_truth"][0]
    apriori = np.asarray(f.spec.pose.position_m) + rng.normal(size=3) * 2e-3 * row["range_m"]  # 0.2 % per axis
    frame = CentreLimbFrame(image=f.dn.astype(float), valid=None, camera=f.spec.camera,
                            pose=CameraPose(R_body_from_cam=f.spec.pose.rotation.as_matrix(), position_m=apriori),
                            sun_body=np.asarray(f.spec.sun.direction_render), index=f.index,
                            body=BodyModel(semi_axes_m=np.full(3, 1737.4e3)))
    return frame, np.array([row["centre_s"], row["centre_l"]])


def test_methods_beat_the_raw_centroid_on_rendered_phases(rendered):
    rng = np.random.default_rng(20240611)
    allowed = {r.value for r in CentreLimbReason}
    for f in rendered:
        frame, truth = _frame(f, rng)
        saved = frame.image.copy()
        err = {}
        for name, make in BUILTIN.items():
            res, again = make().measure(frame), make().measure(frame)
            assert res.reason in allowed and res.has_result, (name, res.reason, res.diagnostics)
            assert again.centre_s == res.centre_s and again.centre_l == res.centre_l      # replay
            assert np.array_equal(again.limb_points, res.limb_points)
            err[name] = float(np.hypot(res.centre_s - truth[0], res.centre_l - truth[1]))
            if name in ("limb_ellipse", "horizon_opnav"):
                assert abs(res.range_m / f.truth["centre_truth"][0]["range_m"] - 1) < 0.02, (name, res.range_m)
        assert np.array_equal(frame.image, saved)
        phase = f.truth["centre_truth"][0]["phase_deg"]
        assert err["centroid_raw"] > 5.0, (phase, err)                  # the offset the correction is for
        for name in ("centroid_phase", "limb_ellipse", "horizon_opnav"):
            assert err[name] < err["centroid_raw"] / 5, (phase, name, err)
        assert err["horizon_opnav"] < 0.3, (phase, err)


def test_no_result_reasons_are_named(rendered):
    frame, _ = _frame(rendered[0], np.random.default_rng(0))
    dark = dataclasses.replace(frame, image=np.zeros_like(frame.image))
    far = dataclasses.replace(frame, body=BodyModel(semi_axes_m=np.full(3, 1.0)))     # a 1 m body: a few µpx
    for name, make in BUILTIN.items():
        for fr, expect in ((dark, "unlit"), (far, "too_small")):
            res = make().measure(fr)
            assert not res.has_result and res.reason == expect, (name, res.reason, res.diagnostics)
