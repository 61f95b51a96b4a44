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

from renderlab.config_types import Finite, NonNegative, Seed, Strict

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

    position_sigma_m: NonNegVec3 = [0.0, 0.0, 0.0]  # truth camera/trajectory position, render frame
    position_cov_m2: Matrix | None = None  # full 3x3 covariance; replaces position_sigma_m
    velocity_sigma_mps: NonNegVec3 = [0.0, 0.0, 0.0]  # truth velocity (worlds with a dynamic state)
    attitude_sigma_deg: NonNegative = 0.0  # truth pointing: rotation vector per camera axis
    apriori_position_sigma_m: NonNegVec3 = [0.0, 0.0, 0.0]  # estimator prior error
    apriori_velocity_sigma_mps: NonNegVec3 = [0.0, 0.0, 0.0]
    apriori_attitude_sigma_deg: NonNegative = 0.0  # estimator prior pointing error, per camera axis
    apriori_cov: Matrix | None = None  # full 6x6 [position m, velocity m/s]; replaces the two above
    focal_length_sigma_frac: Annotated[float, Field(ge=0, lt=0.5, allow_inf_nan=False)] = 0.0
    principal_point_sigma_px: NonNegative = 0.0
    distortion_sigma: dict[str, NonNegative] = {}  # absolute 1σ per coefficient (k1, k2, p1, ...)
    maplet_spacing_sigma_frac: Annotated[float, Field(ge=0, lt=0.5, allow_inf_nan=False)] = 0.0
    sun_direction_sigma_deg: NonNegative = 0.0  # per axis of a small rotation of the sun vector

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

    study: str = ""
    seed: Seed = 0
    target: str = ""
