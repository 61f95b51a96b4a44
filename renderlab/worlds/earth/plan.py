"""The Earth world's :class:`~renderlab.worlds.base.WorldPlan`: LEO frames, one ENU tile per frame.

Frame k is taken at t_k = start_s + k·dt_s after the epoch. The orbit (GCRF elements) is two-body (Kepler, paper
eqs. 10-12), RK4 two-body + J2, or the high-fidelity truth propagator
(:mod:`renderlab.dynamics.truth_orbit`, ``trajectory.truth_model = "zonal_dop853"``); the true attitude is nadir
(plus an optional seeded pointing error); the star tracker's reported attitude (noise σ) goes to the manifest for
the estimators. Earth orientation (GCRF → ITRF, :mod:`.orientation`) and the sun (:mod:`.sun`) are computed for
all frame epochs at once. A file trajectory (``table``, ``ccsds``, ``spice``) replaces the orbit and, where the
files give one, the attitude (:mod:`.file_trajectory`); everything after the spacecraft state is the same.

Frames named in the manifest (each frame record's ``frames``): ``inertial = "GCRF"`` (every ``*_eci`` key),
``earth_fixed = "ITRF"`` (every ``*_ecef`` key, the WGS-84 ellipsoid), ``render = "ENU_TILE"`` (the frame's own
``render_frame``: ``p_itrf = R_ecef_from_render @ p_render + origin_ecef_m``, parent ITRF), ``camera`` (lab
convention: +z boresight, +x right, +y down). Per frame the manifest gets the tile's render frame, the epoch, the
true GCRF/ITRF state, the GCRF→ITRF rotation with the Earth orientation parameters used, and the sun.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import timedelta

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.dynamics.camera_paths import CameraPose
from renderlab.dynamics.orbits import OrbitElements, nadir_attitude, propagate, star_tracker_attitude
from renderlab.geometry.camera import CameraModel
from renderlab.photometry import make_law
from renderlab.render.scene import BodySpec, FrameSpec, SceneDescription, SunSpec
from renderlab.worlds.base import WorldPlan
from renderlab.worlds.earth import orientation
from renderlab.worlds.earth import sun as sunmod
from renderlab.worlds.earth import tiles, wgs84
from renderlab.worlds.earth.clouds import CloudField
from renderlab.worlds.earth.frame_orbit import FrameOrbit
from renderlab.errors import UserError

GROUND_ID, CLOUD_ID = 0, 1
FRAMES = {"inertial": "GCRF", "earth_fixed": "ITRF", "render": "ENU_TILE", "camera": "CAMERA",
          "keys": "*_eci: GCRF; *_ecef: ITRF; R_ecef_from_eci: GCRF to ITRF; R_ecef_from_render: ENU_TILE to ITRF"}


def truth_orbit(tr, epoch, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """True GCRF position and velocity (N, 3) at ``t`` (s after the epoch) for the ``leo`` trajectory ``tr``."""
    el = OrbitElements(wgs84.A + tr.altitude_km * 1e3, tr.eccentricity, np.radians(tr.inclination_deg),
                       np.radians(tr.raan_deg), np.radians(tr.argp_deg), np.radians(tr.true_anomaly_deg))
    r0, v0 = el.state(0.0)
    if tr.truth_model in ("zonal_dop853", "egm2008_dop853"):
        from renderlab.dynamics.geopotential import EarthRotation
        from renderlab.dynamics.truth_orbit import forces_from_config, propagate_truth

        t_end = float(t.max(initial=0.0))
        step = 21600.0 if tr.truth_model == "zonal_dop853" else 60.0  # the pole every <= 6 h; ITRF every minute
        nodes = np.linspace(0.0, t_end, max(2, int(np.ceil(t_end / step)) + 1))
        eo = orientation.earth_orientation(epoch, nodes)
        tt = eo.time[0].tt
        rotation = EarthRotation(nodes, eo.R_itrf_from_gcrf, orientation.OMEGA_ERA)
        forces = forces_from_config(tr, (float(tt.jd1), float(tt.jd2)), (nodes, eo.pole_gcrf), rotation)
        times, back = np.unique(np.concatenate([[0.0], t]), return_inverse=True)  # start_s = 0: t_eval strictly
        x = propagate_truth(np.concatenate([r0, v0]), times, forces)[back][1:]   # increasing for DOP853
        return x[:, :3], x[:, 3:]
    if tr.j2:
        x = propagate(np.concatenate([r0, v0]), np.concatenate([[0.0], t]), j2=True)[1:]
        return x[:, :3], x[:, 3:]
    return el.state(t)


def leo_orbit(scenario) -> FrameOrbit:
    """The ``leo`` trajectory's frames: the orbit of ``truth_model``, nadir attitude (+ seeded pointing error)."""
    w, tr = scenario.world, scenario.trajectory
    if tr.fov_deg is not None:  # validation moves it into the camera (config.leo_camera); a hand-built one is refused
        from renderlab.errors import UserError

        raise UserError("trajectory.fov_deg is not used by the Earth world (the [camera] section is the one source "
                        "of the field of view); validate the scenario, or give camera.fov_deg")
    camera = CameraModel.from_dict(scenario.camera.model_dump())
    epoch = wgs84.parse_epoch(tr.epoch_utc)
    t = tr.start_s + tr.dt_s * np.arange(tr.frames)
    r, v = truth_orbit(tr, epoch, t)
    R_eci_cam = nadir_attitude(r, v)
    rng = np.random.default_rng(np.random.SeedSequence([w.seed, 0xA77]))
    if tr.pointing_error_deg > 0:
        R_eci_cam = star_tracker_attitude(R_eci_cam, np.radians(tr.pointing_error_deg), rng)
    R_st = star_tracker_attitude(R_eci_cam, np.radians(tr.star_tracker_sigma_arcsec / 3600.0), rng)
    model = tr.truth_model if tr.truth_model != "j2_rk4" else ("rk4_two_body_j2" if tr.j2 else "kepler_two_body")
    stamps = [(epoch + timedelta(seconds=float(tk))).isoformat().replace("+00:00", "Z") for tk in t]
    return FrameOrbit(camera, epoch, t, t, stamps, r, v, R_eci_cam, R_st, orientation.earth_orientation(epoch, t),
                      model, float(tr.star_tracker_sigma_arcsec))


