"""Earth world: WGS-84, GSHHG land/water, real sun, LEO nadir camera, one local ENU tile per frame.

``make_plan(scenario, base_dir)`` returns an :class:`EarthPlan`. Modules: :mod:`.wgs84` (ellipsoid, ENU,
Earth rotation), :mod:`.sun` (Almanac ephemeris), :mod:`.gshhg` (polygons + STRtree, cached),
:mod:`.footprint` (exact footprints, paper eq. 1), :mod:`.tiles` (tile meshes and albedo raster),
:mod:`.clouds`, :mod:`.coastline_truth`, :mod:`.coast_db`, :mod:`.visibility` (paper Fig. 4).
"""

from __future__ import annotations


def check_installed(scenario=None) -> None:
    """A one-line UserError naming the 'earth' extra when shapely or roaring-landmask is not installed (the plan
    and the coastline study call it before anything is made)."""
    from renderlab.extras import require

    require("shapely", "earth", load=False)
    require("roaring_landmask", "earth", load=False)


def make_plan(scenario, base_dir):
    check_installed()
    from renderlab.worlds.earth.plan import EarthPlan

    return EarthPlan.from_scenario(scenario, base_dir)
