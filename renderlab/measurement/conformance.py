"""Conformance harness for landmark methods: does a method follow :mod:`renderlab.contracts.landmark`?

Call :func:`check_landmark_method` with your method's factory (usually the class) or
:func:`check_landmark_method_name` with a registered name; each returns a list of human-readable failures
(empty: the method conforms)::

    from renderlab.measurement.conformance import check_landmark_method
    assert check_landmark_method(MyMethod) == []

The harness builds its own small, exact synthetic case (:func:`synthetic_case`), so it needs no truth set,
Mitsuba render or file. A *world* maplet (121 × 121 points at 0.1 m: smooth Gaussian hills plus a little smooth
noise, a smooth random albedo texture, tilted against the body frame) is imaged by the lab's template
renderer (:func:`estimators.retina.predict.render_template`, 8 × 8 samples per pixel, McEwen shading with
β = exp(−α/60°), cast shadows) at the TRUE pose with a pinhole camera (128 × 128 px), pasted into a constant
background and scaled to DN (``40 + 800·I``). The landmarks are 31 × 31 sub-grids of the world maplet, so
their facets are exactly the imaged ones. The a-priori pose is the true pose moved sideways (in the camera's
x/y plane) so that every predicted landmark pixel is off by about :data:`KNOWN_SHIFT_PX` = (+0.37, −0.61) px;
the exact expected shift per landmark is ``truth − pred`` of the two projections. The methods get
``LandmarkMethodOptions()`` (the defaults: ``L_table=()``, i.e. the same β = exp(−α/60°) as the image).

Frames ("cases"):

``clean``
    three landmarks (ids 17, 4, 9), the sun 50° above the maplet horizon, search distance 4 px.
``off_image``
    one landmark (id 23) whose centre projects ~40 px beyond the right edge of the image.
``too_small``
    the camera 15 × farther away: each landmark covers ~2 × 2 px.
``shadowed``
    the sun 15° below the maplets' horizon (the image is rendered with it: dark).

Rules checked (each failure names its rule):

(a) on ``clean`` every landmark has a result within :data:`SHIFT_TOLERANCE_PX` = 0.2 px (Euclidean) of the
    expected shift. Measured (largest error of the three landmarks): seed 0 — Retina 0.140 px (its default
    ``retina_3x3`` V-shaped peak fit is biased on this smooth texture), SPC 0.021 px, ncc_baseline 0.086 px;
    over seeds 0–19 the largest is Retina 0.140, SPC 0.051, ncc_baseline 0.086 px.
(b) every result passes :meth:`~renderlab.contracts.landmark.LandmarkResult.check` (``has_result`` exactly when
    the shift is finite, otherwise a :class:`~renderlab.contracts.reasons.LandmarkReason` other than ``ok``:
    never a silent NaN), and on ``off_image``, ``too_small`` and ``shadowed`` no landmark has a result (any
    non-``ok`` reason is accepted; typically ``off_image``, ``too_few_pixels`` and ``facing_away``). SPC fails
    ``too_small`` today: it has no minimum footprint in image pixels and returns shifts for 2 × 2 px landmarks.
(c) replays are bit-identical: two fresh instances, and the first one called again, give identical results on
    every case (every field but ``t_ms``, NaN-aware).
(d) the inputs are not modified: image, valid mask, every maplet array, the pose arrays, ``sun_body`` and
    ``search_px`` equal their copies afterwards.
(e) one :class:`~renderlab.contracts.landmark.LandmarkResult` per landmark, in order, with its ``landmark_id``.

Besides: the factory must make an object following :class:`~renderlab.contracts.landmark.LandmarkMethod`
(a ``name`` string and ``measure_frame``), and ``measure_frame`` must not raise.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from estimators.retina import build_mesh
from estimators.retina.predict import CameraPoseEstimate, TemplateOptions, render_template
from renderlab import plugins
from renderlab.contracts.landmark import (
    CameraPose,
    LandmarkFrame,
    LandmarkMethod,
    LandmarkMethodOptions,
    LandmarkResult,
)
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.maplet import Maplet
from renderlab.geometry.rotations import look_at

#: the a-priori pose puts every predicted landmark about this far from its true pixel, (Δs, Δl) px
KNOWN_SHIFT_PX = (0.37, -0.61)
#: rule (a): largest allowed |measured − expected| shift on the clean case, px
SHIFT_TOLERANCE_PX = 0.2
#: search distance of every landmark, px
SEARCH_PX = 4

_CAMERA = CameraModel(width=128, height=128, fx=110.0, fy=112.0, cx=63.3, cy=62.8)
_N_WORLD, _N_LANDMARK, _SPACING_M = 121, 31, 0.1
#: (landmark_id, column offset, row offset) of each landmark's centre from the world centre, grid cells
_LANDMARKS = ((17, -30, -26), (4, 29, -21), (9, 2, 30))
_OFF_IMAGE_ID = 23
_CAMERA_IN_WORLD_M = np.array([0.4, -0.3, 11.0])
_FAR_FACTOR = 15.0
_DN_BIAS, _DN_GAIN = 40.0, 800.0


@dataclass(frozen=True)
class SyntheticCase:
    """The harness's frames (module docstring) and what is known about them.

    Attributes
    ----------
    frames : dict of str to LandmarkFrame
        ``clean``, ``off_image``, ``too_small``, ``shadowed``.
    expected_shift : dict of int to (2,) ndarray
        Exact (Δs, Δl) = truth − pred of each ``clean`` landmark, px.
    true_pose : CameraPose
        The pose the ``clean`` image was rendered at.
    """

    frames: dict
    expected_shift: dict
    true_pose: CameraPose


def _world_maplet(rng: np.random.Generator) -> Maplet:
    """Smooth relief (hills + smooth noise) and a smooth albedo texture on a tilted 121 × 121 grid."""
    from scipy.ndimage import gaussian_filter
    from scipy.spatial.transform import Rotation

    n, s = _N_WORLD, _SPACING_M
    t = (np.arange(n) - (n - 1) / 2) * s
    X, Y = np.meshgrid(t, t)
    Z = np.zeros_like(X)
    for _ in range(6):
        cx, cy = rng.uniform(-5.0, 5.0, 2)
        sig, amp = rng.uniform(1.2, 2.5), rng.uniform(-0.35, 0.35)
        Z += amp * np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * sig * sig))
    noise = gaussian_filter(rng.normal(size=X.shape), 3.0)
    Z += 0.04 * noise / noise.std()
    tex = gaussian_filter(rng.normal(size=X.shape), 1.5)
    albedo = np.clip(1.0 + 0.3 * tex / tex.std(), 0.4, 1.8)
    R = Rotation.from_rotvec([0.15, -0.1, 0.3]).as_matrix()
    return Maplet(0, np.array([1.0, -0.5, 0.2]), R, s, Z, albedo)


def _sub_maplet(world: Maplet, landmark_id: int, di: int, dj: int) -> Maplet:
    """The 31 × 31 sub-grid of ``world`` centred ``di`` columns and ``dj`` rows from its centre (same facets)."""
    c, h = (world.n - 1) // 2, (_N_LANDMARK - 1) // 2
    i0, j0 = c + di, c + dj
    H = np.asarray(world.heights_m, float)
    centre = world.to_body(np.array([di * world.spacing_m, dj * world.spacing_m, H[j0, i0]]))
    rows, cols = slice(j0 - h, j0 + h + 1), slice(i0 - h, i0 + h + 1)
    return Maplet(landmark_id, centre, np.array(world.R_body_from_maplet, float), world.spacing_m,
                  H[rows, cols] - H[j0, i0], np.array(world.albedo, float)[rows, cols])


def _sun(world: Maplet, elevation_deg: float, azimuth_deg: float = 30.0) -> np.ndarray:
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.asarray(world.R_body_from_maplet, float) @ np.array([math.cos(e) * math.cos(a),
                                                                   math.cos(e) * math.sin(a), math.sin(e)])


def _render_image(world_mesh, pose: CameraPose, sun: np.ndarray) -> np.ndarray:
    """DN image of the world maplet at ``pose`` (8 × 8 samples per pixel) on a constant background."""
    cam = _CAMERA
    img = np.zeros((cam.height, cam.width))
    tpl = render_template(world_mesh, cam, CameraPoseEstimate(pose.R_body_from_cam, pose.position_m), sun,
                          TemplateOptions(supersample=8, max_size_px=4096))
    if tpl is not None:
        h, w = tpl.image.shape
        ys, xs = np.mgrid[0:h, 0:w]
        li, si = ys + tpl.l0, xs + tpl.s0
        ok = tpl.valid & (li >= 0) & (li < cam.height) & (si >= 0) & (si < cam.width)
        img[li[ok], si[ok]] = tpl.image[ok]
    return _DN_BIAS + _DN_GAIN * img


def _poses(world: Maplet, distance_factor: float) -> tuple[CameraPose, CameraPose]:
    """(true, a-priori): the camera above the world maplet looking at its centre; the a-priori pose moved
    sideways so that a point at the world centre's depth moves by :data:`KNOWN_SHIFT_PX`."""
    centre = np.asarray(world.center_m, float)
    pos = centre + distance_factor * (world.to_body(_CAMERA_IN_WORLD_M) - centre)
    R = look_at(pos, centre, np.asarray(world.R_body_from_maplet, float)[:, 1]).as_matrix()
    true = CameraPose(R, pos)
    z = float(true.to_camera(centre)[2])
    ds, dl = KNOWN_SHIFT_PX
    # moving the camera by +δ along its x axis moves the image of a point by −f δ / z: pred = truth − shift
    delta = np.array([ds * z / _CAMERA.fx, dl * z / _CAMERA.fy, 0.0])
    return true, CameraPose(R, pos + R @ delta)


