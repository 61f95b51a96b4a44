"""Scenario sections of a Monte Carlo campaign: ``[perturbations]`` and ``[campaign]``.

The perturbations follow the Retina/SPC analysis (Wright et al., "Retina", §"Retina performance"
and Fig. 12): the trajectory / a-priori state, the camera parameters (focal length, principal
point — the pixel map of eq. 4), the distortion coefficients, the landmark resolution (maplet
spacing) and the direction to the Sun. Every dispersion is a 1σ of a zero-mean Gaussian; all
default to 0 (no perturbation). Light: pydantic only.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import Field, model_validator

from renderlab.contracts.config_types import Finite, NonNegative, Seed, Strict

NonNegVec3 = Annotated[list[NonNegative], Field(min_length=3, max_length=3)]
Matrix = list[list[Finite]]


def _check_cov(cov: Matrix | None, n: int, name: str) -> None:
    if cov is None:
        return
    a = np.asarray(cov, float)
    if a.shape != (n, n):
        raise ValueError(f"{name} must be a {n}x{n} matrix, got shape {list(a.shape)}")
    if not np.allclose(a, a.T, rtol=1e-9, atol=1e-15 * max(1.0, float(np.abs(a).max()))):
        raise ValueError(f"{name} must be symmetric")
    if np.linalg.eigvalsh(0.5 * (a + a.T)).min() < -1e-12 * max(1.0, float(np.abs(a).max())):
        raise ValueError(f"{name} must be positive semi-definite")


class PerturbationConfig(Strict):
    """Dispersions of one Monte Carlo run (1σ, zero-mean Gaussian, independent streams).

    *Truth* dispersions change the world that is rendered; *a-priori* dispersions change only what
    the estimator is told (its prior state). Camera, distortion, spacing and sun dispersions change
    the truth while the estimator keeps the nominal scenario values (a calibration/model error).
    """

    position_sigma_m: NonNegVec3 = Field([0.0, 0.0, 0.0], description="Truth camera/trajectory position 1σ per "
                                         "axis, render frame [m]")
    position_cov_m2: Matrix | None = Field(None, description="Full 3x3 truth position covariance; replaces "
                                           "position_sigma_m [m²]")
    velocity_sigma_mps: NonNegVec3 = Field([0.0, 0.0, 0.0], description="Truth velocity 1σ per axis (worlds with a "
                                           "dynamic state) [m/s]")
    attitude_sigma_deg: NonNegative = Field(0.0, description="Truth pointing 1σ: rotation vector per camera axis "
                                            "[deg]")
    apriori_position_sigma_m: NonNegVec3 = Field([0.0, 0.0, 0.0], description="Estimator prior position error 1σ "
                                                 "per axis [m]")
    apriori_velocity_sigma_mps: NonNegVec3 = Field([0.0, 0.0, 0.0], description="Estimator prior velocity error "
                                                   "1σ per axis [m/s]")
    apriori_attitude_sigma_deg: NonNegative = Field(0.0, description="Estimator prior pointing error 1σ, per "
                                                    "camera axis [deg]")
    apriori_cov: Matrix | None = Field(None, description="Full 6x6 prior covariance [position m, velocity m/s]; "
                                       "replaces the two sigmas above [m², m²/s, m²/s²]")
    focal_length_sigma_frac: Annotated[float, Field(ge=0, lt=0.5, allow_inf_nan=False)] = Field(
        0.0, description="Truth focal length 1σ, fraction of fx and fy (calibration error) [fraction]")
    principal_point_sigma_px: NonNegative = Field(0.0, description="Truth principal point 1σ per axis [px]")
    distortion_sigma: dict[str, NonNegative] = Field({}, description="Absolute 1σ per distortion coefficient "
                                                     "(k1, k2, p1, ...) of the truth camera")
    maplet_spacing_sigma_frac: Annotated[float, Field(ge=0, lt=0.5, allow_inf_nan=False)] = Field(
        0.0, description="Landmark resolution 1σ: relative error of the maplet spacing [fraction]")
    sun_direction_sigma_deg: NonNegative = Field(0.0, description="Sun direction 1σ per axis of a small rotation "
                                                 "of the sun vector [deg]")

    @model_validator(mode="after")
    def _covariances(self):
        _check_cov(self.position_cov_m2, 3, "position_cov_m2")
        _check_cov(self.apriori_cov, 6, "apriori_cov")
        return self


class CampaignConfig(Strict):
    """What a campaign runs: the study (a registered name, :data:`renderlab.plugins.studies`; a scenario never
    names a Python module) and the root seed.

    ``study = ""`` picks the default study of the world kind (:data:`renderlab.plugins.DEFAULT_STUDY`).
    ``target`` names the body a study measures where it needs one (``analytic_pointing``: a sphere).
    """

    study: str = Field("", description="Registered study name (renderlab scenes lists them); empty: the world "
                       "kind's default study")
    seed: Seed = Field(0, description="Root seed: run i is seeded by SeedSequence(seed, spawn_key=(i,))")
    target: str = Field("", description="Body the study measures where it needs one (analytic_pointing: a "
                        "sphere's name)")
