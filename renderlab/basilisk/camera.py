"""``RenderlabCamera``: renderlab as Basilisk's camera, a Basilisk Python ``SysModel`` that renders each camera step.

At each of its task's steps the module reads

* ``scStateInMsg`` (``SCStatesMsgPayload``: ``r_BN_N``, ``sigma_BN``), required;
* ``planetInMsg`` (``SpicePlanetStateMsgPayload``: ``PositionVector``, ``J20002Pfix``) of the body the world draws;
  not linked: the planet at the inertial origin with its axes along the inertial ones;
* ``sunInMsg`` (``SpicePlanetStateMsgPayload`` of the Sun), optional: the sun direction of the frame, turned into the
  planet-fixed frame (irradiance: the world's ``[sun] irradiance_w_m2``); not linked: the world's own sun, fixed in its
  render frame (the ``planet`` world's ``[sun] direction``),

builds the lab's camera pose in the world's render frame (:func:`renderlab.basilisk.frames.camera_pose`: the render
frame is the planet-fixed frame centred on the planet), renders it with ``renderer.frame(time_s=t, pose=...)``
(:class:`renderlab.Renderer`: radiance → the scenario's sensor model → DN, seeded by the time), encodes the DN image as
an 8-bit grey PNG in memory (``round(255 · DN / (2^bits − 1))``: the ADC's full scale is white) and writes

* ``imageOutMsg`` (``CameraImageMsgPayload``): ``timeTag`` = the step's time (ns), ``valid`` = 1, ``cameraID``,
  ``imageType`` = 1 (channels), ``imageBufferLength`` and ``imagePointer`` to the PNG bytes — the encoding Basilisk's
  image-processing modules decode (``cv::imdecode``); they use an image only when ``timeTag`` ≥ their own time, so
  run the camera before them in the same task (a higher priority) or in an earlier task;
* ``cameraConfigOutMsg`` (``CameraConfigMsgPayload``): ``cameraID``, ``fieldOfView``, ``resolution``, ``sigma_CB``,
  ``cameraPos_B``, ``isOn`` — what ``pixelLineConverter``, ``limbFinding`` and ``horizonOpNav`` read.

Camera conventions (:mod:`renderlab.basilisk.frames`): Basilisk's ``fieldOfView`` is edge to edge along the camera's
y axis (image height), pixels are square, and the principal point is the centre of the detector — ``(W/2, H/2)`` with
pixel corners at integers, ``cx = (W − 1)/2``, ``cy = (H − 1)/2`` in the lab's pixel-centre coordinates.
``pixelLineConverter`` re-centres a pixel ``u`` as ``u − W/2 + 0.5``, which is that principal point for ``u`` in
pixel-centre coordinates. Which coordinates an image-processing module's output is really in, and with what bias, is
for the lab to measure: ``last_frame.truth`` holds the reference (the ``planet`` world's ``centre_truth``: projected
centre and true limb conic of the rendered pose, in pixel-centre coordinates).

The PNG bytes live in the module (the last ``keep_images`` images): a message, or a recorder's copy of it, points
into them only that long. ``last_frame`` holds the last :class:`renderlab.pipeline.frame_api.Frame` (its truth rows,
e.g. the ``planet`` world's ``centre_truth``, and, with ``keep_truth``, the truth AOVs).

Basilisk is imported when the class is first used (``renderlab --help`` stays instant); without it the use is one
line naming the ``basilisk`` extra.
"""

from __future__ import annotations

import collections
import functools

import numpy as np

from renderlab.basilisk import frames
from renderlab.errors import UserError
from renderlab.extras import require

#: what needs the extra (the subject of the missing-extra message)
WHAT = "renderlab's Basilisk camera"


