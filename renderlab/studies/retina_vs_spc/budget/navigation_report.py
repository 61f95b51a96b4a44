"""The navigation budget's statistics, tables and figure (:mod:`.navigation`), from its tables alone: per mapping,
method and statistic (touchdown-proxy rms 3-D, east, north, up) each source's contribution ``sign(d)·√|d|``, d =
v²(source alone) − v²(all off), the quadrature sum against all on (PASS within 20 %), the floor, ``peak_step`` and
``shadow_approximation``; runs that diverged in any configuration left out; 95 % bootstrap over runs, paired
(``docs/retina_vs_spc.md``). ``validation``: geometric all-on against the rendered closed-loop campaign. The figure
(:func:`navigation_figure`): per method the terms' touchdown rms 3-D (mapping ``altitude``, the others as markers),
PASS/FAIL over the sum bar; below, the validation.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.campaign.oat_tables import TABLES
from renderlab.report import style
from renderlab.report.csvio import write_csv
from renderlab.studies.retina_vs_spc.budget.navigation import NONE_CONFIG, NONE_METHOD, RENDERED, TABLE, term_order
from renderlab.studies.retina_vs_spc.budget.plan import method_order

N_BOOT, SEED, TOL = 1000, 21, 0.2
SHADOW_CONFIG = "no_shadows"  # .shadows.CONFIG: its term is at all off, like the peak step
STATS = ("rms_3d", "rms_e", "rms_n", "rms_u")
AXES = {"rms_3d": ("e", "n", "u"), "rms_e": ("e",), "rms_n": ("n",), "rms_u": ("u",)}


def _by(cols, mapping, config, method):
    m = (cols["mapping"] == mapping) & (cols["config"] == config) & (cols["method"] == method)
    o = np.argsort(cols["run"][m])
    return {k: v[m][o] for k, v in cols.items()}


def _columns(table) -> dict:
    cols = {k: np.asarray(table.column(k).to_pylist()) for k in ("mapping", "config", "method")}
    for k in ("run", "err_e_m", "err_n_m", "err_u_m", "err_norm_m", "track_lost", "diverged"):
        cols[k] = np.asarray(table.column(k).to_numpy(zero_copy_only=False))
    return cols


def _sq(rows, stat) -> np.ndarray:
    return sum(rows[f"err_{a}_m"].astype(float) ** 2 for a in AXES[stat])


def _ci(reps) -> tuple[float, float]:
    r = reps[np.isfinite(reps)]
    return (float(np.percentile(r, 2.5)), float(np.percentile(r, 97.5))) if r.size >= 10 else (np.nan, np.nan)


def _signed_root(d):
    return np.sign(d) * np.sqrt(np.abs(d))


def terms(table, sources: list[str]) -> list[dict]:
    """Per mapping, method and statistic: floor, all off, each source, peak step, quadrature sum, all on, ratio."""
    cols = _columns(table)
    floor_rows = _by(cols, "", NONE_CONFIG, NONE_METHOD)
    out = []
    for mp in [m for m in dict.fromkeys(cols["mapping"]) if m]:
        for meth in method_order(cols["method"][cols["mapping"] == mp]):
            have = [s for s in sources if (_by(cols, mp, s, meth)["run"]).size]
            names = ["all_off", *have, "all_on"]
            rows = {c: _by(cols, mp, c, meth) for c in names}
            if meth == "retina" and _by(cols, mp, "all_off", "retina_refined")["run"].size:
                rows["refined_off"] = _by(cols, mp, "all_off", "retina_refined")
            if _by(cols, mp, SHADOW_CONFIG, meth)["run"].size:
                rows[SHADOW_CONFIG] = _by(cols, mp, SHADOW_CONFIG, meth)
            rows["floor"] = floor_rows
            runs = floor_rows["run"]
            ok = np.ones(runs.size, bool)
            for r in rows.values():
                if not np.array_equal(r["run"], runs):
                    raise ValueError(f"navigation budget: {mp}/{meth}: configurations have different runs")
                ok &= ~r["diverged"].astype(bool) & np.isfinite(r["err_norm_m"].astype(float))
            rng = np.random.default_rng(SEED)
            idx = rng.integers(0, int(ok.sum()), (N_BOOT, int(ok.sum())))
            for st in STATS:
                sq = {c: _sq(r, st)[ok] for c, r in rows.items()}
                est = _term_values(sq, have, lambda x: np.mean(x))
                rep = _term_values(sq, have, lambda x, idx=idx: np.mean(x[idx], axis=1))
                for term, v in est.items():
                    lo, hi = _ci(rep[term])
                    chk = ("PASS" if abs(v - 1) <= TOL else "FAIL") if term == "sum_over_all_on" else ""
                    out.append({"mapping": mp, "method": meth, "statistic": st, "term": term, "value": float(v),
                                "lo": lo, "hi": hi, "check": chk, "runs": int(ok.sum()),
                                "runs_lost": int((~ok).sum())})
    return out


def _term_values(sq: dict, have: list, mean) -> dict:
    v2 = {c: mean(x) for c, x in sq.items()}
    d = {s: v2[s] - v2["all_off"] for s in have}
    q = v2["all_off"] + sum(d.values())
    t = {"floor": np.sqrt(v2["floor"]), "all_off": np.sqrt(v2["all_off"]), **{s: _signed_root(x) for s, x in d.items()}}
    if "refined_off" in v2:
        t["peak_step"] = _signed_root(v2["all_off"] - v2["refined_off"])
    if SHADOW_CONFIG in v2:
        t["shadow_approximation"] = _signed_root(v2["all_off"] - v2[SHADOW_CONFIG])
    t["quadrature_sum"] = np.sqrt(np.clip(q, 0, None))
    t["all_on"] = np.sqrt(v2["all_on"])
    with np.errstate(invalid="ignore", divide="ignore"):
        t["sum_over_all_on"] = t["quadrature_sum"] / t["all_on"]
    return t


def validation(table, rendered) -> list[dict]:
    """Geometric all-on (each mapping) against the rendered campaign, per method, on the runs that kept track
    in the rendered campaign (and did not diverge in the geometric one): rms (3-D, per axis), median, p95."""
    cols = _columns(table)
    rc = {k: np.asarray(rendered.column(k).to_pylist()) for k in ("run", "method", "track_lost")}
    for a in "enu":
        rc[f"err_{a}_m"] = np.asarray(rendered.column(f"err_{a}_m").to_numpy(zero_copy_only=False), float)
    out = []
    for meth in method_order(rc["method"]):
        r_m = rc["method"] == meth
        good = {int(r) for r, lost in zip(rc["run"][r_m], rc["track_lost"][r_m]) if not lost}
        sources = [("rendered", "", {k: v[r_m] for k, v in rc.items()})]
        sources += [("geometric", mp, _by(cols, mp, "all_on", meth)) for mp in dict.fromkeys(cols["mapping"]) if mp]
        for kind, mp, rows in sources:
            if rows["run"].size == 0:
                continue
            keep = np.array([int(r) in good for r in rows["run"]])
            if "diverged" in rows:
                keep &= ~rows["diverged"].astype(bool)
            e = np.stack([rows[f"err_{a}_m"][keep].astype(float) for a in "enu"], 1)
            out.append({"method": meth, "kind": kind, "mapping": mp, **_val_stats(e)})
    return out


def _val_stats(e: np.ndarray) -> dict:
    n = np.linalg.norm(e, axis=1)
    rng = np.random.default_rng(SEED)
    idx = rng.integers(0, len(n), (N_BOOT, len(n)))
    row = {"runs": int(len(n))}
    fns = {"rms_3d": lambda x: np.sqrt(np.mean(x ** 2, axis=-1)), "median_norm": lambda x: np.median(x, axis=-1),
           "p95_norm": lambda x: np.percentile(x, 95, axis=-1)}
    for k, f in fns.items():
        row[k] = float(f(n))
        row[f"{k}_lo"], row[f"{k}_hi"] = _ci(f(n[idx]))
    for j, a in enumerate("enu"):
        row[f"rms_{a}"] = float(np.sqrt(np.mean(e[:, j] ** 2)))
        row[f"mean_{a}"] = float(np.mean(e[:, j]))
    return row


def markdown(term_rows: list[dict], val_rows: list[dict]) -> str:
    """The README's navigation tables: the budget per mapping (rms_3d, with per-axis rows), the validation."""
    out = []
    for mp in dict.fromkeys(r["mapping"] for r in term_rows):
        rows = [r for r in term_rows if r["mapping"] == mp]
        meths = list(dict.fromkeys(r["method"] for r in rows))
        out += [f"### navigation: touchdown-proxy (50 m) position error, mapping `{mp}` (m; rms over runs; "
                "contribution = signed √(v²(source alone) − v²(all off)))", "",
                "| term | statistic | " + " | ".join(meths) + " |", "|---|---|" + "---|" * len(meths)]
        for term in term_order(rows):
            for st in STATS:
                cells = []
                for m in meths:
                    r = next((x for x in rows if x["method"] == m and x["term"] == term and x["statistic"] == st),
                             None)
                    cells.append("–" if r is None else _fmt(r))
                if any(c != "–" for c in cells):
                    out.append(f"| {term} | {st} | " + " | ".join(cells) + " |")
        out.append("")
    out += ["### navigation: geometric all-on vs the rendered closed-loop campaign (touchdown proxy, runs that "
            "kept track in the rendered campaign; m)", "",
            "| method | source | mapping | runs | rms 3-D [95 %] | median \\|δr\\| [95 %] | p95 \\|δr\\| | rms e, n, u |"
            " mean e, n, u |", "|---|---|---|---|---|---|---|---|---|"]
    for r in val_rows:
        out.append(f"| {r['method']} | {r['kind']} | {r['mapping'] or '–'} | {r['runs']} | {r['rms_3d']:.4f} "
                   f"[{r['rms_3d_lo']:.4f}, {r['rms_3d_hi']:.4f}] | {r['median_norm']:.4f} [{r['median_norm_lo']:.4f}, "
                   f"{r['median_norm_hi']:.4f}] | {r['p95_norm']:.4f} | {r['rms_e']:.4f}, {r['rms_n']:.4f}, "
                   f"{r['rms_u']:.4f} | {r['mean_e']:+.4f}, {r['mean_n']:+.4f}, {r['mean_u']:+.4f} |")
    return "\n".join(out) + "\n"


