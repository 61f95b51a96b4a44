r"""Measuring sub-pixel peak steps: pixel-locking bias over known fractional shifts and noise over SNR (the
kernel of ``benchmarks/bench_retina_peak_step.py``; numpy + Retina's own eq. 9 correlation and tracer).

Description
-----------
A :class:`Case` is one registration with a known answer: a noise-free image (and its valid mask), a template
(and its footprint) placed at (s0, l0) at zero shift, and the true shift (Δs, Δl) of the image content
relative to the template. Two kinds:

* :func:`texture_case` — a band-limited random texture (periodic, Gaussian spectrum of σ px) moved by an exact
  Fourier shift; the template is the unmoved texture's central window (the locking benchmark's texture, with
  its real context around the window, so there is no edge to ring).
* :func:`rendered_case` — Retina's own prediction (:func:`~.predict.render_template`) of a maplet at the true
  pose, pasted into an empty image (valid only on its footprint), and the template Retina predicts from an
  a-priori camera translated parallel to the image plane so that the predicted centre is off by the wanted
  shift (eqs. 1–4 give the realised one). This is what Retina meets: the template is re-rendered, not
  resampled.

:func:`estimates` correlates the template with the image (eq. 9, search radius ``radius``) plus Gaussian pixel
noise of σ = std(template over its footprint) / SNR (:func:`noise_sigma`; the template, the prediction, stays
noise-free as onboard) and runs every step of :data:`STEPS`: each finder of :data:`~estimators.landmarks.peaks.FINDERS` on the
integer maximum, the re-centred passes of :mod:`.recentre` and the maximum-likelihood shift of :mod:`.ml_shift`.
Estimate − true shift is the step's error: its mean over noise-free cases at many fractions is the pixel-locking
curve, its spread over noise draws is compared with a Cramér–Rao bound.

Which bound: on a texture case every image pixel is observed and the registration CRLB of
:func:`renderlab.campaign.scoring.registration_crlb` (finite-difference gradients of the noise-free image) is
the bound. A rendered case's image is zero and masked outside the maplet's footprint; finite differences across
that border count the step from terrain to the masked zeros as signal, which no estimator can use (the pixels
beyond it are not observed): on the benchmark's EV5 templates that bound is 2–4× too small (measured by
``benchmarks/bench_retina_peak_step.py``).
:func:`rendered_crlb` is the Fisher information of the rendered model itself (ML-3 of :mod:`.ml_shift`):
the derivative of every observed pixel with respect to the shift from templates re-rendered at ±``h_px``
(finely supersampled, so the pixel integral is smooth in the shift), gain and offset as nuisance parameters.
Tuning
------
``radius`` (search distance, px; 3 = a 7 × 7 surface); the shifts, SNRs and noise draws are the caller's.

Use
---
::

    from estimators.retina.peak_step import STEPS, estimates, texture_case
    case = texture_case(1.2, (0.3, 0.15), seed=0)
    err = {m: np.subtract(e, case.shift) for m, e in estimates(case).items()}     # px, per step
    noisy = estimates(case, snr=20.0, rng=np.random.default_rng(1))

References
----------
C. A. Wright et al., "Relative Terrain Imaging Navigation (RETINA) Tool for the Asteroid Redirect Robotic Mission
(ARRM)", NASA GSFC, 2016 (eqs. 1–4 projection, eq. 9 correlation, "Peak Finding": the 3×3 linear-interpolation
step). J. P. Lewis, "Fast normalized cross-correlation", Vision Interface 1995 (eq. 9's sums).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from estimators.landmarks.correlation import correlation_surface
from estimators.landmarks.peaks import FINDERS, locate_peak, shifted_texture
from estimators.landmarks.pose import CameraPoseEstimate, project_point
from estimators.retina.ml_shift import REFINEMENTS
from estimators.retina.predict import TemplateOptions, render_template
from estimators.retina.recentre import recentred_shift


class Step(NamedTuple):
    """A peak step: the finder of :data:`~estimators.landmarks.peaks.FINDERS`, re-centred passes (:mod:`.recentre`) after it, and a
    refinement of :data:`~.ml_shift.REFINEMENTS` after those ("" = none)."""

    finder: str
    passes: int = 0
    refine: str = ""


#: the steps compared: every finder of :data:`~estimators.landmarks.peaks.FINDERS` alone (0 passes), re-centred (:mod:`.recentre`,
#: 2 passes) on the two 2-D fits, and the maximum-likelihood shift (:mod:`.ml_shift`) from ``gaussian_2d``
STEPS = {**{m: Step(m) for m in FINDERS}, "quadric_2d_rc": Step("quadric_2d", 2), "gaussian_2d_rc": Step("gaussian_2d", 2),
         "ml_shift": Step("gaussian_2d", 0, "ml_shift")}


@dataclass(frozen=True)
class Case:
    """One registration with a known answer (module docstring); ``shift`` = (Δs, Δl) px."""

    image: np.ndarray
    image_valid: np.ndarray | None
    template: np.ndarray
    valid: np.ndarray
    s0: int
    l0: int
    shift: tuple


def texture_case(sigma_px: float, shift_sl, seed: int, size: int = 96, tpl: int = 48) -> Case:
    """A band-limited texture (σ = ``sigma_px``, seeded) moved by ``shift_sl``; template = the central window."""
    base, moved = shifted_texture((size, size), shift_sl, sigma_px, np.random.default_rng(seed))
    s0 = (size - tpl) // 2
    return Case(moved, None, base[s0:s0 + tpl, s0:s0 + tpl], np.ones((tpl, tpl), bool), s0, s0,
                (float(shift_sl[0]), float(shift_sl[1])))


def rendered_case(mesh, camera, true_pose, sun_body, shift_sl, template_options=None) -> Case | None:
    """Retina's rendering of ``mesh`` at ``true_pose`` and its prediction from an a-priori camera translated so
    the prediction is off by ≈ ``shift_sl`` (module docstring); None if either template cannot be made."""
    opts = template_options or TemplateOptions()
    truth_tpl = render_template(mesh, camera, true_pose, sun_body, opts)
    if truth_tpl is None:
        return None
    img = np.zeros((camera.height, camera.width))
    ok = np.zeros(img.shape, bool)
    h, w = truth_tpl.image.shape
    if truth_tpl.s0 < 0 or truth_tpl.l0 < 0 or truth_tpl.s0 + w > camera.width or truth_tpl.l0 + h > camera.height:
        return None
    img[truth_tpl.l0:truth_tpl.l0 + h, truth_tpl.s0:truth_tpl.s0 + w] = truth_tpl.image
    ok[truth_tpl.l0:truth_tpl.l0 + h, truth_tpl.s0:truth_tpl.s0 + w] = truth_tpl.valid
    c = mesh.maplet.center_m
    truth = project_point(camera, true_pose, c)
    R, p0 = true_pose.R_body_from_cam, np.asarray(true_pose.position_m, float)
    step = 1e-4 * float(np.linalg.norm(p0 - c))  # translation along the camera x and y axes, body frame
    J = np.column_stack([(project_point(camera, CameraPoseEstimate(R, p0 + step * R[:, i]), c) - truth) / step
                         for i in (0, 1)])
    dxy = np.linalg.solve(J, -np.asarray(shift_sl, float))  # prediction ≈ truth − shift
    ap = CameraPoseEstimate(R, p0 + R[:, :2] @ dxy)
    tpl = render_template(mesh, camera, ap, sun_body, opts)
    if tpl is None:
        return None
    d = truth - project_point(camera, ap, c)
    return Case(img, ok, tpl.image, tpl.valid, tpl.s0, tpl.l0, (float(d[0]), float(d[1])))


def _pasted(case: Case, shape) -> tuple[np.ndarray, np.ndarray]:
    img, ok = np.zeros(shape), np.zeros(shape, bool)
    h, w = case.template.shape
    img[case.l0:case.l0 + h, case.s0:case.s0 + w] = case.template
    ok[case.l0:case.l0 + h, case.s0:case.s0 + w] = case.valid
    return img, ok


def rendered_crlb(mesh, camera, true_pose, sun_body, shift_sl, sigma: float, h_px: float = 0.1,
                  supersample: int = 9) -> tuple[float, float]:
    """Cramér–Rao bound (1σ, px) of (Δs, Δl) for the rendered case of ``shift_sl`` in white noise of σ ``sigma``:
    the Fisher information (ML-3 of :mod:`.ml_shift`) with each observed pixel's derivative from the
    prediction re-rendered at ``shift_sl`` ± ``h_px`` on each axis (``supersample``² rays per pixel, so the pixel
    values are smooth in the shift), over the image's footprint where all four renders are valid; gain and
    offset as nuisance parameters (module docstring). ``(inf, inf)`` when a render fails or J is singular."""
    base = rendered_case(mesh, camera, true_pose, sun_body, (0.0, 0.0))
    if base is None:
        return float("inf"), float("inf")
    opts = TemplateOptions(supersample=int(supersample))
    ok = base.image_valid.copy()
    grads = []
    for ax in (0, 1):
        pair = []
        for sgn in (1.0, -1.0):
            sh = np.array(shift_sl, float)
            sh[ax] += sgn * h_px
            c = rendered_case(mesh, camera, true_pose, sun_body, tuple(sh), opts)
            if c is None:
                return float("inf"), float("inf")
            img, v = _pasted(c, base.image.shape)
            pair.append((img, c.shift[ax]))
            ok &= v
        grads.append((pair[0][0] - pair[1][0]) / (pair[0][1] - pair[1][1]))
    J = np.column_stack([grads[0][ok], grads[1][ok], base.image[ok], np.ones(int(ok.sum()))])
    info = J.T @ J / float(sigma) ** 2
    if np.linalg.cond(info) > 1e14:
        return float("inf"), float("inf")
    cov = np.linalg.inv(info)
    return float(np.sqrt(cov[0, 0])), float(np.sqrt(cov[1, 1]))


def noise_sigma(case: Case, snr: float) -> float:
    """Pixel noise σ of a given SNR: std of the template over its footprint / SNR."""
    return float(np.std(case.template[case.valid]) / snr)


def estimate(step: str, C, image, case: Case, image_valid=None) -> tuple[float, float]:
    """(Δs, Δl) of one step on the surface C of the case's template in ``image``; NaN on the search border."""

    finder, passes, refine = STEPS[step]
    p = locate_peak(C, finder)
    if p is None or p.on_border:
        return np.nan, np.nan
    ds, dl = p.ds, p.dl
    if passes:
        ds, dl = recentred_shift(image, case.template, case.valid, case.s0, case.l0, ds, dl, finder, passes,
                                 image_valid, 64)
    if refine:
        ds, dl = REFINEMENTS[refine](image, case.template, case.valid, case.s0, case.l0, ds, dl, image_valid, 64)
    return ds, dl


def estimates(case: Case, steps=tuple(STEPS), snr: float | None = None, rng: np.random.Generator | None = None,
              radius: int = 3) -> dict:
    """``{step: (Δs, Δl)}`` on the case's image, with N(0, :func:`noise_sigma`²) noise from ``rng`` if ``snr``."""
    image = case.image
    if snr is not None:
        image = image + rng.normal(0.0, noise_sigma(case, snr), image.shape)
    C, _ = correlation_surface(image, case.template, case.valid, case.s0, case.l0, radius, case.image_valid)
    return {m: estimate(m, C, image, case, case.image_valid) for m in steps}
