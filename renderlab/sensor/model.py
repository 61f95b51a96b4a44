"""Sensor model: band-integrated radiance image → digital numbers (DN), seeded.

The camera is a monochrome CCD/CMOS with a Gaussian PSF, Poisson shot noise, Gaussian
read noise, a full well, a linear gain, a bias and an N-bit ADC. The steps, for each
pixel, with radiance ``L`` in W m⁻² sr⁻¹ integrated over the camera passband:

1. PSF (optional): ``L' = G_σ * L``, a Gaussian of standard deviation ``σ = psf_sigma_px``
   pixels (``scipy.ndimage.gaussian_filter``, mode ``'nearest'``, so flux away from the
   border is conserved).
2. Mean electrons: ``μ = L' · τ · (π/4) D² · Ω · t · QE / (h c / λ) + i_dark · t``.
   ``(π/4) D²`` is the aperture area and ``Ω`` the solid angle of one pixel, so their
   product is the étendue of one pixel; ``h c / λ`` turns joules into photons at the
   effective wavelength ``λ``.
3. Shot noise: ``n = Poisson(μ)`` — one draw of the *total* mean (signal + dark), exact in distribution
   (inversion below μ = 10, Hörmann's PTRS rejection from 10 up to the cap of 1e15; :mod:`renderlab.sensor.noise`).
4. Read noise: ``e = n + Normal(0, σ_read)`` (Box–Muller on two of the pixel's own draws).
5. Full well: ``e ← min(e, FW)``.
6. Gain: ``DN = round(bias + e / g)``.
7. ADC: ``DN ← clip(DN, 0, 2^bits − 1)``, stored as ``uint16``.

**One focal length.** The focal length is the camera's (``camera.fx``, ``camera.fy`` in pixels): the pixel
solid angle is ``Ω = 1 / (fx fy)`` (:func:`pixel_solid_angle_sr`) and, with the pixel pitch ``p`` (the
square root of a pixel's area), the lens focal length is ``f = p sqrt(fx fy)``. The aperture is given as an
f-number ``N`` (``sensor.f_number``, default 4), ``D = f / N``, so the étendue ``(π/4) D² Ω = (π/4) (p/N)²``
does not depend on the focal length at all: the sensor needs no focal length of its own. A scenario's
``sensor.aperture_diameter_m`` becomes ``N = f / D`` with the camera's ``f`` when the scenario is loaded
(:func:`renderlab.scenario.camera.resolve_optics`), and the former ``sensor.focal_length_m`` is accepted
there only where ``focal_length_m / pixel_pitch_m`` agrees with the camera (0.1 %). Outside a scenario,
:class:`SensorOptions` still takes ``aperture_diameter_m`` with ``focal_length_m`` (``N = f/D``, ``Ω = (p/f)²``).

Random draws are keyed per pixel (``noise_stream = "per_pixel"``, default): every variate of pixel ``i``
(row-major) is a pure function of (frame key, ``i``, draw number) from the counter-based Philox4x64-10
(:mod:`renderlab.sensor.noise`), so radiance images that differ in a few pixels give DN that differ there only.
The 128-bit frame key is two 64-bit draws of the ``numpy.random.Generator`` passed in, so a seed replays an image
bit for bit. ``"sequential"`` keeps the former order bit for bit (``rng.poisson`` over the image, then ``rng.normal``).
:func:`expected_dn` gives the noise-free expectation ``clip(bias + min(μ, FW)/g, 0, 2^bits−1)``
(no rounding) and :func:`exposure_for_peak` the exposure time that puts a high percentile of
``μ`` at a chosen fraction of the full well (auto-exposure).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from numbers import Integral, Real

import numpy as np
from scipy.ndimage import gaussian_filter

from renderlab.errors import UserError

PLANCK_J_S = 6.62607015e-34
"""Planck constant h (exact, SI 2019)."""
SPEED_OF_LIGHT_M_S = 299_792_458.0
"""Speed of light in vacuum c (exact)."""
_MAX_POISSON_MEAN = 1.0e15
"""Means above this are drawn at this value; they are far beyond any allowed full well."""
_MAX_FULL_WELL_E = 1.0e12
_DEFAULT_F_NUMBER = 4.0
"""f/4: the ARRM navigation camera's 25 mm lens with a 6.25 mm aperture."""
_REFERENCE_FOCAL_M = 25.0e-3
"""Focal length at which an f-number is written as ``(π/4) D² (p/f)²``; any value gives ``(π/4) (p/N)²``,
this one keeps the default f/4 bit-identical to the former default lens (D = 6.25 mm, f = 25 mm)."""
_OPTICS_RTOL = 1.0e-3
"""Relative disagreement above which two spellings of the optics (f/p vs the camera, N vs f/D) are refused."""


