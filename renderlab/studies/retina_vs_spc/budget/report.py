"""The error budget's report, from its tables alone (:mod:`renderlab.campaign.oat_tables`, statistics
:mod:`renderlab.stats.oat_budget`; what each file holds: ``docs/retina_vs_spc.md``): ``FOLDER/report/``
``budget_summary.csv``, ``budget_terms.csv`` (PASS when sum / all-on is within 20 %), ``budget_breakdown.csv``,
``budget_table.md``, ``error_budget.png``; with the probes' tables ``budget_supersample.csv`` and ``budget_crlb.csv``
(made by ``investigations/error_budget/``; :mod:`.crlb`); with the navigation tables ``budget_navigation*.csv`` and ``.png``
(:mod:`.navigation_report`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from renderlab.campaign import store
from renderlab.campaign.oat_tables import TABLES
from renderlab.errors import UserError
from renderlab.report.budget_figure import budget_figure
from renderlab.report.csvio import write_csv
from renderlab.stats import oat_budget as S
from renderlab.stats.bootstrap import cluster_bootstrap
from renderlab.studies.retina_vs_spc.budget import crlb as BC
from renderlab.studies.retina_vs_spc.budget import navigation_report as NR
from renderlab.studies.retina_vs_spc.budget.plan import BUDGET_TABLES, TERMS_ORDER, method_order
from renderlab.studies.retina_vs_spc.config import RetinaVsSpcConfig
from renderlab.studies.retina_vs_spc.report import well_measured_mask

N_BOOT_SUMMARY, N_BOOT_JOINT, SEED = 1000, 500, 20
SUPERSAMPLE, PROBE = (1, 3, 6), "budget_supersample"  # the template-sampling probe's k and table
SHADOW_CONFIG = "no_shadows"  # renderlab.studies.retina_vs_spc.budget.shadows.CONFIG
BANDS = (("gsd<0.5", 0.0, 0.5), ("0.5<=gsd<=2", 0.5, 2.0), ("gsd>2", 2.0, np.inf))


def compute(meas, configs, gross_px: float = 1.0) -> tuple[list, list, list]:
    """(summary rows, term rows, breakdown rows) of a budget's tables (module docstring)."""
    cols = S.columns(meas)
    runs = dict(zip(configs.column("config").to_pylist(), configs.column("runs").to_pylist()))
    sources = [s for s in configs.column("source").to_pylist() if s]
    methods = method_order(cols["method"])
    weights = S.joint_weights(cols["n_clusters"], N_BOOT_JOINT, SEED)
    summary, terms = [], []
    subsets = {"all": np.ones(meas.num_rows, bool), "well_measured": well_measured_mask(meas, RetinaVsSpcConfig())}
    for sub, mask in subsets.items():
        for axis in S.AXES:
            samp = {m: {c: S.sample(cols, c, m, mask, axis, runs[c]) for c in runs} for m in methods}
            for m in methods:
                for c in runs:
                    row = S.summary_row(samp[m][c], weights, gross_px, N_BOOT_SUMMARY, SEED)
                    summary.append({"config": c, "method": m, "subset": sub, "axis": axis, **row})
                rows = S.budget_rows(samp[m], sources, weights, gross_px)
                if m == "retina" and "retina_refined" in samp:
                    rows += _peak_rows(S, samp["retina"]["all_off"], samp["retina_refined"]["all_off"], weights,
                                       gross_px)
                if SHADOW_CONFIG in samp[m]:
                    rows += _peak_rows(S, samp[m]["all_off"], samp[m][SHADOW_CONFIG], weights, gross_px,
                                       "shadow_approximation")
                for r in rows:
                    r.update(method=m, subset=sub, axis=axis)
                terms += _with_check(rows)
    return summary, terms, _breakdown(S, cols, runs, methods, gross_px)


def _peak_rows(S, a, b, weights, gross_px, name: str = "peak_step") -> list[dict]:
    """A term measured at all off, signed √(v²(a) − v²(b)): ``peak_step`` (a = Retina's 3×3 step, b =
    ``retina_refined``) or ``shadow_approximation`` (a = all off, b = ``no_shadows``, :mod:`.shadows`)."""
    out = []
    for st in S.STATS:
        def term(w, st=st):
            d = np.asarray(S.weighted_stat(st, a, w, gross_px)) ** 2 - np.asarray(S.weighted_stat(st, b, w, gross_px)) ** 2
            return np.sign(d) * np.sqrt(np.abs(d))
        lo, hi = S._ci(term(weights))
        out.append({"statistic": st, "term": name, "value": float(term(np.ones(weights.shape[1]))), "lo": lo,
                    "hi": hi})
    return out


