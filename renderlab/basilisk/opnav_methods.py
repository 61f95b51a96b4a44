"""Basilisk's OpNav image processing as centre/limb methods (:mod:`renderlab.contracts.centre_limb`), unmodified.

Each image runs through a **fresh one-step Basilisk simulation** of the stock modules: the frame's image, scaled to
8 bits (``round(255·DN/full_scale)``, as :class:`renderlab.basilisk.camera.RenderlabCamera` sends it) and encoded as a
PNG in memory, is written to a ``CameraImageMsg`` (``timeTag`` 0, the sim's time), with a ``CameraConfigMsg`` of the
frame's camera and a ``NavAttMsg``; the modules step once at t = 0 and their output messages are read back.

=========================  =====================================================================================
name                       Basilisk modules → what the result holds
=========================  =====================================================================================
``bsk_hough_circles``      ``houghCircles`` → the circle's centre as the body centre (px), its radius as the limb;
                           covariance: the module's ``uncertainty`` (``noiseSF · votes / voteThresh`` px²)
``bsk_hough_pixel_line``   ``houghCircles`` → ``pixelLineConverter`` → camera-to-body vector ``−r_BN_C`` and
                           ``covar_C``; the centre is that vector projected by the frame's camera
``bsk_limb_horizon``       ``limbFinding`` → ``horizonOpNav`` → ``−r_BN_C``, ``covar_C``, the limb points; the centre
                           is the vector projected
=========================  =====================================================================================

Frames: the inertial frame N of the modules is the camera frame (``sigma_BN = 0``, ``sigma_CB = 0``), so
``r_BN_C = r_BN_N``; the a-priori pose is used only by the wrapper's gate.

What the wrappers add, and nothing else (they do **not** correct Basilisk):

* **Gate** (the lab methods' rule): from the a-priori pose, a body behind the camera or off the image gives
  ``off_image`` and one smaller than ``min_radius_px`` ``too_small``, before Basilisk is run (its modules only see
  pixels, so a turned-away camera with a body in the image would otherwise "measure" it).
* **Radius adapter**: ``houghCircles`` and ``limbFinding`` tag every detection as Mars (``planetIds = 2``) and
  ``pixelLineConverter`` / ``horizonOpNav`` use Mars' equatorial radius ``REQ_MARS`` (3396.19 km) as a sphere. Both
  are exactly linear in the radius (``ρ = R / sin θ``; horizonOpNav's ``n`` does not depend on R and ``r = −R n /
  √(nᵀn − 1)``), so the position is scaled by ``R_body / REQ_MARS`` and its covariance by the square: exact for a
  sphere; for an ellipsoid ``R_body`` is its largest semi-axis (Basilisk's equatorial radius).
* **Camera**: Basilisk's camera is a centred pinhole with square pixels (``fieldOfView`` along y); a frame whose
  camera is not (``fx ≠ fy``, principal point off ``((W−1)/2, (H−1)/2)``, distortion) gives ``method_error``.

Default tunings are Basilisk's own OpNav scenarios (``BSK_OpNavFsw.py``: Hough ``cannyThresh`` 200, ``voteThresh`` 25,
``houghMinDist`` 50, ``houghMinRadius`` 20, ``blurrSize`` 9, ``noiseSF`` 1, ``dpValue`` 1; limbFinding 50 / 100 / 5 /
0; horizonOpNav ``noiseSF`` 1).

Reasons: no circle / no limb message → ``unlit`` when the 8-bit image has no pixel ≥ 15 (houghCircles' threshold),
else ``fit_failed``; a non-finite output → ``fit_failed``.

References: Teil, Schaub & Kubitschek, "Centroid and Apparent Diameter Optical Navigation on Mars Orbit", JSR 58(4),
2021, doi:10.2514/1.A34815 (houghCircles + pixelLineConverter + relativeODuKF); Christian & Robinson, "Noniterative
horizon-based optical navigation by Cholesky factorization", JGCD 39(12), 2016, doi:10.2514/1.G000539 (the
algorithm horizonOpNav implements).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from renderlab.contracts.centre_limb import CentreLimbFrame, CentreLimbReason, CentreLimbResult

REQ_MARS_M = 3396.19e3  #: Basilisk's ``REQ_MARS`` (km in its astroConstants), the radius its modules assume


@dataclass(frozen=True)
class BskOptions:
    """Settings of the Basilisk wrappers (module docstring): Basilisk's ``BSK_OpNavFsw`` tuning by default."""

    full_scale_dn: float | None = None  #: DN shown as white; None: the image's maximum
    min_radius_px: float = 20.0          #: the gate's smallest predicted apparent radius (= houghMinRadius)
    canny_thresh: int = 200
    vote_thresh: int = 25
    hough_min_dist: int = 50
    hough_blur: int = 9
    hough_noise_sf: float = 1.0
    dp_value: int = 1
    canny_low: int = 50
    canny_high: int = 100
    limb_blur: int = 5
    horizon_noise_sf: float = 1.0


