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
noise-free as onboard) and runs every step of :data:`STEPS`: each finder of :data:`~.peaks.FINDERS` on the
integer maximum, and the re-centred passes of :mod:`.recentre`. Estimate − true shift is the step's error: its
mean over noise-free cases at many fractions is the pixel-locking curve, its spread over noise draws is compared
with the registration Cramér–Rao bound (the benchmark uses :func:`renderlab.campaign.scoring.registration_crlb`,
independent code, on the noise-free image over the template's footprint).

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

import numpy as np

from estimators.retina.correlation import correlation_surface
from estimators.retina.peaks import FINDERS, locate_peak, shifted_texture

#: the steps compared: every finder of :data:`~.peaks.FINDERS` alone (0 passes), and re-centred
#: (:mod:`.recentre`, 2 passes) on the two 2-D fits: name → (finder, passes)
STEPS = {**{m: (m, 0) for m in FINDERS}, "quadric_2d_rc": ("quadric_2d", 2), "gaussian_2d_rc": ("gaussian_2d", 2)}


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
    from estimators.retina.predict import CameraPoseEstimate, TemplateOptions, project_point, render_template

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


def noise_sigma(case: Case, snr: float) -> float:
    """Pixel noise σ of a given SNR: std of the template over its footprint / SNR."""
    return float(np.std(case.template[case.valid]) / snr)


def estimate(step: str, C, image, case: Case, image_valid=None) -> tuple[float, float]:
    """(Δs, Δl) of one step on the surface C of the case's template in ``image``; NaN on the search border."""
    from estimators.retina.recentre import recentred_shift

    finder, passes = STEPS[step]
    p = locate_peak(C, finder)
    if p is None or p.on_border:
        return np.nan, np.nan
    if passes == 0:
        return p.ds, p.dl
    return recentred_shift(image, case.template, case.valid, case.s0, case.l0, p.ds, p.dl, finder, passes,
                           image_valid, 64)


def estimates(case: Case, steps=tuple(STEPS), snr: float | None = None, rng: np.random.Generator | None = None,
              radius: int = 3) -> dict:
    """``{step: (Δs, Δl)}`` on the case's image, with N(0, :func:`noise_sigma`²) noise from ``rng`` if ``snr``."""
    image = case.image
    if snr is not None:
        image = image + rng.normal(0.0, noise_sigma(case, snr), image.shape)
    C, _ = correlation_surface(image, case.template, case.valid, case.s0, case.l0, radius, case.image_valid)
    return {m: estimate(m, C, image, case, case.image_valid) for m in steps}