def _check_real(name: str, value, *, positive: bool = False, nonneg: bool = False,
                upper: float | None = None) -> None:
    if isinstance(value, bool) or not isinstance(value, Real):
        raise UserError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise UserError(f"{name} must be finite, got {value!r}")
    if positive and v <= 0.0:
        raise UserError(f"{name} must be > 0, got {value!r}")
    if nonneg and v < 0.0:
        raise UserError(f"{name} must be >= 0, got {value!r}")
    if upper is not None and v > upper:
        raise UserError(f"{name} must be <= {upper:g}, got {value!r}")


@dataclass(frozen=True)
class SensorOptions:
    """Camera and detector parameters, SI units.

    The defaults look like the ARRM navigation camera's detector: 5.5 µm pixels, 10-bit
    monochrome, f/4 optics (the focal length, hence the field of view, is the camera model's).
    The exposure default puts a surface of albedo 0.1 at 1 AU (L ≈ 22 W m⁻² sr⁻¹) at about half
    the full well; use :func:`exposure_for_peak` for auto-exposure.

    Attributes
    ----------
    aperture_diameter_m : float or None
        Entrance pupil diameter D (m), > 0; needs `focal_length_m` (a scenario's loader turns it
        into `f_number` with the camera's focal length instead).
    focal_length_m : float or None
        Focal length f (m), > 0; only to turn `aperture_diameter_m` into an f-number outside a
        scenario (the pixel solid angle is then ``(p/f)²``).
    pixel_pitch_m : float
        Pixel pitch p (m), > 0: the square root of a pixel's area.
    exposure_s : float
        Exposure (integration) time t (s), > 0.
    quantum_efficiency : float
        Band-averaged quantum efficiency, in (0, 1].
    wavelength_m : float
        Effective wavelength λ used for the photon energy h c / λ (m), > 0.
    optical_transmission : float
        Optics transmission τ, in (0, 1].
    dark_current_e_per_s : float
        Dark current (electrons per second per pixel), >= 0.
    read_noise_e : float
        Read noise standard deviation (electrons), >= 0.
    full_well_e : float
        Full-well capacity (electrons), > 0 and <= 1e12.
    gain_e_per_dn : float
        Conversion gain g (electrons per DN), > 0.
    bias_dn : float
        Bias (offset) added before the ADC (DN), in [0, 2^bits − 1].
    bits : int
        ADC bit depth, 1..16.
    psf_sigma_px : float
        Standard deviation of the Gaussian PSF in pixels; 0 means no blur.
    f_number : float or None
        Focal ratio N = f / D, > 0; None: ``focal_length_m / aperture_diameter_m`` when both are
        given, else 4. Given with both, it must agree with their ratio (0.1 %).
    noise_stream : str
        Order of the random draws: ``"per_pixel"`` (every pixel's draws keyed by the frame and its index; a
        changed radiance pixel changes that pixel's DN only) or ``"sequential"`` (the former single stream,
        bit for bit, to re-make truth sets made with it).
    """

    aperture_diameter_m: float | None = None
    focal_length_m: float | None = None
    pixel_pitch_m: float = 5.5e-6
    exposure_s: float = 2.5e-4
    quantum_efficiency: float = 0.5
    wavelength_m: float = 600.0e-9
    optical_transmission: float = 0.9
    dark_current_e_per_s: float = 20.0
    read_noise_e: float = 15.0
    full_well_e: float = 20000.0
    gain_e_per_dn: float = 20.0
    bias_dn: float = 16.0
    bits: int = 10
    psf_sigma_px: float = 0.0
    f_number: float | None = None
    noise_stream: str = "per_pixel"

    def __post_init__(self) -> None:
        for name in ("aperture_diameter_m", "focal_length_m", "f_number"):
            if getattr(self, name) is not None:
                _check_real(f"sensor.{name}", getattr(self, name), positive=True)
        for name in ("pixel_pitch_m", "exposure_s", "wavelength_m", "gain_e_per_dn"):
            _check_real(f"sensor.{name}", getattr(self, name), positive=True)
        for name in ("quantum_efficiency", "optical_transmission"):
            _check_real(f"sensor.{name}", getattr(self, name), positive=True, upper=1.0)
        for name in ("dark_current_e_per_s", "read_noise_e", "psf_sigma_px"):
            _check_real(f"sensor.{name}", getattr(self, name), nonneg=True)
        _check_real("sensor.full_well_e", self.full_well_e, positive=True, upper=_MAX_FULL_WELL_E)
        if isinstance(self.bits, bool) or not isinstance(self.bits, Integral):
            raise UserError(f"sensor.bits must be an integer, got {self.bits!r}")
        if not 1 <= int(self.bits) <= 16:
            raise UserError(f"sensor.bits must be in 1..16, got {self.bits!r}")
        _check_real("sensor.bias_dn", self.bias_dn, nonneg=True, upper=float(self.adc_max))
        if not isinstance(self.noise_stream, str) or self.noise_stream not in ("per_pixel", "sequential"):
            raise UserError(f"sensor.noise_stream must be 'per_pixel' or 'sequential', got {self.noise_stream!r}")
        self._check_optics()

    def _check_optics(self) -> None:
        d, f, n = self.aperture_diameter_m, self.focal_length_m, self.f_number
        if d is None:
            return
        if f is None:
            raise UserError("sensor.aperture_diameter_m needs a focal length for its f-number: give sensor.f_number "
                            "(in a scenario file the loader takes the focal length from camera.fx, camera.fy)")
        if n is not None and abs(f / d - n) > _OPTICS_RTOL * n:
            raise UserError(f"sensor.f_number = {n:g} disagrees with sensor.focal_length_m / "
                            f"sensor.aperture_diameter_m = {f:g} / {d:g} = {f / d:g}; give one of them")

    @property
    def adc_max(self) -> int:
        """Largest DN the ADC can output, ``2^bits − 1``."""
        return (1 << int(self.bits)) - 1

    @property
    def effective_f_number(self) -> float:
        """Focal ratio N: `f_number`, else ``focal_length_m / aperture_diameter_m``, else 4."""
        if self.f_number is not None:
            return float(self.f_number)
        if self.aperture_diameter_m is not None:
            return float(self.focal_length_m) / float(self.aperture_diameter_m)
        return _DEFAULT_F_NUMBER

    @property
    def etendue_m2_sr(self) -> float:
        """Étendue of one pixel, ``(π/4) D² (p/f)² = (π/4) (p/N)²`` (m² sr).

        With `aperture_diameter_m` (and its `focal_length_m`) those; otherwise ``D = f/N`` at a reference
        ``f`` (it cancels: a pixel's étendue depends on the f-number and the pixel size only).
        """
        if self.aperture_diameter_m is not None:
            diameter, focal = float(self.aperture_diameter_m), float(self.focal_length_m)
        else:
            focal = _REFERENCE_FOCAL_M
            diameter = focal / self.effective_f_number
        area = 0.25 * math.pi * diameter ** 2
        return area * (self.pixel_pitch_m / focal) ** 2

    @property
    def electrons_per_radiance(self) -> float:
        """Signal electrons per unit radiance, ``τ · étendue · t · QE · λ / (h c)``."""
        photon_energy_j = PLANCK_J_S * SPEED_OF_LIGHT_M_S / self.wavelength_m
        return (self.optical_transmission * self.etendue_m2_sr * self.exposure_s
                * self.quantum_efficiency / photon_energy_j)


