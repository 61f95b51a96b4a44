"""The closed body of an EV5 world for a polyhedron gravity field (dynamics only; nothing here is rendered).

Why the rendered mesh cannot serve: the world's global mesh is cut under the landing site
(:func:`renderlab.worlds.ev5.site.build_site` removes the global facets inside the patch's zero-taper strip, which
the site DEM covers), so its edges around that hole belong to one face only (18 of 122 838 edges on the tiny test
world, 75 of 490 563 on ``results/descent_gnc``'s world) and the Werner & Scheeres field, whose edge sums need every
edge shared by two faces, refuses it. The uncut procedural body has no seam, pole or duplicated vertex: the
subdivided icosahedron shares every midpoint, so it is a closed, consistently oriented genus-0 surface.

:func:`gravity_mesh` rebuilds that uncut body from the world's seed: the same radius function r(u)
(:class:`~renderlab.worlds.ev5.shape.RadiusFunction`, drawn from the world's ``shape`` stream exactly as the rendered
shape is) pushed onto an icosphere. At the world's own ``facet_m`` its vertices are the rendered global mesh's
before the cut, bit for bit; a larger ``facet_m`` samples the same r(u) on a coarser icosphere (the usual practice
for a polyhedron truth field: the cost of one evaluation grows with the facet count). It differs from what is drawn
only under the site: there the rendered surface is the DEM (the same base surface plus the site's craters, boulders
and regolith detail), which the gravity body omits. A user's shape model (``world.shape_file``) is returned as
read, uncut (it must itself be closed).
"""

from __future__ import annotations

from pathlib import Path

from renderlab.errors import UserError


def gravity_mesh(world, base_dir: Path | str = ".", facet_m: float | None = None):
    """The closed, uncut body of ``world`` for the gravity field (module docstring).

    Parameters
    ----------
    world : EV5World
        A validated EV5 world section.
    base_dir : path
        Directory a relative ``world.shape_file`` is resolved against.
    facet_m : float, optional
        Mean facet edge of the gravity mesh, m; None: the world's ``facet_m`` (the rendered mesh's vertices).

    Returns
    -------
    GlobalShape
        Vertices (m, body frame), faces counter-clockwise seen from outside, ``radius_fn`` r(u) (procedural).
    """
    import numpy as np

    from renderlab.worlds.ev5 import stream
    from renderlab.worlds.ev5.shape import GlobalShape, RadiusFunction, icosphere, level_for_facet, load_shape_file

    if world.shape_file:
        if facet_m is not None:
            raise UserError("gravity mesh: a coarser facet size is offered for the procedural EV5 body only, not for "
                            "world.shape_file (give the coarser model as its own file)")
        return load_shape_file((Path(base_dir) / world.shape_file).resolve(), world.shape_file_units)
    facet = float(world.facet_m if facet_m is None else facet_m)
    if not facet >= world.facet_m:
        raise UserError(f"gravity mesh: facet_m {facet:g} m is finer than the world's ({world.facet_m:g} m); the "
                        f"radius function has no detail below it")
    radius = RadiusFunction(world, stream(world.seed, "shape"))   # the rendered shape's first draws, same order
    u, faces = icosphere(level_for_facet(radius.R, facet))
    vertices = radius.surface_point(u)
    return GlobalShape(vertices, faces, np.ones(len(vertices), np.float32), radius)