def basilisk_modules():
    """(messaging, sysModel, sim_model) of the installed Basilisk, or a one-line error naming the extra."""
    messaging = require("Basilisk.architecture.messaging", "basilisk", WHAT)
    sys_model = require("Basilisk.architecture.sysModel", "basilisk", WHAT)
    sim_model = require("Basilisk.architecture.sim_model", "basilisk", WHAT)
    return messaging, sys_model, sim_model


def encode_png8(dn: np.ndarray, full_scale: int) -> np.ndarray:
    """The DN image as 8-bit grey PNG bytes (uint8 array): ``round(255 · DN / full_scale)``, clipped to 0..255."""
    import cv2

    dn = np.asarray(dn)
    if dn.ndim != 2 or dn.size == 0:
        raise UserError(f"the camera image must be a non-empty 2-D array, got shape {dn.shape}")
    if full_scale <= 0:
        raise UserError(f"the ADC full scale must be positive, got {full_scale}")
    img = np.clip(np.rint(dn.astype(np.float64) * (255.0 / float(full_scale))), 0, 255).astype(np.uint8)
    ok, buf = cv2.imencode(".png", img)
    if not ok:
        raise UserError("OpenCV could not encode the camera image as PNG")
    return np.ascontiguousarray(buf.reshape(-1))


def set_image_pointer(payload, buffer: np.ndarray) -> None:
    """Point ``payload.imagePointer`` (a ``void*``) at ``buffer``'s bytes, through the payload's numpy layout
    (``CameraImageMsgPayload.__dtype__``; SWIG takes no Python integer for a ``void*``)."""
    import ctypes

    messaging, _, sim_model = basilisk_modules()
    layout = getattr(messaging.CameraImageMsgPayload, "__dtype__", None)
    if layout is None:
        raise UserError("this Basilisk has no CameraImageMsgPayload.__dtype__ (needs bsk >= 2.12)")
    dt = np.dtype(layout)
    raw = (ctypes.c_byte * dt.itemsize).from_address(int(sim_model.getObjectAddress(payload)))
    view = np.ndarray(1, dtype=dt, buffer=raw)
    view[0]["imagePointer"] = int(buffer.ctypes.data)
    payload.imageBufferLength = int(buffer.size)


