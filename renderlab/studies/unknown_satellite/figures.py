"""Figures and score summary of an unknown-satellite campaign, like Ivanov et al. (2018) Figs 5-7 (stage-1
convergence, inertia ratios with their Cramér–Rao σ, reference points) and 13-14 (stage-2 errors against time),
over runs, from the campaign's tables alone in the report style (:mod:`renderlab.report.style`). Body-frame
quantities are drawn with the principal axes relabelled to the truth's (the ``*_aligned`` columns)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.campaign.scoring import column_array as column
from renderlab.report import style
from renderlab.report.axes import integer_ticks, plain_log
from renderlab.studies.unknown_satellite.config import RUN_FLAGS


def _score_id(col: str, scale: float) -> str:
    """The score id in the unit of the summary: a column in m (m/s) scaled by 100 is in cm (cm/s)."""
    if scale != 100:
        return col
    return col[:-4] + "_cm_s" if col.endswith("_mps") else col[:-2] + "_cm"


#: scores summarised across runs: column → (score id in the unit of the summary, label, scale, unit, group)
SCORES = {c: (_score_id(c, k), label, k, unit, g) for c, label, k, unit, g in [
    ("point_lvlh_err_rms_m", "reference points, RMS error in LVLH at the epoch", 100, "cm", "g"),
    ("point_lvlh_crlb_rms_m", "reference points in LVLH, CRLB σ (RMS over points, eq. 7)", 100, "cm", "g"),
    ("point_shape_err_rms_m", "reference points, RMS error after the best rotation", 100, "cm", "g"),
    ("r0_err_m", "initial position error ‖r0‖", 100, "cm", "g"),
    ("v0_err_mps", "initial velocity error ‖v0‖", 100, "cm/s", "g"),
    ("v0_crlb_mps", "initial velocity CRLB σ (eq. 7)", 100, "cm/s", "g"),
    ("stage2_pos_rms_m", "stage 2: position RMS", 100, "cm", "g"),
    ("stage2_vel_rms_mps", "stage 2: velocity RMS", 100, "cm/s", "g"),
    ("w0_norm_est_deg_s", "‖ω0‖ estimated", 1, "deg/s", "g"),
    ("w0_norm_err_deg_s", "‖ω0‖ error", 1, "deg/s", "g"),
    ("w0_norm_crlb_deg_s", "‖ω0‖ CRLB σ (eq. 7)", 1, "deg/s", "g"),
    ("w0_lvlh_err_deg_s", "ω0 error in LVLH (vector)", 1, "deg/s", "g"),
    ("err_moments_sorted_max", "trace-normalised principal moments, max error (axis labels free)", 1, "—", "g"),
    ("inertia_tensor_lvlh_err_max", "trace-normalised inertia tensor in LVLH, max error", 1, "—", "g"),
    ("point_err_rms_m", "reference points, RMS error in the body frame", 100, "cm", "b"),
    ("point_err_rms_aligned_m", "reference points, RMS error in the body frame, axes relabelled to truth", 100, "cm",
     "b"),
    ("stage2_att_rms_deg", "stage 2: attitude RMS error (principal axes)", 1, "deg", "b"),
    ("stage2_att_rms_aligned_deg", "stage 2: attitude RMS error, axes relabelled to truth", 1, "deg", "b"),
    *((f"stage2_w{a}_rms_deg_s", f"stage 2: ω{a} RMS error", 1, "deg/s", "b") for a in "xyz"),
    *((f"stage2_w{a}_rms_aligned_deg_s", f"stage 2: ω{a} RMS error, axes relabelled", 1, "deg/s", "b") for a in "xyz"),
    ("err_ratio_12", "I1/I3 error", 1, "—", "b"),
    ("err_ratio_12_aligned", "I1/I3 error, axes relabelled to truth", 1, "—", "b"),
    ("err_ratio_23", "I2/I3 error", 1, "—", "b"),
    ("err_ratio_23_aligned", "I2/I3 error, axes relabelled to truth", 1, "—", "b"),
    ("ratio_sigma_1", "I1/I3 CRLB σ (eq. 7)", 1, "—", "b"),
    ("ratio_sigma_2", "I2/I3 CRLB σ (eq. 7)", 1, "—", "b"),
    ("stage1_rms_px", "stage 1: residual RMS", 1, "px", "d"),
    ("database_points", "database points", 1, "points", "d"),
    ("rigidity_rejected", "tracks rejected by the rigidity test", 1, "tracks", "d")]}
#: (raw, relabelled) score columns: the same quantity before and after the discrete principal-axes gauge
PAIRS = [(c.replace("_aligned", ""), c) for c in SCORES if "_aligned" in c]


#: the columns of the per-iterate and per-frame tables that the figures read (and the filter-table core of ``stage2``)
PUBLISHED_COLUMNS = {
    "stage1_history": ("campaign", "run", "iteration", *(f"err_r0_{a}_m" for a in "xyz"),
                       *(f"err_v0_{a}_mps" for a in "xyz"), "err_ratio12", "err_ratio23", "err_points_rms_m"),
    "stage2": ("campaign", "run", "t_s", "has_result", "reason", *(f"err_{q}{a}_{u}" for q, u in (("r", "m"),
               ("v", "mps")) for a in "xyz"), *(f"err_w{a}_aligned_deg_s" for a in "xyz"), "err_att_aligned_deg"),
}


def publish_tables(tables: dict) -> dict:
    """What a published folder ships (:attr:`renderlab.contracts.study.Study.publish_tables`): ``scores`` and
    ``inertia_observability`` whole, ``stage1_history`` and ``stage2`` with the columns the report reads; ``points``
    and ``perturbations``, which the report does not read, left out (recorded in ``raw_tables.json``)."""
    from renderlab.campaign.compact import keep_columns

    kept = {k: v for k, v in tables.items() if k not in ("points", "perturbations")}
    return keep_columns(kept, PUBLISHED_COLUMNS)


def score_summary(scores) -> list[dict]:
    """Per score: runs, mean, std, median, 10th and 90th percentile in the unit of :data:`SCORES` (the score id
    carries that unit); per run flag: ``flagged`` runs of ``runs`` and their ``rate`` (fraction)."""
    rows = []
    for col, (sid, label, scale, unit, _) in SCORES.items():
        if col not in scores.column_names:
            continue
        v = column(scores, col) * scale
        v = v[np.isfinite(v)]
        if not len(v):
            continue
        p10, med, p90 = np.percentile(v, [10, 50, 90])
        rows.append({"score": sid, "label": label, "unit": unit, "runs": len(v), "mean": float(v.mean()),
                     "std": float(v.std(ddof=1)) if len(v) > 1 else float("nan"), "median": float(med),
                     "p10": float(p10), "p90": float(p90)})

    for name, on in run_flags(scores).items():
        rows.append({"score": f"flag_{name}", "label": RUN_FLAGS[name], "unit": "runs", "runs": len(on),
                     "flagged": int(np.sum(on)), "rate": float(np.mean(on)) if len(on) else float("nan")})
    return rows


def run_flags(scores) -> dict[str, np.ndarray]:
    """Flag name → bool per run, from the ``flag_<name>`` columns."""
    return {n: column(scores, f"flag_{n}", bool) for n in RUN_FLAGS if f"flag_{n}" in scores.column_names}


def same_pairs(scores) -> set[str]:
    """Raw score columns equal to their relabelled twin in every run (no run relabelled: show one)."""
    out = set()
    for raw, al in PAIRS:
        if raw in scores.column_names and al in scores.column_names:
            if np.allclose(column(scores, raw), column(scores, al), rtol=1e-12, atol=0, equal_nan=True):
                out.add(raw)
    return out


def _by_run(t, cols):
    runs = column(t, "run", np.int64)
    for r in np.unique(runs):
        sel = runs == r
        yield r, {c: column(t, c)[sel] for c in cols}


def _runs_line(ax, n: int, color=style.OKABE_ITO[0]) -> None:
    ax.plot([], [], color=color, lw=0.8, alpha=0.7, label=f"one line per run ({n} runs)")


def _run_lines(ax, t, x: str, ys: list[str], scale: float = 1, lw: float = 0.7, alpha: float = 0.6) -> list:
    """One line per run of ``scale``·‖(ys)‖ (the column itself for one) against column ``x``; the values drawn."""
    vals = []
    for _, d in _by_run(t, [x, *ys]):
        vals.append(scale * (np.linalg.norm([d[c] for c in ys], axis=0) if len(ys) > 1 else d[ys[0]]))
        ax.plot(d[x], vals[-1], color=style.OKABE_ITO[0], lw=lw, alpha=alpha)
    return vals


def _two_panels(figsize: tuple[float, float]):
    return style.plt().subplots(1, 2, figsize=figsize, constrained_layout=True)


def _finish(fig, ax, title: str, stem: Path, which: str = "both") -> list[str]:
    """Legend and grid on both panels, the title, saved (PNG; SVG under ``--svg``)."""
    for a in ax:
        a.legend(fontsize=8)
        a.grid(alpha=0.3, which=which)
    fig.suptitle(title)
    return style.save(fig, stem)


def fig5_convergence(hist, stem: Path) -> list[str]:
    fig, ax = _two_panels((10, 3.8))
    for a, q, u, ylabel, title in ((ax[0], "r0", "m", "‖r0 error‖ (cm)", "(a) initial CM position"),
                                   (ax[1], "v0", "mps", "‖v0 error‖ (cm/s)", "(b) initial CM velocity")):
        vals = _run_lines(a, hist, "iteration", [f"err_{q}_{c}_{u}" for c in "xyz"], 100)
        plain_log(a, np.concatenate(vals))
        _runs_line(a, len(vals))
        integer_ticks(a)
        a.set(xlabel="accepted iterate (count)", ylabel=ylabel, title=title)
    return _finish(fig, ax, "Stage 1: convergence of the initial centre-of-mass state (cf. Ivanov et al. Fig. 5)", stem)


def fig6_inertia(hist, scores, stem: Path) -> list[str]:
    c1, c2 = style.OKABE_ITO[0], style.OKABE_ITO[1]
    fig, ax = _two_panels((10.5, 4.2))
    for _, d in _by_run(hist, ["iteration", "err_ratio12", "err_ratio23"]):
        ax[0].plot(d["iteration"], d["err_ratio12"], color=c1, lw=0.6, alpha=0.6)
        ax[0].plot(d["iteration"], d["err_ratio23"], color=c2, lw=0.6, alpha=0.6)
    ax[0].plot([], [], color=c1, label="I1/I3 (one line per run)")
    ax[0].plot([], [], color=c2, label="I2/I3 (one line per run)")
    ax[0].axhline(0, color="k", lw=0.5)
    integer_ticks(ax[0])
    ax[0].set(xlabel="accepted iterate (count)", ylabel="ratio error (dimensionless)",
              title="(a) convergence, principal axes as estimated")
    al = "ratio_I1_I3_aligned" in scores.column_names
    e1 = column(scores, "ratio_I1_I3_aligned" if al else "ratio_I1_I3_est")
    e2 = column(scores, "ratio_I2_I3_aligned" if al else "ratio_I2_I3_est")
    s1, s2 = column(scores, "ratio_sigma_1"), column(scores, "ratio_sigma_2")
    fb = run_flags(scores).get("inertia_boundary", np.zeros(scores.num_rows, bool))
    t1, t2 = column(scores, "ratio_I1_I3_true"), column(scores, "ratio_I2_I3_true")
    lo, hi = np.nanmin(np.r_[e1, e2, t1, t2]) - 0.2, np.nanmax(np.r_[e1, e2, t1, t2]) + 0.2
    lo = max(lo, 0)
    wide = ~((s1 <= 0.25 * (hi - lo)) & (s2 <= 0.25 * (hi - lo)))  # a bar across the panel says nothing: not drawn
    for m, mk, col, lab in ((~fb, "o", c1, "free solve"), (fb, "s", c2, "physical re-solve (boundary)")):
        if m.any():
            ax[1].errorbar(e1[m & ~wide], e2[m & ~wide], xerr=s1[m & ~wide], yerr=s2[m & ~wide], fmt=mk, color=col,
                           ms=4, lw=0.6, alpha=0.7, label=f"{lab}: {int(m.sum())} runs")
            ax[1].plot(e1[m & wide], e2[m & wide], mk, color=col, ms=4, mfc="none", alpha=0.8)
    ax[1].plot(t1, t2, "k*", ms=12, label="truth")
    x = np.linspace(0, 2, 50)
    ax[1].plot(x, 1 - x, "k:", lw=0.8, label="I1 + I2 = I3 (flat body)")
    bars = "bars: CRLB 1σ" if not wide.any() else (
        f"bars: CRLB 1σ; {int(wide.sum())} of {len(wide)} runs (open) have σ > ¼ of the panel "
        f"(median {np.nanmedian(np.r_[s1[wide], s2[wide]]):.2g}), not drawn")
    ax[1].set(xlim=(lo, hi), ylim=(lo, hi), xlabel="I1/I3 (dimensionless)", ylabel="I2/I3 (dimensionless)",
              title="(b) final ratios" + (", axes relabelled" if al else ""))
    ax[1].text(0.98, 0.02, bars, transform=ax[1].transAxes, fontsize=7, ha="right", va="bottom",
               bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "0.7", "alpha": 0.85})
    return _finish(fig, ax, "Stage 1: inertia ratios (cf. Ivanov et al. Fig. 6)", stem, which="major")


def fig7_points(hist, scores, stem: Path) -> list[str]:
    fig, ax = _two_panels((10.5, 4.0))
    vals = _run_lines(ax[0], hist, "iteration", ["err_points_rms_m"], 100)
    plain_log(ax[0], np.concatenate(vals) if vals else [])
    _runs_line(ax[0], len(vals))
    integer_ticks(ax[0])
    ax[0].set(xlabel="accepted iterate (count)", ylabel="RMS point error, body frame (cm)", title="(a) convergence")
    runs = column(scores, "run", np.int64)
    series = [("point_lvlh_err_rms_m", "o", "LVLH at the epoch (gauge-free)")]
    if "point_err_rms_aligned_m" in scores.column_names:
        series.append(("point_err_rms_aligned_m", "^", "body frame, axes relabelled to truth"))
    if "point_err_rms_m" not in same_pairs(scores):
        series.append(("point_err_rms_m", "s", "body frame, principal axes as estimated"))
    allv = []
    for k, (col, mk, lab) in enumerate(series):
        v = 100 * column(scores, col)
        ax[1].plot(runs, v, mk, color=style.OKABE_ITO[k], mfc="none" if k else None, label=lab)
        allv.append(v)
    ax[1].axhline(3.0, color="k", ls="--", lw=0.8, label="paper: 3 cm")
    plain_log(ax[1], np.concatenate(allv + [[3.0]]))
    integer_ticks(ax[1])
    ax[1].set(xlabel="run (index)", ylabel="RMS point error (cm)", title="(b) final, per run")
    ax[0].legend(fontsize=8)
    ax[1].legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=2)
    for a in ax:
        a.grid(alpha=0.3, which="both")
    fig.suptitle("Stage 1: reference points (cf. Ivanov et al. Fig. 7)")
    return style.save(fig, stem)


def _rms_over_runs(t, col):
    ts, v = column(t, "t_s"), column(t, col)
    u = np.unique(ts)
    return u, np.array([np.sqrt(np.nanmean(v[ts == x] ** 2)) for x in u])


def fig13_position(s2, stem: Path) -> list[str]:
    fig, ax = _two_panels((10.5, 4.0))
    for k, (q, u) in enumerate((("r", "m"), ("v", "mps"))):
        cols = [f"err_{q}{a}_{u}" for a in "xyz"]
        n = len(_run_lines(ax[k], s2, "t_s", cols, 100, lw=0.5, alpha=0.4))
        t = np.unique(column(s2, "t_s"))
        ax[k].plot(t, 100 * np.sqrt(sum(_rms_over_runs(s2, c)[1] ** 2 for c in cols)), "k", lw=1.5,
                   label="RMS over runs")
        _runs_line(ax[k], n)
    ax[1].axhline(1.0, color=style.OKABE_ITO[1], ls="--", lw=1.0, label="paper: ≈1 cm/s")
    ax[0].set(xlabel="time (s)", ylabel="‖position error‖ (cm)", title="(a) CM position, LVLH")
    ax[1].set(xlabel="time (s)", ylabel="‖velocity error‖ (cm/s)", title="(b) CM velocity, LVLH")
    return _finish(fig, ax, "Stage 2: relative centre-of-mass position and velocity (cf. Ivanov et al. Fig. 13)", stem,
                   which="major")


def fig14_attitude(s2, stem: Path) -> list[str]:
    fig, ax = _two_panels((10.5, 4.0))
    al = "err_wx_aligned_deg_s" in s2.column_names
    for i, a in enumerate("xyz"):
        u, r = _rms_over_runs(s2, f"err_w{a}_aligned_deg_s" if al else f"err_w{a}_deg_s")
        ax[0].plot(u, r, color=style.OKABE_ITO[i], lw=1.5, label=f"ω{a}, RMS over runs")
    ax[0].set(xlabel="time (s)", ylabel="body-rate error (deg/s)",
              title="(a) body rates" + (", axes relabelled" if al else ""))
    att = "err_att_aligned_deg" if "err_att_aligned_deg" in s2.column_names else "err_att_deg"
    _runs_line(ax[1], len(_run_lines(ax[1], s2, "t_s", [att], lw=0.5, alpha=0.5)))
    plain_log(ax[1], column(s2, att))
    ax[1].set(xlabel="time (s)", ylabel="attitude error (deg)",
              title="(b) principal-axes attitude" + (", axes relabelled" if att != "err_att_deg" else ""))
    return _finish(fig, ax, "Stage 2: body rates and attitude of the principal axes (cf. Ivanov et al. Fig. 14)", stem)


def campaign_figures(tables: dict, out_dir: Path, prefix: str = "unknown_satellite_") -> list[dict]:
    """Draw the figures that the tables allow (PNG; SVG under ``--svg``); return ``{"name", "png", "svg", "caption"}``
    each (``svg`` None when none is written)."""
    out_dir = Path(out_dir)
    done = []
    sc, hist, s2 = tables.get("scores"), tables.get("stage1_history"), tables.get("stage2")
    jobs = [("fig5_convergence", hist is not None, lambda p: fig5_convergence(hist, p),
             "Stage-1 errors of the initial centre-of-mass position and velocity at every accepted iterate."),
            ("fig6_inertia", hist is not None and sc is not None, lambda p: fig6_inertia(hist, sc, p),
             "Inertia ratios: convergence, and the final ratios of every run with their Cramér–Rao 1σ."),
            ("fig7_points", hist is not None and sc is not None, lambda p: fig7_points(hist, sc, p),
             "Reference-point RMS error: convergence (body frame), and per run at the end."),
            ("fig13_stage2_position", s2 is not None, lambda p: fig13_position(s2, p),
             "Stage-2 centre-of-mass position and velocity error against time."),
            ("fig14_stage2_attitude", s2 is not None, lambda p: fig14_attitude(s2, p),
             "Stage-2 body-rate RMS error per axis and the principal-axes attitude error per run.")]
    for name, ok, draw, caption in jobs:
        if ok:
            png, svg = draw(out_dir / f"{prefix}{name}")
            done.append({"name": name, "png": png, "svg": svg, "caption": caption})
    return done

