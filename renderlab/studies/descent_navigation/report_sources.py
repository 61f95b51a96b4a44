"""Report section of the descent study's injected-error sources (:mod:`.sources`, eq. G1): consistency and
touchdown error against the injected bias, from the published ``descent_filter`` and ``descent_images`` tables
(docs/descent_navigation.md)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from renderlab.report.csvio import write_csv
from renderlab.report.html_table import plain_table
from renderlab.report.style import OKABE_ITO, badge, fmt, plt, save
from renderlab.studies.descent_navigation.publish import INJ
from renderlab.studies.descent_navigation.scoring import POS, chi2_band_sum, columns, tracked


def _bias_only(r: dict) -> bool:
    """A source that injects a common bias (or nothing) on top of the model-matched noise."""
    return (r["inj_sigma_bias_px"] == 0 and r["inj_scale"] == 0 and math.isnan(r["inj_sigma_noise_px"])
            and r["inj_map_offset_h_m"] == 0 and r["inj_map_offset_v_m"] == 0
            and r["inj_bias_s_px"] == r["inj_bias_l_px"])


def source_rows(ftab, images: dict, summary: list[dict]) -> list[dict]:
    """One row per injected-error source (module docstring); ``images``: ``{(method, frame): row}`` of
    ``descent_images`` (mean squared 1σ of the last image), ``summary`` the rows of method_summary."""
    c = columns(ftab, ("method", "frame", "nees", "track_lost", *POS, "src_kind", *INJ))
    kept = columns(tracked(ftab), ("method", "frame", "nees", "nis", "dof", *POS))
    last_k = int(c["frame"].max())
    by = {r["method"]: r for r in summary}
    out = []
    for m in sorted({str(m) for m, k in zip(c["method"], c["src_kind"]) if k is not None}):
        s = c["method"] == m
        inj = {k: float(c[k][s][0]) for k in INJ}
        last = (kept["method"] == m) & (kept["frame"] == last_k) & np.isfinite(kept["nees"])
        n = int(last.sum())
        lo, hi = chi2_band_sum(6.0 * n)
        a_last = float(np.mean(kept["nees"][last]) / 6.0) if n else math.nan
        img = images.get((m, last_k), {})
        sm = by[m]
        out.append({"source": m, "kind": str(c["src_kind"][s][0]), **inj, "n_runs": sm["n_runs"],
                    "n_tracked_runs": sm["n_tracked_runs"], "anees_over_6": sm["anees_over_6"],
                    "anees_over_6_lo": sm["anees_over_6_lo"], "anees_over_6_hi": sm["anees_over_6_hi"],
                    "anees_pass": bool(sm["anees_over_6_lo"] <= 1.0 <= sm["anees_over_6_hi"]),
                    "anees_images_in_band": sm["anees_inside_frac"],
                    "anees_last_over_6": a_last, "anees_last_band_lo": lo, "anees_last_band_hi": hi,
                    "anees_last_pass": bool(lo <= a_last <= hi) if n else False,
                    "anis_per_dof": sm["anis_per_dof"], "anis_per_dof_lo": sm["anis_per_dof_lo"],
                    "anis_per_dof_hi": sm["anis_per_dof_hi"],
                    "anis_pass": bool(sm["anis_per_dof_lo"] <= 1.0 <= sm["anis_per_dof_hi"]),
                    "anis_images_in_band": sm["anis_inside_frac"],
                    "touchdown_pos_err_median_m": sm["touchdown_pos_err_median_m"],
                    "touchdown_pos_err_rms_m": sm["touchdown_pos_err_rms_m"],
                    "touchdown_pos_err_p95_m": sm["touchdown_pos_err_p95_m"],
                    "touchdown_pos_3sig_rms_m": float(3.0 * np.sqrt(img["sig2_pos"])) if n else math.nan,
                    **{f"touchdown_mean_err_{a}_m": float(np.mean(kept[p][last])) if n else math.nan
                       for a, p in zip("enu", POS)},
                    **{f"touchdown_sig_{a}_rms_m": float(np.sqrt(img[f"sig2_{a}"])) if n else math.nan for a in "enu"},
                    "touchdown_rms_over_1sig": float(sm["touchdown_pos_err_rms_m"] / np.sqrt(img["sig2_pos"]))
                    if n else math.nan, "track_lost_runs": sm["track_lost_runs"]})
    return out


def sweep_figure(rows: list[dict], out_dir: Path) -> list[str]:
    """ANEES/6 (run mean with its bootstrap interval; last image with its χ² band) and the touchdown error (median,
    RMS, p95, filter 3σ) against the common bias μ; the other sources as dotted reference lines."""
    sweep = sorted((r for r in rows if _bias_only(r)), key=lambda r: r["inj_bias_s_px"])
    others = [r for r in rows if not _bias_only(r)]
    pyplot = plt()
    fig, (a1, a2, a3) = pyplot.subplots(1, 3, figsize=(15.0, 4.2))
    mu = np.array([r["inj_bias_s_px"] for r in sweep])
    if sweep:
        m6 = np.array([r["anees_over_6"] for r in sweep])
        err = np.abs(np.array([[r["anees_over_6_lo"], r["anees_over_6_hi"]] for r in sweep]).T - m6)
        a1.errorbar(mu, m6, yerr=err, fmt="o-", color=OKABE_ITO[0], capsize=3,
                    label="ANEES/6, mean over images (95 % run bootstrap)")
        a1.fill_between(mu, [r["anees_last_band_lo"] for r in sweep], [r["anees_last_band_hi"] for r in sweep],
                        color=OKABE_ITO[1], alpha=0.2, lw=0, label="95 % χ² band, last image")
        a1.plot(mu, [r["anees_last_over_6"] for r in sweep], "s--", color=OKABE_ITO[1], ms=4,
                label="ANEES/6, last image (50 m)")
        for key, style, lab in (("touchdown_pos_err_median_m", "o-", "median"), ("touchdown_pos_err_rms_m", "s-",
                                "RMS"), ("touchdown_pos_err_p95_m", "^-", "p95"),
                                ("touchdown_pos_3sig_rms_m", "k--", "filter 3σ (RMS over runs)")):
            a2.plot(mu, [r[key] for r in sweep], style, ms=4, label=f"|δr| at 50 m, {lab}")
        for a, col, mk, ls in zip("enu", ("tab:blue", "tab:red", "tab:green"), "os^", (":", "-.", "--")):
            a3.plot(mu, [1e3 * r[f"touchdown_mean_err_{a}_m"] for r in sweep], mk + "-", color=col, ms=4,
                    label=f"mean δ{a} over runs")
            a3.plot(mu, [1e3 * r[f"touchdown_sig_{a}_rms_m"] for r in sweep], ls, color=col, lw=1.0,
                    label=f"filter 1σ {a} (RMS)")
    for j, r in enumerate(others):
        col = OKABE_ITO[(j + 3) % len(OKABE_ITO)]
        a1.axhline(r["anees_over_6"], color=col, ls=":", lw=1.2, label=f"{r['source']} (ANEES/6, mean)")
        a2.axhline(r["touchdown_pos_err_rms_m"], color=col, ls=":", lw=1.2, label=f"{r['source']} (RMS)")
    a1.axhline(1.0, color="k", lw=0.6)
    a1.set_yscale("log")
    a1.set_xlabel("injected common bias μ per image axis (px)")
    a1.set_ylabel("ANEES / 6 (—)")
    a1.set_title("state consistency vs bias (1 = consistent)", fontsize=9)
    a2.set_xlabel("injected common bias μ per image axis (px)")
    a2.set_ylabel("touchdown-proxy position error (m)")
    a2.set_title("position error at the last image (50 m)", fontsize=9)
    a3.axhline(0.0, color="k", lw=0.6)
    a3.set_yscale("symlog", linthresh=1.0)
    a3.set_xlabel("injected common bias μ per image axis (px)")
    a3.set_ylabel("touchdown-proxy error, site axes (mm)")
    a3.set_title("mean error per axis at 50 m (east, north, up) vs the filter's 1σ", fontsize=9)
    for ax in (a1, a2, a3):
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=6.5)
    fig.tight_layout()
    return save(fig, out_dir / "descent_bias_sweep")


def sources_section(ftab, images: dict, summary: list[dict], out_dir: Path) -> tuple[str, list[str]]:
    """(HTML, figure names) of the injected-error sources."""
    rows = source_rows(ftab, images, summary)
    if not rows:
        return "", []
    write_csv(Path(out_dir) / "descent_sources.csv", rows)
    head = ("source", "μ s, l (px)", "σ_b (px)", "scale", "σ_n (px)", "runs (tracked)", "ANEES/6 [95 % CI]",
            "last image ANEES/6 [χ² band]", "ANIS/dof [95 % CI]", "touchdown |δr| median / RMS / p95 (m)",
            "filter 3σ (m)", "track lost")
    out = []
    for r in rows:
        sn = "declared" if math.isnan(r["inj_sigma_noise_px"]) else fmt(r["inj_sigma_noise_px"], 3)
        cells = [r["source"], f"{fmt(r['inj_bias_s_px'], 3)}, {fmt(r['inj_bias_l_px'], 3)}",
                 fmt(r["inj_sigma_bias_px"], 3), fmt(r["inj_scale"], 3), sn,
                 f"{r['n_runs']} ({r['n_tracked_runs']})",
                 f"{fmt(r['anees_over_6'], 3)} [{fmt(r['anees_over_6_lo'], 3)}, {fmt(r['anees_over_6_hi'], 3)}] "
                 + badge(r["anees_pass"]),
                 f"{fmt(r['anees_last_over_6'], 3)} [{fmt(r['anees_last_band_lo'], 3)}, "
                 f"{fmt(r['anees_last_band_hi'], 3)}] " + badge(r["anees_last_pass"]),
                 f"{fmt(r['anis_per_dof'], 3)} [{fmt(r['anis_per_dof_lo'], 3)}, {fmt(r['anis_per_dof_hi'], 3)}] "
                 + badge(r["anis_pass"]),
                 f"{fmt(r['touchdown_pos_err_median_m'], 3)} / {fmt(r['touchdown_pos_err_rms_m'], 3)} / "
                 f"{fmt(r['touchdown_pos_err_p95_m'], 3)}", fmt(r["touchdown_pos_3sig_rms_m"], 3),
                 str(r["track_lost_runs"])]
        out.append(cells)
    note = ("<p>Injected-error sources (eq. G1 of renderlab.studies.descent_navigation.sources): the true pixel of "
            "each landmark plus the injected error; σ_n 'declared' is each landmark's declared filter σ. The runs "
            "are independent (nothing rendered or mapped is shared); CIs resample whole runs; PASS: 1 inside the "
            "interval or the band.</p>")
    return "<h3>Injected-error sources</h3>" + plain_table(head, out) + note, sweep_figure(rows, out_dir)
