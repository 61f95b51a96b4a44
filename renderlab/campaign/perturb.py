"""Draw and apply the perturbations of one Monte Carlo run.

Each dispersion of :class:`~renderlab.scenario.campaign.PerturbationConfig` has its own random
stream (a fixed-order child of the run's perturbation ``SeedSequence``), so switching one
dispersion on or off never changes the draws of the others. Gaussian draws with a covariance
``P`` use ``x = L z``, ``P = L Lᵀ`` (eigen-factorisation, so a semi-definite ``P`` is allowed).
Small rotations (pointing, Sun direction) are rotation vectors with i.i.d. N(0, σ²) components.
Camera perturbations act on the pixel map of Wright et al. eq. 4: ``fx, fy ← (1+δf)·(fx, fy)``,
``(s0, l0) ← (s0, l0) + δc``, distortion coefficients ``k ← k + δk``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

#: stream order (append only: the index of a stream is its place here)
STREAMS = ("position", "velocity", "attitude", "apriori", "focal", "principal_point", "distortion",
           "spacing", "sun")


def _gauss_cov(rng: np.random.Generator, cov: np.ndarray) -> np.ndarray:
    w, v = np.linalg.eigh(0.5 * (cov + cov.T))
    L = v * np.sqrt(np.clip(w, 0.0, None))
    return L @ rng.standard_normal(len(w))


@dataclass(frozen=True)
class PerturbationDraw:
    """One run's perturbation (all zeros = the nominal scenario)."""

    dposition_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    dvelocity_mps: np.ndarray = field(default_factory=lambda: np.zeros(3))
    attitude_rotvec_rad: np.ndarray = field(default_factory=lambda: np.zeros(3))  # camera frame
    apriori_dposition_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    apriori_dvelocity_mps: np.ndarray = field(default_factory=lambda: np.zeros(3))
    focal_scale: float = 1.0
    dprincipal_point_px: np.ndarray = field(default_factory=lambda: np.zeros(2))
    ddistortion: dict = field(default_factory=dict)
    spacing_scale: float = 1.0
    sun_rotvec_rad: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def to_row(self) -> dict:
        """Flat JSON/Parquet-able record (one row of the run's ``perturbations`` table)."""
        row = {}
        for name, vec, axes in (("dpos", self.dposition_m, "xyz"), ("dvel", self.dvelocity_mps, "xyz"),
                                ("att_rotvec", self.attitude_rotvec_rad, "xyz"),
                                ("apriori_dpos", self.apriori_dposition_m, "xyz"),
                                ("apriori_dvel", self.apriori_dvelocity_mps, "xyz"),
                                ("sun_rotvec", self.sun_rotvec_rad, "xyz"), ("dpp", self.dprincipal_point_px, "sl")):
            for a, v in zip(axes, vec):
                row[f"{name}_{a}"] = float(v)
        row["focal_scale"] = float(self.focal_scale)
        row["spacing_scale"] = float(self.spacing_scale)
        for k, v in sorted(self.ddistortion.items()):
            row[f"ddist_{k}"] = float(v)
        return row


