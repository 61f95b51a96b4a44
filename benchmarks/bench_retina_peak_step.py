"""Choosing Retina's sub-pixel peak step: every finder of ``estimators.landmarks.peaks`` side by side, in one run, on

* **EV5 templates**: Retina's predicted templates (``render_template``, 3×3 supersampling) of the maplets of the
  published Retina-vs-SPC world (``results/retina_vs_spc/scenario.toml``: procedural EV5 seed 2008, its three
  frames at 200 / 100 / 50 m), those in view, facing camera and Sun, with GSD ratio in [0.5, 2] (the study's
  well-measured range), at most ``--per-frame`` per frame;
* **textures**: band-limited random textures (σ = ``--sigma`` px, the locking benchmark's), 48 × 48 px;

with the kernel of ``estimators.retina.peak_step``: the template moved by exact Fourier shifts (f, f/2),
correlated by eq. 9 and each step's estimate − true shift → pixel-locking bias (max over the fractions of
|mean over templates|, and RMS over templates × fractions × axes); the steps: every finder, the re-centred
passes (``*_rc``) and the maximum-likelihood shift (``ml_shift``, ``estimators.retina.ml_shift``, the
``retina_ml`` method). Noise: the spread of the estimates over ``--trials`` draws of Gaussian pixel noise at each
SNR (σ = std(template) / SNR) at a seeded random fractional shift per template, divided by the Cramér–Rao bound
of that template in that noise, mean over templates × axes. The bound (``estimators.retina.peak_step``):
textures: the registration CRLB (``renderlab.campaign.scoring.registration_crlb``, the study's
``crlb_s``/``crlb_l``); EV5 templates: ``rendered_crlb``, the Fisher information of the re-rendered model
(9 × 9 rays per pixel, ±0.1 px, gain and offset as nuisance), because finite differences over a template pasted
into a masked image count its border as signal; ``border@20`` keeps σ at SNR 20 over that former bound for
comparison. ``same@20``: SNR 20 when the prediction is identical to the image (zero shift, no template error; a
step whose locking curve is flat near zero shows less than 1 there, its response to a shift being below 1).
Time per call of each step on the templates' noise-free surfaces (7 × 7). Then the pixel-locking curve of
``estimators.retina.locking`` (the a-priori camera translated, the template re-rendered: what the study's
Retina does) for the same steps.

    .venv/bin/python benchmarks/bench_retina_peak_step.py [--per-frame 5] [--textures 6] [--trials 25] [--snr 10 20 50]

Criterion for a better peak step: |bias| < 0.02 px and noise ≤ 1.5 × CRLB at SNR ≥ 20 (``ok`` column).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from estimators.retina.peak_step import (STEPS, estimate, estimates, noise_sigma, rendered_case, rendered_crlb,
                                         texture_case)

ROOT = Path(__file__).resolve().parents[1]
FRACTIONS = np.round(np.linspace(-0.5, 0.5, 11), 3)


def ev5_landmarks(per_frame: int):
    """[(mesh, camera, true pose, sun, label)] of the published study's world (module docstring)."""
    from estimators.retina import CameraPoseEstimate, build_mesh, render_template
    from estimators.retina.landmarks import facing_flags
    from renderlab.scenario import load_scenario
    from renderlab.worlds.ev5 import make_plan

    folder = ROOT / "results" / "retina_vs_spc"
    sc = load_scenario(folder / "scenario.toml")[0]
    plan = make_plan(sc, folder)
    out = []
    for fr in plan.frames:
        pose = CameraPoseEstimate(fr.pose.rotation.as_matrix(), np.asarray(fr.pose.position_m, float))
        sun = np.asarray(fr.sun.direction_render, float)
        n = 0
        for m in plan.model.maplets:
            g = float(np.linalg.norm(np.asarray(m.center_m) - pose.position_m)) / fr.camera.fx / m.spacing_m
            if n >= per_frame or not 0.5 <= g <= 2.0 or facing_flags(m, pose, sun):
                continue
            mesh = build_mesh(m)
            tpl = render_template(mesh, fr.camera, pose, sun)
            if tpl is None or tpl.valid.sum() < 64 or np.ptp(tpl.image[tpl.valid]) <= 0:
                continue
            if rendered_case(mesh, fr.camera, pose, sun, (0.0, 0.0)) is None:
                continue
            out.append((mesh, fr.camera, pose, sun, f"frame {fr.index} landmark {m.landmark_id} GSD ratio {g:.2f}"))
            n += 1
    return out


