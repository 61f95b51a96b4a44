"""Scenario section ``[coastline]`` of the coastline-navigation study (Straub & Christian). Light: pydantic only.

The orbit, cadence, field of view and star-tracker noise come from the scenario's ``trajectory`` (kind
``"leo"``: altitude, inclination, RAAN, ω, ν, epoch, ``dt_s``, ``fov_deg``, ``star_tracker_sigma_arcsec``,
``j2``); the initial dispersion (paper: 500 m / 5 mm/s per axis) from ``perturbations.apriori_position_sigma_m``
and ``perturbations.apriori_velocity_sigma_mps`` (ECI axes). This section holds what only the coastline study
needs: the measurement mode, the LOS noise σθ the filter assumes (eq. 18), the matched points per image, the
database spacing, the duration and the image-mode extraction/matching settings.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from renderlab.config_types import NonNegative, Positive, Strict


class CoastlineStudyConfig(Strict):
    """Options of study ``coastline_ekf``.

    ``mode = "geometric"``: LOS to database points in the field of view plus angular noise σθ (the paper's
    simulation, vectorised, no rendering). ``mode = "image"``: every frame of the trajectory is rendered (Earth
    world), coastline pixels are extracted from the sensor image, registered to the onboard database projected
    with the a-priori state, and the matched LOS feed the same EKF.
    """

    mode: Literal["geometric", "image"] = "geometric"
    sigma_theta_mrad: Positive = 0.5               # filter's per-axis LOS σ (eq. 18)
    points_per_image: Annotated[int, Field(ge=1, le=4096)] = 16
    db_spacing_m: Annotated[float, Field(ge=100, allow_inf_nan=False)] = 2000.0  # geometric database thinning
    duration_s: Positive | None = None             # geometric: None = one orbital period; image: trajectory.frames
    process_noise_m2_s3: NonNegative = 0.0          # white-acceleration PSD q of the onboard model
    filter_step_s: Positive = 10.0                  # RK4 step of the onboard propagation
    # image mode
    match_gate_px: Positive = 1.5                   # max distance of an inlier after registration
    search_px: Positive = 40.0                      # max a-priori offset the registration searches
    cloud_rejection: bool = True                    # drop edges next to bright, textured (cloud) pixels
    sensor_noise: bool = True                       # re-expose the cached radiance with this run's noise
    map_error_m: NonNegative | None = None          # None: world.coast_db_error_m; per-run map realisation
    map_error_in_filter: bool = False               # filter models the map error as a shared per-image LOS term