def png8(image: np.ndarray, full_scale: float | None) -> np.ndarray:
    """The image as 8-bit grey PNG bytes (``renderlab.basilisk.camera.encode_png8``), full scale as given or the max."""
    from renderlab.basilisk.camera import encode_png8

    img = np.nan_to_num(np.asarray(image, float), nan=0.0, posinf=0.0, neginf=0.0)
    fs = float(full_scale) if full_scale else float(max(img.max(), 1e-300))
    return encode_png8(img, fs)


def _camera_ok(cam) -> str:
    if cam.fx != cam.fy or abs(cam.cx - (cam.width - 1) / 2) > 1e-9 or abs(cam.cy - (cam.height - 1) / 2) > 1e-9:
        return "Basilisk's camera is a centred pinhole with square pixels; this camera is not"
    if any(float(v) != 0.0 for v in cam.distortion.values()) or cam.skew or cam.skew_yx:
        return "Basilisk's camera has no distortion or skew; this camera has"
    return ""


def gate(frame: CentreLimbFrame, min_radius_px: float) -> str:
    """The a-priori gate: ``off_image``, ``too_small`` or "" (module docstring)."""
    cam, pose = frame.camera, frame.pose
    r = np.asarray(pose.R_body_from_cam, float).T @ (np.asarray(frame.body.centre_m, float) -
                                                      np.asarray(pose.position_m, float))
    R = float(np.max(frame.body.semi_axes_m))
    if r[2] <= R:
        return CentreLimbReason.OFF_IMAGE.value
    uv = cam.project(r)
    rad = cam.fx * R / math.sqrt(max(float(r @ r) - R * R, 1e-300))
    if not (-rad <= uv[0] <= cam.width - 1 + rad and -rad <= uv[1] <= cam.height - 1 + rad):
        return CentreLimbReason.OFF_IMAGE.value
    if rad < min_radius_px:
        return CentreLimbReason.TOO_SMALL.value
    return ""


class _OneStep:
    """A fresh Basilisk simulation of one task at t = 0 holding the image, camera and attitude messages."""

    def __init__(self, frame: CentreLimbFrame, opts: BskOptions):
        from Basilisk.architecture import messaging
        from Basilisk.utilities import SimulationBaseClass

        from renderlab.basilisk.camera import set_image_pointer

        cam = frame.camera
        self.sim = SimulationBaseClass.SimBaseClass()
        self.sim.CreateNewProcess("proc", 10).addTask(self.sim.CreateNewTask("task", int(1e9)))
        self.buffer = png8(frame.image, opts.full_scale_dn)
        self.brightest = float(np.max(np.asarray(frame.image, float))) if frame.image.size else 0.0
        img = messaging.CameraImageMsgPayload()
        set_image_pointer(img, self.buffer)
        img.timeTag, img.valid, img.cameraID, img.imageType = 0, 1, 1, 1
        self.image_msg = messaging.CameraImageMsg().write(img, 0)
        cfg = messaging.CameraConfigMsgPayload()
        cfg.cameraID, cfg.isOn = 1, 1
        cfg.fieldOfView = 2.0 * math.atan((cam.height / 2.0) / cam.fy)
        cfg.resolution = [int(cam.width), int(cam.height)]
        cfg.sigma_CB, cfg.cameraPos_B = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
        self.config_msg = messaging.CameraConfigMsg().write(cfg, 0)
        att = messaging.NavAttMsgPayload()
        att.sigma_BN = [0.0, 0.0, 0.0]
        self.att_msg = messaging.NavAttMsg().write(att, 0)
        self.n = 0

    def add(self, module) -> None:
        module.ModelTag = f"m{self.n}"
        self.sim.AddModelToTask("task", module, 100 - self.n)
        self.n += 1

    def run(self) -> None:
        self.sim.InitializeSimulation()
        self.sim.ConfigureStopTime(0)
        self.sim.ExecuteSimulation()


