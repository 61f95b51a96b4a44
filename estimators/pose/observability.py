r"""Observability of the stage-1 parameters by the rank of the Fisher information matrix (Ivanov et al. eq. 7).

    F = Σ_k Σ_j (∂ẑ_jk/∂θ)ᵀ R⁻¹ (∂ẑ_jk/∂θ) = JᵀJ   (J: Jacobian of the whitened residuals)

θ is observable when rank F = dim θ. Rank is judged on the singular values of J with unit-norm
columns (so that units do not decide it): a relative singular value below ``tol_unobservable`` is a
direction the measurements cannot see (a null direction of F); below ``tol_weak`` a direction seen only
through tiny effects. Evaluated with the inertia as three log-moments (ln I1, ln I2, ln I3), the
direction (1, 1, 1)/√3 — the absolute inertia scale — is exactly unobservable (eq. 2 depends on ratios
only), while the ratios are observable. Without the range prior the monocular scale direction
(r0 − d, v0, p_j) ∝ (themselves) is observable only through O(n·t) CW terms: weak.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .stage1 import Stage1Problem


@dataclass
class Direction:
    relative_singular_value: float
    vector: np.ndarray            # unit vector in parameter units (θ coordinates)
    names: list[str]

    def dominant(self, k: int = 4) -> list[tuple[str, float]]:
        idx = np.argsort(-np.abs(self.vector))[:k]
        return [(self.names[i], float(self.vector[i])) for i in idx]


@dataclass
class ObservabilityReport:
    names: list[str]
    relative_singular_values: np.ndarray   # descending
    rank: int
    n_params: int
    unobservable: list[Direction]
    weak: list[Direction]

    @property
    def full_rank(self) -> bool:
        return self.rank == self.n_params

    def lines(self) -> list[str]:
        out = [f"FIM rank {self.rank} of {self.n_params} parameters"]
        for tag, dirs in (("unobservable", self.unobservable), ("weakly observable", self.weak[-3:])):
            for d in dirs:
                comp = ", ".join(f"{n} {v:+.2f}" for n, v in d.dominant())
                out.append(f"{tag} (σ/σmax = {d.relative_singular_value:.1e}): {comp}")
        return out


def parameter_names(n_points: int, inertia_mode: str) -> list[str]:
    base = ["r0_x", "r0_y", "r0_z", "v0_x", "v0_y", "v0_z", "phi0_x", "phi0_y", "phi0_z",
            "w0_x", "w0_y", "w0_z"]
    base += ["lnI1", "lnI2", "lnI3"] if inertia_mode == "full" else ["ln(I1/I3)", "ln(I2/I3)"]
    return base + [f"p{j}_{a}" for j in range(n_points) for a in "xyz"]


def fisher_information(problem: Stage1Problem, theta: np.ndarray, inertia_mode: str = "full",
                       prior: bool = True) -> np.ndarray:
    """F = JᵀJ (eq. 7) with the analytic derivatives of the whitened residuals."""
    J = problem.jacobian_analytic(theta, inertia_mode, prior)
    return J.T @ J


def observability(problem: Stage1Problem, theta: np.ndarray, inertia_mode: str = "full", prior: bool = True,
                  tol_unobservable: float = 1e-7, tol_weak: float = 1e-3) -> ObservabilityReport:
    """Rank of the Fisher information (eq. 7) and its (near-)null directions at ``theta``."""
    J = problem.jacobian_analytic(theta, inertia_mode, prior)
    norms = np.linalg.norm(J, axis=0)
    norms = np.where(norms > 0, norms, 1.0)
    _, s, vt = np.linalg.svd(J / norms, full_matrices=False)
    rel = s / s[0]
    names = parameter_names(problem.db.n_points, inertia_mode)
    unobs, weak = [], []
    for k in range(len(s)):
        if rel[k] >= tol_weak:
            continue
        v = vt[k] / norms
        v = v / np.linalg.norm(v)
        v = v * np.sign(v[np.argmax(np.abs(v))])
        (unobs if rel[k] < tol_unobservable else weak).append(Direction(float(rel[k]), v, names))
    return ObservabilityReport(names, rel, int(np.sum(rel >= tol_unobservable)), len(s), unobs, weak)


def with_full_inertia(theta_ratios: np.ndarray, inertia_scale: float = 1.0) -> np.ndarray:
    """θ with (ln(I1/I3), ln(I2/I3)) → (ln I1, ln I2, ln I3) for I3 = ``inertia_scale``."""
    c = np.log(inertia_scale)
    return np.r_[theta_ratios[:12], theta_ratios[12:14] + c, c, theta_ratios[14:]]