def pixel_solid_angle_sr(fx: float, fy: float, skew: float = 0.0, skew_yx: float = 0.0) -> float:
    """Solid angle of one pixel on the boresight, ``1 / |fx fy - skew skew_yx|`` (sr), for a camera's pixel map
    ``[[fx, skew], [skew_yx, fy]]`` (px per unit normalized coordinate)."""
    for name, v in (("camera.fx", fx), ("camera.fy", fy), ("camera.skew", skew), ("camera.skew_yx", skew_yx)):
        _check_real(name, v)
    det = abs(float(fx) * float(fy) - float(skew) * float(skew_yx))
    if not det > 0.0:
        raise UserError(f"camera pixel map [[fx, skew], [skew_yx, fy]] is singular (fx*fy - skew*skew_yx = {det!r})")
    return 1.0 / det


@dataclass(frozen=True)
class SensorResult:
    """Output of :func:`expose`.

    Attributes
    ----------
    dn : numpy.ndarray
        Digital numbers, ``uint16``, shape (H, W), values in [0, 2^bits − 1].
    electrons_mean : numpy.ndarray
        Expected electrons per pixel before any noise (after the PSF, dark current included),
        ``float64``, shape (H, W).
    saturated : numpy.ndarray
        ``bool`` (H, W): the noisy charge reached the full well or the ADC hit 2^bits − 1.
    """

    dn: np.ndarray
    electrons_mean: np.ndarray
    saturated: np.ndarray


