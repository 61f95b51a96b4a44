"""The error budget's report, from its tables alone (:mod:`renderlab.campaign.oat_tables`, statistics
:mod:`renderlab.stats.oat_budget`).

``python -m renderlab.studies.retina_vs_spc.budget report FOLDER`` writes ``FOLDER/report/``:

* ``budget_summary.csv`` — per configuration, method, subset (``all``: every landmark with a truth pixel;
  ``well_measured``: the study's pre-declared subset) and axis: rates, mean, robust σ, std, per-landmark bias
  rms and noise sd with 95 % cluster-bootstrap intervals (landmark-frames), median CRLB, noise / CRLB;
* ``budget_terms.csv`` — per method, subset, axis and statistic: all-off value, each source's contribution,
  the quadrature sum, all-on and sum / all-on (joint cluster bootstrap), ``check`` PASS when sum / all-on is
  within 20 %; for ``retina`` also ``peak_step`` (3×3 step vs ``retina_refined``, both all off); with the
  ``no_shadows`` configuration, ``shadow_approximation`` (all off vs no cast shadows, :mod:`.shadows`);
* ``budget_breakdown.csv`` — the all-off rows by GSD ratio band and by truth shadow (none vs some): where the
  residual of the exact models comes from; and the sensor-noise-alone rms noise sd / CRLB in the same groups;
* ``budget_table.md`` — the README's tables; ``error_budget.png`` — the figure (``.svg`` with ``--svg``);
* with ``tables/budget_navigation.parquet`` (:mod:`.navigation`): ``budget_navigation.csv`` (each
  source's contribution to the descent filter's touchdown-proxy error), ``budget_navigation_validation.csv``
  (geometric all-on vs the rendered closed-loop campaign) and ``budget_navigation.png``
  (:mod:`.navigation_report`);
* with ``tables/budget_crlb.parquet`` (:mod:`.crlb`): ``budget_crlb.csv`` — the budget's CRLB (from its
  8-spp truth render) against clean renders' bound, and the sensor-noise-alone noise / CRLB with each bound.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from renderlab.campaign import store
from renderlab.campaign.oat_tables import TABLES
from renderlab.errors import UserError
from renderlab.report.budget_figure import budget_figure
from renderlab.stats import oat_budget as S
from renderlab.studies.retina_vs_spc.budget import crlb as BC
from renderlab.studies.retina_vs_spc.budget import navigation_report as NR
from renderlab.studies.retina_vs_spc.budget.plan import BUDGET_TABLES, TERMS_ORDER
from renderlab.studies.retina_vs_spc.budget.probe import PROBE, probe_rows
from renderlab.studies.retina_vs_spc.config import RetinaVsSpcConfig
from renderlab.studies.retina_vs_spc.report import well_measured_mask

N_BOOT_SUMMARY, N_BOOT_JOINT, SEED = 1000, 500, 20
SHADOW_CONFIG = "no_shadows"  # renderlab.studies.retina_vs_spc.budget.shadows.CONFIG
BANDS = (("gsd<0.5", 0.0, 0.5), ("0.5<=gsd<=2", 0.5, 2.0), ("gsd>2", 2.0, np.inf))


def _subsets(table, cols) -> dict:
    return {"all": np.ones(table.num_rows, bool), "well_measured": well_measured_mask(table, RetinaVsSpcConfig())}


def _write_csv(path: Path, rows: list[dict]) -> None:
    keys = list(rows[0]) if rows else []
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=keys, lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def compute(meas, configs, gross_px: float = 1.0) -> tuple[list, list, list]:
    """(summary rows, term rows, breakdown rows) of a budget's tables (module docstring)."""
    cols = S.columns(meas)
    runs = dict(zip(configs.column("config").to_pylist(), configs.column("runs").to_pylist()))
    sources = [s for s in configs.column("source").to_pylist() if s]
    methods = sorted(set(cols["method"]), key=lambda m: (m != "retina", m != "retina_refined", m))
    weights = S.joint_weights(cols["n_clusters"], N_BOOT_JOINT, SEED)
    summary, terms = [], []
    for sub, mask in _subsets(meas, cols).items():
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


def _probe(folder: Path) -> list[dict]:
    """The template-sampling probe's rows (:mod:`.probe`), or [] when the folder has no probe table."""
    import pyarrow.parquet as pq


    p = Path(folder) / TABLES / f"{PROBE}.parquet"
    return probe_rows(pq.read_table(p)) if p.is_file() else []


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
    probe = _probe(folder)
    out_dir = Path(out_dir) if out_dir is not None else folder / "report"
    with store.staged_folder(out_dir, "the error-budget report") as stage:
        _write_csv(stage / "budget_summary.csv", summary)
        _write_csv(stage / "budget_terms.csv", terms)
        _write_csv(stage / "budget_breakdown.csv", breakdown)
        md = markdown(summary, terms)
        if probe:
            _write_csv(stage / "budget_supersample.csv", probe)
            md += _probe_markdown(probe)

        crlb_probe = BC.read_probe(folder)
        if crlb_probe is not None:
            crlb_rows = BC.report_rows(meas, configs, crlb_probe)
            _write_csv(stage / "budget_crlb.csv", crlb_rows)
            md += "\n" + BC.markdown(crlb_rows)

        sources = [s for s in configs.column("source").to_pylist() if s]
        nav = NR.write(folder, stage, sources, _write_csv)
        md += ("\n" + nav) if nav else ""
        (stage / "budget_table.md").write_text(md, encoding="utf-8")
        budget_figure(summary, terms, stage / "error_budget", TERMS_ORDER)
    return out_dir


class _BudgetFolder:
    """An error-budget folder (``budget.json`` + ``tables/``) as a result-folder kind
    (:mod:`renderlab.contracts.result_folder`): ``renderlab report FOLDER`` regenerates its report."""

    name = "error_budget"

    def recognises(self, folder: Path) -> bool:
        return (Path(folder) / "budget.json").is_file()

    def write_report(self, folder: Path, out_dir: Path | None) -> list[Path]:
        out = write_report(folder, out_dir)
        return sorted(out.iterdir())


RESULT_FOLDER = _BudgetFolder()