def _fmt(r) -> str:
    if r["term"] == "sum_over_all_on":
        return f"{r['value']:.2f} [{r['lo']:.2f}, {r['hi']:.2f}] {r['check']}"
    return f"{r['value']:.4f} [{r['lo']:.4f}, {r['hi']:.4f}]"


# ------------------------------------------------------------------- the figure
PRIMARY = "altitude"
MARKERS = {"ground": "v", "pixel": "^"}


def _bars(ax, rows, methods, labels, colors):
    width = 0.8 / max(len(methods), 1)
    x = np.arange(len(labels))
    for j, m in enumerate(methods):
        xs = x - 0.4 + (j + 0.5) * width
        vals, lo, hi = (np.full(len(labels), np.nan) for _ in range(3))
        for i, t in enumerate(labels):
            r = next((r for r in rows if r["mapping"] == PRIMARY and r["method"] == m and r["term"] == t), None)
            if r is not None:
                vals[i], lo[i], hi[i] = r["value"], r["lo"], r["hi"]
        err = np.where(np.isfinite(np.vstack([vals - lo, hi - vals])), np.vstack([vals - lo, hi - vals]), 0.0)
        ax.bar(xs, np.nan_to_num(vals), width, color=colors[m], label=f"{m} ({PRIMARY})",
               yerr=np.clip(err, 0, None), capsize=2, error_kw={"elinewidth": 0.8})
        for mp, mk in MARKERS.items():
            v = [next((r["value"] for r in rows if r["mapping"] == mp and r["method"] == m and r["term"] == t),
                      np.nan) for t in labels]
            ax.plot(xs, v, mk, color="black", ms=3, ls="none", label=f"{mp} mapping" if j == 0 else None)
        chk = next((r for r in rows if r["mapping"] == PRIMARY and r["method"] == m
                    and r["term"] == "sum_over_all_on"), None)
        if chk is not None and "quadrature_sum" in labels:
            i = labels.index("quadrature_sum")
            top = max([np.nan_to_num(hi[i])] + [r["value"] for r in rows if r["method"] == m
                                                 and r["term"] == "quadrature_sum"])
            ax.text(xs[i], top * 1.04, f"{chk['check']} {chk['value']:.2f}", rotation=90,
                    ha="center", va="bottom", fontsize=7)
    ax.axhline(0, color="grey", lw=0.5)
    lo_y, hi_y = ax.get_ylim()
    ax.set_ylim(lo_y, hi_y + 0.3 * (hi_y - lo_y))
    ax.set_xticks(x, [t.replace("_", " ") for t in labels], rotation=30, ha="right")
    ax.set_xlabel("budget term (contribution = signed √(v²(source alone) − v²(all off)))")
    ax.set_ylabel("touchdown rms 3-D position error (m)")
    ax.set_title("navigation budget at the 50 m touchdown proxy (PASS: quadrature sum within 20 % of all on)")
    ax.legend(ncol=3, loc="upper left", fontsize=7)


