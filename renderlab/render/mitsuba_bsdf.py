"""Mitsuba 3 BSDF plugins for the lab's photometric laws: ``rl_lambert``, ``rl_lommel_seeliger``,
``rl_mcewen`` and ``rl_hapke``.

Each plugin evaluates the same radiance factor per unit solar irradiance r(mu0, mu, g) as
:mod:`renderlab.photometry` (see that module for the theory, equations and sources), written again
here in Dr.Jit so that the tests can catch a mistake in either implementation.

Mapping to Mitsuba
------------------
Mitsuba's ``BSDF.eval(ctx, si, wo)`` returns f(wi, wo) * cos(theta_o), the BRDF with the cosine
foreshortening of ``wo``. In a camera path ``si.wi`` points to the camera and ``wo`` to the light, so
with mu = cos(theta_i), mu0 = cos(theta_o) (local frame: z along the shading normal) and g the angle
between ``si.wi`` and ``wo``::

    eval = r(mu0=cos(theta_o), mu=cos(theta_i), g)

and a ``directional`` emitter of irradiance E gives the pixel radiance E * eval, i.e. L = E_sun * r. The
laws are reciprocal (r/mu0 is symmetric in mu0 <-> mu), so light tracing and multi-bounce path tracing
see the same BRDF. ``sample`` draws cosine-weighted directions (pdf = cos(theta_o)/pi) and returns
weight = eval / pdf. Flags: DiffuseReflection | FrontSide; below either horizon eval, pdf and weight are 0.

Properties (``mi.load_dict``)
-----------------------------
``albedo``   float or nested texture (e.g. ``{'type': 'bitmap', ...}``); A, or w for ``rl_hapke``.
``rl_mcewen``: ``alpha0`` (rad, 60 deg), ``ls_weight`` (2).
``rl_hapke``:  ``b0``, ``h``, ``theta_bar`` (rad), ``xi``, optional ``b`` and ``c`` (double-lobed HG);
               defaults as :class:`renderlab.photometry.HapkeParams`.

Call :func:`register_bsdfs` after :func:`renderlab.render.variant.init_mitsuba`.
"""

from __future__ import annotations

import math
import sys
from numbers import Real

import numpy as np

from renderlab.errors import UserError
from renderlab.photometry import HapkeParams, McEwenParams, PhotometricLaw

PLUGINS = ("rl_lambert", "rl_lommel_seeliger", "rl_mcewen", "rl_hapke")
_registered: set[str] = set()