def _check_options(options) -> SensorOptions:
    if not isinstance(options, SensorOptions):
        raise TypeError(f"options must be SensorOptions, got {type(options).__name__}")
    return options


def blur(radiance: np.ndarray, options: SensorOptions) -> np.ndarray:
    """Validate a radiance image and apply the Gaussian PSF (step 1).

    Parameters
    ----------
    radiance : array_like, shape (H, W)
        Band-integrated radiance, W m⁻² sr⁻¹; finite and non-negative.
    options : SensorOptions
        ``psf_sigma_px`` sets the blur; 0 returns a float64 copy.

    Returns
    -------
    numpy.ndarray
        float64 (H, W) radiance seen by the detector.
    """
    options = _check_options(options)
    img = np.asarray(radiance)
    if img.ndim != 2 or img.size == 0:
        raise UserError(f"radiance must be a non-empty 2-D (H, W) image, got shape {img.shape}")
    if not np.issubdtype(img.dtype, np.number) or np.iscomplexobj(img):
        raise UserError(f"radiance must be a real numeric image, got dtype {img.dtype}")
    img = img.astype(np.float64)
    if np.isnan(img).any():
        raise UserError(f"radiance has {int(np.isnan(img).sum())} NaN pixels")
    if not np.isfinite(img).all():
        raise UserError("radiance has infinite pixels")
    if (img < 0).any():
        raise UserError(f"radiance has negative pixels (min {img.min():g} W m^-2 sr^-1)")
    if options.psf_sigma_px > 0:
        img = gaussian_filter(img, sigma=float(options.psf_sigma_px), mode="nearest")
    return img


def mean_electrons(radiance: np.ndarray, options: SensorOptions) -> np.ndarray:
    """Expected electrons per pixel before noise (steps 1–2).

    ``μ = G_σ * L · τ · (π/4) D² · (p/f)² · t · QE · λ / (h c) + i_dark · t``.

    Parameters
    ----------
    radiance : array_like, shape (H, W)
        Band-integrated radiance, W m⁻² sr⁻¹.
    options : SensorOptions
        Camera parameters.

    Returns
    -------
    numpy.ndarray
        float64 (H, W) mean electrons (signal + dark).
    """
    img = blur(radiance, options)
    return img * options.electrons_per_radiance + options.dark_current_e_per_s * options.exposure_s


