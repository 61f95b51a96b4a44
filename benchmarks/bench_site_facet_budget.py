"""The site-facet budget (``world.site.facets_per_pixel``): frame time and truth accuracy, side by side in one run.

For each budget (none = today's levels, lod_pixels = 1; then 4, 2, 1 facets per pixel) the same EV5 descent frames
are rendered through ``renderlab.Renderer`` (two-scene Mitsuba path), each frame right after the previous one (the
tile set changes every frame). Per frame: seconds, site facets rendered, the facet limit the budget set
(``lod_pixels_used``), the LOD height-error bound. Accuracy: at ``--pixels`` seeded random site pixels per frame the
range AOV is compared with the float64 ray oracle (:func:`renderlab.render.ray_oracle.centre_ranges`, Möller–Trumbore
in numpy, no Mitsuba) on the *full-resolution* DEM around the hit (a ±``--patch`` m window of the site grid,
triangulated as the DEM), in units of the pixel footprint (GSD = range / fx): what the coarser levels cost in truth.

Usage::

    .venv/bin/python benchmarks/bench_site_facet_budget.py [--frames 4] [--size 1024] [--spp 16] [--pixels 200]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
BUDGETS = (None, 4.0, 2.0, 1.0)


def _patch_oracle(site, p_body: np.ndarray, half_m: float):
    """OracleScene of the full-resolution DEM within ±half_m (site x, y) of body point ``p_body``."""
    from renderlab.photometry import make_law
    from renderlab.render.ray_oracle import oracle_scene
    from renderlab.render.scene import BodySpec, SceneDescription
    from renderlab.worlds.ev5.terrain import rect_faces

    ps = site.to_site(p_body)
    k = int(np.ceil(half_m / site.cell_m))
    c = np.clip(np.round((ps[:2] - site.x0_m) / site.cell_m).astype(int), k, site.n - 1 - k)
    rows, cols = np.arange(c[1] - k, c[1] + k + 1), np.arange(c[0] - k, c[0] + k + 1)
    X, Y = np.meshgrid(site.x0_m + cols * site.cell_m, site.x0_m + rows * site.cell_m)
    V = site.to_body(np.stack([X, Y, site.heights_m[np.ix_(rows, cols)]], -1).reshape(-1, 3))
    body = BodySpec(name="patch", body_id=1, shape="trimesh", center_m=np.zeros(3), R_render_from_body=np.eye(3),
                    law=make_law("lambert"), albedo=1.0, vertices=V, faces=rect_faces(len(rows), len(cols)))
    return oracle_scene(SceneDescription([body]))


def _range_errors(r, frame, n: int, half_m: float, rng) -> np.ndarray:
    """|range AOV − float64 oracle range| / GSD at ``n`` random site pixels of ``frame``."""
    from renderlab.render.ray_oracle import centre_ranges

    ids = frame.aovs.body_id
    line, s = np.nonzero(ids == 1)
    pick = rng.choice(len(s), size=min(n, len(s)), replace=False)
    site = r.plan.model.site
    out = []
    for i in pick:
        p = frame.aovs.position[line[i], s[i]].astype(np.float64)
        sc = _patch_oracle(site, p, half_m)
        t = centre_ranges(sc, frame.spec, np.array([[s[i], line[i]]], float))[0]
        out.append(abs(float(frame.aovs.range_m[line[i], s[i]]) - t) / (t / frame.spec.camera.fx))
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--pixels", type=int, default=200)
    ap.add_argument("--patch", type=float, default=0.6, help="half width of the oracle's DEM window [m]")
    args = ap.parse_args()
    sys.path.insert(0, str(REPO / "benchmarks"))
    from bench_frame_api import _sets

    from renderlab.pipeline.frame_api import Renderer

    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}", flush=True)
    for budget in BUDGETS:
        extra = [] if budget is None else [f"world.site.facets_per_pixel={budget}"]
        r = Renderer(REPO / "scenes" / "ev5_descent.toml", overrides=_sets(args.size, args.spp, args.frames) + extra)
        r.frame(0)  # kernels compiled
        rng = np.random.default_rng(7)
        for k in range(args.frames):
            t0 = time.perf_counter()
            f = r.frame(k)
            dt = time.perf_counter() - t0
            lod = f.meta["ev5"]["lod"]
            err = _range_errors(r, f, args.pixels, args.patch, rng)
            ok = np.isfinite(err)
            q = np.percentile(err[ok], [50, 99]) if ok.any() else [np.nan, np.nan]
            print(f"budget {str(budget):>4} frame {k} ({f.meta['ev5']['altitude_m']:6.0f} m): {dt:5.2f} s, "
                  f"{lod['n_faces'] / 1e6:6.3f} M facets ({lod['n_faces'] / args.size ** 2:5.2f}/px), facet limit "
                  f"{lod.get('lod_pixels_used', lod['lod_pixels']):.2f} px, height bound "
                  f"{lod['max_height_error_m'] * 100:.1f} cm; range error vs float64 oracle (full DEM) at "
                  f"{ok.sum()}/{len(err)} px: median {q[0]:.4f}, p99 {q[1]:.3f} GSD", flush=True)
        r.close()
    print(f"load average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