def _validation(ax, val, methods, colors):
    kinds = list(dict.fromkeys((r["kind"], r["mapping"]) for r in val))
    width = 0.8 / max(len(kinds), 1)
    x = np.arange(len(methods))
    hatch = {"rendered": "", "altitude": "//", "ground": "..", "pixel": "xx"}
    for j, (kind, mp) in enumerate(kinds):
        xs = x - 0.4 + (j + 0.5) * width
        rs = [next((r for r in val if r["method"] == m and r["kind"] == kind and r["mapping"] == mp), None)
              for m in methods]
        v = np.array([r["rms_3d"] if r else np.nan for r in rs])
        err = np.array([[r["rms_3d"] - r["rms_3d_lo"], r["rms_3d_hi"] - r["rms_3d"]] if r else [0, 0] for r in rs]).T
        ax.bar(xs, np.nan_to_num(v), width, color=[colors[m] for m in methods], edgecolor="black", lw=0.5,
               hatch=hatch.get(mp or kind, ""), yerr=np.clip(np.nan_to_num(err), 0, None), capsize=2)
        ax.bar([np.nan], [np.nan], color="white", edgecolor="black", lw=0.5, hatch=hatch.get(mp or kind, ""),
               label="rendered campaign" if kind == "rendered" else f"geometric, {mp} mapping")  # legend swatch
        med = [r["median_norm"] if r else np.nan for r in rs]
        ax.plot(xs, med, "o", color="black", ms=3, ls="none", label="median |δr|" if j == 0 else None)
    ax.set_xticks(x, methods)
    ax.set_xlabel("landmark method (all sources on; colour = method, hatch = source of the error)")
    ax.set_ylabel("touchdown rms 3-D position error (m)")
    ax.set_title("validation: rendered closed-loop campaign vs the geometric model, runs that kept track")
    ax.legend(ncol=3, loc="upper left", fontsize=7)
    lo_y, hi_y = ax.get_ylim()
    ax.set_ylim(lo_y, hi_y + 0.3 * (hi_y - lo_y))