def hough(step: _OneStep, o: BskOptions):
    from Basilisk.fswAlgorithms import houghCircles

    h = houghCircles.HoughCircles()
    h.imageInMsg.subscribeTo(step.image_msg)
    h.expectedCircles, h.cannyThresh, h.voteThresh, h.houghMinDist = 1, o.canny_thresh, o.vote_thresh, \
        o.hough_min_dist
    h.houghMinRadius, h.houghMaxRadius, h.blurrSize = int(o.min_radius_px), 0, o.hough_blur
    h.noiseSF, h.dpValue = o.hough_noise_sf, o.dp_value
    step.add(h)
    return h


def _position(res: CentreLimbResult, frame: CentreLimbFrame, opnav) -> CentreLimbResult:
    """Fill the result from an ``OpNavMsg`` (``r_BN_C``, ``covar_C``) with the radius adapter (module docstring)."""
    k = float(np.max(frame.body.semi_axes_m)) / REQ_MARS_M
    r = -k * np.asarray(opnav.r_BN_C, float)
    P = k * k * np.asarray(opnav.covar_C, float).reshape(3, 3)
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(P)) and r[2] > 0):
        res.reason, res.diagnostics = CentreLimbReason.FIT_FAILED.value, f"non-finite or backward r_BN_C {r}"
        return res
    cam = frame.camera
    uv = cam.project(r)
    J = np.array([[cam.fx / r[2], 0.0, -cam.fx * r[0] / r[2] ** 2],
                  [0.0, cam.fy / r[2], -cam.fy * r[1] / r[2] ** 2]])
    res.centre_s, res.centre_l = float(uv[0]), float(uv[1])
    res.cov_centre_px2, res.r_cam_m, res.cov_r_cam_m2 = J @ P @ J.T, r, P
    return res


class _BskMethod:
    """Common part: options, the gate, timing and the reason of an empty output."""

    name = ""

    def __init__(self, options: BskOptions | None = None):
        self.options = options or BskOptions()

    def measure(self, frame: CentreLimbFrame) -> CentreLimbResult:
        t0 = time.perf_counter()
        why = _camera_ok(frame.camera)
        if why:
            res = CentreLimbResult(reason=CentreLimbReason.METHOD_ERROR.value, diagnostics=why)
        else:
            g = gate(frame, self.options.min_radius_px)
            res = CentreLimbResult(reason=g, diagnostics="a-priori gate") if g else self._run(frame)
        res.t_ms = (time.perf_counter() - t0) * 1e3
        res.check(f"{self.name}: ")
        return res

    def _empty(self, step: _OneStep, what: str) -> CentreLimbResult:
        dark = int(np.max(np.frombuffer(_decoded(step.buffer), np.uint8))) < 15
        return CentreLimbResult(reason=(CentreLimbReason.UNLIT if dark else CentreLimbReason.FIT_FAILED).value,
                                diagnostics=f"{what} not valid")


def _decoded(buf: np.ndarray) -> bytes:
    import cv2

    return cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE).tobytes()


