"""Acceptance figures of the scenario's own world (scenes/ev5_descent.toml), not the tests' tiny one.

    .venv/bin/python investigations/ev5_descent/check_full_world.py [--old-catalog TRUTHSET]

Builds the full world (1 m global facets, 64 m site at 2 cm, 72 landmarks) and writes
``results/ev5_descent/full_world_checks.json`` (``--out``):

* global body: extents vs 420 × 410 × 390 m (±10 %), volume-equivalent diameter vs 400 m;
* site: grid size, boulders, craters, target boulder height above its surroundings;
* maplets: heights − truth heights resampled independently by Mitsuba ray casts along −z of each
  maplet onto the site mesh (k × k rays per maplet cell, averaged), rms per tier and overall,
  vs the configured ``mapping_error_m`` (±10 %);
* ``--old-catalog``: the largest change of the maplet heights against another truth set's catalog of
  the same world (e.g. one made before a change of the truth resampling), and that catalog's rms
  against the same Mitsuba-resampled truth;
* peak resident memory of the world build (and of the whole script).
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
RESULT = REPO / "results" / "ev5_descent"
sys.path.insert(0, str(REPO))


def _peak_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6


def mitsuba_truth_differences(model) -> tuple[dict[int, np.ndarray], list[int]]:
    """{landmark_id: maplet heights − Mitsuba-resampled truth cell means} (see the module docstring; NaN
    for a cell where a ray missed the mesh) and the number of rays that missed, per maplet."""
    from renderlab.render.mitsuba_backend import MitsubaBackend
    from renderlab.render.scene import RenderSettings, SceneDescription

    site_body = model.bodies()[1]
    backend = MitsubaBackend(SceneDescription(bodies=[site_body]), RenderSettings())
    mi = backend.mi
    out, missed = {}, []
    for m in model.maplets:
        k = int(min(8, max(1, round(m.spacing_m / model.site.cell_m))))
        x, y = m.grid_xy()
        sub = ((np.arange(k) + 0.5) / k - 0.5) * m.spacing_m
        U, V = np.broadcast_arrays(x[None, :, None, None] + sub[None, None, None, :],
                                   y[:, None, None, None] + sub[None, None, :, None])
        top = m.to_body(np.stack([U, V, np.full(U.shape, 20.0)], -1)).reshape(-1, 3)
        d = -m.R_body_from_maplet[:, 2]
        ray = mi.Ray3f(mi.Point3f(*[top[:, i].astype(np.float32) for i in range(3)]),
                       mi.Vector3f(*[np.full(len(top), d[i], np.float32) for i in range(3)]))
        si = backend.scene.ray_intersect(ray)
        valid = np.array(si.is_valid(), dtype=bool).reshape(U.shape)
        t = np.where(valid, np.array(si.t, dtype=np.float64).reshape(U.shape), np.nan)
        h_truth = 20.0 - t.mean(axis=(2, 3))  # NaN in a cell where a ray slipped through the mesh
        missed.append(int((~valid).sum()))
        out[m.landmark_id] = m.heights_m - h_truth
    return out, missed


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old-catalog", help="a truth set of the same world whose maplets to compare with")
    ap.add_argument("--out", default=str(RESULT), help="folder of full_world_checks.json (default: %(default)s)")
    args = ap.parse_args()

    from renderlab.scenario import load_scenario
    from renderlab.worlds.ev5 import build_model

    sc, base = load_scenario(REPO / "scenes" / "ev5_descent.toml", [])
    t0 = time.perf_counter()
    model = build_model(sc.world, base)
    t_build = time.perf_counter() - t0
    peak_build = _peak_gb()
    st = model.full_shape_stats
    ext = np.array(st["extents_m"])
    site = model.site
    ring = [site.height_at(3.0 * np.cos(a), 3.0 * np.sin(a)) for a in np.linspace(0, 2 * np.pi, 16, endpoint=False)]
    out = {
        "command": "python investigations/ev5_descent/check_full_world.py"
                   + (f" --old-catalog {args.old_catalog}" if args.old_catalog else ""),
        "world_build_s": round(t_build, 1),
        "peak_rss_after_world_build_gb": round(peak_build, 2),
        "global": {"extents_m": [round(float(v), 2) for v in ext],
                   "extents_vs_radar": [round(float(v), 4) for v in ext / np.array([420.0, 410.0, 390.0]) - 1],
                   "equivalent_diameter_m": round(st["equivalent_diameter_m"], 2), "n_faces": st["n_faces"]},
        "site": {"n": site.n, "cell_m": site.cell_m, "extent_m": site.extent_m, "n_boulders": site.n_boulders,
                 "n_craters": site.n_craters, "target_boulder_m": site.target_diameter_m,
                 "target_top_above_ring_3m_m": round(float(site.height_at(0.0, 0.0) - np.median(ring)), 3)},
    }
    diffs, missed = mitsuba_truth_differences(model)
    tiers = sorted(set(model.tiers.values()))
    rms = {t: float(np.sqrt(np.nanmean(np.concatenate([d.ravel() for i, d in diffs.items() if model.tiers[i] == t]) ** 2)))
           for t in tiers}
    all_rms = float(np.sqrt(np.nanmean(np.concatenate([d.ravel() for d in diffs.values()]) ** 2)))
    n_cells = sum(d.size for d in diffs.values())
    n_nan = sum(int(np.isnan(d).sum()) for d in diffs.values())
    out["maplets"] = {"configured_rms_m": sc.world.mapping_error_m, "n": len(diffs), "cells": n_cells,
                      "cells_skipped_ray_missed": n_nan, "rays_missed": int(sum(missed)),
                      "rms_m": round(all_rms, 5), "rms_vs_configured": round(all_rms / sc.world.mapping_error_m - 1, 4),
                      "rms_m_per_tier": {t: round(v, 5) for t, v in rms.items()}}
    if args.old_catalog:
        from renderlab.worlds.ev5.catalog import read_catalog

        old = {m.landmark_id: m for m in read_catalog(args.old_catalog)}
        change = {t: 0.0 for t in tiers}
        n_changed = 0
        old_d = np.concatenate([(diffs[m.landmark_id] + old[m.landmark_id].heights_m - m.heights_m).ravel()
                                for m in model.maplets])
        for m in model.maplets:
            dh = np.abs(m.heights_m - old[m.landmark_id].heights_m).max()
            change[model.tiers[m.landmark_id]] = max(change[model.tiers[m.landmark_id]], float(dh))
            n_changed += int(dh > 1e-4)
        out["maplets"]["vs_old_catalog"] = {"max_abs_change_m_per_tier": {t: round(v, 4) for t, v in change.items()},
                                            "maplets_changed_over_0.1mm": n_changed,
                                            "old_rms_m": round(float(np.sqrt(np.nanmean(old_d ** 2))), 5)}
    out["peak_rss_gb"] = round(_peak_gb(), 2)
    (Path(args.out) / "full_world_checks.json").write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