class CameraLogic:
    """What ``RenderlabCamera`` does (module docstring); the class itself adds Basilisk's ``SysModel``.

    Parameters
    ----------
    renderer : renderlab.Renderer
        The world, opened once (a ``planet`` world: its render frame is the planet-fixed frame).
    fieldOfView : float
        rad, edge to edge along the camera's y axis (Basilisk's ``CameraConfigMsgPayload.fieldOfView``).
    resolution : (int, int)
        Width, height in pixels.
    sigma_CB, cameraPos_B : 3-vectors
        Camera mount: MRPs of the camera frame relative to the body, its position in the body frame (m).
    cameraID : int
        Written into both messages.
    spp : int, optional
        Samples per pixel (default: the scenario's ``render.spp``).
    keep_images : int
        How many encoded images stay alive (≥ 1): a message, or a recorder's copy, may point into them.
    keep_truth : bool
        Keep the truth AOVs of the last frame in ``last_frame.aovs`` (the truth rows are always kept).
    """

    def _setup(self, messaging, renderer, *, fieldOfView: float, resolution, sigma_CB=(0.0, 0.0, 0.0),
               cameraPos_B=(0.0, 0.0, 0.0), cameraID: int = 1, spp: int | None = None, keep_images: int = 2,
               keep_truth: bool = False) -> None:
        if isinstance(keep_images, bool) or not isinstance(keep_images, int) or keep_images < 1:
            raise UserError(f"keep_images must be an integer >= 1, got {str(keep_images)[:40]}")
        self._messaging, self.renderer = messaging, renderer
        self.camera = frames.camera_model(fieldOfView, resolution)
        self.fieldOfView = float(fieldOfView)
        self.sigma_CB = frames.dcm_to_mrp(frames.mrp_to_dcm(sigma_CB))  # validated, the short set
        self.cameraPos_B = frames.vec3(cameraPos_B, "cameraPos_B")
        self.cameraID, self.spp, self.keep_truth = int(cameraID), spp, bool(keep_truth)
        self.scStateInMsg = messaging.SCStatesMsgReader()
        self.planetInMsg = messaging.SpicePlanetStateMsgReader()
        self.sunInMsg = messaging.SpicePlanetStateMsgReader()
        self.imageOutMsg = messaging.CameraImageMsg()
        self.cameraConfigOutMsg = messaging.CameraConfigMsg()
        self._buffers = collections.deque(maxlen=keep_images)
        self.last_frame = None
        self.frames_rendered = 0

    def config_payload(self):
        """The ``CameraConfigMsgPayload`` of this camera."""
        p = self._messaging.CameraConfigMsgPayload()
        p.cameraID, p.isOn, p.fieldOfView = self.cameraID, 1, self.fieldOfView
        p.resolution = [int(self.camera.width), int(self.camera.height)]
        p.sigma_CB = [float(v) for v in self.sigma_CB]
        p.cameraPos_B = [float(v) for v in self.cameraPos_B]
        return p

    def Reset(self, CurrentSimNanos=0):
        if not self.scStateInMsg.isLinked():
            raise UserError("RenderlabCamera.scStateInMsg is not connected (subscribe it to the spacecraft's "
                            "scStateOutMsg)")
        self.cameraConfigOutMsg.write(self.config_payload(), CurrentSimNanos, self.moduleID)

    def pose_at(self, CurrentSimNanos: int):
        """(lab camera pose, sun direction in the render frame or None) from the input messages."""
        sc = self.scStateInMsg()
        r_P, PN = np.zeros(3), None
        if self.planetInMsg.isLinked():
            pl = self.planetInMsg()
            r_P, PN = np.array(pl.PositionVector, float), np.array(pl.J20002Pfix, float)
        pose = frames.camera_pose(sc.r_BN_N, sc.sigma_BN, sigma_CB=self.sigma_CB, cameraPos_B=self.cameraPos_B,
                                  r_PN_N=r_P, dcm_PN=PN, time_s=CurrentSimNanos * 1e-9)
        sun = frames.sun_direction(self.sunInMsg().PositionVector, r_P, PN) if self.sunInMsg.isLinked() else None
        return pose, sun

    def UpdateState(self, CurrentSimNanos):
        pose, sun = self.pose_at(CurrentSimNanos)
        frame = self.renderer.frame(time_s=CurrentSimNanos * 1e-9, pose=pose, sun=sun, camera=self.camera,
                                    spp=self.spp, outputs=("dn", "truth"))
        if not self.keep_truth:
            frame.aovs = None
        buf = encode_png8(frame.dn, self.renderer.options.adc_max)
        self._buffers.append(buf)  # alive until keep_images newer images replace it
        p = self._messaging.CameraImageMsgPayload()
        set_image_pointer(p, buf)
        p.timeTag, p.valid, p.cameraID, p.imageType = int(CurrentSimNanos), 1, self.cameraID, 1
        self.imageOutMsg.write(p, CurrentSimNanos, self.moduleID)
        self.cameraConfigOutMsg.write(self.config_payload(), CurrentSimNanos, self.moduleID)
        self.last_frame, self.frames_rendered = frame, self.frames_rendered + 1


@functools.lru_cache(maxsize=1)
def camera_class():
    """The ``RenderlabCamera`` class: :class:`CameraLogic` on Basilisk's ``SysModel``, built at first use."""
    messaging, sys_model, _ = basilisk_modules()

    class RenderlabCamera(CameraLogic, sys_model.SysModel):
        __doc__ = CameraLogic.__doc__

        def __init__(self, renderer, **settings):
            sys_model.SysModel.__init__(self)
            self._setup(messaging, renderer, **settings)

    return RenderlabCamera


def __getattr__(name: str):
    if name == "RenderlabCamera":
        return camera_class()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