@dataclass
class EarthPlan(WorldPlan):
    #: the scene is a local tangent tile built around each planned frame's footprint: the frame API refuses to move
    #: the camera of such a world (renderlab.pipeline.frame_api)
    scene_follows_pose = True
    world: object = None
    traj: object = None
    epoch: object = None
    states: list = field(default_factory=list)  # per frame dict of arrays
    orbit_model: str = ""
    star_tracker_sigma_arcsec: float = 0.0
    _scene_cache: dict = field(default_factory=dict)

    @classmethod
    def from_scenario(cls, scenario, base_dir=None) -> "EarthPlan":
        """The plan of a scenario: the ``leo`` orbit, or a file trajectory (relative paths against ``base_dir``,
        the scenario folder; :mod:`.file_trajectory`)."""
        if scenario.trajectory.kind == "leo":
            orbit = leo_orbit(scenario)
        else:
            from renderlab.worlds.earth.file_trajectory import file_orbit

            orbit = file_orbit(scenario, base_dir)
        eo, r, v = orbit.eo, orbit.r_eci, orbit.v_eci
        jd = wgs84.julian_date(orbit.epoch, orbit.elapsed_s)
        R_ef = eo.R_itrf_from_gcrf
        r_ef, v_ef = eo.to_itrf(r, v)
        s_eci, dist_au = sunmod.sun_gcrf(eo.time)
        frames, states = [], []
        for k, tk in enumerate(orbit.time_s):
            pos, vel = r_ef[k], v_ef[k]
            R_ecef_cam = R_ef[k] @ orbit.R_eci_from_cam[k]
            tile = tiles.TileFrame.at_boresight(pos, R_ecef_cam)
            R_ren = tile.R_ecef_from_render
            s_ecef = R_ef[k] @ s_eci[k]
            pose = CameraPose(float(tk), tile.to_render(pos), Rotation.from_matrix(R_ren.T @ R_ecef_cam))
            sun = SunSpec(R_ren.T @ s_ecef, float(sunmod.sun_irradiance(dist_au[k])))
            frames.append(FrameSpec(k, pose, orbit.camera, sun))
            states.append(dict(t=float(tk), jd=float(jd[k]), r_eci=r[k], v_eci=v[k], r_ecef=pos, v_ecef=vel,
                               R_ecef_from_eci=R_ef[k], R_ecef_from_cam=R_ecef_cam,
                               R_eci_from_cam_st=orbit.R_eci_from_cam_st[k], sun_eci=s_eci[k], sun_ecef=s_ecef,
                               tile=tile, earth_orientation=eo.record(k), epoch_utc=orbit.epochs_utc[k]))
        return cls(frames=frames, render_frame={"name": "ENU_TILE", "parent_frame": "ITRF", "inertial_frame": "GCRF"},
                   world=scenario.world, traj=scenario.trajectory, epoch=orbit.epoch, states=states,
                   orbit_model=orbit.model, star_tracker_sigma_arcsec=orbit.star_tracker_sigma_arcsec)

    # ------------------------------------------------------------------ scenes
    def scene_key(self, spec: FrameSpec):
        return spec.index

    def gsd_m(self, k: int) -> float:
        """Smallest ground sample distance of frame k (nadir range / largest focal length), metres."""
        st = self.states[k]
        rng = float(np.linalg.norm(st["r_ecef"] - st["tile"].origin_ecef_m))
        cam = self.frames[k].camera
        return rng / max(cam.fx, cam.fy)

    def scene(self, key) -> SceneDescription:
        from renderlab.worlds.earth.gshhg import load_gshhg

        k = int(key)
        if k in self._scene_cache:
            return self._scene_cache[k]
        w, st, spec = self.world, self.states[k], self.frames[k]
        tile, cam = st["tile"], spec.camera
        V, F = tiles.grid_mesh(cam, st["r_ecef"], st["R_ecef_from_cam"], tile, w.tile_grid, w.tile_margin_px)
        cell = self.gsd_m(k) / w.texture_oversample
        e0, e1 = V[:, 0].min() - cell, V[:, 0].max() + cell
        n0, n1 = V[:, 1].min() - cell, V[:, 1].max() + cell
        shape = (int(np.ceil((n1 - n0) / cell)), int(np.ceil((e1 - e0) / cell)))
        if max(shape) * w.antialias > 32768:
            raise UserError(f"world.texture_oversample: albedo raster {shape} x{w.antialias} is too large")
        region = tiles.region_of(V, w.tile_grid, tile)
        cov = tiles.land_coverage(tile, region, load_gshhg(), e0, n1, cell, shape, w.antialias)
        amap = w.water_albedo + (w.land_albedo - w.water_albedo) * cov
        bodies = [BodySpec(name="ground", body_id=GROUND_ID, shape="trimesh", center_m=np.zeros(3),
                           R_render_from_body=np.eye(3), law=make_law("lambert"), albedo=1.0, vertices=V, faces=F,
                           albedo_map=amap, vertex_uv=tiles.texture_uv(V, e0, n1, cell, shape))]
        if w.cloud_cover > 0:
            bodies.append(self._cloud_body(k))
        scene = SceneDescription(bodies=bodies, render_frame=tile.to_dict())
        self._scene_cache = {k: scene}
        return scene

    def _cloud_body(self, k: int) -> BodySpec:
        w, st, spec = self.world, self.states[k], self.frames[k]
        n = w.cloud_grid
        V, F = tiles.grid_mesh(spec.camera, st["r_ecef"], st["R_ecef_from_cam"], st["tile"], n, w.tile_margin_px,
                               h_m=w.cloud_altitude_m)
        quads = len(F) // 2
        centre = (V[F[:quads, 0]] + V[F[:quads, 2]]) / 2
        cloudy = CloudField(w.cloud_cover, w.seed, scale_min_m=w.cloud_scale_m).cloudy(st["tile"].to_ecef(centre))
        keep = np.concatenate([cloudy, cloudy])
        if not keep.any():  # a clear sky: one degenerate-free tiny facet far outside the view is not needed;
            keep[:] = False  # Mitsuba accepts an empty mesh poorly, so keep one facet outside the image
            keep[0] = True
        return BodySpec(name="clouds", body_id=CLOUD_ID, shape="trimesh", center_m=np.zeros(3),
                        R_render_from_body=np.eye(3), law=make_law("lambert"), albedo=w.cloud_albedo,
                        vertices=V, faces=F[keep])

    # ------------------------------------------------------------------ metadata and truth
    def frame_meta(self, spec: FrameSpec, scene: SceneDescription) -> dict:
        st = self.states[spec.index]
        vec = lambda a: [float(x) for x in np.ravel(a)]  # noqa: E731
        mat = lambda a: [[float(x) for x in row] for row in a]  # noqa: E731
        return {
            "bodies": {b.name: b.state() for b in scene.bodies},
            "render_frame": {**st["tile"].to_dict(), "parent_frame": "ITRF"},
            "frames": dict(FRAMES),
            "earth_orientation": st["earth_orientation"],
            "truth_orbit_model": self.orbit_model,
            "epoch_utc": st["epoch_utc"],
            "julian_date_utc": st["jd"],
            "spacecraft": {"r_eci_m": vec(st["r_eci"]), "v_eci_mps": vec(st["v_eci"]),
                           "r_ecef_m": vec(st["r_ecef"]), "v_ecef_mps": vec(st["v_ecef"]),
                           "R_ecef_from_eci": mat(st["R_ecef_from_eci"]),
                           "quat_ecef_from_cam_xyzw": vec(Rotation.from_matrix(st["R_ecef_from_cam"]).as_quat()),
                           "star_tracker_quat_eci_from_cam_xyzw":
                               vec(Rotation.from_matrix(st["R_eci_from_cam_st"]).as_quat()),
                           "star_tracker_sigma_arcsec": self.star_tracker_sigma_arcsec},
            "sun_eci": vec(st["sun_eci"]), "sun_ecef": vec(st["sun_ecef"]),
            "gsd_m": self.gsd_m(spec.index),
        }

    def footprint_region(self, k: int, margin_px: float = 0.0):
        from renderlab.worlds.earth import footprint

        st, cam = self.states[k], self.frames[k].camera
        dirs = footprint.boundary_dirs_camera(cam, 32, margin_px)
        return footprint.footprint_polygons(st["r_ecef"], st["R_ecef_from_cam"], dirs)[0]

    def frame_rows(self, spec: FrameSpec, rendered) -> dict[str, list[dict]]:
        import shapely

        from renderlab.worlds.earth.coastline_truth import coastline_pixels
        from renderlab.worlds.earth.gshhg import load_gshhg

        st = self.states[spec.index]
        region = self.footprint_region(spec.index, margin_px=2.0)
        pieces = shapely.get_parts(load_gshhg().coast_in(region))
        lines = [np.asarray(p.coords) for p in pieces if p.geom_type == "LineString"]
        s, ln, lon, lat, piece = coastline_pixels(spec.camera, st["r_ecef"], st["R_ecef_from_cam"], lines)
        rows = [{"frame": spec.index, "s": float(a), "l": float(b), "lon_deg": float(c), "lat_deg": float(d),
                 "piece": int(e)} for a, b, c, d, e in zip(s, ln, lon, lat, piece)]
        return {"coastline_truth": rows}

    def write_static(self, writer) -> None:
        import json

        import pyarrow as pa
        import shapely

        from renderlab.worlds.earth.coast_db import CoastDBOptions, build_coast_db
        from renderlab.worlds.earth.gshhg import load_gshhg

        w = self.world
        region = shapely.union_all([self.footprint_region(k) for k in range(len(self.frames))])
        region = region.buffer(w.coast_db_margin_deg)
        opt = CoastDBOptions(w.coast_db_tolerance_m, w.coast_db_error_m, w.coast_db_error_scale_m, w.seed)
        cols = build_coast_db(load_gshhg(), region, opt)
        writer.add_table("coast_db", pa.table(cols))
        info = {"source": "GSHHG full resolution (roaring-landmask)", "tolerance_m": opt.tolerance_m,
                "map_error_m_1sigma_per_axis": opt.error_m, "map_error_scale_m": opt.scale_m, "seed": opt.seed,
                "region_bounds_lonlat_deg": [float(v) for v in region.bounds]}
        writer.add_file("coast_db.json", (json.dumps(info, indent=1) + "\n").encode())
