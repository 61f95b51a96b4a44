"""Retina and SPC speed on one core: templates per second for a 64 × 64 px landmark with a ±16 px search
and shadow rays, and seconds per 1 Mpx frame with 20 landmarks; the plain-numpy Retina (brute-force ray
casting, numpy correlation) measured in the same run for the ratio.

Targets (issue 5, from ARRM's 3 Hz on a 75 MHz processor): ≥ 200 templates/s, ≤ 100 ms per frame.

    NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/bench_retina_speed.py [--supersample K]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from scipy.ndimage import gaussian_filter  # noqa: E402

from estimators.retina import (CameraPoseEstimate, RetinaOptions, TemplateOptions, build_mesh,  # noqa: E402
                               measure_landmark, render_template)
from estimators.retina.correlation import correlation_surface_numpy  # noqa: E402
from estimators.retina.peaks import locate_peak  # noqa: E402
import estimators.spc as spc  # noqa: E402
from renderlab.geometry.camera import CameraModel  # noqa: E402
from renderlab.geometry.maplet import Maplet  # noqa: E402


def scene(n_landmarks: int, seed: int = 0):
    """A 1024² camera 50 m above flat-ish terrain; maplets of 65 × 65 points at the ground sample distance."""
    rng = np.random.default_rng(seed)
    cam = CameraModel.from_fov(1024, 1024, 12.6)
    alt = 50.0
    gsd = alt / cam.fx
    R = np.diag([1.0, -1.0, -1.0])
    pose = CameraPoseEstimate(R, np.array([0.0, 0.0, alt]))
    sun = np.array([0.6, 0.3, 0.5]) / np.linalg.norm([0.6, 0.3, 0.5])
    maplets = []
    half = 0.4 * 1024 * gsd
    for k in range(n_landmarks):
        c = np.array([rng.uniform(-half, half), rng.uniform(-half, half), 0.0])
        h = gaussian_filter(rng.normal(0, 0.05, (65, 65)), 1.5) + 0.04 * (rng.random((65, 65)) > 0.97)
        a = np.clip(1 + 0.2 * gaussian_filter(rng.normal(size=(65, 65)), 1.0) / 0.28, 0.3, 3)
        maplets.append(Maplet(k, c, np.eye(3), gsd, h, a))
    return cam, pose, sun, maplets


def image_from_templates(cam, pose, sun, meshes):
    img = np.full((cam.height, cam.width), 10.0)
    for m in meshes:
        t = render_template(m, cam, pose, sun)
        h, w = t.image.shape
        img[t.l0:t.l0 + h, t.s0:t.s0 + w] = np.where(t.valid, 100 * t.image + 10, img[t.l0:t.l0 + h, t.s0:t.s0 + w])
    return img


def time_it(fn, reps):
    fn()  # warm-up (numba compilation, caches)
    t0 = time.perf_counter()
    for _ in range(reps):
        fn()
    return (time.perf_counter() - t0) / reps


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--supersample", type=int, default=2)
    ap.add_argument("--reps", type=int, default=20)
    args = ap.parse_args()
    cam, pose, sun, maplets = scene(20)
    meshes = [build_mesh(m) for m in maplets]
    img = image_from_templates(cam, pose, sun, meshes)
    opts = RetinaOptions(template=TemplateOptions(supersample=args.supersample))
    m0 = meshes[0]
    t_tpl = time_it(lambda: measure_landmark(img, m0, cam, pose, sun, 16, opts), args.reps)
    t_render = time_it(lambda: render_template(m0, cam, pose, sun, opts.template), args.reps)
    t_spc = time_it(lambda: spc.measure_landmark(img, maplets[0], cam, pose, sun, 16), args.reps)

    def numpy_landmark():
        t = render_template(m0, cam, pose, sun, TemplateOptions(supersample=args.supersample, tracer="numpy"))
        C, _ = correlation_surface_numpy(img, t.image, t.valid, t.s0, t.l0, 16)
        return locate_peak(C, "retina_3x3")

    t_np = time_it(numpy_landmark, 1)
    t_frame = time_it(lambda: [measure_landmark(img, m, cam, pose, sun, 16, opts) for m in meshes], 3)
    tpl = render_template(m0, cam, pose, sun, opts.template)
    print(f"landmark template {tpl.image.shape[1]}x{tpl.image.shape[0]} px, search ±16 px, "
          f"supersample {args.supersample}x{args.supersample}, shadow rays, NUMBA_NUM_THREADS={os.environ['NUMBA_NUM_THREADS']}")
    print(f"retina (numba):  {1 / t_tpl:8.1f} templates/s  ({t_tpl * 1e3:.2f} ms; render {t_render * 1e3:.2f} ms)"
          f"   target >= 200/s")
    print(f"retina (numpy):  {1 / t_np:8.2f} templates/s  ({t_np * 1e3:.0f} ms)   numba/numpy speed-up {t_np / t_tpl:.0f}x")
    print(f"spc-style:       {1 / t_spc:8.1f} landmarks/s  ({t_spc * 1e3:.2f} ms)   retina/spc time ratio {t_tpl / t_spc:.2f}")
    print(f"1 Mpx frame, 20 landmarks (retina): {t_frame * 1e3:.0f} ms   target <= 100 ms")


if __name__ == "__main__":
    main()
