r"""Geometry probe of the image-scale part of the landmark errors (``scale_probe.py`` beside it): does the rendered
truth surface lie off the surface the landmarks are defined on, and does that offset predict the measured scale?

A landmark's truth pixel is the projection of its centre c, a point of the full-resolution site DEM; the maplets
are cell means of that DEM. The truth image is rendered from the frame's tiles at their levels of detail
(:mod:`renderlab.worlds.ev5.tiles`): vertices of the DEM at a stride of 2^L cells, albedo at the same vertices.
If the rendered surface lies δz along the site normal n off the DEM over a landmark's footprint, its texture is
seen at c + δz n instead of c, so the landmark is measured at

.. math::  \mathbf e = \pi(\mathbf c + \delta z\,\mathbf n) - \pi(\mathbf c)   \quad (G1)

(π the true projection, Retina eqs. 1–4), a scale of δz/R about the principal point for a nadir view. Per
landmark in view (the ``scale_probe.in_view`` selection) it gives three offsets δz:

* ``dz_lod`` — the frame's tile surface minus the DEM, h_L − h, averaged over the maplet's grid nodes
  (the footprint the template correlates over);
* ``dz_aov`` — the truth set's position AOV, interpolated bilinearly over the pixel centres at the truth pixel,
  minus c, along n (what was actually rendered on the landmark's line of sight, at one point);
* ``dz_map`` — the maplet (heights along its +z) minus the DEM under each node, averaged (the map's own offset).

and the scale of the similarity fit (``scale_probe.similarity_scale``) of the errors of eq. G1 over the
image's landmarks, for each.

A second probe (:func:`probe_fresh`) asks whether the scale belongs to the *image* or to the catalogue's few
landmarks: the truth images do not depend on the maplets, so any number of fresh, error-free landmarks of a tier
can be made on the same site (uniform in the tier's disc, seeded; frame and cell means as the catalogue,
:mod:`renderlab.worlds.ev5.landmarks` steps 1–3) and measured at the true pose. A scale of the image (camera,
range, renderer) is the same for every landmark set; one made by the fixed errors of a few landmarks is not,
and averages out over many. The interval is a bootstrap over the fresh landmarks (independent positions; their
footprints may overlap, which the bootstrap does not model: it is the spread of the landmark set's draw).
Beside it: the mean gradient-weighted relief offset of the fresh maplets (:func:`relief_offset`, the DEM above the
maplet's smoothed surface where the image has contrast) and the scale eq. G1 predicts from it.
A diagnostic, not a study: it explains part of ``results/descent_navigation_map_states/README.md`` and is not part
of the lab (nothing imports it).

    .venv/bin/python investigations/descent_navigation_map_states/scale_geometry.py SCENARIO TRUTHSET FRAMES
    .venv/bin/python investigations/descent_navigation_map_states/scale_geometry.py SCENARIO TRUTHSET FRAMES \
        METHOD TIER COUNT

(``TIER`` a tier name, or ``NAME@SPACINGxSIZE`` for fresh maplets in that tier's disc on another grid, e.g.
``regional@0.04x151``: the DEM's own cells over the regional footprint.)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from scale_probe import in_view, similarity_scale  # beside this file (the script's folder is on sys.path)


def tile_heights(tiled, keys, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Height h_L along site +z of the rendered tile surface at site (x, y): the tile under each point at its
    level in ``keys`` (:class:`~renderlab.worlds.ev5.tiles.TileKey` list), triangulated like the DEM
    (:func:`renderlab.worlds.ev5.terrain.grid_faces`); NaN where no tile of ``keys`` covers the point."""
    s, e = tiled.site, tiled.edges
    level = {(k.row, k.col): k.level for k in keys}
    x, y = np.asarray(x, float), np.asarray(y, float)
    u, v = (x - s.x0_m) / s.cell_m, (y - s.x0_m) / s.cell_m
    col = np.clip(np.searchsorted(e, u, side="right") - 1, 0, tiled.n_tiles - 1)
    row = np.clip(np.searchsorted(e, v, side="right") - 1, 0, tiled.n_tiles - 1)
    out = np.full(x.shape, np.nan)
    for (r, c), L in level.items():
        m = (row == r) & (col == c)
        if not m.any():
            continue
        st = 2 ** L
        g = np.asarray(s.heights_m[e[r]:e[r + 1] + 1:st, e[c]:e[c + 1] + 1:st], float)
        uu, vv = np.clip((u[m] - e[c]) / st, 0, g.shape[1] - 1), np.clip((v[m] - e[r]) / st, 0, g.shape[0] - 1)
        i, j = np.minimum(uu.astype(np.int64), g.shape[1] - 2), np.minimum(vv.astype(np.int64), g.shape[0] - 2)
        fx, fy = uu - i, vv - j
        h00, h01, h10, h11 = g[j, i], g[j, i + 1], g[j + 1, i], g[j + 1, i + 1]
        out[m] = np.where(fx >= fy, h00 + fx * (h01 - h00) + fy * (h11 - h01),
                          h00 + fy * (h10 - h00) + fx * (h11 - h10))
    return out