def _with_check(rows: list[dict]) -> list[dict]:
    for r in rows:
        r["check"] = ("PASS" if abs(r["value"] - 1) <= 0.2 else "FAIL") if r["term"] == "sum_over_all_on" and \
            np.isfinite(r["value"]) else ""
    order = {t: i for i, t in enumerate(TERMS_ORDER + ("sum_over_all_on",))}
    return sorted(rows, key=lambda r: (r["statistic"], order.get(r["term"], 99)))


def _breakdown(S, cols, runs, methods, gross_px) -> list[dict]:
    """All-off rows (both axes) by GSD-ratio band and by truth shadow: rms of the per-landmark bias."""
    out = []
    g, sh = cols["gsd_ratio"], cols["shadow_fraction"]
    groups = [(n, (g >= lo) & (g < hi) if np.isfinite(hi) else g >= lo) for n, lo, hi in BANDS]
    groups += [("no_truth_shadow", sh == 0), ("truth_shadow>0", sh > 0)]
    for m in methods:
        for name, mask in groups:
            s = S.sample(cols, "all_off", m, mask, "both", runs["all_off"])
            ones = np.ones(cols["n_clusters"])
            out.append({"method": m, "group": name, "results": int(s.err.size),
                        "landmark_frames": int(np.unique(s.cluster).size),
                        "robust_sigma": S.weighted_stat("robust_sigma", s, ones, gross_px),
                        "bias_rms": S.weighted_stat("bias_rms", s, ones, gross_px),
                        "crlb": float(np.nanmedian(s.crlb)) if np.isfinite(s.crlb).any() else float("nan"),
                        "noise_over_crlb_sensor_noise": _noise_ratio(S, cols, runs, m, mask, gross_px)})
    return out


def _noise_ratio(S, cols, runs, method, mask, gross_px) -> float:
    """rms of noise sd / CRLB of the sensor-noise-alone configuration over the rows of ``mask`` (NaN if absent)."""
    if runs.get("sensor_noise", 0) < 2:
        return float("nan")
    r = S.noise_over_crlb(S.sample(cols, "sensor_noise", method, mask, "both", runs["sensor_noise"]), gross_px)
    return float(np.sqrt(np.mean(r))) if r.size else float("nan")


def _cell(rows, method, term, stat) -> str:
    r = next((r for r in rows if r["method"] == method and r["term"] == term and r["statistic"] == stat), None)
    if r is None or not np.isfinite(r["value"]):
        return "–"
    if term == "sum_over_all_on":
        return f"{r['value']:.2f} [{r['lo']:.2f}, {r['hi']:.2f}] {r['check']}"
    return f"{r['value']:.3f} [{r['lo']:.3f}, {r['hi']:.3f}]"


def markdown(summary: list[dict], terms: list[dict]) -> str:
    """The README's tables: per statistic, the budget terms per method (subset all, both axes pooled)."""
    rows = [r for r in terms if r["subset"] == "all" and r["axis"] == "both"]
    methods = list(dict.fromkeys(r["method"] for r in rows))
    out = []
    names = {"robust_sigma": "robust σ", "std": "std", "bias_rms": "per-landmark bias rms",
             "noise_sd": "per-landmark noise sd"}
    for st, title in names.items():
        out += [f"### {title} (px; all landmarks with a truth pixel, both axes pooled; contribution = "
                "signed √(v²(source alone) − v²(all off)))", "",
                "| term | " + " | ".join(methods) + " |", "|---|" + "---|" * len(methods)]
        for t in TERMS_ORDER + ("sum_over_all_on",):
            if any(r["term"] == t and r["statistic"] == st for r in rows):
                out.append(f"| {t} | " + " | ".join(_cell(rows, m, t, st) for m in methods) + " |")
        out.append("")
    crlb = [r for r in summary if r["subset"] == "all" and r["axis"] == "both" and r["config"] == "sensor_noise"]
    out += ["### sensor noise alone against the CRLB (all landmarks, both axes pooled)", "",
            "| method | median CRLB (px) | noise sd (px) | rms of noise sd / CRLB |", "|---|---|---|---|"]
    for r in crlb:
        out.append(f"| {r['method']} | {r['crlb']:.4f} | {r['noise_sd']:.4f} [{r['noise_sd_lo']:.4f}, "
                   f"{r['noise_sd_hi']:.4f}] | {r['noise_over_crlb']:.2f} [{r['noise_over_crlb_lo']:.2f}, "
                   f"{r['noise_over_crlb_hi']:.2f}] |")
    return "\n".join(out) + "\n"