def navigation_figure(terms: list[dict], val: list[dict], stem: Path) -> list[str]:
    """Draw the figure into ``stem``.png (statistic rms_3d); returns the file names."""
    rows = [r for r in terms if r["statistic"] == "rms_3d"]
    methods = list(dict.fromkeys(r["method"] for r in rows))
    labels = [t for t in term_order(rows) if t != "sum_over_all_on"]
    colors = style.method_colors(methods)
    plt = style.plt()
    fig, axes = plt.subplots(2 if val else 1, 1, figsize=(11, 9 if val else 5), squeeze=False)
    _bars(axes[0, 0], rows, methods, labels, colors)
    if val:
        _validation(axes[1, 0], val, [m for m in methods if any(r["method"] == m for r in val)], colors)
    fig.tight_layout()
    return style.save(fig, stem)


def write(folder: Path, stage: Path, sources: list[str]) -> str:
    """Write ``budget_navigation.csv``, ``budget_navigation_validation.csv`` and the figure into ``stage`` from
    ``folder/tables``; returns the markdown section ("" when the folder has no navigation table)."""
    import pyarrow.parquet as pq

    p, q = Path(folder) / TABLES / f"{TABLE}.parquet", Path(folder) / TABLES / f"{RENDERED}.parquet"
    if not p.is_file():
        return ""
    nav = pq.read_table(p)
    t = terms(nav, sources)
    v = validation(nav, pq.read_table(q)) if q.is_file() else []
    write_csv(stage / "budget_navigation.csv", t)
    if v:
        write_csv(stage / "budget_navigation_validation.csv", v)
    navigation_figure(t, v, stage / "budget_navigation")
    return markdown(t, v)