def cases_of(kind, item, shifts):
    if kind == "texture":
        return [texture_case(item[0], sh, item[1]) for sh in shifts]
    return [rendered_case(*item[:4], sh) for sh in shifts]


def border_crlb(case, snr):
    """Registration CRLB (s, l), px, of the noise-free image over the template's footprint at the true shift
    (``registration_crlb``, finite differences; the benchmark's former bound: on a rendered case the
    differences cross the footprint's border into the masked zeros, ``estimators.retina.peak_step``)."""
    from renderlab.campaign.scoring import registration_crlb

    var = np.full(case.image.shape, np.inf)
    yy, xx = np.nonzero(case.valid)
    li, si = yy + case.l0 + int(round(case.shift[1])), xx + case.s0 + int(round(case.shift[0]))
    inside = (li >= 0) & (li < var.shape[0]) & (si >= 0) & (si < var.shape[1])
    var[li[inside], si[inside]] = noise_sigma(case, snr) ** 2
    if case.image_valid is not None:
        var[~case.image_valid] = np.inf
    return registration_crlb(case.image, var)


def crlb(kind, item, case, snr):
    """The bound of the case (``estimators.retina.peak_step``): textures: :func:`border_crlb` (every pixel
    observed); rendered: the Fisher information of the re-rendered model (``rendered_crlb``)."""
    if kind == "texture":
        return border_crlb(case, snr)
    return rendered_crlb(*item[:4], case.shift, noise_sigma(case, snr))


def measure(kind, items, snrs, trials, seed):
    """Locking errors {step: (T, F, 2)}, noise ratios {(step, snr): [σ/CRLB per template and axis]} (and
    (step, "same"): SNR 20 with the prediction identical to the image, zero shift), cases."""
    errs = {m: [] for m in STEPS}
    ratio = {(m, s): [] for m in STEPS for s in snrs}
    rng = np.random.default_rng(seed)
    noisy_cases = []
    for k, item in enumerate(items):
        e = [estimates(c) for c in cases_of(kind, item, [(f, f / 2) for f in FRACTIONS])]
        cs = cases_of(kind, item, [(f, f / 2) for f in FRACTIONS])
        for m in STEPS:
            errs[m].append(np.array([np.subtract(ek[m], c.shift) for ek, c in zip(e, cs)]))
        case, same = cases_of(kind, item, [tuple(rng.uniform(-0.5, 0.5, 2)), (0.0, 0.0)])
        noisy_cases.append(case)
        for s in list(snrs) + ["same"]:  # "same": SNR 20 with the template = the image (zero shift)
            c, snr = (same, 20.0) if s == "same" else (case, s)
            draws = np.random.default_rng([seed, k, int(snr), s == "same"])
            est = [estimates(c, snr=snr, rng=draws) for _ in range(trials)]
            cr, old = crlb(kind, item, c, snr), border_crlb(c, snr)
            for m in STEPS:
                a = np.array([x[m] for x in est], float)
                a = a[np.all(np.isfinite(a), axis=1)]
                sd = np.std(a, axis=0, ddof=1) if len(a) > 2 else (np.nan, np.nan)
                ratio.setdefault((m, s), []).extend([sd[0] / cr[0], sd[1] / cr[1]])
                ratio.setdefault((m, s, "border"), []).extend([sd[0] / old[0], sd[1] / old[1]])
        print(f"  {k + 1}/{len(items)} {item[-1]}", flush=True)
    return errs, ratio, noisy_cases


