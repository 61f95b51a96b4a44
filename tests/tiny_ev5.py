"""The tiny EV5 world the landmark-study tests render (test helper, not part of renderlab): 4 m global facets, a
30 m site at 5 cm cells, two tiers of 8 maplets of 15 x 15 points. Each test adds its own name, trajectory, camera
and study sections around it: ``TINY = f'name = "..."\n{TINY_EV5_WORLD}[trajectory] ...'``."""

TINY_EV5_WORLD = """[world]
kind = "ev5"
seed = 5
facet_m = 4.0
[world.site]
extent_m = 30.0
cell_m = 0.05
taper_m = 1.0
crater_max_m = 3.0
boulder_min_m = 0.3
[[world.landmarks]]
name = "regional"
count = 8
spacing_m = 0.2
size = 15
radius_m = 6.0
[[world.landmarks]]
name = "site"
count = 8
spacing_m = 0.1
size = 15
radius_m = 2.5
"""

#: the tiny EV5 world as a scenario dict (4 m facets, a 30 m site at 5 cm cells, two tiers of 10 maplets of 21 × 21)
TINY_WORLD = {
    "kind": "ev5", "seed": 11, "facet_m": 4.0,
    "site": {"extent_m": 30.0, "cell_m": 0.05, "taper_m": 1.0, "crater_max_m": 3.0, "boulder_min_m": 0.3},
    "landmarks": [{"name": "regional", "count": 10, "spacing_m": 0.2, "size": 21, "radius_m": 5.5},
                  {"name": "site", "count": 10, "spacing_m": 0.1, "size": 21, "radius_m": 2.5}],
}


def tiled_descent(name: str, site_keys: str, altitudes_m: list[float]) -> str:
    """A tiny tiled EV5 descent scenario (96² pinhole, 4 spp, seed 3): ``site_keys`` are added to ``[world.site]``."""
    return f'name = "{name}"\n' + TINY_EV5_WORLD.replace("[world.site]\n", f"[world.site]\n{site_keys}", 1) + f"""
[trajectory]
kind = "ev5_descent"
altitudes_m = {altitudes_m}
[camera]
width = 96
height = 96
fx = 460.0
fy = 460.0
cx = 47.5
cy = 47.5
[render]
spp = 4
seed = 3
near_clip_m = 0.01
"""


def render_with_tile_design(tmp_path, scenario: str, design: str):
    """(backend, the static scene as first loaded, frames, plan) of ``scenario`` rendered by Mitsuba with
    ``MitsubaBackend.tile_design = design`` (frame k seeded 11 + k)."""
    from renderlab.pipeline import make_backend
    from renderlab.render.mitsuba_backend import tile_design
    from renderlab.scenario import load_scenario
    from renderlab.worlds.base import make_plan

    path = tmp_path / "tiled_descent.toml"
    path.write_text(scenario)
    sc, base = load_scenario(path, [])
    plan = make_plan(sc, base)
    with tile_design(design):
        backend = make_backend(sc, plan.static_scene, "mitsuba")
        static = backend.scene
        frames = [backend.render(spec, seed=11 + k) for k, spec in enumerate(plan.frames)]
    return backend, static, frames, plan