def bilinear_aov(position: np.ndarray, s: float, l: float) -> np.ndarray:
    """The position AOV (H, W, 3; pixel centres at integer (s, l)) interpolated bilinearly at (s, l)."""
    i, j = int(np.floor(s)), int(np.floor(l))
    fx, fy = s - i, l - j
    P = np.asarray(position[j:j + 2, i:i + 2], float)
    if P.shape[:2] != (2, 2):
        return np.full(3, np.nan)
    return (1 - fy) * ((1 - fx) * P[0, 0] + fx * P[0, 1]) + fy * ((1 - fx) * P[1, 0] + fx * P[1, 1])


def landmark_offsets(site, tiled, keys, maplet, position, camera, pose) -> dict:
    """``dz_lod``, ``dz_aov``, ``dz_map`` of one landmark (module docstring), m along the site normal."""
    n_up = site.R_body_from_site[:, 2]
    nodes = site.to_site(maplet.points_body().reshape(-1, 3))      # maplet nodes (its heights) in the site frame
    flat = site.to_site(maplet.to_body(np.c_[maplet.points_maplet()[..., :2].reshape(-1, 2), np.zeros(maplet.n ** 2)]))
    h_dem = site.height_at(flat[:, 0], flat[:, 1])
    dz_lod = float(np.nanmean(tile_heights(tiled, keys, flat[:, 0], flat[:, 1]) - h_dem))
    dz_map = float(np.mean(nodes[:, 2] - site.height_at(nodes[:, 0], nodes[:, 1])))
    sl = camera.project(pose.to_camera(maplet.center_m))
    P = bilinear_aov(position, float(sl[0]), float(sl[1]))
    return {"dz_lod": dz_lod, "dz_aov": float((P - maplet.center_m) @ n_up), "dz_map": dz_map}


def predicted_errors(camera, pose, centres: np.ndarray, dz: np.ndarray, n_up: np.ndarray) -> np.ndarray:
    """Eq. G1 for landmarks (n, 3) with offsets dz (n,) along n_up ((3,) or one per landmark (n, 3)): (n, 2) px."""
    return camera.project(pose.to_camera(centres + dz[:, None] * n_up)) - camera.project(pose.to_camera(centres))


def probe_geometry(scenario_path: Path, ts_dir: Path, frames: list[int]) -> list[str]:
    """Per image: the mean offsets and the scale eq. G1 predicts from each (module docstring)."""
    from scipy.spatial.transform import Rotation

    from renderlab.contracts.landmark import CameraPose
    from renderlab.files.truthset import TruthSet
    from renderlab.measurement.runner import _frame_record
    from renderlab.scenario import load_scenario
    from renderlab.studies.descent_navigation.run import section
    from renderlab.worlds.ev5 import build_model
    from renderlab.worlds.ev5.catalog import read_catalog

    sc, _ = load_scenario(scenario_path)
    lo, hi = section(sc).gsd_ratio_range
    ts = TruthSet.open(ts_dir)
    cat = read_catalog(ts_dir)
    lod = sc.world.site
    model = build_model(sc.world, scenario_path.parent)
    site, tiled = model.site, model.tiled_site(lod.tile_cells, lod.lod_pixels)
    cen = np.array([m.center_m for m in cat])
    spacing = np.array([m.spacing_m for m in cat])
    out = []
    for k in frames:
        fr = _frame_record(ts, k)
        pose = CameraPose(fr.R, fr.position)
        keys = tiled.select(fr.camera, SimpleNamespace(rotation=Rotation.from_matrix(fr.R), position_m=fr.position))
        xc = pose.to_camera(cen)
        sel = in_view(fr.camera, pose, cen, spacing, lo, hi)
        position = ts.load(k).position
        rows = [landmark_offsets(site, tiled, keys, cat[i], position, fr.camera, pose) for i in sel]
        truth = fr.camera.project(xc[sel])
        cells = [f"levels {tiled.lod_summary(keys)['levels']}", f"{len(sel)} landmarks", f"range {xc[sel, 2].mean():.1f} m"]
        for name in ("dz_lod", "dz_aov", "dz_map"):
            dz = np.array([r[name] for r in rows])
            pred = predicted_errors(fr.camera, pose, cen[sel], np.nan_to_num(dz), site.R_body_from_site[:, 2])
            cells.append(f"{name} mean {dz.mean() * 100:+.2f} cm -> scale {similarity_scale(truth, pred):+.2e}")
        out.append(f"image {k}: " + " | ".join(cells))
    return out