def expose(radiance: np.ndarray, options: SensorOptions, rng) -> SensorResult:
    """Simulate one exposure: radiance → DN with shot and read noise (steps 1–7).

    Parameters
    ----------
    radiance : array_like, shape (H, W)
        Band-integrated radiance, W m⁻² sr⁻¹; finite and non-negative.
    options : SensorOptions
        Camera parameters.
    rng : numpy.random.Generator, numpy.random.SeedSequence or int
        Every draw's source (a SeedSequence or int: ``default_rng(rng)``): per pixel, the frame key
        ``rng.integers(0, 2**64, size=2, dtype=uint64)``; sequential, ``rng.poisson`` then ``rng.normal``.

    Returns
    -------
    SensorResult
        ``dn`` (uint16), ``electrons_mean`` (float64), ``saturated`` (bool).
    """
    from renderlab.sensor.noise import draw_electrons  # numba: compiled on first use

    mu = mean_electrons(radiance, options)
    electrons = draw_electrons(np.minimum(mu, _MAX_POISSON_MEAN), options.read_noise_e, options.noise_stream, rng)
    full = electrons >= options.full_well_e
    electrons = np.minimum(electrons, float(options.full_well_e))
    dn = np.rint(float(options.bias_dn) + electrons / float(options.gain_e_per_dn))
    dn = np.clip(dn, 0, options.adc_max)
    saturated = full | (dn >= options.adc_max)
    return SensorResult(dn=dn.astype(np.uint16), electrons_mean=mu, saturated=saturated)


def expected_dn(radiance: np.ndarray, options: SensorOptions) -> np.ndarray:
    """Noise-free expected DN, ``clip(bias + min(μ, FW) / g, 0, 2^bits − 1)``, unrounded.

    Exact for the mean of :func:`expose` away from the full well and the ADC limits (where
    clipping of the noise distribution makes the mean slightly smaller); rounding to
    integers adds no bias once the noise is larger than about 0.5 DN.

    Parameters
    ----------
    radiance : array_like, shape (H, W)
        Band-integrated radiance, W m⁻² sr⁻¹.
    options : SensorOptions
        Camera parameters.

    Returns
    -------
    numpy.ndarray
        float64 (H, W) expected DN.
    """
    mu = np.minimum(mean_electrons(radiance, options), float(options.full_well_e))
    return np.clip(float(options.bias_dn) + mu / float(options.gain_e_per_dn), 0.0,
                   float(options.adc_max))


def exposure_for_peak(radiance: np.ndarray, options: SensorOptions, fraction: float = 0.8,
                      percentile: float = 99.9) -> float:
    """Exposure time putting a high percentile of the mean charge at a fraction of full well.

    The mean charge is linear in t: ``μ(t) = t · (k L' + i_dark)`` with ``k`` the electrons
    per unit radiance per second, so ``t = fraction · FW / P(k L' + i_dark)`` where ``P`` is
    the ``percentile``-th percentile over the image (after the PSF).

    Parameters
    ----------
    radiance : array_like, shape (H, W)
        Band-integrated radiance, W m⁻² sr⁻¹.
    options : SensorOptions
        Camera parameters; ``exposure_s`` is ignored.
    fraction : float, optional
        Target fraction of the full well, in (0, 1]. Default 0.8.
    percentile : float, optional
        Percentile of the image that is put at the target, in (0, 100]. Default 99.9.

    Returns
    -------
    float
        Exposure time in seconds; use ``dataclasses.replace(options, exposure_s=t)``.
    """
    _check_real("exposure_for_peak fraction", fraction, positive=True, upper=1.0)
    _check_real("exposure_for_peak percentile", percentile, positive=True, upper=100.0)
    rate = mean_electrons(radiance, options) / options.exposure_s  # electrons per second
    peak = float(np.percentile(rate, float(percentile)))
    if not peak > 0.0:
        raise UserError("cannot choose an exposure: the image is dark (no signal at the "
                        f"{percentile:g}th percentile and no dark current)")
    return float(fraction) * float(options.full_well_e) / peak


def with_exposure(options: SensorOptions, exposure_s: float) -> SensorOptions:
    """Return a copy of ``options`` with ``exposure_s`` replaced (validated)."""
    return dataclasses.replace(options, exposure_s=exposure_s)
