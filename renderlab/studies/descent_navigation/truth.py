r"""The true descent the filter navigates: the kinematic ARRM trajectory, the truth's gravity (point mass + J2,
eq. T1) and the control it implies (eq. T2), docs/descent_navigation.md "The true descent"."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderlab.geometry.camera import CameraModel
from renderlab.geometry.rotations import rotation_from_quat_xyzw
from renderlab.worlds.base import make_plan
from renderlab.worlds.ev5.descent import DescentProfile


@dataclass(frozen=True)
class TrueDescent:
    """The kinematic descent and the truth's gravity (module docstring)."""

    profile: object          # renderlab.worlds.ev5.descent.DescentProfile
    omega_rad_s: float
    origin_m: np.ndarray
    normal: np.ndarray
    gm: float
    j2: float
    r_ref_m: float

    @property
    def omega(self) -> np.ndarray:
        return np.array([0.0, 0.0, self.omega_rad_s])

    def position(self, t) -> np.ndarray:
        """r(t) (..., 3) in the body frame."""
        t = np.asarray(t, float)
        tf = t.reshape(-1)
        q = self.origin_m + self.profile.altitude(tf)[:, None] * self.normal
        th = np.where(tf < self.profile.t_spin_match, self.omega_rad_s * (self.profile.t_spin_match - tf), 0.0)
        c, s = np.cos(th), np.sin(th)
        out = np.stack([c * q[:, 0] - s * q[:, 1], s * q[:, 0] + c * q[:, 1], q[:, 2]], axis=-1)
        return out.reshape(t.shape + (3,))

    def state(self, t) -> np.ndarray:
        """[r, v] (..., 6)."""
        h = 1e-3
        v = (self.position(np.asarray(t) + h) - self.position(np.asarray(t) - h)) / (2 * h)
        return np.concatenate([self.position(t), v], axis=-1)

    def acceleration(self, t) -> np.ndarray:
        """r̈(t) (..., 3), kinematic."""
        h = 1e-2
        t = np.asarray(t, float)
        return (self.position(t + h) - 2 * self.position(t) + self.position(t - h)) / h**2

    def gravity(self, r) -> np.ndarray:
        """g_T of eq. T1 (..., 3)."""
        r = np.asarray(r, float)
        rn = np.linalg.norm(r, axis=-1, keepdims=True)
        z2 = (r[..., 2:3] / rn) ** 2
        f = -1.5 * self.j2 * self.gm * self.r_ref_m**2 / rn**5
        j2 = f * np.concatenate([r[..., :2] * (1 - 5 * z2), r[..., 2:3] * (3 - 5 * z2)], axis=-1)
        return -self.gm * r / rn**3 + j2

    def control(self, t) -> np.ndarray:
        """u(t) of eq. T2 (..., 3)."""
        x = self.state(t)
        r, v = x[..., :3], x[..., 3:]
        w = np.broadcast_to(self.omega, r.shape)
        return self.acceleration(t) - self.gravity(r) + 2 * np.cross(w, v) + np.cross(w, np.cross(w, r))

    def accelerometer(self, t0, t1, sigma: float, rng: np.random.Generator) -> np.ndarray:
        """The accelerometer's readings over the samples [t0, t1] (n,): the mean of u (Simpson) + N(0, σ²) per axis,
        (n, 3); the noise drawn sample by sample, 3 normals each."""
        t0, t1 = np.atleast_1d(np.asarray(t0, float)), np.atleast_1d(np.asarray(t1, float))
        u = self.control(np.stack([t0, 0.5 * (t0 + t1), t1], 1))
        return (u[:, 0] + 4 * u[:, 1] + u[:, 2]) / 6.0 + sigma * rng.standard_normal((len(t0), 3))


def site_frame(ts) -> tuple[np.ndarray, np.ndarray]:
    """(origin_m, R_body_from_site) of the landing site from the truth set's ``site.json`` (columns east, north, up)."""
    import json

    info = json.loads((ts.path / "site.json").read_text(encoding="utf-8"))
    return np.asarray(info["origin_m"], float), np.asarray(info["R_body_from_site"], float)


def true_descent(ts, scenario, cfg) -> TrueDescent:
    """The :class:`TrueDescent` of an EV5 descent truth set: the site and spin as rendered (``site.json``, the
    frames' ``ev5.spin``), the profile of ``scenario.trajectory``, the truth gravity of ``cfg``."""
    return _true(scenario, cfg, float(ts.frames[0]["ev5"]["spin"]["period_s"]), *site_frame(ts))


def _true(scenario, cfg, period_s: float, origin, R_site) -> TrueDescent:
    return TrueDescent(DescentProfile(scenario.trajectory), 2.0 * np.pi / period_s, np.asarray(origin, float),
                       np.asarray(R_site, float)[:, 2], float(cfg.gm_true_m3_s2), float(cfg.j2_true), float(cfg.r_ref_m))


_PLANNED: dict = {}


def planned_descent(scenario, base_dir, cfg) -> tuple[dict, TrueDescent, list]:
    """(frames, truth, maplets) of a descent scenario from the world's plan, without rendering: ``frames`` holds
    ``times`` (K,), ``R_true`` (K, 3, 3) body ← camera, ``pos_true`` (K, 3), ``cameras`` (K,) and ``R_site``
    (body ← site), as a truth set's manifest and ``site.json`` give them; the maplets sorted by landmark id, as the
    truth set's catalogue. Cached per process (the plan builds the world)."""
    import json
    from pathlib import Path

    key = (json.dumps(scenario.to_dict(), sort_keys=True, default=str), str(Path(base_dir).resolve()))
    if key not in _PLANNED:
        plan = make_plan(scenario, Path(base_dir))
        model, states = plan.model, plan.states
        R_site = np.asarray(model.site.R_body_from_site, float)
        truth = _true(scenario, cfg, model.spin.period_s, model.site.origin_m, R_site)
        cam = CameraModel.from_dict(scenario.camera.model_dump())
        frames = {"times": np.array([s.time_s for s in states], float),
                  "R_true": np.stack([s.pose.rotation.as_matrix() for s in states]),
                  "pos_true": np.stack([np.asarray(s.pose.position_m, float) for s in states]),
                  "cameras": [cam] * len(states), "R_site": R_site}
        _PLANNED.clear()
        _PLANNED[key] = (frames, truth, sorted(model.maplets, key=lambda m: m.landmark_id))
    return _PLANNED[key]


def truthset_frames(ts) -> dict:
    """The ``frames`` of :func:`planned_descent` from a truth set's manifest and ``site.json``."""
    return {"times": np.array([float(rec["time_s"]) for rec in ts.frames]),
            "R_true": np.stack([rotation_from_quat_xyzw(rec["pose"]["quat_render_from_cam_xyzw"]).as_matrix()
                                for rec in ts.frames]),
            "pos_true": np.array([rec["pose"]["position_m"] for rec in ts.frames], float),
            "cameras": [CameraModel.from_dict(rec["camera"]) for rec in ts.frames], "R_site": site_frame(ts)[1]}
