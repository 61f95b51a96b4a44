#!/usr/bin/env python
"""Mitsuba LLVM vs scalar: seconds per single-bounce frame, measured side by side in one run.

Scene: ``scenes/analytic_sphere_box.toml``, frame 0 of its orbit, camera overridden to a square
``--size`` x ``--size`` image (default 512) that keeps the scenario's horizontal view: fx, fy and the
principal point's offset from the image centre are scaled by size/256 (the scenario is 256 px wide).
``max_depth = 2``: one bounce, direct sunlight only.

Two comparisons, every configuration timed in the same process, repetitions interleaved
(round r runs every configuration once, in an order rotated by r) because the machine is shared:

(a) the lab's render path, :meth:`MitsubaBackend.render` (exact camera rays from
    :meth:`CameraModel.unproject`, truth-AOV intersection pass + radiance pass), in
    ``llvm_ad_mono`` (and ``llvm_ad_rgb``, the same channel count as the scalar fallback) vs
    ``scalar_rgb`` (the fallback: rays traced one at a time from Python), 1 sample per pixel
    (``pixel_filter = "center"``); LLVM also at 16 spp (``pixel_filter = "box"``).
    If a full scalar frame would take longer than ``--scalar-frame-limit`` seconds (estimated from a
    thin probe band), a fixed band of ``--band-fraction`` x H rows is timed instead and scaled up by
    H / rows; such rows are marked ``EXTRAPOLATED``. The band is placed where the fraction of its
    pixels that hit a body equals the full frame's (misses are far cheaper than hits).
(b) Mitsuba's own renderer, ``mi.render`` of a scene with a ``perspective`` sensor (``hdrfilm``,
    ``box`` rfilter, ``independent`` sampler), ``path`` integrator with ``max_depth = 2``, at
    1 and 16 spp, in ``llvm_ad_rgb`` vs ``scalar_rgb``; each variant loads its own scene.
    ``--native-bsdf lab`` uses the lab's Python BSDF plugins (rl_lambert,
    rl_lommel_seeliger: the same scene as (a)); ``diffuse`` uses Mitsuba's built-in C++
    ``diffuse`` BSDF for every body (same albedos; the box loses its Lommel-Seeliger law);
    ``both`` (default) times both.

The first call of every configuration (JIT tracing + kernel compilation, or loading kernels from
Dr.Jit's on-disk cache ``~/.drjit`` when an earlier run compiled them; ``--cold-jit`` points Dr.Jit
at an empty cache) is excluded from the statistics and printed separately. Reported: median and
minimum of ``--repeats`` timed calls, and the scalar / LLVM ratios of both.

Run:  .venv/bin/python benchmarks/bench_mitsuba_llvm_vs_scalar.py            # 512², 3 repeats
      .venv/bin/python benchmarks/bench_mitsuba_llvm_vs_scalar.py --size 64 --repeats 1   # smoke
"""

from __future__ import annotations

import argparse
import atexit
import math
import os
import platform
import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from sphere_box_scene import (  # noqa: E402  (the benchmarks folder on the path first)
    REF_WIDTH,
    SCENE_FILE,
    band_frame,
    lab_settings,
    load_inputs,
    native_scene,
    representative_band,
    sensor_ray_error_px,
    set_variant,
)

SEED = 7


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--size", type=int, default=512, help="image width = height in pixels (default 512)")
    p.add_argument("--repeats", type=int, default=3, help="timed calls per configuration after the warm-up (default 3)")
    p.add_argument("--spp", type=int, default=16, help="samples per pixel of the multi-sample rows (default 16)")
    p.add_argument("--scalar-frame-limit", type=float, default=60.0,
                   help="if one full scalar lab-path frame is estimated to take longer (s), time a band of rows "
                        "and extrapolate (default 60)")
    p.add_argument("--band-fraction", type=float, default=0.125,
                   help="fraction of the rows in the band when extrapolating (default 0.125)")
    p.add_argument("--native-bsdf", choices=("lab", "diffuse", "both"), default="both",
                   help="BSDFs of the mi.render scenes: the lab's plugins, Mitsuba's built-in diffuse, or both (default)")
    p.add_argument("--cold-jit", action="store_true",
                   help="use an empty Dr.Jit kernel cache so the first LLVM calls include compilation")
    a = p.parse_args(argv)
    if a.size < 8:
        p.error("--size must be at least 8")
    if a.repeats < 1:
        p.error("--repeats must be at least 1")
    if not 0 < a.band_fraction <= 1:
        p.error("--band-fraction must be in (0, 1]")
    return a