def _frame(image, landmarks, pose, sun, index, seed) -> LandmarkFrame:
    valid = np.ones(image.shape, bool)
    valid[1:4, 1:4] = False  # a few "saturated" pixels, far from every landmark
    return LandmarkFrame(image=image, valid=valid, camera=_CAMERA, pose=pose, sun_body=sun, landmarks=list(landmarks),
                         search_px=np.full(len(landmarks), SEARCH_PX, int), index=index, seed=seed)


@functools.lru_cache(maxsize=4)
def _case_cached(seed: int) -> SyntheticCase:
    world = _world_maplet(np.random.default_rng(seed))
    mesh = build_mesh(world)
    lms = [_sub_maplet(world, lid, di, dj) for lid, di, dj in _LANDMARKS]
    sun, sun_low = _sun(world, 50.0), _sun(world, -15.0)
    true, ap = _poses(world, 1.0)
    far_true, far_ap = _poses(world, _FAR_FACTOR)
    image = _render_image(mesh, true, sun)
    expected = {m.landmark_id: _CAMERA.project(true.to_camera(m.center_m)) - _CAMERA.project(ap.to_camera(m.center_m))
                for m in lms}
    # off the image: landmark 17's maplet moved along the camera x axis until it projects ~40 px beyond the edge
    m0 = lms[0]
    x0 = true.to_camera(m0.center_m)
    dx = (_CAMERA.width + 40 - _CAMERA.project(x0)[0]) * x0[2] / _CAMERA.fx
    off = dataclasses.replace(m0, landmark_id=_OFF_IMAGE_ID,
                              center_m=np.asarray(m0.center_m) + np.asarray(true.R_body_from_cam)[:, 0] * dx)
    frames = {"clean": _frame(image, lms, ap, sun, 0, seed),
              "off_image": _frame(image, [off], ap, sun, 1, seed),
              "too_small": _frame(_render_image(mesh, far_true, sun), lms, far_ap, sun, 2, seed),
              "shadowed": _frame(_render_image(mesh, true, sun_low), lms, ap, sun_low, 3, seed)}
    return SyntheticCase(frames, expected, true)


