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