# ---------------------------------------------------------------------------- configurations
@dataclass
class Config:
    part: str  # "lab" or "native"
    variant: str
    spp: int
    label: str  # path description
    short: str  # BSDF / filter description for the sanity lines
    make_run: object  # band -> (() -> image); band None = the full frame, else (first row, rows)
    run: object = None
    height: int = 0  # image rows
    band: tuple | None = None  # (first row, rows) when the time is extrapolated from a band
    first: float = float("nan")
    times: list = field(default_factory=list)
    image: object = None

    @property
    def key(self):
        return (self.part, self.variant, self.spp, self.short)

    @property
    def scale(self) -> float:
        return 1.0 if self.band is None else self.height / self.band[1]

    @property
    def note(self) -> str:
        if self.band is None:
            return ""
        r0, n = self.band
        return f"EXTRAPOLATED: rows {r0}..{r0 + n - 1} timed, x{self.scale:g}"

    def call(self) -> float:
        set_variant(self.variant)
        t0 = time.perf_counter()
        img = self.run()
        dt = time.perf_counter() - t0
        self.image = img
        return dt * self.scale


def lab_maker(backend, frame):
    def make(band):
        f = frame if band is None else band_frame(frame, band)
        return lambda: backend.render(f, seed=SEED)  # RenderedFrame (radiance + truth AOVs)

    return make


def native_maker(scenario, scene, frame, variant, spp, bsdf):
    def make(band):
        mi = set_variant(variant)
        nscene = native_scene(mi, scenario, scene, frame, spp, bsdf, band)

        def run():
            img = mi.render(nscene, spp=spp, seed=0)
            return np.array(img)  # forces evaluation (LLVM) / copies (scalar)

        return run

    return make


