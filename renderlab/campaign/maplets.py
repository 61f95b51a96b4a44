"""Onboard map realisations of a campaign run: the EV5 maplet catalogue rebuilt from the site DEM with the run's own
mapping-error and albedo-error draw (what a fresh SPC survey of the same terrain would uplink).

The truth images do not depend on the maplets (they are rendered from the site DEM itself), so a run that only
re-draws its map reuses the cached truth render. The rebuild follows :mod:`renderlab.worlds.ev5.landmarks`
(steps 3–5): the truth heights and albedo averaged over each maplet cell at ``spacing · scale``, plus a Gaussian
height error of rms ``world.mapping_error_m`` correlated over ``world.mapping_error_corr_cells`` cells, and the
relative albedo times (1 + ``world.albedo_error_rms`` · white noise). Same landmark ids, centres and frames.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from renderlab.geometry.maplet import Maplet
from renderlab.worlds.ev5 import build_model
from renderlab.worlds.ev5.config import EV5World
from renderlab.worlds.ev5.landmarks import cell_means, correlated_error


@functools.lru_cache(maxsize=2)
def _site(world_json: str, base_dir: str):
    return build_model(EV5World.model_validate_json(world_json), Path(base_dir)).site


def respaced_maplets(maplets, world, base_dir, scale: float, rng: np.random.Generator) -> list:
    """The catalogue rebuilt at ``spacing·scale`` from the site DEM (same centres/frames, fresh mapping and albedo
    error from ``rng``); ``scale = 1`` is a fresh map realisation at the catalogue's own spacing."""
    site = _site(world.model_dump_json(), str(Path(base_dir).resolve()))
    out = []
    for m in maplets:
        n, sp = m.heights_m.shape[0], m.spacing_m * scale
        h, a = cell_means(site, m.center_m, m.R_body_from_maplet, sp, n)
        h = h + correlated_error(n, world.mapping_error_m, world.mapping_error_corr_cells, rng)
        a = a / a.mean() * (1.0 + world.albedo_error_rms * rng.standard_normal(a.shape))
        out.append(Maplet(m.landmark_id, m.center_m, m.R_body_from_maplet, float(sp), h, a))
    return out