def draw_perturbation(cfg, seed_sequence: np.random.SeedSequence) -> PerturbationDraw:
    """Draw one run's perturbation from ``cfg`` (a PerturbationConfig).

    Parameters
    ----------
    cfg : PerturbationConfig
        The dispersions.
    seed_sequence : numpy.random.SeedSequence
        The run's perturbation seed; its children (one per entry of :data:`STREAMS`, in that order)
        feed independent ``numpy.random.Generator`` streams.
    """
    rngs = {name: np.random.default_rng(ss) for name, ss in zip(STREAMS, seed_sequence.spawn(len(STREAMS)))}
    pos_cov = (np.asarray(cfg.position_cov_m2, float) if cfg.position_cov_m2 is not None
               else np.diag(np.square(cfg.position_sigma_m)))
    if cfg.apriori_cov is not None:
        ap_cov = np.asarray(cfg.apriori_cov, float)
    else:
        ap_cov = np.diag(np.square([*cfg.apriori_position_sigma_m, *cfg.apriori_velocity_sigma_mps]))
    ap = _gauss_cov(rngs["apriori"], ap_cov)
    dist_rng = rngs["distortion"]
    ddist = {k: float(s * dist_rng.standard_normal()) for k, s in sorted(cfg.distortion_sigma.items())}
    return PerturbationDraw(
        dposition_m=_gauss_cov(rngs["position"], pos_cov),
        dvelocity_mps=np.asarray(cfg.velocity_sigma_mps) * rngs["velocity"].standard_normal(3),
        attitude_rotvec_rad=np.radians(cfg.attitude_sigma_deg) * rngs["attitude"].standard_normal(3),
        apriori_dposition_m=ap[:3], apriori_dvelocity_mps=ap[3:],
        focal_scale=float(1.0 + cfg.focal_length_sigma_frac * rngs["focal"].standard_normal()),
        dprincipal_point_px=cfg.principal_point_sigma_px * rngs["principal_point"].standard_normal(2),
        ddistortion=ddist,
        spacing_scale=float(1.0 + cfg.maplet_spacing_sigma_frac * rngs["spacing"].standard_normal()),
        sun_rotvec_rad=np.radians(cfg.sun_direction_sigma_deg) * rngs["sun"].standard_normal(3),
    )


# ------------------------------------------------------------------------------------ applying
def perturb_camera(camera: dict, draw: PerturbationDraw) -> dict:
    """A camera dict (scenario ``camera`` section or manifest camera) with the draw applied.

    Distortion offsets need a model with those coefficients; on a ``pinhole`` camera with a
    non-empty distortion draw the model becomes ``brown``.
    """
    out = dict(camera)
    out["fx"] = float(camera["fx"]) * draw.focal_scale
    out["fy"] = float(camera["fy"]) * draw.focal_scale
    out["cx"] = float(camera["cx"]) + float(draw.dprincipal_point_px[0])
    out["cy"] = float(camera["cy"]) + float(draw.dprincipal_point_px[1])
    if draw.ddistortion:
        dist = dict(camera.get("distortion") or {})
        for k, dv in draw.ddistortion.items():
            dist[k] = float(dist.get(k, 0.0)) + dv
        out["distortion"] = dist
        if out.get("model", "pinhole") == "pinhole":
            out["model"] = "brown"
    return out


def perturb_sun(direction, draw: PerturbationDraw) -> np.ndarray:
    """The unit sun direction rotated by the draw's small rotation."""
    d = np.asarray(direction, float)
    d = Rotation.from_rotvec(draw.sun_rotvec_rad).apply(d / np.linalg.norm(d))
    return d / np.linalg.norm(d)


def perturb_pose(position_m, R_render_from_cam: Rotation, draw: PerturbationDraw) -> tuple[np.ndarray, Rotation]:
    """Truth pose with the draw applied: position offset (render frame) and a pointing error
    ``R ← R · Exp(δθ)`` (δθ in the camera frame)."""
    return (np.asarray(position_m, float) + draw.dposition_m,
            R_render_from_cam * Rotation.from_rotvec(draw.attitude_rotvec_rad))


def perturb_scenario_dict(data: dict, draw: PerturbationDraw) -> dict:
    """Scenario data with the camera, distortion and sun perturbations applied (world-agnostic).

    Trajectory and pose perturbations depend on the world and are applied by the study
    (:func:`perturb_pose` for a camera pose, :attr:`PerturbationDraw.dvelocity_mps` for a state).
    """
    import copy

    out = copy.deepcopy(data)
    out["camera"] = perturb_camera(out.get("camera", {}), draw)
    sun = dict(out.get("sun", {}))
    if "direction" in sun:
        sun["direction"] = [float(v) for v in perturb_sun(sun["direction"], draw)]
    out["sun"] = sun
    return out


def refuse_unused(p, used, message: str) -> None:
    """UserError ``message.format(name=...)`` for the first non-zero key of the ``[perturbations]`` section ``p`` that
    is not in ``used`` (a study refusing a dispersion it does not model)."""
    from renderlab.errors import UserError

    for name, value in p.model_dump().items():
        if name not in used and value is not None and np.any(np.asarray(
                list(value.values()) or [0.0] if isinstance(value, dict) else value, float) != 0):
            raise UserError(message.format(name=name))
