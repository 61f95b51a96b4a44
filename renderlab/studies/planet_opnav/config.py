"""Scenario section ``[planet_opnav]`` of the planet OpNav study. Light: pydantic only.

The grid: every ``ranges_m`` × ``phases_deg`` × ``laws`` is a *cell*; each campaign run renders every cell once (its
own seeds: a Monte Carlo draw of render and sensor noise and of the a-priori position) and measures each image with
every method of ``methods`` (names registered for the ``centre_limb`` kind: the lab's ``centroid_raw``,
``centroid_phase``, ``limb_ellipse``, ``horizon_opnav`` and the Basilisk wrappers ``bsk_hough_circles``,
``bsk_hough_pixel_line``, ``bsk_limb_horizon``). Every method sees the same image and a-priori position.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from renderlab.contracts.config_types import Finite, Positive, RegisteredName, Strict


class PlanetOpNavConfig(Strict):
    """Options of study ``planet_opnav`` (module docstring)."""

    ranges_m: Annotated[list[Positive], Field(min_length=1, max_length=32)] = Field(
        [12.6e6, 18.0e6, 28.0e6, 50.0e6], description="Camera-to-centre ranges of the grid [m]")
    phases_deg: Annotated[list[Annotated[float, Field(ge=0, lt=180, allow_inf_nan=False)]],
                          Field(min_length=1, max_length=64)] = Field(
        [0.0, 20.0, 40.0, 60.0, 80.0, 100.0, 120.0], description="Sun–body–camera phase angles of the grid [deg]")
    laws: Annotated[list[Literal["lambert", "lommel_seeliger", "mcewen", "hapke"]], Field(min_length=1,
                                                                                        max_length=4)] = Field(
        ["lambert", "lommel_seeliger"], description="Photometric laws of the grid (world.law per cell)")
    methods: Annotated[list[RegisteredName], Field(min_length=1, max_length=16)] = Field(
        ["centroid_raw", "centroid_phase", "limb_ellipse", "horizon_opnav", "bsk_hough_circles",
         "bsk_hough_pixel_line", "bsk_limb_horizon"], description="Registered centre_limb method names")
    offset_deg: Annotated[list[Finite], Field(min_length=2, max_length=2)] = Field(
        [2.0, -1.5], description="Where the body centre lies off the boresight (camera x, y angles) [deg]")
    apriori_sigma_frac: Annotated[float, Field(ge=0, le=0.1, allow_inf_nan=False)] = Field(
        0.002, description="1σ a-priori position error per axis, as a fraction of the range [fraction]")
