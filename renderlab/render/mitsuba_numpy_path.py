"""The former numpy ray path of :class:`~renderlab.render.mitsuba_backend.MitsubaBackend` (a mix-in).

Every sample's (s, l) goes through :meth:`CameraModel.unproject` in float64 numpy, one wavefront per sample
(``ray_path = "numpy"``, kept for the benchmarks); scalar variants (the fallback when LLVM is unusable) trace the
same rays one at a time from Python: identical semantics, much slower (``benchmarks/``). The sub-pixel pattern is
the R2 sequence with one Cranley–Patterson shift per pixel, as in :mod:`renderlab.render.mitsuba_rays`.
"""

from __future__ import annotations

import numpy as np

from renderlab.render.mitsuba_rays import R2_ALPHA, aligned_f32
from renderlab.render.scene import FrameSpec, RenderedFrame


def subpixel_offsets(spp: int, n_pixels: int, rng: np.random.Generator) -> np.ndarray:
    """(spp, n_pixels, 2) offsets in [−½, ½)²: R2 sequence with a per-pixel random shift (the numpy path)."""
    base = (0.5 + np.arange(spp)[:, None] * R2_ALPHA[None, :]) % 1.0
    shift = rng.random((n_pixels, 2))
    return (base[:, None, :] + shift[None, :, :]) % 1.0 - 0.5


class NumpyRayPath:
    """Mix-in: the numpy ray path (``_render_numpy``) of a Mitsuba backend."""

    def _ray_arrays(self, frame: FrameSpec, sl: np.ndarray):
        """float32 ray origins (N, 3), directions (N, 3) and max distances (N,) for pixels ``sl``."""
        d_cam = frame.camera.unproject(sl)
        d_cam = d_cam / np.linalg.norm(d_cam, axis=1, keepdims=True)
        R = frame.pose.rotation.as_matrix()
        o = np.asarray(frame.pose.position_m, float) - self.origin
        d = d_cam @ R.T
        t_near = self.settings.near_clip_m / d_cam[:, 2]
        org = o[None, :] + d * t_near[:, None]
        maxt = self.settings.far_clip_m / d_cam[:, 2] - t_near
        return org.astype(np.float32), d.astype(np.float32), maxt.astype(np.float32)

    def _rays(self, frame: FrameSpec, sl: np.ndarray):
        """One wavefront of Mitsuba rays (JIT variants) for pixel coordinates ``sl`` (N, 2)."""
        mi = self.mi
        org, d, maxt = self._ray_arrays(frame, sl)
        c = aligned_f32
        ray = mi.RayDifferential3f(mi.Point3f(c(org[:, 0]), c(org[:, 1]), c(org[:, 2])),
                                   mi.Vector3f(c(d[:, 0]), c(d[:, 1]), c(d[:, 2])))
        ray.maxt = mi.Float(c(maxt))
        return ray

    def _scalar_rays(self, frame: FrameSpec, sl: np.ndarray):
        mi = self.mi
        for o, d, t in zip(*self._ray_arrays(frame, sl)):
            ray = mi.RayDifferential3f(mi.Point3f(*o.tolist()), mi.Vector3f(*d.tolist()))
            ray.maxt = float(t)
            yield ray

    def _intersect(self, frame: FrameSpec, centres: np.ndarray):
        """(valid, P (3, N), N (3, N), registry id) of the first hit along each centre ray."""
        mi, dr = self.mi, self.dr
        if not self.scalar:
            si = self._hit(self._rays(frame, centres), coherent=False)
            reg = np.array(dr.reinterpret_array(mi.UInt32, si.shape), dtype=np.int64)
            return (np.array(si.is_valid(), dtype=bool), np.array(si.p, dtype=np.float64),
                    np.array(si.sh_frame.n, dtype=np.float64), reg)
        n = len(centres)
        valid, P, N, reg = np.zeros(n, bool), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n, np.int64)
        shapes = list(self.scene.shapes())
        for k, ray in enumerate(self._scalar_rays(frame, centres)):
            si = self.scene.ray_intersect(ray)
            if si.is_valid():
                valid[k], P[k], N[k] = True, list(si.p), list(si.sh_frame.n)
                reg[k] = self._scalar_reg[shapes.index(si.shape)] if si.shape in shapes else 0
        return valid, P.T, N.T, reg

    def _radiance(self, frame: FrameSpec, sl: np.ndarray, seed: int) -> np.ndarray:
        """Radiance (channels, N) along the rays through ``sl`` with a sampler seeded by ``seed``."""
        mi, dr = self.mi, self.dr
        n = len(sl)
        sampler = mi.load_dict({"type": "independent"})
        if not self.scalar:
            sampler.seed(dr.opaque(mi.UInt32, seed), n)
            spec = self._sample(sampler, self._rays(frame, sl))
            return np.array(spec, dtype=np.float64).reshape(3 if self.rgb else 1, n)
        out = np.zeros((3 if self.rgb else 1, n))
        sampler.seed(seed, 1)
        for k, ray in enumerate(self._scalar_rays(frame, sl)):
            spec, _, _ = self._integrator.sample(self.scene, sampler, ray)
            out[:, k] = list(spec) if self.rgb else float(spec[0] if hasattr(spec, "__len__") else spec)
            sampler.advance()
        return out

    def _render_numpy(self, frame: FrameSpec, seed: int) -> RenderedFrame:
        """The former path: float64 numpy rays per sample (CameraModel.unproject), one wavefront per sample."""
        cam = frame.camera
        W, H = cam.width, cam.height
        self._set_sun(frame)
        centres = cam.pixel_grid().reshape(-1, 2)

        ss = np.random.SeedSequence(seed)
        if self.settings.pixel_filter == "center":
            offsets = np.zeros((1, W * H, 2))
        else:
            offsets = subpixel_offsets(self.settings.spp, W * H, np.random.default_rng(ss.spawn(1)[0]))
        sampler_seeds = ss.generate_state(len(offsets), dtype=np.uint32)
        acc = np.zeros((3 if self.rgb else 1, W * H), dtype=np.float64)
        for j in range(len(offsets)):
            acc += self._radiance(frame, centres + offsets[j], int(sampler_seeds[j]))
        return self._frame(frame, acc / len(offsets), self._intersect(frame, centres))
