"""World plan of the unknown-satellite scenario: separation, tumbling, one static scene.

Render frame = the target's body frame ("MICROSAT_BODY", principal axes, origin at the centre of mass):
the satellite is static there and only the camera pose and the sun move, so the Mitsuba scene is
loaded once. Per frame t_k = k·dt:

* relative position/velocity of the target's centre of mass in the chaser's LVLH frame from the
  Clohessy-Wiltshire solution (Ivanov et al. eq. 1, :mod:`renderlab.dynamics.relative_motion`);
* target attitude ``R_lvlh_from_body`` and body rate from Euler + gravity gradient (eq. 2,
  :mod:`renderlab.dynamics.attitude`);
* the chaser holds LVLH attitude; camera at ``d`` (LVLH) with ``R_lvlh_from_cam`` fixed, so
  ``position_body = Rᵀ(d − r)`` and ``R_body_from_cam = Rᵀ R_lvlh_from_cam`` (eq. 3 read backwards);
* the sun is inertially fixed, seen in LVLH as ``Rz(−n t) s0``. No Earth in the view: the
  background is black space (the paper's algorithm needs a dark background, §4).

A file trajectory (``table``, ``ccsds``, ``spice``) replaces the Clohessy-Wiltshire motion and the fixed camera by
the camera's own LVLH pose relative to the target (:mod:`.file_trajectory`); the tumble and the sun stay.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.dynamics.attitude import propagate_attitude
from renderlab.dynamics.camera_paths import CameraPose
from renderlab.dynamics.relative_motion import cw_propagate, mean_motion, sun_in_lvlh
from renderlab.errors import UserError
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.rotations import look_at
from renderlab.render.scene import BodySpec, FrameSpec, RenderedFrame, SceneDescription, SunSpec
from renderlab.worlds.base import WorldPlan

from .model import KNOB_ID0, PART_IDS, build_parts
from .truth import SeparationTruth


def separation_truth(scenario, features_body: np.ndarray) -> SeparationTruth:
    """Integrate the relative motion and attitude of the scenario at its frame times."""
    tr, world = scenario.trajectory, scenario.world
    n = mean_motion(tr.altitude_m)
    times = np.arange(tr.frames) * tr.dt_s
    rv = cw_propagate(np.r_[tr.r0_lvlh_m, tr.v0_lvlh_mps], n, times)
    q0 = np.asarray(tr.q0_lvlh_from_body_xyzw, float)
    Q, W = propagate_attitude(q0 / np.linalg.norm(q0), np.radians(tr.omega0_body_deg_s), world.inertia_kg_m2,
                              n, times, substeps=tr.attitude_substeps)
    d = np.asarray(tr.camera_offset_lvlh_m, float)
    R_lc = look_at(d, d + np.asarray(tr.camera_boresight_lvlh, float), tr.camera_up_lvlh).as_matrix()
    sun = np.array([sun_in_lvlh(world.sun_lvlh, n, t) for t in times])
    return SeparationTruth(times, rv, Q, W, np.asarray(world.inertia_kg_m2, float), n, d, R_lc, sun,
                           np.asarray(features_body, float))


@dataclass
class MicrosatPlan(WorldPlan):
    truth: SeparationTruth | None = None
    knob_ids: list[int] = field(default_factory=list)

    def frame_meta(self, spec: FrameSpec, scene: SceneDescription) -> dict:
        k, t = spec.index, self.truth
        epoch = {} if t.epochs_utc is None else {"epoch_utc": t.epochs_utc[k]}
        v = t.rv_lvlh[k, 3:]
        return {
            "bodies": {b.name: b.state() for b in scene.bodies},
            **epoch,
            "microsat": {
                "r_lvlh_m": t.rv_lvlh[k, :3].tolist(), "v_lvlh_mps": v.tolist() if np.isfinite(v).all() else None,
                "quat_lvlh_from_body_xyzw": t.quat_lvlh_from_body[k].tolist(),
                "omega_body_rad_s": t.omega_body[k].tolist(), "inertia_kg_m2": t.inertia.tolist(),
                "mean_motion_rad_s": t.n, "camera_offset_lvlh_m": t.camera_offset_lvlh.tolist(),
                "quat_lvlh_from_cam_xyzw": Rotation.from_matrix(t.R_lc(k)).as_quat().tolist(),
                "sun_lvlh": t.sun_lvlh[k].tolist(),
            },
        }

    def write_static(self, writer) -> None:
        import pyarrow as pa

        f = self.truth.features_body
        writer.add_table("features", pa.table({
            "feature_id": np.arange(len(f)), "body_id": np.asarray(self.knob_ids),
            "x_body_m": f[:, 0], "y_body_m": f[:, 1], "z_body_m": f[:, 2]}))

    def frame_rows(self, spec: FrameSpec, rendered: RenderedFrame) -> dict[str, list[dict]]:
        return {"feature_truth": feature_truth_rows(spec, rendered, self.truth.features_body, self.knob_ids)}


def feature_truth_rows(spec: FrameSpec, rendered: RenderedFrame, features_body, knob_ids) -> list[dict]:
    """Pixel truth of every feature: projection of the knob centre; occluded when the truth ray through
    the nearest pixel centre hits another body first (id AOV)."""
    R = spec.pose.rotation.as_matrix()
    p_cam = (np.asarray(features_body) - spec.pose.position_m) @ R  # Rᵀ(p − c)
    sl = spec.camera.project(p_cam)
    inside = spec.camera.in_image(sl)
    sun = spec.sun.direction_render
    lum = rendered.radiance if rendered.radiance.ndim == 2 else rendered.radiance.mean(-1)
    rows = []
    for j, (p, q) in enumerate(zip(p_cam, sl)):
        occluded, rad = False, float("nan")
        if inside[j]:
            s_i, l_i = int(np.rint(q[0])), int(np.rint(q[1]))
            occluded = bool(rendered.body_id[l_i, s_i] != knob_ids[j])
            rad = float(lum[max(l_i - 1, 0):l_i + 2, max(s_i - 1, 0):s_i + 2].max())
        to_cam = -(R @ p) / np.linalg.norm(p)
        rows.append({
            "frame": spec.index, "feature_id": j,
            "s": float(q[0]) if inside[j] else float("nan"), "l": float(q[1]) if inside[j] else float("nan"),
            "visible": bool(inside[j] and not occluded), "occluded": occluded,
            "x_body_m": float(features_body[j][0]), "y_body_m": float(features_body[j][1]),
            "z_body_m": float(features_body[j][2]), "range_m": float(np.linalg.norm(p)),
            "radiance_peak": rad,  # max radiance in the 3×3 pixels around the truth pixel (dark = shadowed)
            "phase_deg": float(np.degrees(np.arccos(np.clip(to_cam @ sun, -1, 1)))),
        })
    return rows


def make_plan(scenario, base_dir) -> MicrosatPlan:
    """The microsat world plan: one static scene in the target body frame, camera and sun per frame (the
    separation, or a file trajectory: :mod:`.file_trajectory`)."""
    from renderlab.photometry import make_law

    file_kind = scenario.trajectory.kind != "separation"
    if not file_kind and scenario.world.tumble is not None:
        raise UserError("world.tumble: the separation trajectory sets the tumble itself (q0_lvlh_from_body_xyzw, "
                        "omega0_body_deg_s, altitude_m); [world.tumble] is for file trajectories")
    parts, tips = build_parts(scenario.world)
    if file_kind:
        from .file_trajectory import file_truth

        truth = file_truth(scenario, base_dir, tips)
    else:
        truth = separation_truth(scenario, tips)
    law = make_law("lambert")
    bodies, knob_ids = [], []
    for p in parts:
        bid = PART_IDS.get(p.name)
        if bid is None:
            bid = KNOB_ID0 + int(p.name.removeprefix("knob"))
            knob_ids.append(bid)
        bodies.append(BodySpec(name=p.name, body_id=bid, shape="trimesh", center_m=np.zeros(3),
                               R_render_from_body=np.eye(3), law=law, albedo=p.albedo,
                               vertices=p.vertices, faces=p.faces))
    camera = CameraModel.from_dict(scenario.camera.model_dump())
    E = scenario.sun.irradiance_w_m2
    frames = []
    for k, t in enumerate(truth.times_s):
        R_lb = Rotation.from_quat(truth.quat_lvlh_from_body[k]).as_matrix()
        pos_b = R_lb.T @ (truth.camera_offset_lvlh - truth.rv_lvlh[k, :3])
        R_bc = R_lb.T @ truth.R_lc(k)
        if (R_bc.T @ -pos_b)[2] <= 0:
            raise UserError(f"trajectory: at frame {k} the target is behind the camera "
                            + ("(check the file's positions and attitude: LVLH, the camera relative to the target)"
                               if file_kind else "(check r0_lvlh_m, camera_offset_lvlh_m and camera_boresight_lvlh)"))
        epoch = None if truth.epochs_utc is None else truth.epochs_utc[k]
        frames.append(FrameSpec(index=k, pose=CameraPose(float(t), pos_b, Rotation.from_matrix(R_bc), epoch),
                                camera=camera, sun=SunSpec(R_lb.T @ truth.sun_lvlh[k], E)))
    return MicrosatPlan(frames=frames, render_frame={"name": "MICROSAT_BODY"},
                        static_scene=SceneDescription(bodies=bodies, render_frame={"name": "MICROSAT_BODY"}),
                        truth=truth, knob_ids=knob_ids)