def fresh_maplets(site, tier, count: int, rng: np.random.Generator) -> list:
    """``count`` error-free maplets of ``tier`` (spacing, size, radius) uniform in its disc about the site centre
    (no minimum separation), ids from 10**6 up: frame and centre by :func:`~renderlab.worlds.ev5.landmarks.maplet_frame`,
    heights and albedo by :func:`~renderlab.worlds.ev5.landmarks.cell_means` (albedo normalised to mean 1)."""
    from renderlab.geometry.maplet import Maplet
    from renderlab.worlds.ev5.landmarks import cell_means, maplet_frame

    r = tier.radius_m * np.sqrt(rng.random(count))
    a = 2 * np.pi * rng.random(count)
    out = []
    for k, xy in enumerate(np.column_stack([r * np.cos(a), r * np.sin(a)])):
        centre, R = maplet_frame(site, xy, (tier.size - 1) / 2 * tier.spacing_m)
        h, alb = cell_means(site, centre, R, tier.spacing_m, tier.size)
        out.append(Maplet(10**6 + k, centre, R, float(tier.spacing_m), h, alb / alb.mean()))
    return out


def relief_offset(site, maplet, grad2: np.ndarray, camera, pose) -> float:
    """The DEM's height above the maplet's surface (along maplet +z) at the DEM nodes under the footprint,
    averaged with the weight |∇I|² of the truth image at each node's pixel (what a correlation locks on): the
    effective height δz of eq. G1 that the maplet's smoothing leaves (bright boulder tops above the cell means)."""
    half = maplet.half_width_m
    c = site.to_site(maplet.center_m)
    i0 = int(np.floor((c[0] - 1.5 * half - site.x0_m) / site.cell_m))
    j0 = int(np.floor((c[1] - 1.5 * half - site.x0_m) / site.cell_m))
    m = int(np.ceil(3 * half / site.cell_m)) + 2
    X, Y = np.meshgrid(site.x0_m + (i0 + np.arange(m)) * site.cell_m, site.x0_m + (j0 + np.arange(m)) * site.cell_m)
    P = site.surface_point(X.ravel(), Y.ravel())
    q = (P - maplet.center_m) @ maplet.R_body_from_maplet
    dz = q[:, 2] - maplet.height_at(q[:, 0], q[:, 1])
    sl = camera.project(pose.to_camera(P))
    H, W = grad2.shape
    ok = np.isfinite(dz) & (sl[:, 0] >= 0) & (sl[:, 0] <= W - 1) & (sl[:, 1] >= 0) & (sl[:, 1] <= H - 1)
    i, j = np.minimum(sl[ok, 0].astype(int), W - 2), np.minimum(sl[ok, 1].astype(int), H - 2)
    fx, fy = sl[ok, 0] - i, sl[ok, 1] - j
    w = ((1 - fy) * ((1 - fx) * grad2[j, i] + fx * grad2[j, i + 1])
         + fy * ((1 - fx) * grad2[j + 1, i] + fx * grad2[j + 1, i + 1]))
    return float(np.sum(w * dz[ok]) / np.sum(w)) if np.sum(w) > 0 else float("nan")


def bootstrap_scale(truth: np.ndarray, err: np.ndarray, rng: np.random.Generator, n: int = 1000) -> tuple:
    """(scale, 2.5 %, 97.5 % bootstrap quantiles over landmarks) of ``scale_probe.similarity_scale``."""
    idx = rng.integers(0, len(truth), (n, len(truth)))
    b = np.array([similarity_scale(truth[i], err[i]) for i in idx])
    return similarity_scale(truth, err), float(np.quantile(b, 0.025)), float(np.quantile(b, 0.975))


def _relief_cell(site, maplets, dn, camera, pose, truth) -> str:
    """The mean :func:`relief_offset` of measured landmarks and the scale eq. G1 predicts from it (text)."""
    gy, gx = np.gradient(np.asarray(dn, float))
    dz = np.array([relief_offset(site, m, gx**2 + gy**2, camera, pose) for m in maplets])
    cen = np.array([m.center_m for m in maplets])
    z = np.array([m.R_body_from_maplet[:, 2] for m in maplets])
    pred = predicted_errors(camera, pose, cen, np.nan_to_num(dz), z)
    return f"relief dz {np.nanmean(dz) * 100:+.2f} cm -> G1 scale {similarity_scale(truth, pred):+.2e}"


