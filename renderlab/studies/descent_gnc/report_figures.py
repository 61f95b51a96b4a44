"""Figures of the ``descent_gnc`` report (the lab's figure writer, :func:`renderlab.report.style.save`): landing
dispersion with 3σ ellipses, estimation vs control error over time, ANEES/ANIS against their χ² bands."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from renderlab.report.style import method_colors, plt, save
from renderlab.studies.descent_gnc.scoring import claimed_cov


def _ellipse(ax, centre, cov: np.ndarray, **kw) -> None:
    """The 3σ ellipse of a 2×2 covariance around ``centre``."""
    w, v = np.linalg.eigh(cov)
    a = np.linspace(0.0, 2.0 * math.pi, 121)
    pts = (v @ (3.0 * np.sqrt(np.maximum(w, 0.0))[:, None] * np.stack([np.cos(a), np.sin(a)]))).T + centre
    ax.plot(pts[:, 0], pts[:, 1], **kw)


def dispersion_figure(r: dict, out_dir: Path) -> list[str]:
    """Touchdown position (top) and velocity (bottom) in site east/north per method: closed-loop runs (colour), the
    replay (grey), the runs' 3σ ellipse about their mean (solid) and the filter's claimed 3σ at contact (dashed, RMS
    covariance over runs, drawn about the target: the filter believes it landed there); lost-track runs as red ✕,
    clipped to the panel edge and counted."""
    methods = sorted(set(r["method"]))
    colors = method_colors(methods)
    fig, axes = plt().subplots(2, len(methods), figsize=(3.7 * len(methods), 7.2), squeeze=False)
    for j, m in enumerate(methods):
        for i, (pre, unit, label) in enumerate((("", "m", "position"), ("v", "mps", "velocity"))):
            ax = axes[i, j]
            cl = (r["method"] == m) & (r["mode"] == "closed")
            rp = (r["method"] == m) & (r["mode"] == "replay")
            e, n = r[f"td_{pre}e_{unit}"], r[f"td_{pre}n_{unit}"]
            ok, lost = cl & ~r["track_lost"], cl & r["track_lost"]
            if rp.any():
                ax.plot(e[rp], n[rp], ".", color="0.6", ms=3, label="replay (guidance on truth)")
            ax.plot(e[ok], n[ok], ".", color=colors[m], ms=4, label="closed loop")
            lim = 1e-9
            if cl.sum() > 2:
                mu = np.array([e[cl].mean(), n[cl].mean()])
                cov = np.cov(np.stack([e[cl], n[cl]]))
                _ellipse(ax, mu, cov, color=colors[m], lw=1.5, label="runs' 3σ")
                _ellipse(ax, np.zeros(2), claimed_cov(r, cl, pre, unit), color="k", lw=1.0, ls="--",
                         label="filter's claimed 3σ (about the target)")
                lim = 1.25 * 3.0 * math.sqrt(max(np.linalg.eigvalsh(cov)[-1], np.linalg.eigvalsh(
                    claimed_cov(r, cl, pre, unit))[-1])) + float(np.abs(mu).max())
            lim = max(lim, float(np.percentile(np.abs(np.r_[e[ok], n[ok]]), 98)) * 1.1 if ok.any() else lim)
            if lost.any():
                ax.plot(np.clip(e[lost], -lim, lim), np.clip(n[lost], -lim, lim), "x", color="#D00000", ms=7,
                        mew=1.5, label=f"lost track ({int(lost.sum())})")
            u = "m" if unit == "m" else "m/s"
            ax.set(xlim=(-lim, lim), ylim=(-lim, lim), aspect="equal", xlabel=f"east {label} error ({u})",
                   ylabel=f"north {label} error ({u})")
            ax.axhline(0, color="0.85", lw=0.5)
            ax.axvline(0, color="0.85", lw=0.5)
            if i == 0:
                ax.set_title(f"{m}: touchdown ({int(cl.sum())} runs)", fontsize=9)
            ax.legend(fontsize=6, loc="upper right")
    fig.tight_layout()
    return save(fig, Path(out_dir) / "gnc_landing_dispersion")


def history_figure(ts_rows: list[dict], out_dir: Path) -> list[str]:
    """RMS over all runs of the horizontal estimation error (filter − truth) and control error (truth − nominal)
    per image time, closed loop and replay, with the filter's 3σ, one panel per method."""
    methods = sorted({t["method"] for t in ts_rows})
    colors = method_colors(methods)
    fig, axes = plt().subplots(1, len(methods), figsize=(3.8 * len(methods), 3.8), squeeze=False, sharey=True)
    for ax, m in zip(axes[0], methods):
        for mode, ls in (("closed", "-"), ("replay", ":")):
            rows = [t for t in ts_rows if t["method"] == m and t["mode"] == mode and t["runs"] == "all"]
            if not rows:
                continue
            t = [x["t_s"] for x in rows]

            def pos(key: str, rows=rows) -> list:
                return [x[key] if x[key] > 0 else math.nan for x in rows]     # log axis: 0 (first image) not drawn

            ax.plot(t, pos("est_h_rms_m"), ls, color=colors[m], lw=1.6, marker="o", ms=3,
                    label=f"estimation error, {mode}")
            ax.plot(t, pos("ctl_h_rms_m"), ls, color="0.3", lw=1.2, marker="s", ms=3,
                    label=f"control error, {mode}")
            if mode == "closed":
                ax.plot(t, pos("sig3_h_rms_m"), "--", color=colors[m], lw=0.8,
                        label="filter 3σ (RMS), closed")
        ax.set(yscale="log", xlabel="time (s)")
        ax.set_ylim(bottom=1e-3)         # the replay meets its waypoints to ~1e-5 m: below the axis
        ax.set_title(f"{m}: horizontal, RMS over runs\n(control error at the first image is 0: not drawn)", fontsize=9)
        ax.legend(fontsize=6)
    axes[0, 0].set_ylabel("horizontal error (m)")
    fig.tight_layout()
    return save(fig, Path(out_dir) / "gnc_error_history")


