"""Report piece of ``descent_navigation`` for campaigns whose filter table has the whitened errors (``white_*``):
``descent_independence.csv`` (per method and image: the share of the error common to all runs, N_eff and the
effective χ² bands beside the plain ones, :mod:`.independence`), ``descent_bands.csv`` (per method: share of images
inside each band), ``descent_bias_by_tier.csv`` (kept-landmark bias and rms per method and maplet tier), ``descent_pattern.csv``
(the scale / rotation / shift common to an image's landmark errors) and the figure ``descent_independence`` (PNG)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.report.csvio import write_csv
from renderlab.report.html_table import plain_table
from renderlab.report.style import fmt, method_colors, plt, save
from renderlab.stats.bootstrap import cluster_mean_bootstrap
from renderlab.stats.independence import band_summary, independence_rows
from renderlab.studies.descent_navigation.publish import TIERS


def independence_figure(rows: list[dict], out_dir: Path) -> list[str]:
    """Per method (columns): ANEES/6 and ANIS/dof with the plain (shaded) and effective (dashed) 95 % bands, PASS ●
    / FAIL ✕ against the plain band, and ρ (state), ρ_ν (innovations) vs time."""
    methods = sorted({r["method"] for r in rows})
    colors = method_colors(methods)
    pyplot = plt()
    fig, axes = pyplot.subplots(3, len(methods), figsize=(3.4 * len(methods), 7.6), sharex=True, squeeze=False)
    for j, m in enumerate(methods):
        rr = [r for r in rows if r["method"] == m]
        t = np.array([r["t_s"] for r in rr])
        for i, (key, lo, hi, inside, what) in enumerate((("anees_over_6", "anees_lo", "anees_hi", "anees_inside",
                                                          "ANEES / 6"),
                                                         ("anis_per_dof", "anis_lo", "anis_hi", "anis_inside",
                                                          "ANIS / dof"))):
            ax = axes[i, j]
            v = np.array([r[key] for r in rr], float)
            ok = np.array([bool(r[inside]) for r in rr])
            ax.fill_between(t, [r[lo] for r in rr], [r[hi] for r in rr], color=colors[m], alpha=0.18, lw=0,
                            label="95 % band, independent runs")
            ax.plot(t, [r[f"{lo}_eff"] for r in rr], "--", color="0.3", lw=0.9, label="95 % band, N_eff runs")
            ax.plot(t, [r[f"{hi}_eff"] for r in rr], "--", color="0.3", lw=0.9)
            ax.plot(t, v, color=colors[m], lw=1.2)
            ax.plot(t[ok], v[ok], "o", color=colors[m], ms=4, label="inside plain band (PASS)")
            ax.plot(t[~ok], v[~ok], "x", color=colors[m], ms=6, mew=1.5, label="outside plain band (FAIL)")
            ax.axhline(1.0, color="k", lw=0.5)
            ax.set_yscale("log")
            ax.set_ylabel(f"{what} (—)")
            if i == 0:
                ax.set_title(m, fontsize=9)
                ax.legend(fontsize=6, loc="lower left")
        ax = axes[2, j]
        ax.plot(t, [r["rho_state"] for r in rr], "o-", color=colors[m], ms=3, label="ρ state (whitened error)")
        ax.plot(t, [r["rho_innov"] for r in rr], "s--", color="0.4", ms=3, label="ρ_ν innovations")
        ax.plot(t, [0.5 * (r["common_share_err_s"] + r["common_share_err_l"]) for r in rr], "^:", color="0.6",
                ms=3, label="landmark errors (mean of s, l)")
        ax.set_ylim(0, 1)
        ax.set_ylabel("share common to all runs (—)")
        ax.set_xlabel("time (s)")
        ax.legend(fontsize=6)
    fig.tight_layout()
    return save(fig, out_dir / "descent_independence")


def bias_by_tier(tiers) -> list[dict]:
    """Per method and maplet tier (spacing): bias of the kept landmarks per axis with a 95 % cluster-bootstrap
    interval over runs, and their rms error, in px and on the ground (px × GSD); runs that kept track. ``tiers``:
    the published ``descent_landmark_tiers`` table (per method, tier and run: counts and sums)."""
    c = {n: np.asarray(v) for n, v in tiers.to_pydict().items()}
    out = []
    for m in sorted(set(c["method"].tolist())):
        for sp in sorted(set(c["spacing_m"].tolist()), reverse=True):
            k = (c["method"] == m) & (c["spacing_m"] == sp)
            n = int(c["n_rows"][k].sum())
            if n < 2:
                continue
            row = {"method": m, "spacing_m": float(sp), "n_landmarks": n,
                   "gsd_m_mean": float(c["sum_gsd_m"][k].sum() / n)}
            for ax in ("s", "l"):
                iv = cluster_mean_bootstrap(c[f"n_{ax}"][k], c[f"sum_{ax}"][k], cluster_name="runs")
                row.update({f"bias_{ax}_px": iv.estimate, f"bias_{ax}_px_lo": iv.lo, f"bias_{ax}_px_hi": iv.hi,
                            f"rms_{ax}_px": float(np.sqrt(c[f"sumsq_{ax}"][k].sum() / n)),
                            f"rms_{ax}_m": float(np.sqrt(c[f"sumsq_{ax}_m"][k].sum() / n))})
            out.append(row)
    return out


PATTERN = ("n_landmarks", "scale", "rotation_rad", "shift_s_px", "shift_l_px", "radius_max_px")


def pattern_rows(images: dict) -> list[dict]:
    """Per method and image with ≥ 3 kept landmarks: the similarity pattern of their errors
    (:func:`renderlab.stats.independence.similarity_pattern`, ``pattern_*`` of ``descent_images``)."""
    return [{"method": m, "frame": k, **{p: r[f"pattern_{p}"] for p in PATTERN}}
            for (m, k), r in sorted(images.items()) if r.get("pattern_n_landmarks") is not None]


def independence_section(ftab, tables: dict, images: dict, ts_rows: list[dict], out_dir: Path) \
        -> tuple[str, list[str]]:
    """(HTML table, figure files) of the independence piece; writes its CSVs (the tier and pattern ones where the
    landmarks' maplet tiers are known)."""
    rows = independence_rows(ftab, images, ts_rows)
    bands = band_summary(rows)
    write_csv(out_dir / "descent_independence.csv", rows)
    write_csv(out_dir / "descent_bands.csv", bands)
    if TIERS in tables:
        write_csv(out_dir / "descent_bias_by_tier.csv", bias_by_tier(tables[TIERS]))
        write_csv(out_dir / "descent_pattern.csv", pattern_rows(images))
    head = ("method", "images in NEES band (plain / N_eff)", "images in NIS band (plain / N_eff)",
            "ρ state mean (max)", "N_eff min", "ρ_ν innovations mean", "landmark-error share s, l")
    out = []
    for b in bands:
        cells = (b["method"], f"{b['nees_inside_plain']:.0%} / {b['nees_inside_eff']:.0%}",
                 f"{b['nis_inside_plain']:.0%} / {b['nis_inside_eff']:.0%}",
                 f"{fmt(b['rho_state_mean'], 2)} ({fmt(b['rho_state_max'], 2)})", fmt(b["n_eff_min"], 3),
                 fmt(b["rho_innov_mean"], 2),
                 f"{fmt(b['common_share_err_s_mean'], 2)}, {fmt(b['common_share_err_l_mean'], 2)}")
        out.append(cells)
    note = ("<p>Share common to all runs: of the whitened state error (ρ), of the innovations (ρ_ν) and of the "
            "landmark errors, per image (descent_independence.csv). The effective band treats the runs as "
            "N_eff = N/(1 + (N−1)ρ²) independent ones; it is shown beside the plain χ² band, PASS/FAIL marks are "
            "against the plain band.</p>")
    return plain_table(head, out) + note, independence_figure(rows, out_dir)
