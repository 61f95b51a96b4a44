"""Scenario section ``[coastline]`` of the coastline-navigation study (Straub & Christian); pydantic only. The orbit,
cadence, FOV and star tracker come from ``trajectory`` (kind ``"leo"``), the initial dispersion from
``perturbations.apriori_*`` (docs/coastline_ekf.md).
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import Field

from renderlab.contracts.config_types import NonNegative, Positive, Strict
from renderlab.errors import UserError


class CoastlineStudyConfig(Strict):
    """Options of study ``coastline_ekf``.

    ``mode = "geometric"``: the paper's simulation (LOS to database points plus σθ noise, no rendering); ``"image"``:
    rendered frames, extracted and registered coastline, the matched LOS into the same EKF."""

    mode: Literal["geometric", "image"] = Field("geometric", description="geometric: LOS to database points plus "
                                                "angular noise (no rendering); image: rendered frames, extracted "
                                                "coastline")
    sigma_theta_mrad: Positive = Field(0.5, description="Filter's per-axis LOS σ (eq. 18) [mrad]")
    points_per_image: Annotated[int, Field(ge=1, le=4096)] = Field(16, description="Matched points per image")
    db_spacing_m: Annotated[float, Field(ge=100, allow_inf_nan=False)] = Field(
        2000.0, description="Geometric database thinning: spacing of the database points [m]")
    duration_s: Positive | None = Field(None, description="geometric: run length (None = one orbital period); "
                                        "image: trajectory.frames [s]")
    process_noise_m2_s3: NonNegative = Field(0.0, description="White-acceleration PSD q of the onboard model "
                                             "[m²/s³]")
    filter_step_s: Positive = Field(10.0, description="RK4 step of the onboard propagation [s]")
    # image mode
    match_gate_px: Positive = Field(1.5, description="image: max distance of an inlier after registration [px]")
    search_px: Positive = Field(40.0, description="image: max a-priori offset the registration searches [px]")
    cloud_rejection: bool = Field(True, description="image: drop edges next to bright, textured (cloud) pixels")
    sensor_noise: bool = Field(True, description="image: re-expose the cached radiance with this run's noise")
    map_error_m: NonNegative | None = Field(None, description="image: per-run map realisation 1σ (None: "
                                            "world.coast_db_error_m) [m]")
    map_error_in_filter: bool = Field(False, description="image: the filter models the map error as a shared "
                                      "per-image LOS term")


SUPPORTED_PERTURBATIONS = ("apriori_position_sigma_m", "apriori_velocity_sigma_mps")


def check_perturbations(p) -> None:
    """Refuse perturbations the coastline study does not model (one line naming the key)."""
    from renderlab.campaign.perturb import refuse_unused

    refuse_unused(p, SUPPORTED_PERTURBATIONS, "study coastline_ekf does not model perturbations.{name}; the initial "
                  "dispersion is perturbations.apriori_position_sigma_m / apriori_velocity_sigma_mps (ECI, per axis)")
    pos, vel = np.asarray(p.apriori_position_sigma_m, float), np.asarray(p.apriori_velocity_sigma_mps, float)
    if np.any(pos <= 0) or np.any(vel <= 0):
        raise UserError("study coastline_ekf needs perturbations.apriori_position_sigma_m and "
                        "apriori_velocity_sigma_mps > 0 on every axis (the filter's P0; paper: 500 m, 0.005 m/s)")