def probe_rows(table, n_boot: int = 1000, seed: int = 20) -> list[dict]:
    """The template-sampling probe's table (``investigations/error_budget/supersample_probe.py``): per method and k, per-landmark bias rms (both axes; all-off rows are deterministic, so the
    error of each landmark-frame is its bias) with a 95 % cluster-bootstrap interval over landmark-frames."""
    d = {c: np.asarray(table.column(c).to_pylist()) for c in table.column_names}
    out = []
    for m in dict.fromkeys(d["method"]):
        for k in SUPERSAMPLE:
            sel = (d["method"] == m) & (d["supersample"] == k) & d["truth_visible"].astype(bool)
            e = np.concatenate([d["err_s"][sel], d["err_l"][sel]]).astype(float)
            clu = np.concatenate([d["frame"][sel] * 1_000_000 + d["item"][sel]] * 2)
            ok = np.isfinite(e) & (np.abs(e) <= 1.0)
            iv = cluster_bootstrap(e[ok], clu[ok], "rms", n_boot=n_boot, rng=seed, cluster_name="landmark-frames")
            out.append({"method": m, "supersample": int(k), "results": int(ok.sum()), "bias_rms": iv.estimate,
                        "bias_rms_lo": iv.lo, "bias_rms_hi": iv.hi})
    return out


def _probe_markdown(rows: list[dict]) -> str:
    out = ["### all off: Retina's template supersampling k × k (per-landmark bias rms, px, both axes)", "",
           "| method | k | results | bias rms |", "|---|---|---|---|"]
    out += [f"| {r['method']} | {r['supersample']} | {r['results']} | {r['bias_rms']:.4f} [{r['bias_rms_lo']:.4f}, "
            f"{r['bias_rms_hi']:.4f}] |" for r in rows]
    return "\n".join(out) + "\n"


def write_report(folder: Path, out_dir: Path | None = None) -> Path:
    """Write ``out_dir`` (default ``folder/report/``) from ``folder/tables/`` alone (staged: all or nothing);
    returns the report folder."""
    folder = Path(folder)
    if not folder.is_dir():
        raise UserError(f"{folder}: no such folder")
    meas, configs = BUDGET_TABLES.read(folder)
    summary, terms, breakdown = compute(meas, configs)
    p = folder / TABLES / f"{PROBE}.parquet"
    probe = probe_rows(pq.read_table(p)) if p.is_file() else []
    out_dir = Path(out_dir) if out_dir is not None else folder / "report"
    with store.staged_folder(out_dir, "the error-budget report") as stage:
        write_csv(stage / "budget_summary.csv", summary)
        write_csv(stage / "budget_terms.csv", terms)
        write_csv(stage / "budget_breakdown.csv", breakdown)
        md = markdown(summary, terms)
        if probe:
            write_csv(stage / "budget_supersample.csv", probe)
            md += _probe_markdown(probe)
        crlb_probe = BC.read_probe(folder)
        if crlb_probe is not None:
            crlb_rows = BC.report_rows(meas, configs, crlb_probe)
            write_csv(stage / "budget_crlb.csv", crlb_rows)
            md += "\n" + BC.markdown(crlb_rows)

        sources = [s for s in configs.column("source").to_pylist() if s]
        nav = NR.write(folder, stage, sources)
        md += ("\n" + nav) if nav else ""
        (stage / "budget_table.md").write_text(md, encoding="utf-8")
        budget_figure(summary, terms, stage / "error_budget", TERMS_ORDER)
    return out_dir


class _BudgetFolder:
    """An error-budget folder (``budget.json`` + ``tables/``) as a result-folder kind of ``renderlab report``."""

    name = "error_budget"

    def recognises(self, folder: Path) -> bool:
        return (Path(folder) / "budget.json").is_file()

    def write_report(self, folder: Path, out_dir: Path | None) -> list[Path]:
        out = write_report(folder, out_dir)
        return sorted(out.iterdir())


RESULT_FOLDER = _BudgetFolder()