def _build_classes(mi, dr):
    """Define the plugin classes for the active variant (they must subclass that variant's mi.BSDF)."""
    flag_diffuse = mi.BSDFFlags.DiffuseReflection

    class _RLBase(mi.BSDF):
        law = ""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            if "albedo" not in props:
                raise UserError(f"{self.law} BSDF: property 'albedo' is required")
            self.m_albedo = props.get_texture("albedo")
            flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
            self.m_components = [flags]
            self.m_flags = flags

        # --- law-specific radiance factor; mu0 = cos(to sun), mu = cos(to camera) ---
        def radiance_factor(self, albedo, mu0, mu, wi, wo):  # pragma: no cover - abstract
            raise NotImplementedError

        def _value(self, si, wo, active):
            mu = mi.Frame3f.cos_theta(si.wi)
            mu0 = mi.Frame3f.cos_theta(wo)
            active = active & (mu > 0.0) & (mu0 > 0.0)
            albedo = self.m_albedo.eval(si, active)
            # Keep the math finite on inactive lanes (they are discarded by the select).
            mu_s = dr.select(active, mu, 1.0)
            mu0_s = dr.select(active, mu0, 1.0)
            value = self.radiance_factor(albedo, mu0_s, mu_s, si.wi, wo)
            return dr.select(active, value, 0.0), active

        def eval(self, ctx, si, wo, active=True):
            if not ctx.is_enabled(flag_diffuse):
                return mi.Spectrum(0.0)
            return self._value(si, wo, active)[0]

        def pdf(self, ctx, si, wo, active=True):
            if not ctx.is_enabled(flag_diffuse):
                return mi.Float(0.0)
            mu = mi.Frame3f.cos_theta(si.wi)
            pdf = mi.warp.square_to_cosine_hemisphere_pdf(wo)
            return dr.select(active & (mu > 0.0) & (mi.Frame3f.cos_theta(wo) > 0.0), pdf, 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            bs = dr.zeros(mi.BSDFSample3f)
            if not ctx.is_enabled(flag_diffuse):
                return bs, mi.Spectrum(0.0)
            bs.wo = mi.warp.square_to_cosine_hemisphere(sample2)
            bs.pdf = mi.warp.square_to_cosine_hemisphere_pdf(bs.wo)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+flag_diffuse)
            bs.sampled_component = mi.UInt32(0)
            value, ok = self._value(si, bs.wo, active)
            ok = ok & (bs.pdf > 0.0)
            weight = dr.select(ok, value / dr.select(ok, bs.pdf, 1.0), 0.0)
            bs.pdf = dr.select(ok, bs.pdf, 0.0)
            return bs, weight

        def eval_diffuse_reflectance(self, si, active=True):
            return self.m_albedo.eval(si, active)

        def traverse(self, callback):
            callback.put("albedo", self.m_albedo, mi.ParamFlags.Differentiable)

        def parameters_changed(self, keys):
            pass

        def to_string(self):
            return f"{type(self).__name__}[albedo={self.m_albedo}]"

    class RLLambert(_RLBase):
        law = "rl_lambert"

        def radiance_factor(self, albedo, mu0, mu, wi, wo):
            return albedo * (mu0 * (1.0 / math.pi))

    class RLLommelSeeliger(_RLBase):
        law = "rl_lommel_seeliger"

        def radiance_factor(self, albedo, mu0, mu, wi, wo):
            return albedo * ((2.0 / math.pi) * mu0 / (mu0 + mu))

    def _phase(wi, wo):
        """Phase angle between the camera and sun directions (atan2 form, accurate near 0)."""
        return dr.atan2(dr.norm(dr.cross(wi, wo)), dr.dot(wi, wo))

    class RLMcEwen(_RLBase):
        law = "rl_mcewen"

        def __init__(self, props):
            super().__init__(props)
            p = McEwenParams(
                alpha0=props.get("alpha0", math.radians(60.0)), ls_weight=props.get("ls_weight", 2.0)
            )
            self.alpha0, self.ls_weight = p.alpha0, p.ls_weight

        def radiance_factor(self, albedo, mu0, mu, wi, wo):
            beta = dr.exp(_phase(wi, wo) * (-1.0 / self.alpha0))
            lam = (1.0 - beta) * mu0
            ls = self.ls_weight * beta * mu0 / (mu0 + mu)
            return albedo * ((lam + ls) * (1.0 / math.pi))

        def to_string(self):
            return f"RLMcEwen[albedo={self.m_albedo}, alpha0={self.alpha0}, ls_weight={self.ls_weight}]"

    class RLHapke(_RLBase):
        law = "rl_hapke"

        def __init__(self, props):
            super().__init__(props)
            d = HapkeParams()
            kw = {k: props.get(k, getattr(d, k)) for k in ("b0", "h", "theta_bar", "xi")}
            for k in ("b", "c"):
                if k in props:
                    kw[k] = props.get(k)
            self.p = HapkeParams(**kw)

        def _h_function(self, x, w):
            # Hapke (2002) eq. 13, evaluated independently of renderlab.photometry.
            gam = dr.sqrt(dr.maximum(1.0 - w, 0.0))
            r0 = (1.0 - gam) / (1.0 + gam)
            x = dr.maximum(x, 1e-7)
            inner = r0 + (0.5 - r0 * x) * dr.log((1.0 + x) / x)
            return dr.rcp(1.0 - w * x * inner)

        def _phase_function(self, cos_g):
            p = self.p
            if p.b is None:
                k = p.xi
                return (1.0 - k * k) / dr.power(1.0 + 2.0 * k * cos_g + k * k, 1.5)
            b, c = p.b, p.c
            lobe_back = (1.0 - b * b) / dr.power(1.0 + b * b - 2.0 * b * cos_g, 1.5)
            lobe_fwd = (1.0 - b * b) / dr.power(1.0 + b * b + 2.0 * b * cos_g, 1.5)
            return (0.5 + 0.5 * c) * lobe_back + (0.5 - 0.5 * c) * lobe_fwd

        def _roughness(self, mu0, mu, wi, wo):
            """Hapke (1984) effective cosines and shadowing S, from local-frame vectors."""
            tb = math.tan(self.p.theta_bar)
            k1, k2 = 2.0 / (math.pi * tb), 1.0 / (math.pi * tb * tb)
            chi = 1.0 / math.sqrt(1.0 + math.pi * tb * tb)
            sin_i = dr.sqrt(wo.x * wo.x + wo.y * wo.y)  # sun side: incidence
            sin_e = dr.sqrt(wi.x * wi.x + wi.y * wi.y)  # camera side: emission
            cot_i = mu0 / sin_i
            cot_e = mu / sin_e
            e1i, e1e = dr.exp(-k1 * cot_i), dr.exp(-k1 * cot_e)
            e2i, e2e = dr.exp(-k2 * cot_i * cot_i), dr.exp(-k2 * cot_e * cot_e)
            # Azimuth between the incidence and emission planes, in [0, pi].
            cz = wo.x * wi.y - wo.y * wi.x
            psi = dr.atan2(dr.abs(cz), wo.x * wi.x + wo.y * wi.y)
            cpsi = dr.cos(psi)
            half_sin2 = 0.5 * (1.0 - cpsi)  # sin^2(psi/2)
            # f(psi) -> 0 as psi -> pi; at psi = float32(pi) (sun and camera azimuths exactly opposite)
            # tan(psi/2) is huge and negative (f = inf, S = NaN): below 3.1415 f is already exp(-21600) = 0
            fpsi = dr.select(psi < 3.1415, dr.exp(-2.0 * dr.tan(0.5 * psi)), 0.0)
            frac = psi * (1.0 / math.pi)
            eta_i = chi * (mu0 + sin_i * tb * e2i / (2.0 - e1i))
            eta_e = chi * (mu + sin_e * tb * e2e / (2.0 - e1e))
            inc_first = mu0 >= mu  # i <= e
            den = dr.select(inc_first, 2.0 - e1e - frac * e1i, 2.0 - e1i - frac * e1e)
            num_i = dr.select(inc_first, cpsi * e2e + half_sin2 * e2i, e2i - half_sin2 * e2e)
            num_e = dr.select(inc_first, e2e - half_sin2 * e2i, cpsi * e2i + half_sin2 * e2e)
            mu0e = chi * (mu0 + sin_i * tb * num_i / den)
            mue = chi * (mu + sin_e * tb * num_e / den)
            last = dr.select(inc_first, mu0 / eta_i, mu / eta_e)
            shadow = (mue / eta_e) * (mu0 / eta_i) * chi / (1.0 - fpsi + fpsi * chi * last)
            return mu0e, mue, shadow

        def radiance_factor(self, albedo, mu0, mu, wi, wo):
            p = self.p
            w = albedo
            g = _phase(wi, wo)
            if p.theta_bar > 0.0:
                mu0e, mue, shadow = self._roughness(mu0, mu, wi, wo)
            else:
                mu0e, mue, shadow = mu0, mu, 1.0
            opposition = p.b0 / (1.0 + dr.tan(0.5 * g) * (1.0 / p.h))
            single = (1.0 + opposition) * self._phase_function(dr.cos(g))
            multiple = self._h_function(mu0e, w) * self._h_function(mue, w) - 1.0
            geom = mu0e / (mu0e + mue) * shadow * (1.0 / (4.0 * math.pi))
            return w * geom * (single + multiple)

        def to_string(self):
            return f"RLHapke[albedo={self.m_albedo}, {self.p}]"

    return {
        "rl_lambert": RLLambert,
        "rl_lommel_seeliger": RLLommelSeeliger,
        "rl_mcewen": RLMcEwen,
        "rl_hapke": RLHapke,
    }