def _copy_frame(frame: LandmarkFrame) -> LandmarkFrame:
    """A deep copy of every array of ``frame`` (so a method that writes into one cannot spoil the next)."""
    lms = [dataclasses.replace(m, center_m=np.array(m.center_m, copy=True),
                               R_body_from_maplet=np.array(m.R_body_from_maplet, copy=True),
                               heights_m=np.array(m.heights_m, copy=True), albedo=np.array(m.albedo, copy=True))
           for m in frame.landmarks]
    pose = CameraPose(np.array(frame.pose.R_body_from_cam, copy=True), np.array(frame.pose.position_m, copy=True))
    return dataclasses.replace(frame, image=np.array(frame.image, copy=True),
                               valid=None if frame.valid is None else np.array(frame.valid, copy=True),
                               pose=pose, sun_body=np.array(frame.sun_body, copy=True), landmarks=lms,
                               search_px=np.array(frame.search_px, copy=True))


def synthetic_case(seed: int = 0) -> SyntheticCase:
    """The harness's synthetic frames (module docstring), freshly copied (safe to hand to a method)."""
    c = _case_cached(int(seed))
    true = CameraPose(np.array(c.true_pose.R_body_from_cam), np.array(c.true_pose.position_m))
    return SyntheticCase({k: _copy_frame(f) for k, f in c.frames.items()},
                         {k: np.array(v) for k, v in c.expected_shift.items()}, true)


