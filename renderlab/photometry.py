"""Photometric laws of airless surfaces: numpy reference implementations.

Convention (the lab's contract)
-------------------------------
Every law returns the *radiance factor per unit solar irradiance* ``r(mu0, mu, g; albedo, params)``
in sr^-1, so that the reflected radiance is ``L = E_sun * r`` where ``E_sun`` (W m^-2) is the solar
irradiance on a surface normal to the sun. ``mu0 = cos(i)`` (incidence), ``mu = cos(e)`` (emission) and
``g`` is the phase angle (rad) between the directions from the surface point to the sun and to the
camera. ``r`` already contains the ``mu0`` foreshortening (it is Hapke's *bidirectional reflectance*;
the BRDF is ``r / mu0``) and is 0 wherever ``mu0 <= 0`` or ``mu <= 0``. ``albedo`` is what an albedo
map modulates; it broadcasts against the angles. All angles are in radians (SI inside).

Laws
----
``lambert``          r = A mu0 / pi.
``lommel_seeliger``  r = (A/pi) * 2 mu0 / (mu0 + mu). Equal to Lambert at mu0 = mu = 1. It is Hapke's
                     single-scattering term w/(4 pi) * mu0/(mu0+mu) with isotropic particles and w = 8A.
``mcewen``           lunar-Lambert law (McEwen 1991, Icarus 92, 298), as used by Retina
                     (Wright et al., eq. 5-8):
                     r = (A/pi) [(1 - beta) mu0 + c beta mu0/(mu0 + mu)],  beta = exp(-g/alpha0)     (5)
                     with cos i = n.s (6), cos e = n.r (7), g = acos(s.r) (8). ``alpha0`` defaults to
                     60 deg (Gaskell's SPC choice); ``ls_weight`` c defaults to 2, McEwen's normalisation
                     that makes the Lommel-Seeliger part equal Lambert at normal incidence and emission;
                     ``ls_weight=1`` is Retina eq. 5 literally (up to the 1/pi).
``hapke``            isotropic-multiple-scattering approximation (IMSA, Hapke 1981, 1984, 1986; 2012 book)
                     r = (w/4pi) mu0e/(mu0e+mue) [(1 + B_SH(g)) p(g) + H(mu0e) H(mue) - 1] S(i, e, g)
                     - ``albedo`` is w, the single-scattering albedo (0 <= w <= 1); porosity factor K = 1.
                     - shadow-hiding opposition effect B_SH(g) = B0 / (1 + tan(g/2)/h).
                     - p(g): single-lobe Henyey-Greenstein in the *phase angle*,
                       p = (1 - xi^2) / (1 + 2 xi cos g + xi^2)^(3/2): xi < 0 is back-scattering (peak at
                       g = 0), xi > 0 forward-scattering. If ``b`` and ``c`` are given, the double-lobed
                       form (Hapke 2012) p = (1+c)/2 (1-b^2)/(1-2b cos g+b^2)^(3/2)
                       + (1-c)/2 (1-b^2)/(1+2b cos g+b^2)^(3/2), 0 <= b < 1, where c > 0 is back-scattering.
                     - H: Hapke's (2002, Icarus 157, 523, eq. 13) approximation of Chandrasekhar's H
                       function, H(x) = 1/(1 - w x [r0 + (1 - 2 r0 x)/2 ln((1+x)/x)]), gamma = sqrt(1-w),
                       r0 = (1-gamma)/(1+gamma); accurate to about 1 % (checked by the tests against a
                       numerical solution of the integral equation).
                     - macroscopic roughness (Hapke 1984, Icarus 59, 41): mean slope theta_bar gives the
                       effective cosines mu0e, mue and the shadowing function S; theta_bar = 0 reduces
                       exactly to the smooth law (mu0e = mu0, mue = mu, S = 1).

Default Hapke parameters (:class:`HapkeParams`) are the fit to the C-type asteroid (253) Mathilde from
NEAR MSI and telescopic data (Clark et al. 1999, Icarus 140, 53-65): w = 0.035, xi = -0.25, h = 0.074,
B0 = 3.18, theta_bar = 19 deg. ``C_TYPE_SINGLE_SCATTERING_ALBEDO`` holds that w.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

import numpy as np

from renderlab.errors import UserError

LAWS = frozenset({"lambert", "lommel_seeliger", "mcewen", "hapke"})
C_TYPE_SINGLE_SCATTERING_ALBEDO = 0.035  # (253) Mathilde, Clark et al. (1999)


def _finite(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise UserError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise UserError(f"{name} must be finite, got {value!r}")
    return v


@dataclass(frozen=True)
class McEwenParams:
    """Parameters of the McEwen (lunar-Lambert) law.

    Attributes
    ----------
    alpha0 : float
        Phase-angle decay constant of beta = exp(-g/alpha0), rad, in (0, pi]. Default 60 deg.
    ls_weight : float
        Weight c of the Lommel-Seeliger term, >= 0. Default 2 (McEwen 1991); 1 is Retina eq. 5.
    """

    alpha0: float = math.radians(60.0)
    ls_weight: float = 2.0

    def __post_init__(self):
        a = _finite("mcewen.alpha0", self.alpha0)
        if not 0.0 < a <= math.pi:
            raise UserError(f"mcewen.alpha0 must be in (0, pi] rad, got {self.alpha0!r} (radians, not degrees)")
        if _finite("mcewen.ls_weight", self.ls_weight) < 0.0:
            raise UserError(f"mcewen.ls_weight must be >= 0, got {self.ls_weight!r}")
        object.__setattr__(self, "alpha0", a)
        object.__setattr__(self, "ls_weight", float(self.ls_weight))


@dataclass(frozen=True)
class HapkeParams:
    """Parameters of the Hapke law (w is the ``albedo`` argument, not a parameter here).

    Defaults: (253) Mathilde, Clark et al. (1999), a C-type asteroid.

    Attributes
    ----------
    b0 : float
        Shadow-hiding opposition amplitude B0 >= 0 (3.18).
    h : float
        Shadow-hiding opposition width h > 0 (0.074).
    theta_bar : float
        Mean macroscopic slope angle, rad, in [0, pi/2) (19 deg).
    xi : float
        Single-lobe Henyey-Greenstein asymmetry in (-1, 1); < 0 back-scattering (-0.25).
    b, c : float or None
        Double-lobe Henyey-Greenstein width 0 <= b < 1 and back-scatter fraction -1 <= c <= 1. Give both to
        use the double-lobed phase function (``xi`` is then unused); leave both None for single-lobe.
    """

    b0: float = 3.18
    h: float = 0.074
    theta_bar: float = math.radians(19.0)
    xi: float = -0.25
    b: float | None = None
    c: float | None = None

    def __post_init__(self):
        checks = {
            "b0": (lambda v: v >= 0.0, ">= 0"),
            "h": (lambda v: v > 0.0, "> 0"),
            "theta_bar": (lambda v: 0.0 <= v < math.pi / 2, "in [0, pi/2) rad (radians, not degrees)"),
            "xi": (lambda v: -1.0 < v < 1.0, "in (-1, 1)"),
            "b": (lambda v: 0.0 <= v < 1.0, "in [0, 1)"),
            "c": (lambda v: -1.0 <= v <= 1.0, "in [-1, 1]"),
        }
        for name, (ok, text) in checks.items():
            raw = getattr(self, name)
            if raw is None and name in ("b", "c"):
                continue
            v = _finite(f"hapke.{name}", raw)
            if not ok(v):
                raise UserError(f"hapke.{name} must be {text}, got {raw!r}")
            object.__setattr__(self, name, v)
        if (self.b is None) != (self.c is None):
            raise UserError("hapke.b and hapke.c must be given together (double-lobed Henyey-Greenstein)")


def _prepare(mu0, mu, g, albedo, law: str, max_albedo: float | None = None):
    mu0, mu, g, albedo = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (mu0, mu, g, albedo)))
    if np.any(albedo < 0.0) or (max_albedo is not None and np.any(albedo > max_albedo)):
        hi = "" if max_albedo is None else f" and <= {max_albedo:g}"
        raise UserError(f"{law}: albedo must be >= 0{hi}, got values in [{albedo.min():g}, {albedo.max():g}]")
    lit = (mu0 > 0.0) & (mu > 0.0)
    return mu0, mu, g, albedo, lit


def lambert(mu0, mu, g, albedo):
    """Lambert law r = A mu0 / pi (sr^-1); 0 where mu0 <= 0 or mu <= 0.

    Parameters
    ----------
    mu0, mu, g, albedo : array_like
        Cosine of incidence, cosine of emission, phase angle (rad) and Lambert albedo A; broadcast.

    Returns
    -------
    numpy.ndarray
        Radiance factor per unit solar irradiance, float64.
    """
    mu0, mu, g, a, lit = _prepare(mu0, mu, g, albedo, "lambert")
    return np.where(lit, a * mu0 / np.pi, 0.0)


def lommel_seeliger(mu0, mu, g, albedo):
    """Lommel-Seeliger law r = (A/pi) 2 mu0/(mu0 + mu) (sr^-1); equals Lambert at mu0 = mu = 1.

    Same as Hapke's single-scattering term w/(4 pi) mu0/(mu0+mu) with w = 8A. Parameters as :func:`lambert`.
    """
    mu0, mu, g, a, lit = _prepare(mu0, mu, g, albedo, "lommel_seeliger")
    den = np.where(lit, mu0 + mu, 1.0)
    return np.where(lit, a / np.pi * 2.0 * mu0 / den, 0.0)


def mcewen(mu0, mu, g, albedo, alpha0: float = math.radians(60.0), ls_weight: float = 2.0):
    """McEwen lunar-Lambert law (Retina eq. 5-8), r = (A/pi)[(1-beta) mu0 + c beta mu0/(mu0+mu)].

    Parameters
    ----------
    mu0, mu, g, albedo : array_like
        As :func:`lambert`.
    alpha0 : float
        beta = exp(-g/alpha0), rad (default 60 deg).
    ls_weight : float
        c, the weight of the Lommel-Seeliger term (default 2; 1 is Retina eq. 5 literally).
    """
    p = McEwenParams(alpha0=alpha0, ls_weight=ls_weight)
    mu0, mu, g, a, lit = _prepare(mu0, mu, g, albedo, "mcewen")
    beta = np.exp(-g / p.alpha0)
    den = np.where(lit, mu0 + mu, 1.0)
    r = a / np.pi * ((1.0 - beta) * mu0 + p.ls_weight * beta * mu0 / den)
    return np.where(lit, r, 0.0)


def chandrasekhar_h_hapke2002(x, w):
    """Hapke's (2002, eq. 13) approximation of Chandrasekhar's isotropic H function, H(x; w)."""
    x, w = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(w, dtype=np.float64))
    gamma = np.sqrt(1.0 - w)
    r0 = (1.0 - gamma) / (1.0 + gamma)
    xs = np.where(x > 0.0, x, 1.0)
    log_term = np.where(x > 0.0, np.log((1.0 + xs) / xs), 0.0)
    return 1.0 / (1.0 - w * x * (r0 + 0.5 * (1.0 - 2.0 * r0 * x) * log_term))


def _phase_function(cos_g, p: HapkeParams):
    if p.b is None:
        xi = p.xi
        return (1.0 - xi * xi) / (1.0 + 2.0 * xi * cos_g + xi * xi) ** 1.5
    b, c = p.b, p.c
    back = (1.0 - b * b) / (1.0 - 2.0 * b * cos_g + b * b) ** 1.5
    fwd = (1.0 - b * b) / (1.0 + 2.0 * b * cos_g + b * b) ** 1.5
    return 0.5 * (1.0 + c) * back + 0.5 * (1.0 - c) * fwd


def _rough_cosines(mu0, mu, g, theta_bar):
    """Hapke (1984) effective cosines mu0e, mue and shadowing S for mean slope theta_bar > 0."""
    tb = math.tan(theta_bar)
    cot_tb = 1.0 / tb
    chi = 1.0 / math.sqrt(1.0 + math.pi * tb * tb)
    sin_i = np.sqrt(np.clip(1.0 - mu0 * mu0, 0.0, 1.0))
    sin_e = np.sqrt(np.clip(1.0 - mu * mu, 0.0, 1.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        sin_prod = sin_i * sin_e
        cos_psi = np.where(sin_prod > 1e-12, (np.cos(g) - mu0 * mu) / np.where(sin_prod > 1e-12, sin_prod, 1.0), 1.0)
        cos_psi = np.clip(cos_psi, -1.0, 1.0)
        psi = np.arccos(cos_psi)
        cot_i = mu0 / sin_i
        cot_e = mu / sin_e
        e1_i, e1_e = np.exp(-2.0 / np.pi * cot_tb * cot_i), np.exp(-2.0 / np.pi * cot_tb * cot_e)
        e2_i, e2_e = np.exp(-cot_tb**2 * cot_i**2 / np.pi), np.exp(-cot_tb**2 * cot_e**2 / np.pi)
        f = np.exp(-2.0 * np.tan(psi / 2.0))
    s2 = np.sin(psi / 2.0) ** 2
    eta_i = chi * (mu0 + sin_i * tb * e2_i / (2.0 - e1_i))
    eta_e = chi * (mu + sin_e * tb * e2_e / (2.0 - e1_e))
    # Case i <= e
    d1 = 2.0 - e1_e - psi / np.pi * e1_i
    mu0e_1 = chi * (mu0 + sin_i * tb * (cos_psi * e2_e + s2 * e2_i) / d1)
    mue_1 = chi * (mu + sin_e * tb * (e2_e - s2 * e2_i) / d1)
    s_1 = mue_1 / eta_e * mu0 / eta_i * chi / (1.0 - f + f * chi * mu0 / eta_i)
    # Case e < i
    d2 = 2.0 - e1_i - psi / np.pi * e1_e
    mu0e_2 = chi * (mu0 + sin_i * tb * (e2_i - s2 * e2_e) / d2)
    mue_2 = chi * (mu + sin_e * tb * (cos_psi * e2_i + s2 * e2_e) / d2)
    s_2 = mue_2 / eta_e * mu0 / eta_i * chi / (1.0 - f + f * chi * mu / eta_e)
    case1 = mu0 >= mu  # i <= e
    return (np.where(case1, mu0e_1, mu0e_2), np.where(case1, mue_1, mue_2), np.where(case1, s_1, s_2))


def hapke(mu0, mu, g, albedo, params: HapkeParams | None = None):
    """Hapke IMSA law with shadow-hiding opposition effect and macroscopic roughness (sr^-1).

    Parameters
    ----------
    mu0, mu, g : array_like
        Cosine of incidence, cosine of emission, phase angle (rad).
    albedo : array_like
        Single-scattering albedo w in [0, 1].
    params : HapkeParams, optional
        Defaults to :class:`HapkeParams` () ((253) Mathilde, Clark et al. 1999).
    """
    p = HapkeParams() if params is None else params
    mu0, mu, g, w, lit = _prepare(mu0, mu, g, albedo, "hapke", max_albedo=1.0)
    m0 = np.where(lit, mu0, 1.0)
    m = np.where(lit, mu, 1.0)
    g = np.clip(g, 0.0, np.pi)
    if p.theta_bar == 0.0:
        mu0e, mue, shadow = m0, m, 1.0
    else:
        mu0e, mue, shadow = _rough_cosines(m0, m, g, p.theta_bar)
    with np.errstate(over="ignore"):
        b_sh = p.b0 / (1.0 + np.tan(g / 2.0) / p.h)
    multiple = chandrasekhar_h_hapke2002(mu0e, w) * chandrasekhar_h_hapke2002(mue, w) - 1.0
    r = w / (4.0 * np.pi) * mu0e / (mu0e + mue) * ((1.0 + b_sh) * _phase_function(np.cos(g), p) + multiple) * shadow
    return np.where(lit, r, 0.0)


_PARAMS = {"lambert": None, "lommel_seeliger": None, "mcewen": McEwenParams, "hapke": HapkeParams}


@dataclass(frozen=True)
class PhotometricLaw:
    """A named photometric law with its parameters (make one with :func:`make_law`)."""

    name: str
    params: McEwenParams | HapkeParams | None = None

    def radiance_factor(self, mu0, mu, g, albedo):
        """Radiance factor per unit solar irradiance r (sr^-1); see the module docstring."""
        if self.name == "lambert":
            return lambert(mu0, mu, g, albedo)
        if self.name == "lommel_seeliger":
            return lommel_seeliger(mu0, mu, g, albedo)
        if self.name == "mcewen":
            return mcewen(mu0, mu, g, albedo, alpha0=self.params.alpha0, ls_weight=self.params.ls_weight)
        return hapke(mu0, mu, g, albedo, self.params)

    def to_dict(self) -> dict:
        """``{"name": ..., **params}``; ``make_law(**law.to_dict())`` rebuilds the law."""
        out = {"name": self.name}
        if self.params is not None:
            out.update({k: v for k, v in asdict(self.params).items() if v is not None})
        return out


def make_law(name: str, **params) -> PhotometricLaw:
    """Build a :class:`PhotometricLaw` by name, validating its parameters.

    Parameters
    ----------
    name : str
        One of ``hapke``, ``lambert``, ``lommel_seeliger``, ``mcewen``.
    **params
        The law's parameters (fields of :class:`McEwenParams` / :class:`HapkeParams`; angles in rad).

    Raises
    ------
    UserError
        Unknown law, unknown parameter or out-of-range value.
    """
    if name not in LAWS:
        raise UserError(f"unknown photometric law {name!r}; expected one of {', '.join(sorted(LAWS))}")
    cls = _PARAMS[name]
    allowed = [] if cls is None else [f.name for f in fields(cls)]
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        expected = ", ".join(allowed) if allowed else "no parameters"
        raise UserError(f"unknown parameter {unknown[0]!r} for photometric law {name!r}; expected {expected}")
    return PhotometricLaw(name, None if cls is None else cls(**params))


def angles_from_vectors(normal, to_sun, to_cam):
    """Cosines of incidence and emission and the phase angle from (N, 3) (or (3,)) vectors.

    Parameters
    ----------
    normal, to_sun, to_cam : array_like
        Surface normal, direction from the surface point to the sun and to the camera. Need not be
        unit length; broadcast against each other.

    Returns
    -------
    mu0, mu, g : numpy.ndarray
        n.s, n.v and the angle between s and v (rad, via atan2 for accuracy near 0 and pi).
    """
    vecs = []
    for label, v in (("normal", normal), ("to_sun", to_sun), ("to_cam", to_cam)):
        a = np.asarray(v, dtype=np.float64)
        if a.shape[-1:] != (3,) or a.ndim > 2:
            raise UserError(f"{label} must have shape (N, 3) or (3,), got {a.shape}")
        norm = np.linalg.norm(a, axis=-1, keepdims=True)
        if np.any(~(norm > 0.0)) or not np.all(np.isfinite(norm)):
            raise UserError(f"{label} contains zero-length or non-finite vectors")
        vecs.append(a / norm)
    n, s, v = np.broadcast_arrays(*vecs)
    mu0 = np.einsum("...k,...k->...", n, s)
    mu = np.einsum("...k,...k->...", n, v)
    g = np.arctan2(np.linalg.norm(np.cross(s, v), axis=-1), np.einsum("...k,...k->...", s, v))
    return mu0, mu, g
