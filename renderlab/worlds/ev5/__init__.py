"""EV5 world: procedural 2008 EV5, boulder-field landing site, maplet catalog, descent, landmark truth.

Render frame = EV5 body-fixed frame (``EV5_FIXED``): the asteroid is static; the camera and the
sun move per frame (:mod:`.descent`, or the user's file trajectory in ``EV5_FIXED``: :mod:`.file_trajectory`), so
one Mitsuba scene serves every frame. Bodies: id 0 the
global mesh (:mod:`.shape`, cut under the site), id 1 the landing-site DEM (:mod:`.site`; with
``world.site.lod`` as tiles with levels of detail chosen per frame, :mod:`.tiles`). The built shape and
site are cached in the lab cache by content key (:mod:`.world_cache`). The
truth set carries the landmark catalog (:mod:`.catalog`, :mod:`.landmarks`) and
``landmark_truth.parquet`` (:mod:`.landmark_truth`). ``world.seed`` alone makes body, site,
boulders, catalog and maplets (independent random streams per part).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from renderlab.errors import UserError

GLOBAL_ID, SITE_ID = 0, 1
#: spawn keys of the independent random streams under ``world.seed``
STREAMS = {"shape": 0, "terrain": 1, "boulders": 2, "placement": 3, "mapping_error": 4}


def stream(seed: int, name: str) -> np.random.Generator:
    """The seeded generator of one part of the world."""
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(STREAMS[name],)))


@dataclass
class EV5Model:
    """Everything ``world.seed`` makes: shapes, site, catalog, spin state, photometric law."""

    shape: object  # GlobalShape, cut under the site
    site: object  # Site
    maplets: list
    tiers: dict
    spin: object  # SpinState
    law: object  # PhotometricLaw
    albedo: float
    full_shape_stats: dict = field(default_factory=dict)

    def bodies(self, site: bool = True):
        """The global body and (``site``) the full-resolution site DEM as trimesh bodies."""
        from renderlab.render.scene import BodySpec

        common = dict(center_m=np.zeros(3), R_render_from_body=np.eye(3), law=self.law, albedo=self.albedo)
        out = [BodySpec(name="ev5", body_id=GLOBAL_ID, shape="trimesh", vertices=self.shape.vertices,
                        faces=self.shape.faces, vertex_albedo=self.shape.vertex_albedo, **common)]
        if site:
            sv, sf = self.site.mesh()
            out.append(BodySpec(name="landing_site", body_id=SITE_ID, shape="trimesh", vertices=sv, faces=sf,
                                vertex_albedo=np.asarray(self.site.albedo).reshape(-1), **common))
        return out

    def tiled_site(self, tile_cells: int, lod_pixels: float, facets_per_pixel: float | None = None):
        """The site as tiles with levels of detail (:class:`~renderlab.worlds.ev5.tiles.TiledSite`)."""
        from renderlab.worlds.ev5.tiles import TiledSite

        return TiledSite(self.site, tile_cells, lod_pixels, body_id=SITE_ID, name="landing_site", law=self.law,
                         albedo=self.albedo, facets_per_pixel=facets_per_pixel)


def _build_shape_site(world, base_dir: Path, bar):
    """(cut global shape, site, full-shape statistics) built from ``world.seed`` (no cache)."""
    from renderlab.worlds.ev5.shape import load_shape_file, procedural_shape
    from renderlab.worlds.ev5.site import build_site

    bar.set_postfix_str("global shape")
    if world.shape_file:
        shape = load_shape_file((Path(base_dir) / world.shape_file).resolve(), world.shape_file_units)
        facet = float(np.median(np.linalg.norm(shape.vertices[shape.faces[:, 0]] - shape.vertices[shape.faces[:, 1]], axis=1)))
    else:
        shape = procedural_shape(world, stream(world.seed, "shape"))
        facet = world.facet_m
    stats = {"extents_m": [float(v) for v in shape.extents()], "volume_m3": shape.volume(),
             "equivalent_diameter_m": shape.equivalent_diameter(), "n_faces": int(len(shape.faces))}
    bar.update()
    bar.set_postfix_str("landing site")
    site, cut = build_site(shape, world.site, facet, stream(world.seed, "terrain"), stream(world.seed, "boulders"))
    return cut, site, stats


def build_model(world, base_dir: Path) -> EV5Model:
    """Build the EV5 world of a validated :class:`~renderlab.worlds.ev5.config.EV5World`.

    With ``world.build_cache`` the cut shape and the site come from the lab cache when built before
    (:mod:`.world_cache`; arrays memory-mapped, ``radius_fn`` is then None); the catalog is always made
    from the site with its own random streams, so it is the same either way.
    """
    from renderlab.dynamics.small_body import SpinState
    from renderlab.photometry import make_law
    from renderlab.worlds.ev5.landmarks import build_catalog
    from renderlab.worlds.ev5.world_cache import cached_build

    from tqdm import tqdm

    bar = tqdm(total=3, desc="ev5 world", unit="step", disable=None)  # off when not on a terminal
    if world.build_cache:
        cut, site, stats, status = cached_build(world, base_dir, lambda: _build_shape_site(world, base_dir, bar))
        bar.n = 2
        bar.set_postfix_str(f"shape + site: cache {status}")
    else:
        cut, site, stats = _build_shape_site(world, base_dir, bar)
    bar.update()
    bar.set_postfix_str("landmark catalog")
    maplets, tiers = build_catalog(site, world, stream(world.seed, "placement"), stream(world.seed, "mapping_error"))
    bar.update()
    bar.close()
    try:
        law = make_law(world.law, **world.law_params)
    except UserError as err:
        raise UserError(f"world.law_params: {err}") from None
    spin = SpinState(world.pole_lambda_deg, world.pole_beta_deg, world.rotation_period_h * 3600.0)
    return EV5Model(cut, site, maplets, tiers, spin, law, float(world.albedo), stats)


def _rounded(value, digits: int = 10):
    """Floats to ``digits`` significant digits, recursively: the last digits of multithreaded reductions (the
    global-shape statistics) depend on the thread count, and ``site.json`` must be byte-identical for a seed."""
    if isinstance(value, float):
        return float(f"{value:.{digits}g}")
    if isinstance(value, dict):
        return {k: _rounded(v, digits) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_rounded(v, digits) for v in value]
    return value


def _spec_at(model, states: list, n_planned: int, camera, irradiance: float, time_s: float, pose):
    """The EV5 world at any time (the frame API between planned frames): the sun of the nearest planned frame turned
    about the spin pole to ``time_s``; the new state is appended to ``states`` (its index is the frame's)."""
    from renderlab.render.scene import FrameSpec, SunSpec
    from renderlab.worlds.ev5.descent import DescentState

    near = min(states[:n_planned], key=lambda st: abs(st.time_s - time_s))
    sun = model.spin.inertial_to_body_turn(time_s - near.time_s)[0].apply(near.sun_dir_body)
    site = model.site
    alt = float(np.dot(np.asarray(pose.position_m, float) - site.origin_m, site.R_body_from_site[:, 2]))
    states.append(DescentState(float(time_s), alt, pose, sun, None))
    return FrameSpec(index=len(states) - 1, pose=pose, camera=camera,
                     sun=SunSpec(direction_render=sun, irradiance_w_m2=irradiance))


def make_plan(scenario, base_dir: Path):
    """World plan of an EV5 scenario (module docstring): the descent, or a file trajectory in ``EV5_FIXED``
    (:mod:`.file_trajectory`)."""
    from renderlab.geometry.camera import CameraModel
    from renderlab.render.scene import FrameSpec, SceneDescription, SunSpec
    from renderlab.worlds.base import WorldPlan
    from renderlab.worlds.ev5.descent import descent_states
    from renderlab.worlds.ev5.landmark_truth import landmark_rows

    traj = scenario.trajectory
    poses = None
    if traj.kind != "ev5_descent":  # a file trajectory (.file_trajectory): read and checked before the world build
        from renderlab.worlds.ev5.file_trajectory import file_poses

        poses = file_poses(traj, Path(base_dir))
    model = build_model(scenario.world, Path(base_dir))
    camera = CameraModel.from_dict(scenario.camera.model_dump())
    if poses is None:
        states = descent_states(traj, model.spin, model.site.origin_m, model.site.R_body_from_site)
    else:
        from renderlab.worlds.ev5.file_trajectory import file_states

        states = file_states(poses, scenario.sun.direction, model.spin, model.site.origin_m,
                             model.site.R_body_from_site)
    irr = scenario.sun.irradiance_w_m2
    frames = [FrameSpec(index=k, pose=s.pose, camera=camera,
                        sun=SunSpec(direction_render=s.sun_dir_body, irradiance_w_m2=irr)) for k, s in enumerate(states)]

    epoch0 = None
    if traj.epoch_utc and poses is None:
        from renderlab.trajectory_io.timescales import parse_epoch

        epoch0 = parse_epoch(traj.epoch_utc, "UTC", "trajectory.epoch_utc")

    class EV5Plan(WorldPlan):
        def spec_at(self, time_s, pose):
            return _spec_at(model, states, len(frames), camera, irr, time_s, pose)

        def frame_meta(self, spec, scene):
            st = states[spec.index]
            T = model.spin.T_eclip_from_body(st.time_s)
            stamp = st.pose.epoch_utc or (None if epoch0 is None else epoch0.plus(st.time_s).iso("UTC", 6))
            epoch = {} if stamp is None else {"epoch_utc": stamp}
            matched = {} if st.spin_matched is None else {"spin_matched": st.spin_matched}  # descent only
            ev5 = {"altitude_m": st.altitude_m, **matched, "spin": model.spin.to_dict(st.time_s),
                   "sun_direction_eclip": [float(v) for v in T.apply(st.sun_dir_body)]}
            bodies = {b.name: b.state() for b in scene.bodies}
            for t in scene.tiled:  # the tiles and levels this frame rendered (renderlab.worlds.ev5.tiles)
                bodies[t.name] = t.state()
                ev5["lod"] = t.lod_summary([] if t.traced_whole else t.select(spec.camera, spec.pose))
            return {"bodies": bodies, **epoch, "ev5": ev5}

        def write_static(self, writer):
            from renderlab.worlds.ev5.catalog import write_catalog

            write_catalog(writer, model.maplets, model.tiers)
            site = model.site
            info = {"origin_m": site.origin_m.tolist(), "R_body_from_site": site.R_body_from_site.tolist(),
                    "x0_m": site.x0_m, "cell_m": site.cell_m, "n": site.n, "body_id": SITE_ID,
                    "target_boulder_center_xy_m": site.target_center_xy.tolist(),
                    "target_boulder_diameter_m": site.target_diameter_m,
                    "n_boulders": site.n_boulders, "n_craters": site.n_craters,
                    "global_shape": model.full_shape_stats, "global_body_id": GLOBAL_ID}
            writer.add_file("site.json", (json.dumps(_rounded(info), indent=1) + "\n").encode())

        def frame_rows(self, spec, rendered):
            return {"landmark_truth": landmark_rows(spec.index, spec, rendered, model.maplets, model.tiers,
                                                    model.site, self._footprints)}

    lod = scenario.world.site
    tiled = [model.tiled_site(lod.tile_cells, lod.lod_pixels, lod.facets_per_pixel)] if lod.tiled() else []
    plan = EV5Plan(frames=frames, render_frame={"name": "EV5_FIXED"},
                   static_scene=SceneDescription(bodies=model.bodies(site=not tiled), render_frame={"name": "EV5_FIXED"},
                                                 origin_m=np.array(model.site.origin_m, float), tiled=tiled))
    plan._footprints = {}
    plan.model = model
    plan.states = states
    return plan