def register_bsdfs(mi) -> None:
    """Register ``rl_lambert``, ``rl_lommel_seeliger``, ``rl_mcewen``, ``rl_hapke`` for mi's variant.

    Idempotent per variant; call after :func:`renderlab.render.variant.init_mitsuba`.

    Parameters
    ----------
    mi : module
        The ``mitsuba`` module with a variant set.
    """
    import drjit as dr

    variant = mi.variant()
    if variant is None:
        raise RuntimeError("register_bsdfs: no Mitsuba variant is set; call init_mitsuba first")
    if variant in _registered:
        return
    for name, cls in _build_classes(mi, dr).items():
        mi.register_bsdf(name, lambda props, _cls=cls: _cls(props))
    _registered.add(variant)


def _is_texture(obj) -> bool:
    mi = sys.modules.get("mitsuba")
    return mi is not None and mi.variant() is not None and isinstance(obj, mi.Texture)


def bsdf_dict(law: PhotometricLaw, albedo) -> dict:
    """The ``mi.load_dict`` entry of a body's BSDF for ``law``.

    Parameters
    ----------
    law : PhotometricLaw
        From :func:`renderlab.photometry.make_law`.
    albedo : float, dict, numpy.ndarray or mitsuba Texture
        A uniform albedo (w for Hapke), a nested Mitsuba texture dict (e.g. ``{'type': 'bitmap', ...}``),
        an (H, W) or (H, W, 1) array used as a raw bilinear bitmap (row 0 at v = 0, column 0 at u = 0;
        needs the Mitsuba variant set) or a loaded texture object.

    Returns
    -------
    dict
        ``{'type': 'rl_<law>', 'albedo': ..., <law parameters>}``.
    """
    if not isinstance(law, PhotometricLaw):
        raise UserError(f"bsdf_dict: expected a PhotometricLaw, got {type(law).__name__}")
    w_max = 1.0 if law.name == "hapke" else math.inf
    if isinstance(albedo, Real) and not isinstance(albedo, bool):
        a = float(albedo)
        if not (math.isfinite(a) and 0.0 <= a <= w_max):
            raise UserError(f"{law.name} albedo must be in [0, {w_max:g}], got {albedo!r}")
        value = a
    elif isinstance(albedo, dict):
        if "type" not in albedo:
            raise UserError("albedo texture dict needs a 'type' key (e.g. 'bitmap')")
        value = albedo
    elif isinstance(albedo, np.ndarray):
        arr = np.asarray(albedo, dtype=np.float32)
        if arr.ndim == 3 and arr.shape[2] == 1:
            arr = arr[:, :, 0]
        if arr.ndim != 2 or min(arr.shape) < 1:
            raise UserError(f"albedo map must have shape (H, W) or (H, W, 1), got {albedo.shape}")
        if not np.all(np.isfinite(arr)) or arr.min() < 0.0 or arr.max() > w_max:
            raise UserError(f"{law.name} albedo map values must be finite and in [0, {w_max:g}]")
        import mitsuba as mi

        value = {"type": "bitmap", "bitmap": mi.Bitmap(np.ascontiguousarray(arr[:, :, None])), "raw": True}
    elif _is_texture(albedo):
        value = albedo
    else:
        raise UserError(f"albedo must be a number, a texture dict or an array, got {type(albedo).__name__}")
    out = {"type": f"rl_{law.name}", "albedo": value}
    out.update({k: float(v) for k, v in law.to_dict().items() if k != "name"})
    return out
