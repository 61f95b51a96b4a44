"""The landmark error-model contract: what a source of injected landmark-measurement errors gives a geometric flight.

A study that *measures* landmark errors (the error budget, :mod:`renderlab.studies.retina_vs_spc.budget.navigation`)
builds error models; a study that *flies* a filter with geometric measurements
(:mod:`renderlab.studies.descent_navigation.error_flights`) injects them. Neither study imports the other: both speak
this protocol, and a command above both (:mod:`renderlab.commands.navigation_budget`) hands one to the other.

A model names what it describes (``config``, ``method``, ``mapping``: labels copied into the flight's table) and
gives, per image axis (s, l), the mean error μ, the landmark-to-landmark spread of the per-landmark bias σ_b and the
white-noise sd σ_n (px) at the landmarks' depths in the camera (eq. N1 of the flight module:
z = π + μ + σ_b ⊙ β_landmark + σ_n ⊙ ε).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class LandmarkErrorModel(Protocol):
    """Per-axis μ, σ_b, σ_n (px) of landmark measurements as a function of depth."""

    config: str
    method: str
    mapping: str

    def at(self, depth_m: np.ndarray, fx: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(μ, σ_b, σ_n), each (n, 2) px, at depths ``depth_m`` (n,) m for a camera of focal length ``fx`` px."""
        ...