def consistency_figure(ts_rows: list[dict], out_dir: Path) -> list[str]:
    """ANEES/6 and ANIS/dof per image time of the closed loops (all runs), the 95 % χ² band shaded, inside (●,
    PASS) / outside (✕, FAIL)."""
    rows_all = [t for t in ts_rows if t["mode"] == "closed" and t["runs"] == "all"]
    methods = sorted({t["method"] for t in rows_all})
    colors = method_colors(methods)
    fig, axes = plt().subplots(1, 2, figsize=(10, 3.8), squeeze=False)
    for ax, (key, lo, hi, ok_key, title) in zip(axes[0], (
            ("anees_over_6", "anees_lo", "anees_hi", "anees_pass", "ANEES / 6 (state, 6 dof)"),
            ("anis_per_dof", "anis_lo", "anis_hi", "anis_pass", "ANIS / dof (landmark pixels)"))):
        for m in methods:
            rows = [t for t in rows_all if t["method"] == m and np.isfinite(t[key])]
            if not rows:
                continue
            t = np.array([x["t_s"] for x in rows])
            v = np.array([x[key] for x in rows])
            ok = np.array([bool(x[ok_key]) for x in rows])
            ax.fill_between(t, [x[lo] for x in rows], [x[hi] for x in rows], color=colors[m], alpha=0.12, lw=0)
            ax.plot(t, v, color=colors[m], lw=1.2, label=m)
            ax.plot(t[ok], v[ok], "o", color=colors[m], ms=4)
            ax.plot(t[~ok], v[~ok], "x", color=colors[m], ms=6, mew=1.5)
        ax.axhline(1.0, color="k", lw=0.6)
        ax.set(yscale="log", xlabel="time (s)", ylabel=f"{title.split(' (')[0]} (—)")
        ax.set_title(f"{title}, closed loops, all runs\nshaded: 95 % χ² band; ● inside (PASS), ✕ outside (FAIL)",
                     fontsize=8)
        ax.legend(fontsize=8)
    fig.tight_layout()
    return save(fig, Path(out_dir) / "gnc_consistency")
