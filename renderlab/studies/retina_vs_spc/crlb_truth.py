"""The registration CRLB of a landmark on the continuous truth, over exactly the estimator's pixels.

The bound (:func:`renderlab.campaign.crlb.continuous_crlb`, eqs. 1–7 there) needs the scene finer than the
pixels: texture near and above the pixel Nyquist frequency is aliased in the truth image, so its pixels alone
(finite differences of sampled pixels, :func:`renderlab.campaign.scoring.registration_crlb`) miss gradient energy
the estimators can use and the bound comes out too large. Here the truth is rendered again at k × k sub-pixels per
pixel (:func:`fine_truth_dict`: the camera's pixel grid subdivided, the same world and tile levels) and the bound
is taken over the pixels the landmark methods correlate: Retina's template at the true pose
(:func:`maplet_footprint`, the ``valid`` pixels of :func:`estimators.retina.render_template`; the NCC baseline and
the ML shift read the same template, SPC the image resampled over the same maplet), instead of the square window
of half-size ½·(maplet size − 1)/GSD ratio that the finite-difference bound used.

Which bound a table carries: the published ``crlb_s``/``crlb_l`` columns (``results/retina_vs_spc*``,
``results/error_budget``) are the finite-difference window bound; ``investigations/error_budget/crlb_continuous.py``
measures this bound on the error budget's truth and the restatement factor between the two.
"""

from __future__ import annotations

import copy
import math

import numpy as np

from renderlab.campaign.crlb import ContinuousCrlb, continuous_crlb

#: pixels kept around the footprint in the crop the Fourier derivatives are taken on
MARGIN_PX = 6
#: sub-pixels per pixel (each axis) and samples per sub-pixel of the campaigns' fine truth render: one 32-spp render's
#: bound is within 0.994–1.005 (p5–p95) of the cross-product of two (``investigations/error_budget/crlb_continuous.md``)
FINE_K, FINE_SPP = 4, 32


def fine_truth_dict(truth: dict, k: int = FINE_K, spp: int | None = FINE_SPP) -> dict:
    """A truth scenario's dict rendered at k × k sub-pixels per pixel: width/height and fx/fy × k, the principal
    point on the same spot ((c + ½)·k − ½), the site's tile levels unchanged (``lod_pixels`` × k), ``spp`` samples
    per sub-pixel (None: the scenario's)."""
    d = copy.deepcopy(truth)
    if spp is not None:
        d["render"]["spp"] = int(spp)
    cam = d["camera"]
    if cam.get("distortion") or cam.get("model", "pinhole") != "pinhole" or cam.get("skew") or cam.get("skew_yx"):
        raise ValueError("fine_truth_dict needs an undistorted pinhole camera")
    for a in ("width", "height"):
        cam[a] = int(cam[a]) * int(k)
    for a in ("fx", "fy"):
        cam[a] = float(cam[a]) * k
    for a in ("cx", "cy"):
        cam[a] = (float(cam[a]) + 0.5) * k - 0.5
    site = d.get("world", {}).get("site")
    if isinstance(site, dict):
        site["lod_pixels"] = float(site.get("lod_pixels", 1.0)) * k
    return d


def maplet_footprint(record: dict, maplet, L_table: tuple, supersample: int = 3):
    """The pixels Retina's template of ``maplet`` covers at the frame's true pose, inside the image (what the
    estimators read) → (l0, s0, valid (h, w)), or None where no template can be made or none of it is inside."""
    from estimators.retina import CameraPoseEstimate, TemplateOptions, build_mesh, render_template
    from renderlab.geometry.camera import CameraModel
    from renderlab.geometry.rotations import rotation_from_quat_xyzw

    R = rotation_from_quat_xyzw(record["pose"]["quat_render_from_cam_xyzw"], "pose").as_matrix()
    sun = np.asarray(record["sun"]["direction_render"], float)
    cam = CameraModel.from_dict(record["camera"])
    tpl = render_template(build_mesh(maplet), cam, CameraPoseEstimate(R, np.asarray(record["pose"]["position_m"], float)),
                          sun / np.linalg.norm(sun), TemplateOptions(supersample=supersample, L_table=tuple(L_table)))
    if tpl is None:
        return None
    h, w = tpl.valid.shape
    r0, c0 = max(-tpl.l0, 0), max(-tpl.s0, 0)
    r1, c1 = min(h, cam.height - tpl.l0), min(w, cam.width - tpl.s0)
    if r1 <= r0 or c1 <= c0:
        return None
    return int(tpl.l0 + r0), int(tpl.s0 + c0), np.asarray(tpl.valid, bool)[r0:r1, c0:c1]


def footprint_bound(fine_dn: np.ndarray, k: int, variance: np.ndarray, footprint, *, margin: int = MARGIN_PX,
                    nuisances: tuple[str, ...] = (), independent: np.ndarray | None = None) -> ContinuousCrlb | None:
    """:func:`renderlab.campaign.crlb.continuous_crlb` of a frame's fine expected DN (k·H × k·W) over a footprint
    of :func:`maplet_footprint`, on a crop of ``margin`` pixels around it (clipped to the image)."""
    if footprint is None:
        return None
    l0, s0, valid = footprint
    H, W = variance.shape
    h, w = valid.shape
    r0, r1 = max(l0 - margin, 0), min(l0 + h + margin, H)
    c0, c1 = max(s0 - margin, 0), min(s0 + w + margin, W)
    mask = np.zeros((r1 - r0, c1 - c0), bool)
    mask[l0 - r0:l0 - r0 + h, s0 - c0:s0 - c0 + w] = valid
    if mask.sum() < 8:
        return None
    fsl = (slice(r0 * k, r1 * k), slice(c0 * k, c1 * k))
    return continuous_crlb(fine_dn[fsl], k, variance[r0:r1, c0:c1], mask, nuisances=nuisances,
                           independent=None if independent is None else independent[fsl])


def sigma_or_nan(res: ContinuousCrlb | None) -> tuple[float, float]:
    """(σ_s, σ_l) of a bound, NaN where there is none."""
    return (math.nan, math.nan) if res is None else res.sigma