class HoughCirclesMethod(_BskMethod):
    """``bsk_hough_circles``: Basilisk's ``houghCircles`` alone (module docstring)."""

    name = "bsk_hough_circles"

    def _run(self, frame):
        step = _OneStep(frame, self.options)
        h = hough(step, self.options)
        step.run()
        c = h.opnavCirclesOutMsg.read()
        if not c.valid:
            return self._empty(step, "houghCircles")
        s, ll, rad = float(c.circlesCenters[0]), float(c.circlesCenters[1]), float(c.circlesRadii[0])
        cov = np.asarray(c.uncertainty, float).reshape(3, 3)[:2, :2]
        return CentreLimbResult(centre_s=s, centre_l=ll, cov_centre_px2=cov, limb_centre_s=s, limb_centre_l=ll,
                                limb_a_px=rad, limb_b_px=rad, limb_angle_rad=0.0,
                                diagnostics=f"votes/voteThresh·noiseSF={cov[0, 0]:.3g}")


class HoughPixelLineMethod(_BskMethod):
    """``bsk_hough_pixel_line``: ``houghCircles`` → ``pixelLineConverter`` (module docstring)."""

    name = "bsk_hough_pixel_line"

    def _run(self, frame):
        from Basilisk.fswAlgorithms import pixelLineConverter

        step = _OneStep(frame, self.options)
        h = hough(step, self.options)
        p = pixelLineConverter.pixelLineConverter()
        p.circlesInMsg.subscribeTo(h.opnavCirclesOutMsg)
        p.cameraConfigInMsg.subscribeTo(step.config_msg)
        p.attInMsg.subscribeTo(step.att_msg)
        p.planetTarget = 2
        step.add(p)
        step.run()
        c, out = h.opnavCirclesOutMsg.read(), p.opNavOutMsg.read()
        if not (c.valid and out.valid):
            return self._empty(step, "houghCircles/pixelLineConverter")
        s, ll, rad = float(c.circlesCenters[0]), float(c.circlesCenters[1]), float(c.circlesRadii[0])
        res = CentreLimbResult(limb_centre_s=s, limb_centre_l=ll, limb_a_px=rad, limb_b_px=rad, limb_angle_rad=0.0)
        return _position(res, frame, out)


class LimbHorizonMethod(_BskMethod):
    """``bsk_limb_horizon``: ``limbFinding`` → ``horizonOpNav`` (module docstring)."""

    name = "bsk_limb_horizon"

    def _run(self, frame):
        from Basilisk.fswAlgorithms import horizonOpNav, limbFinding

        o = self.options
        step = _OneStep(frame, o)
        lf = limbFinding.LimbFinding()
        lf.imageInMsg.subscribeTo(step.image_msg)
        lf.cannyThreshLow, lf.cannyThreshHigh, lf.blurrSize, lf.limbNumThresh = o.canny_low, o.canny_high, \
            o.limb_blur, 0
        step.add(lf)
        hz = horizonOpNav.horizonOpNav()
        hz.limbInMsg.subscribeTo(lf.opnavLimbOutMsg)
        hz.cameraConfigInMsg.subscribeTo(step.config_msg)
        hz.attInMsg.subscribeTo(step.att_msg)
        hz.planetTarget, hz.noiseSF = 2, o.horizon_noise_sf
        step.add(hz)
        step.run()
        limb, out = lf.opnavLimbOutMsg.read(), hz.opNavOutMsg.read()
        if not (limb.valid and out.valid and limb.numLimbPoints >= 3):
            return self._empty(step, "limbFinding/horizonOpNav")
        n = int(limb.numLimbPoints)
        res = CentreLimbResult(limb_points=np.asarray(limb.limbPoints, float)[:2 * n].reshape(n, 2),
                               diagnostics=f"{n} limb points")
        return _position(res, frame, out)


#: name → factory of the Basilisk wrappers
BASILISK_METHODS = {m.name: m for m in (HoughCirclesMethod, HoughPixelLineMethod, LimbHorizonMethod)}