def _arrays(frame: LandmarkFrame) -> dict:
    """Every input array of ``frame`` by a readable name."""
    out = {"image": frame.image, "valid": frame.valid, "pose.R_body_from_cam": frame.pose.R_body_from_cam,
           "pose.position_m": frame.pose.position_m, "sun_body": frame.sun_body, "search_px": frame.search_px}
    for k, m in enumerate(frame.landmarks):
        for attr in ("center_m", "R_body_from_maplet", "heights_m", "albedo"):
            out[f"landmarks[{k}].{attr}"] = getattr(m, attr)
    return out


def _same(a, b) -> bool:
    """Bit-identical comparison, NaN equal to NaN (floats, arrays, containers)."""
    if isinstance(a, (float, np.floating)) and isinstance(b, (float, np.floating)):
        return type(a) is type(b) and ((math.isnan(a) and math.isnan(b)) or a == b)
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and a == b


#: the cases where no landmark may have a result (rule (b))
_NO_RESULT_CASES = ("off_image", "too_small", "shadowed")
_CASES = ("clean",) + _NO_RESULT_CASES


def _make(factory, options: LandmarkMethodOptions, failures: list) -> object | None:
    """``factory(options)``, or None with a failure when it raises or breaks the protocol."""
    try:
        obj = factory(options)
    except Exception as exc:  # noqa: BLE001 - a harness reports, it does not crash
        failures.append(f"{factory!r}: the factory raised {type(exc).__name__}: {exc}")
        return None
    if not isinstance(obj, LandmarkMethod) or not isinstance(getattr(obj, "name", None), str):
        failures.append(f"{factory!r}: the object made does not follow the LandmarkMethod protocol "
                        "(needs a 'name' string and measure_frame(frame))")
        return None
    return obj


def _run(method, case: str, frame: LandmarkFrame, failures: list) -> list | None:
    """``method.measure_frame(frame)`` with rules (b) result contract, (d) and (e) checked; None when it raised
    or returned something else than one LandmarkResult per landmark."""
    tag = f"{method.name} [{case}]"
    before = _copy_frame(frame)
    try:
        results = method.measure_frame(frame)
    except Exception as exc:  # noqa: BLE001
        failures.append(f"{tag}: measure_frame raised {type(exc).__name__}: {exc}")
        return None
    now, then = _arrays(frame), _arrays(before)
    if now.keys() != then.keys():
        failures.append(f"{tag} rule (d) inputs unchanged: the landmarks sequence was modified")
    for name in now.keys() & then.keys():
        if not _same(now[name], then[name]):
            failures.append(f"{tag} rule (d) inputs unchanged: {name} was modified")
    n = len(before.landmarks)
    if not isinstance(results, (list, tuple)) or len(results) != n:
        got = len(results) if isinstance(results, (list, tuple)) else type(results).__name__
        failures.append(f"{tag} rule (e) one result per landmark: expected a list of {n} results, got {got}")
        return None
    ok = True
    for k, (r, m) in enumerate(zip(results, before.landmarks)):
        if not isinstance(r, LandmarkResult):
            failures.append(f"{tag} rule (e) one result per landmark: result {k} is a {type(r).__name__}, "
                            "not a LandmarkResult")
            ok = False
            continue
        if r.landmark_id != m.landmark_id:
            failures.append(f"{tag} rule (e) one result per landmark: result {k} has landmark_id "
                            f"{r.landmark_id!r}, landmark {k} is {m.landmark_id} (results must keep the order)")
        try:
            r.check()
        except ValueError as err:
            failures.append(f"{tag} rule (b) no silent NaN: {err}")
    return results if ok else None


