r"""Landmark map-error states of the descent filter: augmentation, measurement Jacobian, marginalisation.

The onboard map (SPC maplets) puts landmark i at :math:`\hat{\mathbf p}_i`; the true centre is
:math:`\mathbf p_i = \hat{\mathbf p}_i + \delta\mathbf p_i` with :math:`\delta\mathbf p_i \sim N(0, C_i)`, the map's
declared accuracy (body frame, m²). The error is constant for a landmark — the same maplet error in every image —
so a filter with white pixel noise averages it down and becomes over-confident; here each landmark in view carries
its error as three states (the *absolute*-position error of the landmark, body frame):

.. math::

    \mathbf x_a = [\mathbf r, \mathbf v, \delta\mathbf p_{j_1}, \ldots, \delta\mathbf p_{j_m}],\qquad
    \mathbf h_i = \pi\big(T^T(\hat{\mathbf p}_i + \delta\mathbf p_i - \mathbf r)\big),\qquad
    \frac{\partial\mathbf h_i}{\partial\delta\mathbf p_i} = J_\pi T^T = -\frac{\partial\mathbf h_i}{\partial\mathbf r}
    \quad (L1)

(eq. M1 of :mod:`.measurements` with the map error added). A landmark measured for the first time is *augmented*
with :math:`\hat{\delta\mathbf p} = 0` and covariance :math:`C_i`, uncorrelated with the rest (L2: the map error is
independent of the navigation error before the landmark is first used); its states are *marginalised* — rows and
columns deleted, which is exact for a Gaussian — once it has been absent from ``keep_updates`` consecutive updates
(L3). Between updates the map errors are constant: :math:`\Phi_a = \mathrm{blkdiag}(\Phi, I)`, no process noise
(L4). Mode ``"estimate"`` updates every state (the standard augmented-state EKF, as in visual-inertial
landmark-based navigation, e.g. Mourikis et al., "Vision-Aided Inertial Navigation for Spacecraft Entry, Descent,
and Landing", IEEE Trans. Robotics 25(2), 2009, whose mapped-landmark errors are, like here, part of the
measurement model); mode ``"consider"`` is the Schmidt–Kalman filter: the map states' gain rows are zero, so
their estimate stays 0 while their covariance and cross-covariance with the navigation state are carried
(Schmidt, "Application of state-space methods to navigation problems", Advances in Control Systems 3, 1966;
the Joseph form U3 holds for any gain). A landmark re-measured after its states were marginalised is augmented
anew (L2 again): this forgets what the filter had learnt about it and its correlation with the state, so keep
``keep_updates`` above the longest gap in a landmark's track (the descent's gaps are ≤ 2 images).
"""

from __future__ import annotations

import numpy as np

from renderlab.errors import UserError

MODES = ("off", "estimate", "consider")


class MapStates:
    """Slot table of the landmarks whose map error is in the state: ids, last update each was measured at."""

    def __init__(self, keep_updates: int):
        self.keep = int(keep_updates)
        self.ids: list[int] = []
        self.seen: list[int] = []
        self.count = 0              # updates so far
        self.reaugmented = 0        # landmarks augmented again after a marginalisation
        self._dropped: set[int] = set()

    def reset(self) -> None:
        self.__init__(self.keep)

    def slots(self, ids) -> np.ndarray:
        """Slot index of each id (−1: not in the state)."""
        where = {lid: j for j, lid in enumerate(self.ids)}
        return np.array([where.get(int(i), -1) for i in ids], int)

    def augment(self, x: np.ndarray, P: np.ndarray, ids, covs) -> tuple[np.ndarray, np.ndarray]:
        """x, P with the new landmarks of ``ids`` appended (eq. L2): zero error, covariance ``covs[i]``."""
        new = [i for i, s in enumerate(self.slots(ids)) if s < 0]
        if not new:
            return x, P
        n, m = len(x), 3 * len(new)
        Pa = np.zeros((n + m, n + m))
        Pa[:n, :n] = P
        for j, i in enumerate(new):
            Pa[n + 3 * j:n + 3 * j + 3, n + 3 * j:n + 3 * j + 3] = covs[i]
            lid = int(ids[i])
            self.reaugmented += lid in self._dropped
            self.ids.append(lid)
            self.seen.append(self.count)
        return np.concatenate([x, np.zeros(m)]), Pa

    def remove(self, x: np.ndarray, P: np.ndarray, drop: list[int], forget: bool = False):
        """x, P without the slots ``drop`` (marginalisation, eq. L3); ``forget``: slots augmented in this update and
        not used (nothing learnt, so a later augmentation is exact and not counted as a re-augmentation)."""
        if not drop:
            return x, P
        keep_rows = np.ones(len(x), bool)
        for j in drop:
            keep_rows[6 + 3 * j:9 + 3 * j] = False
            if forget:
                self.reaugmented -= self.ids[j] in self._dropped
            else:
                self._dropped.add(self.ids[j])
        self.ids = [v for j, v in enumerate(self.ids) if j not in drop]
        self.seen = [v for j, v in enumerate(self.seen) if j not in drop]
        return x[keep_rows], P[np.ix_(keep_rows, keep_rows)]

    def end_update(self, used_ids) -> list[int]:
        """Mark the landmarks of ``used_ids`` measured in this update, close the update and return the slots absent
        from the last ``keep`` updates (to marginalise, eq. L3)."""
        for j in self.slots(used_ids):
            if j >= 0:
                self.seen[j] = self.count
        self.count += 1
        return [j for j, s in enumerate(self.seen) if self.count - 1 - s >= self.keep]


def landmark_context(context: dict, k: int, who: str) -> tuple[np.ndarray, np.ndarray]:
    """(ids (k,), covariances (k, 3, 3)) from ``context["landmark_ids"]`` / ``context["landmark_cov_m2"]``."""
    for key in ("landmark_ids", "landmark_cov_m2"):
        if key not in context:
            raise UserError(f"{who}: map states need context key {key!r} (one entry per landmark)")
    ids = np.asarray(context["landmark_ids"]).reshape(-1)
    covs = np.asarray(context["landmark_cov_m2"], float)
    if ids.shape != (k,) or covs.shape != (k, 3, 3) or not np.all(np.isfinite(covs)):
        raise UserError(f"{who}: landmark_ids must be ({k},) and landmark_cov_m2 a finite ({k}, 3, 3) array, got "
                        f"{ids.shape} and {covs.shape}")
    if len(set(ids.tolist())) != k:
        raise UserError(f"{who}: landmark_ids must be unique within one measurement")
    if np.any(np.linalg.eigvalsh(0.5 * (covs + covs.transpose(0, 2, 1)))[:, 0] <= 0):
        raise UserError(f"{who}: every landmark_cov_m2 must be symmetric positive definite")
    return ids, covs


def map_jacobian(H: np.ndarray, slots: np.ndarray, n_state: int) -> np.ndarray:
    """The augmented H (rows of H, n_state columns): H's navigation columns and +J Tᵀ = −∂h/∂r in each landmark's
    map-error columns (eq. L1)."""
    Ha = np.zeros((H.shape[0], n_state))
    Ha[:, :6] = H
    for i, j in enumerate(slots):
        Ha[2 * i:2 * i + 2, 6 + 3 * j:9 + 3 * j] = -H[2 * i:2 * i + 2, :3]
    return Ha