def time_per_call(cases, reps=5):
    """Median µs per call of each step alone (the 7 x 7 surface given; the re-centred passes include their template
    moves and 3 x 3 correlations), every call timed on its own and the steps interleaved (a shared, loaded machine
    preempts single calls; the median ignores them)."""
    from estimators.landmarks.correlation import correlation_surface

    surf = [correlation_surface(c.image, c.template, c.valid, c.s0, c.l0, 3, c.image_valid)[0] for c in cases]
    times = {m: [] for m in STEPS}
    for _ in range(reps):
        for C, c in zip(surf, cases):
            for m in STEPS:
                t0 = time.perf_counter()
                estimate(m, C, c.image, c, c.image_valid)
                times[m].append(time.perf_counter() - t0)
    return {m: float(np.median(v)) * 1e6 for m, v in times.items()}


def print_table(title, errs, ratio, snrs, us):
    print(f"\n{title}")
    print(f"{'step':15s} {'max|bias|':>9s} {'RMS bias':>9s} " + " ".join(f"{'σ/CRLB@' + str(int(s)):>11s}" for s in snrs)
          + f" {'same@20':>8s} {'border@20':>9s} {'µs/call':>8s}  ok")
    for m in STEPS:
        e = np.asarray(errs[m])  # (T, F, 2)
        mb = np.nanmax(np.abs(np.nanmean(e, axis=0)))
        rms = float(np.sqrt(np.nanmean(e ** 2)))
        r = [float(np.nanmean(ratio[(m, s)])) for s in snrs]
        ok = mb < 0.02 and all(x <= 1.5 for x, s in zip(r, snrs) if s >= 20)
        same = float(np.nanmean(ratio[(m, "same")]))
        border = float(np.nanmean(ratio.get((m, 20.0, "border"), [np.nan])))
        print(f"{m:15s} {mb:9.4f} {rms:9.4f} " + " ".join(f"{x:11.2f}" for x in r) + f" {same:8.2f} {border:9.2f} "
              f"{us[m]:8.1f}  {'yes' if ok else 'no'}")
    worst = {m: max(float(np.nanmax(ratio[(m, s)])) for s in snrs if s >= 20) for m in STEPS}
    print("worst single template σ/CRLB at SNR ≥ 20: " + ", ".join(f"{m} {w:.2f}" for m, w in worst.items()))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--per-frame", type=int, default=5, help="EV5 templates per frame (3 frames)")
    ap.add_argument("--textures", type=int, default=6)
    ap.add_argument("--sigma", type=float, default=1.2, help="texture smoothing σ, px")
    ap.add_argument("--trials", type=int, default=25, help="noise draws per SNR and template")
    ap.add_argument("--snr", type=float, nargs="+", default=[10.0, 20.0, 50.0])
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    t0 = time.perf_counter()
    sets = [("EV5 templates (Retina's predictions of the published study's maplets, re-rendered at a translated "
             "a-priori camera)", "rendered", ev5_landmarks(args.per_frame)),
            (f"band-limited textures (σ = {args.sigma} px, 48 x 48 window, Fourier-shifted)", "texture",
             [(args.sigma, 1000 + k, f"texture {k}") for k in range(args.textures)])]
    for title, kind, items in sets:
        print(f"{title}: {len(items)} templates, {len(FRACTIONS)} shifts (f, f/2), f in [-0.5, 0.5]; "
              f"noise: {args.trials} draws per SNR", flush=True)
        errs, ratio, cases = measure(kind, items, args.snr, args.trials, args.seed)
        print_table(title, errs, ratio, args.snr, time_per_call(cases))
    from estimators.retina.locking import rendered_locking_curve

    rc = rendered_locking_curve(FRACTIONS, methods=tuple(STEPS))
    print("\nRetina re-rendering its template at a translated a-priori camera (estimators.retina.locking, 3 plain "
          "maplets): max |bias| s / l, px")
    print("  " + ", ".join(f"{m} {np.abs(rc[m][0]).max():.4f}/{np.abs(rc[m][1]).max():.4f}" for m in rc))
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
