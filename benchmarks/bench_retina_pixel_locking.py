"""Pixel-locking curves of the sub-pixel peak finders: bias (estimated − true shift) vs the fractional
shift of a band-limited random texture (Fourier-shifted, exact), and of Retina-rendered maplets (the
a-priori camera translated by a known sub-pixel amount, ``estimators.retina.locking``), for every finder
of ``estimators.landmarks.peaks``, and for the refined steps of ``estimators.retina.peak_step`` (``gaussian_2d_rc``:
``retina_refined``'s; ``ml_shift``: ``retina_ml``'s), which need the template and image, not only the surface (on
the same textures: ``texture_case`` of the same seeds). Prints both tables; ``--png FILE`` also draws the texture
curves.

    .venv/bin/python benchmarks/bench_retina_pixel_locking.py [--sigma 1.2] [--trials 8] [--png curve.png]

``tests/test_retina_peaks.py::test_pixel_locking_curve_textures`` checks the texture curve (|bias| < 0.1 px,
zero at integer shifts, odd in the shift), ``::test_pixel_locking_curve_rendered_maplets`` the rendered one
(zero at zero shift; |bias| < 0.05 px for the 2-D fits, 0.1 for the 3×3 fit, 0.15 for the 1-D ones).
"""

from __future__ import annotations

import argparse

import numpy as np

from estimators.landmarks.peaks import FINDERS, pixel_locking_curve

#: the refined steps of estimators.retina.peak_step shown beside the finders
REFINED = ("gaussian_2d_rc", "ml_shift")


def refined_locking_curve(fr, trials: int, sigma_px: float, seed: int = 0):
    """{step: (bias_s (F,), bias_l (F,))} of :data:`REFINED` on the textures of ``pixel_locking_curve`` (its seeds)."""
    from estimators.retina.peak_step import estimates, texture_case

    rng = np.random.default_rng(seed)
    out = {m: (np.zeros(len(fr)), np.zeros(len(fr))) for m in REFINED}
    for _ in range(trials):
        texture_seed = int(rng.integers(2**63))  # pixel_locking_curve's draw: the same textures
        for k, f in enumerate(fr):
            c = texture_case(sigma_px, (f, f / 2), texture_seed)
            e = estimates(c, REFINED, radius=4)
            for m in REFINED:
                out[m][0][k] += (e[m][0] - c.shift[0]) / trials
                out[m][1][k] += (e[m][1] - c.shift[1]) / trials
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sigma", type=float, default=1.2, help="texture smoothing σ, px (larger = rounder peak)")
    ap.add_argument("--trials", type=int, default=8)
    ap.add_argument("--png", help="write the curves to this PNG")
    args = ap.parse_args()
    fr = np.round(np.linspace(-0.5, 0.5, 21), 3)
    curve = pixel_locking_curve(fr, trials=args.trials, sigma_px=args.sigma)
    curve.update(refined_locking_curve(fr, args.trials, args.sigma))
    names = (*FINDERS, *REFINED)
    print(f"bias in sample (px) vs fractional shift; texture σ = {args.sigma} px, {args.trials} textures, "
          f"line shift = half the sample shift")
    print("shift   " + " ".join(f"{m:>14s}" for m in names))
    for k, f in enumerate(fr):
        print(f"{f:+.2f}   " + " ".join(f"{curve[m][0][k]:+14.4f}" for m in names))
    print("max|b|  " + " ".join(f"{np.abs(curve[m][0]).max():14.4f}" for m in names))
    from estimators.retina.locking import rendered_locking_curve

    rc = rendered_locking_curve(fr, methods=names)
    print("\nRetina-rendered maplets (41 x 41 points at 0.1 m seen from 10 m, 1.1 px per cell; estimators.retina.locking), "
          "3 maplets: bias in sample / line (px) vs fractional shift (line shift = half the sample shift)")
    print("shift   " + " ".join(f"{m:>15s}" for m in names))
    for k, f in enumerate(fr):
        print(f"{f:+.2f}   " + " ".join(f"{rc[m][0][k]:+7.4f}/{rc[m][1][k]:+7.4f}" for m in names))
    print("max|b|  " + " ".join(f"{np.abs(rc[m][0]).max():7.4f}/{np.abs(rc[m][1]).max():7.4f}" for m in names))
    if args.png:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6.4, 4))
        for m in names:
            ax.plot(fr, curve[m][0], marker="o", ms=3, label=m)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel("true fractional shift (px)")
        ax.set_ylabel("bias (px)")
        ax.set_title(f"Pixel locking of the peak steps (texture σ = {args.sigma} px)")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(args.png, dpi=120)
        print(f"wrote {args.png}")


if __name__ == "__main__":
    main()