def _check_shifts(name: str, results: list, expected: dict, tol: float, failures: list) -> None:
    """Rule (a) on the clean case."""
    for r in results:
        want = expected[r.landmark_id]
        if not r.has_result:
            failures.append(f"{name} [clean] rule (a) shift recovery: landmark {r.landmark_id} has no result "
                            f"(reason {r.reason!r}, {r.diagnostics or 'no diagnostics'}) on the clean synthetic case")
            continue
        err = math.hypot(r.ds - want[0], r.dl - want[1])
        if not err <= tol:
            failures.append(f"{name} [clean] rule (a) shift recovery: landmark {r.landmark_id}: measured (ds, dl) = "
                            f"({r.ds:+.3f}, {r.dl:+.3f}) px, expected ({want[0]:+.3f}, {want[1]:+.3f}): error "
                            f"{err:.3f} px > {tol} px")


def _check_no_result(name: str, case: str, results: list, failures: list) -> None:
    """Rule (b): no result where the landmark cannot be measured."""
    for r in results:
        if r.has_result:
            failures.append(f"{name} [{case}] rule (b) no result where none is possible: landmark {r.landmark_id} "
                            f"has a shift ({r.ds:+.3f}, {r.dl:+.3f}) px with reason {r.reason!r}; expected "
                            f"has_result False with a LandmarkReason")


_COMPARED = [f.name for f in dataclasses.fields(LandmarkResult) if f.name != "t_ms"]


def _check_replay(name: str, case: str, first: list, again: list, label: str, failures: list) -> None:
    """Rule (c): ``again`` equals ``first`` field by field (not ``t_ms``), NaN-aware."""
    for a, b in zip(first, again):
        for f in _COMPARED:
            va, vb = getattr(a, f), getattr(b, f)
            if not _same(va, vb):
                failures.append(f"{name} [{case}] rule (c) bit-identical replay: landmark {a.landmark_id}: {f} "
                                f"differs {label} ({va!r} vs {vb!r})")
                break


def check_landmark_method(factory, *, seed: int = 0, options: LandmarkMethodOptions | None = None,
                          tolerance_px: float = SHIFT_TOLERANCE_PX) -> list[str]:
    """Run a landmark method through the conformance rules (module docstring).

    Parameters
    ----------
    factory : callable
        Makes the method from :class:`~renderlab.contracts.landmark.LandmarkMethodOptions` (usually the class).
    seed : int
        Seed of the synthetic terrain and albedo (and ``LandmarkFrame.seed``).
    options : LandmarkMethodOptions, optional
        Passed to the factory (default ``LandmarkMethodOptions()``).
    tolerance_px : float
        Rule (a): largest error of the recovered shift, px (default :data:`SHIFT_TOLERANCE_PX`, 0.2 px).

    Returns
    -------
    list of str
        One line per failure, each naming the method, the case and the rule; empty when the method conforms.
    """
    options = LandmarkMethodOptions() if options is None else options
    failures: list[str] = []
    first = _make(factory, options, failures)
    if first is None:
        return failures
    case = synthetic_case(seed)
    runs = {c: _run(first, c, case.frames[c], failures) for c in _CASES}
    if runs["clean"] is not None:
        _check_shifts(first.name, runs["clean"], case.expected_shift, tolerance_px, failures)
    for c in _NO_RESULT_CASES:
        if runs[c] is not None:
            _check_no_result(first.name, c, runs[c], failures)
    second = _make(factory, options, failures)
    if second is None:
        return failures
    for method, label in ((second, "between two fresh instances"), (first, "when the same instance runs again")):
        fresh, later = synthetic_case(seed), []
        for c in _CASES:
            again = _run(method, c, fresh.frames[c], later)
            if runs[c] is not None and again is not None:
                _check_replay(first.name, c, runs[c], again, label, failures)
        failures += [f for f in dict.fromkeys(later) if f not in failures]  # (b), (d), (e) new on a replay only
    return failures


def check_landmark_method_name(name: str, **kwargs) -> list[str]:
    """:func:`check_landmark_method` on the method registered as ``name`` in
    :data:`renderlab.plugins.landmark_methods` (built-ins and entry points; a ``module:attr`` reference is
    accepted too). An unknown name raises :class:`~renderlab.errors.UserError` listing the registered ones."""
    return check_landmark_method(plugins.landmark_methods.get(name, allow_reference=True), **kwargs)