def choose_extent(c: Config, hit: np.ndarray, args, log) -> None:
    """Scalar configurations: a thin probe band decides between the full frame and a band of rows."""
    H = hit.shape[0]
    probe_band = representative_band(hit, max(1, H // 64))
    probe = c.make_run(probe_band)
    set_variant(c.variant)
    t0 = time.perf_counter()
    probe()
    t = time.perf_counter() - t0
    est = t * H / probe_band[1]
    if est <= args.scalar_frame_limit:
        c.run = c.make_run(None)
        what = "full frame"
    else:
        c.band = representative_band(hit, max(1, int(round(H * args.band_fraction))))
        c.run = c.make_run(c.band)
        what = f"band of {c.band[1]} rows, extrapolated"
    log(f"  probe {c.variant} {c.part:6s} {c.spp:2d} spp {c.short:16s}: rows {probe_band[0]}.."
        f"{sum(probe_band) - 1} {t:.3f} s -> full frame ~{est:.1f} s (limit {args.scalar_frame_limit:g} s): {what}")


def build_configs(args, scenario, scene, frame, log):
    from renderlab.render.mitsuba_backend import MitsubaBackend

    H = frame.camera.height
    cfgs = []
    # (a) the lab's render path
    for variant, spp, filt in (("llvm_ad_mono", 1, "center"), ("llvm_ad_rgb", 1, "center"),
                               ("llvm_ad_mono", args.spp, "box"), ("scalar_rgb", 1, "center")):
        set_variant(variant)
        be = MitsubaBackend(scene, lab_settings(scenario, variant, spp, filt))
        cfgs.append(Config("lab", variant, spp, f"MitsubaBackend.render, pixel_filter={filt}", filt,
                           lab_maker(be, frame)))
    # (b) Mitsuba's own renderer
    for bsdf in (("lab", "diffuse") if args.native_bsdf == "both" else (args.native_bsdf,)):
        name = "rl_* plugins" if bsdf == "lab" else "built-in diffuse"
        for variant in ("llvm_ad_rgb", "scalar_rgb"):
            for spp in (1, args.spp):
                cfgs.append(Config("native", variant, spp, f"mi.render, perspective, {name}", name,
                                   native_maker(scenario, scene, frame, variant, spp, bsdf)))
    for c in cfgs:
        c.height = H
        if not c.variant.startswith("scalar"):
            c.run = c.make_run(None)
    mi = set_variant("scalar_rgb")
    geo = sensor_ray_error_px(mi, native_scene(mi, scenario, scene, frame, 1, "diffuse"), frame)
    return cfgs, geo


# ---------------------------------------------------------------------------- report
def fmt_s(x: float) -> str:
    if not math.isfinite(x):
        return "-"
    return f"{x:.3f}" if x < 100 else f"{x:.1f}"


def main(argv=None):
    args = parse_args(argv)
    if args.cold_jit:
        home = tempfile.mkdtemp(prefix="drjit-cold-")
        atexit.register(shutil.rmtree, home, ignore_errors=True)
        os.environ["HOME"] = home  # Dr.Jit keeps its kernel cache in ~/.drjit
    t_start = time.perf_counter()

    def log(msg=""):
        print(msg, flush=True)

    scenario, scene, frame = load_inputs(args.size)
    mi = set_variant("llvm_ad_mono")
    import drjit as dr

    cam = frame.camera
    H = cam.height
    cpu = platform.processor() or "?"
    if os.path.exists("/proc/cpuinfo"):
        with open("/proc/cpuinfo") as fh:
            cpu = next((ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")), cpu)
    log("Mitsuba LLVM vs scalar, single-bounce frame (max_depth = 2), one process, interleaved repeats")
    log(f"command : {' '.join([Path(sys.executable).name, *sys.argv])}")
    log(f"machine : {cpu}, {os.cpu_count()} logical CPUs, load avg {os.getloadavg()[0]:.2f} at start; "
        f"Python {platform.python_version()}")
    log(f"mitsuba {mi.__version__}, drjit {dr.__version__}, DRJIT_LIBLLVM_PATH={os.environ.get('DRJIT_LIBLLVM_PATH')}")
    log(f"kernel cache: {Path.home() / '.drjit'}{' (fresh, --cold-jit)' if args.cold_jit else ''}")
    log(f"scene   : {SCENE_FILE.relative_to(ROOT)}, frame 0; camera {cam.width}x{H} "
        f"fx={cam.fx:g} fy={cam.fy:g} cx={cam.cx:g} cy={cam.cy:g} (scenario's 256-px-wide camera scaled "
        f"x{args.size / REF_WIDTH:g}); sun irradiance {frame.sun.irradiance_w_m2:g} W/m2")
    log(f"repeats : {args.repeats} timed calls per configuration after 1 warm-up call, interleaved")
    log()

    cfgs, geo = build_configs(args, scenario, scene, frame, log)
    log(f"native perspective sensor vs lab camera: largest centre-ray angle difference {geo:.2f} px "
        f"(Mitsuba pixels are square: fy = fx = {cam.fx:g} instead of {cam.fy:g}; 0 px when fy = fx)")
    log()

    # warm-up: first call of every configuration, not in the statistics
    def warm(c):
        c.first = c.call()
        log(f"  {c.variant:13s} {c.part:6s} {c.spp:3d} spp {c.short:16s} {fmt_s(c.first):>8s} s"
            f"{'  (' + c.note + ')' if c.note else ''}")

    log("warm-up, LLVM (first call of each configuration: JIT trace + compile or kernel-cache load; excluded):")
    for c in cfgs:
        if c.run is not None:
            warm(c)
    log()
    # which pixels hit a body (LLVM lab path's truth ids): picks representative bands for the scalar probes
    hit = next(c for c in cfgs if c.key == ("lab", "llvm_ad_mono", 1, "center")).image.body_id >= 0
    log("scalar probes: a thin band of rows, with the same fraction of pixels hitting a body as the full frame, "
        "decides between a full frame and an extrapolated band:")
    scalar = [c for c in cfgs if c.run is None]
    for c in scalar:
        choose_extent(c, hit, args, log)
    log()
    log("warm-up, scalar (first timed call after the probe; excluded):")
    for c in scalar:
        warm(c)
    log()

    for r in range(args.repeats):
        k = r % len(cfgs)
        order = cfgs[k:] + cfgs[:k]
        t0 = time.perf_counter()
        for c in order:
            c.times.append(c.call())
        log(f"round {r + 1}/{args.repeats} done in {time.perf_counter() - t0:.1f} s")
    log()

    # ------------------------------------------------------------------ table
    log(f"seconds per {cam.width}x{H} frame (median and min of {args.repeats} timed calls; first call apart, "
        "not included)")
    hdr = f"{'variant':13s} {'path':56s} {'spp':>4s} {'median':>9s} {'min':>9s} {'first':>9s}"
    log(hdr)
    log("-" * len(hdr))
    stats = {}
    for c in cfgs:
        med, mn = statistics.median(c.times), min(c.times)
        stats[c.key] = (med, mn)
        path = f"{'(a) lab' if c.part == 'lab' else '(b) native'}: {c.label}"
        log(f"{c.variant:13s} {path:56s} {c.spp:4d} {fmt_s(med):>9s} {fmt_s(mn):>9s} {fmt_s(c.first):>9s}"
            f"{'  ' + c.note if c.note else ''}")
    log()

    # ------------------------------------------------------------------ ratios
    log(f"{'ratios scalar / LLVM, both measured in this run:':62s} {'median':>11s} {'min':>10s}")
    by = {c.key: c for c in cfgs}

    def ratio(name, num, den):
        (nm, nn), (dm, dn) = stats[num.key], stats[den.key]
        log(f"  {name:60s} {nm / dm:10.1f}x {nn / dn:9.1f}x{'  (scalar extrapolated)' if num.band else ''}")

    lab_sc = by[("lab", "scalar_rgb", 1, "center")]
    ratio("(a) lab path 1 spp: scalar_rgb / llvm_ad_mono", lab_sc, by[("lab", "llvm_ad_mono", 1, "center")])
    ratio("(a) lab path 1 spp: scalar_rgb / llvm_ad_rgb", lab_sc, by[("lab", "llvm_ad_rgb", 1, "center")])
    for c in cfgs:
        if c.part == "native" and c.variant == "scalar_rgb":
            ratio(f"(b) mi.render {c.spp:2d} spp, {c.short}: scalar_rgb / llvm_ad_rgb", c,
                  by[("native", "llvm_ad_rgb", c.spp, c.short)])
    m1 = stats[("lab", "llvm_ad_mono", 1, "center")][0]
    m16 = stats[("lab", "llvm_ad_mono", args.spp, "box")][0]
    log(f"  (lab path llvm_ad_mono {args.spp} spp / 1 spp = {m16 / m1:.1f}x; the scalar lab path is not timed "
        f"at {args.spp} spp)")
    log()

    # ------------------------------------------------------------------ sanity: the same work?
    log("sanity checks (do the compared configurations compute the same image?):")
    ref1 = by[("lab", "llvm_ad_mono", 1, "center")].image
    sc = lab_sc.image
    r0, n = lab_sc.band or (0, H)
    a = ref1.radiance[r0:r0 + n]
    b = sc.radiance.mean(axis=-1) if sc.radiance.ndim == 3 else sc.radiance
    log(f"  (a) lab 1 spp, scalar_rgb vs llvm_ad_mono over rows {r0}..{r0 + n - 1}: "
        f"max |diff| / max = {np.nanmax(np.abs(b - a)) / np.nanmax(a):.1e}, "
        f"body ids equal: {bool(np.array_equal(sc.body_id, ref1.body_id[r0:r0 + n]))}")
    for band in sorted({c.band for c in cfgs if c.band}):
        r0, n = band
        hit_band = float(np.mean(ref1.body_id[r0:r0 + n] >= 0))
        log(f"  extrapolation band rows {r0}..{r0 + n - 1}: {hit_band:.1%} of its pixels hit a body vs "
            f"{float(np.mean(ref1.body_id >= 0)):.1%} of the full frame (rays that miss are cheaper)")
    ref16 = by[("lab", "llvm_ad_mono", args.spp, "box")].image.radiance
    for c in cfgs:
        if c.part == "native" and c.spp == args.spp:
            r0, n = c.band or (0, H)
            img = np.asarray(c.image, float).reshape(n, cam.width, -1).mean(axis=-1)
            log(f"  (b) {c.variant:12s} {c.spp:2d} spp {c.short:16s}: mean radiance rows {r0}..{r0 + n - 1} "
                f"{img.mean():8.3f}  (lab path llvm_ad_mono {args.spp} spp: {float(ref16[r0:r0 + n].mean()):8.3f})")
    log()
    log(f"total wall time of this run: {time.perf_counter() - t_start:.1f} s")


if __name__ == "__main__":
    main()