def probe_fresh(scenario_path: Path, ts_dir: Path, frames: list[int], method: str, tier_name: str,
                count: int, seed: int = 0) -> list[str]:
    """Per image: the scale of ``count`` fresh error-free landmarks of ``tier_name`` at the true pose (module
    docstring), with its bootstrap 95 % interval, beside that of the catalogue's landmarks of the tier."""
    from renderlab.contracts.landmark import CameraPose
    from renderlab.errors import UserError
    from renderlab.files.truthset import TruthSet
    from renderlab.measurement.runner import (
        MeasureOptions,
        _frame_record,
        make_method,
        onboard_photometry,
        run_method_on_image,
    )
    from renderlab.scenario import load_scenario
    from renderlab.worlds.ev5 import build_model
    from renderlab.worlds.ev5.catalog import read_catalog

    sc, _ = load_scenario(scenario_path)
    tiers = {t.name: t for t in sc.world.landmarks}
    name, _, grid = tier_name.partition("@")      # TIER@SPACINGxSIZE: the tier's disc, another maplet grid
    if name not in tiers:
        raise UserError(f"no landmark tier {name!r}; the scenario has {', '.join(tiers)}")
    tier = tiers[name]
    if grid:
        sp, size = grid.split("x")
        tier = tier.model_copy(update={"spacing_m": float(sp), "size": int(size)})
    ts = TruthSet.open(ts_dir)
    rng = np.random.default_rng(seed)
    site = build_model(sc.world, scenario_path.parent).site
    fresh = fresh_maplets(site, tier, count, rng)
    own = [m for m in read_catalog(ts_dir) if m.spacing_m == tiers[name].spacing_m]
    mopts = MeasureOptions(n_sigma=3.0, min_search_px=8, max_search_px=8)
    impl = make_method(method, mopts, onboard_photometry(ts, mopts)[0])
    out = []
    for k in frames:
        fr = _frame_record(ts, k)
        pose = CameraPose(fr.R, fr.position)
        cells = []
        for label, maplets in ((f"{count} fresh", fresh), ("catalogue", own)):
            cen = np.array([m.center_m for m in maplets])
            att, res = run_method_on_image(impl, ts.load(k).dn, fr.adc_max, fr.camera, pose, fr.sun, maplets, cen,
                                           np.eye(3) * 1e-4, np.eye(3) * 1e-10, mopts, k)
            ok = [j for j, r in enumerate(res) if r.has_result]
            truth = fr.camera.project(pose.to_camera(cen[att[ok]]))
            err = np.array([[res[j].meas_s, res[j].meas_l] for j in ok]) - truth
            s, lo, hi = bootstrap_scale(truth, err, rng)
            cells.append(f"{label}: {len(ok)} landmarks, scale {s:+.2e} [{lo:+.2e}, {hi:+.2e}], "
                         f"rms {np.sqrt(np.mean(err**2)):.3f} px")
            if label != "catalogue":
                cells.append(_relief_cell(site, [maplets[a] for a in att[ok]], ts.load(k).dn, fr.camera, pose, truth))
        out.append(f"{method} {tier_name} image {k}: " + " | ".join(cells))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="FRAMES alone: the geometry probe; with METHOD TIER COUNT: the fresh-landmark "
                                        "probe (TIER a tier name, or NAME@SPACINGxSIZE, e.g. regional@0.04x151)")
    ap.add_argument("scenario", metavar="SCENARIO", type=Path, help="the campaign's scenario.toml")
    ap.add_argument("truthset", metavar="TRUTHSET", type=Path, help="the campaign's truth set (its truth cache)")
    ap.add_argument("frames", metavar="FRAMES", help="comma-separated image indices, e.g. 0,3,12")
    ap.add_argument("fresh", nargs="*", metavar="METHOD TIER COUNT", help="the fresh-landmark probe")
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    if len(a.fresh) not in (0, 3):
        ap.error("the fresh-landmark probe takes METHOD TIER COUNT")
    from renderlab.errors import UserError

    try:
        frames = [int(v) for v in a.frames.split(",")]
        lines = (probe_geometry(a.scenario, a.truthset, frames) if not a.fresh else
                 probe_fresh(a.scenario, a.truthset, frames, a.fresh[0], a.fresh[1], int(a.fresh[2])))
        for line in lines:
            print(line, flush=True)
    except (UserError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
