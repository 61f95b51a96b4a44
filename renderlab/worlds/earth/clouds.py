r"""A procedural, seeded cloud field on the globe with a settable cover fraction.

Theory
------
A random-phase sum of J plane waves :math:`f(\mathbf x) = \sqrt{2/J}\sum_j \cos(\mathbf k_j\cdot\mathbf x + \phi_j)`
with isotropic wave vectors (|k| drawn log-uniformly between 1/L_max and 1/L_min) is, by the central limit
theorem, close to a zero-mean unit-variance Gaussian random field on the sphere, smooth at scale L_min.
Thresholding it at :math:`\Phi^{-1}(1-c)` makes a cloud mask covering a fraction ≈ c of the globe (about two
thirds of Earth is cloudy at any time: c = 0.67). The field lives in ECEF and is static; the same function
feeds the visibility study (is a coast point under cloud?) and the rendered cloud layer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtri


@dataclass(frozen=True)
class CloudField:
    cover_fraction: float
    seed: int = 0
    scale_min_m: float = 20e3
    scale_max_m: float = 800e3
    n_waves: int = 256

    def _waves(self):
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, 0xC10D]))
        d = rng.normal(size=(self.n_waves, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        k = np.exp(rng.uniform(np.log(1 / self.scale_max_m), np.log(1 / self.scale_min_m), self.n_waves))
        return d * k[:, None], rng.uniform(0, 2 * np.pi, self.n_waves)

    def value(self, p_ecef: np.ndarray) -> np.ndarray:
        """Field value (≈ N(0, 1)) at ECEF points (…, 3)."""
        kv, ph = self._waves()
        p = np.asarray(p_ecef, float)
        flat = p.reshape(-1, 3)
        out = np.empty(len(flat))
        for a in range(0, len(flat), 65536):  # bounded memory
            out[a:a + 65536] = np.cos(flat[a:a + 65536] @ kv.T + ph).sum(1)
        return (out * np.sqrt(2.0 / self.n_waves)).reshape(p.shape[:-1])

    def cloudy(self, p_ecef: np.ndarray) -> np.ndarray:
        """True where a point (…, 3) ECEF lies under cloud."""
        if self.cover_fraction <= 0:
            return np.zeros(np.shape(p_ecef)[:-1], bool)
        if self.cover_fraction >= 1:
            return np.ones(np.shape(p_ecef)[:-1], bool)
        return self.value(p_ecef) > ndtri(1.0 - self.cover_fraction)
