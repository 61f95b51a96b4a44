"""One sentence of conclusion per method or statistic, computed from a report's own numbers.

Every report section states in words what its table shows, so a reader who does not parse the intervals still gets
the finding, and the wording cannot drift from the numbers: each sentence is built here from the summary rows the
table is built from. The words follow fixed rules (no tuned thresholds):

* a bias is **zero within its interval** when the 95 % cluster-bootstrap interval contains 0, otherwise it is
  **biased** on that axis;
* the robust σ is compared with the registration CRLB as a ratio when the table has a CRLB (a bound on the
  noise-driven spread only), with a note saying which bound the table carries (:func:`crlb_note`);
* gross errors and no-result rates are quoted as they are;
* a filter statistic is **consistent** when ANEES / ANIS lies inside its two-sided χ² band.
"""

from __future__ import annotations

import html
import math

from renderlab.report.style import label

#: the note beside a CRLB ratio of a table whose ``crlb_s``/``crlb_l`` are the finite-difference bound (no
#: ``crlb_bound`` column: every table made before :mod:`renderlab.campaign.crlb`); its figures are measured by
#: ``investigations/error_budget/crlb_continuous.py``
CRLB_NOTE_FINITE_DIFFERENCE = (
    "The registration CRLB bounds only the noise-driven spread of a shift of a known image. This table's bound is the "
    "finite-difference one (derivatives of the sampled truth pixels, over a square window). The bound of the "
    "continuous truth over the pixels the estimator reads (renderlab.campaign.crlb) was 0.755× of it on the error "
    "budget's truth (median per landmark-frame and axis; p5 0.569, p95 1.148) and 0.716× on the truth-perturbed "
    "scene (p5 0.587, p95 0.873), so against that bound the ratios here read about 1.3–1.4× higher "
    "(investigations/error_budget/crlb_continuous.md).")
#: the note for a table whose ``crlb_bound`` column says ``continuous``
CRLB_NOTE_CONTINUOUS = (
    "The registration CRLB bounds only the noise-driven spread of a shift of a known image. This table's bound is "
    "that of the continuous truth, pixel-integrated, with Poisson + read noise, over the pixels the estimator reads "
    "(renderlab.campaign.crlb).")


def crlb_note(table) -> str:
    """The note beside a table's CRLB ratios: which bound its ``crlb_s``/``crlb_l`` carry (column ``crlb_bound``)."""
    if "crlb_bound" in table.column_names and set(table.column("crlb_bound").to_pylist()) == {"continuous"}:
        return CRLB_NOTE_CONTINUOUS
    return CRLB_NOTE_FINITE_DIFFERENCE


def times(x: float) -> str:
    """A ratio for text: ``2.1×``, ``38×``, ``3983×``."""
    return f"{x:.2g}×" if abs(x) < 100 else f"{x:.0f}×"


def _pair(a: float, b: float, digits: int = 3) -> str:
    return f"({a:+.{digits}f}, {b:+.{digits}f}) px"


def _bias_words(s: dict, l_: dict) -> str:
    zero = [r["bias_px_lo"] <= 0.0 <= r["bias_px_hi"] for r in (s, l_)]
    if not all(math.isfinite(r["bias_px"]) for r in (s, l_)):
        return "no bias estimate (no results)"
    if all(zero):
        return f"bias {_pair(s['bias_px'], l_['bias_px'])}, zero within its 95 % interval on both axes"
    axes = " and ".join(n for n, z in zip(("sample", "line"), zero) if not z)
    return f"biased {_pair(s['bias_px'], l_['bias_px'])}: the 95 % interval excludes zero on {axes}"


def landmark_sentence(method: str, s: dict, l_: dict, gross_px: float) -> str:
    """The conclusion for one method from its two :func:`renderlab.report.landmark_stats.method_summary` rows
    (sample, line); HTML-escaped text."""
    if s["n_result"] == 0:
        return (f"<b>{html.escape(method)}</b>: no result on any of its {s['n_rows']} rows "
                f"(see why below).")
    parts = [_bias_words(s, l_),
             f"robust σ {s['robust_sigma_px']:.3f} / {l_['robust_sigma_px']:.3f} px (sample / line)"]
    ratio = [r.get("robust_sigma_over_crlb", math.nan) for r in (s, l_)]
    if all(math.isfinite(x) for x in ratio):
        parts[-1] += f" = {times(ratio[0])} / {times(ratio[1])} the registration CRLB"
    parts.append(f"{100 * s['gross_rate']:.1f} % / {100 * l_['gross_rate']:.1f} % of results beyond the "
                 f"{gross_px:g} px gross-error threshold")
    nores = s["no_result_rate"]
    parts.append("every row has a result" if nores == 0 else f"no result on {100 * nores:.1f} % of rows")
    return f"<b>{html.escape(method)}</b>: " + "; ".join(parts) + "."


def landmark_conclusions(summary: list[dict], gross_px: float) -> str:
    """One sentence per method of a subset's summary rows, as one HTML paragraph body."""
    methods = sorted({r["method"] for r in summary})
    out = []
    for m in methods:
        s = next(r for r in summary if r["method"] == m and r["axis"] == "s")
        l_ = next(r for r in summary if r["method"] == m and r["axis"] == "l")
        out.append(landmark_sentence(m, s, l_, gross_px))
    return "Conclusion. " + " ".join(out) if out else ""


def filter_sentence(rows: list[dict]) -> str:
    """The conclusion for a filter table from :func:`renderlab.campaign.scoring.score_filter` rows."""
    out = []
    for r in rows:
        if r["quantity"] not in ("anees", "anis") or not math.isfinite(r["mean"]):
            continue
        inside = r["chi2_lo"] <= r["mean"] <= r["chi2_hi"]
        word = "consistent" if inside else ("over-confident" if r["mean"] > r["chi2_hi"] else "under-confident")
        out.append(f"{r['quantity'].upper()} {r['mean']:.3g} is {'inside' if inside else 'outside'} its 95 % χ² band "
                   f"[{r['chi2_lo']:.3g}, {r['chi2_hi']:.3g}]: {word} "
                   f"({100 * r['fraction_inside']:.0f} % of the times inside their own band)")
    errs = [r for r in rows if r["quantity"].startswith("err_") and math.isfinite(r.get("rms", math.nan))]
    if errs:
        worst = max(errs, key=lambda r: r["rms"])
        out.append(f"the largest RMS error is in {label(worst['quantity'][4:])}: {worst['rms']:.3g}")
    return ("Conclusion: " + "; ".join(out) + ".") if out else ""
