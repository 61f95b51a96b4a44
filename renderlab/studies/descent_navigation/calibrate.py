r"""The landmark error model the map-state filter declares (eqs. C1–C3 of docs/descent_navigation.md), fitted per
method and maplet tier on a *calibration* campaign's landmark table. ``python -m
renderlab.studies.descent_navigation.calibrate FOLDER`` prints the fit as JSON, then as ``landmark_error_by_method``.
"""

from __future__ import annotations

import json
import math
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np


def track_sums(run, item, err_s, err_l, gsd) -> dict:
    """The sums over one method's and tier's kept landmarks (arrays of equal length) that the fit of eqs. C1–C3
    reads: the bias ``beta_s/l`` (mean error), the cross products within tracks (C2) and the residuals of the
    per-track fit (C3), summed over the tracks (a track: one landmark in one run), with their counts."""
    e = np.stack([err_s, err_l], 1).astype(float)
    ok = np.all(np.isfinite(e), 1) & np.isfinite(gsd) & (gsd > 0)
    e, g, run, item = e[ok], np.asarray(gsd, float)[ok], np.asarray(run)[ok], np.asarray(item)[ok]
    beta = e.mean(0)
    d = e - beta
    m = d * g[:, None]
    tracks = defaultdict(list)
    for j, key in enumerate(zip(run.tolist(), item.tolist())):
        tracks[key].append(j)
    cross, n_pairs, rss, n_res = 0.0, 0, 0.0, 0
    for idx in tracks.values():
        if len(idx) < 2:
            continue
        mm = m[idx]                                          # (n, 2)
        s = mm.sum(0)
        cross += float(np.sum(s**2 - np.sum(mm**2, 0)))      # Σ_{k≠k'} m_k m_k', both axes (C2)
        n_pairs += 2 * len(idx) * (len(idx) - 1)
        x = 1.0 / g[idx]                                     # C3: e = b x + w, b fitted per track and axis
        b = (x @ d[idx]) / (x @ x)
        rss += float(np.sum((d[idx] - np.outer(x, b)) ** 2))
        n_res += 2 * (len(idx) - 1)
    return {"beta_s_px": float(beta[0]), "beta_l_px": float(beta[1]), "cross_m2": cross, "n_pairs": int(n_pairs),
            "rss_px2": rss, "n_res": int(n_res), "n_landmarks": int(len(e)),
            "n_tracks": int(sum(len(v) >= 2 for v in tracks.values()))}


def fit_sums(sums: dict, floor_px: float = 0.02) -> dict:
    """The fit of eqs. C1–C3 from :func:`track_sums`."""
    cross, n_pairs, rss, n_res = sums["cross_m2"], sums["n_pairs"], sums["rss_px2"], sums["n_res"]
    var_map = max(cross / n_pairs, 0.0) if n_pairs else math.nan
    var_px = rss / n_res if n_res else math.nan
    return {"sigma_map_h_m": math.sqrt(var_map) if math.isfinite(var_map) else math.nan,
            "sigma_px": max(math.sqrt(max(var_px, 0.0)), floor_px), "sigma_px_fit": math.copysign(
                math.sqrt(abs(var_px)), var_px) if math.isfinite(var_px) else math.nan,
            "bias_s_px": sums["beta_s_px"], "bias_l_px": sums["beta_l_px"], "n_landmarks": int(sums["n_landmarks"]),
            "n_tracks": int(sums["n_tracks"]), "n_pairs": int(n_pairs // 2)}


def fit_method(run, item, err_s, err_l, gsd, floor_px: float = 0.02) -> dict:
    """The fit of eqs. C1–C3 for one method's kept landmarks (arrays of equal length)."""
    return fit_sums(track_sums(run, item, err_s, err_l, gsd), floor_px)


def fit_rows(cols: dict) -> list[dict]:
    """One :func:`track_sums` row per method and landmark tier (maplet spacing; tiers in decreasing spacing) of the
    kept landmarks, ``cols``: arrays ``method, run, item, kept, err_s, err_l, gsd_m, spacing_m``."""
    out = []
    for meth in sorted(set(cols["method"].tolist())):
        for sp in sorted(set(cols["spacing_m"].tolist()), reverse=True):
            k = (cols["method"] == meth) & cols["kept"] & (cols["spacing_m"] == sp)
            if k.sum() >= 2:
                out.append({"method": meth, "spacing_m": float(sp),
                            **track_sums(cols["run"][k], cols["item"][k], cols["err_s"][k], cols["err_l"][k],
                                         cols["gsd_m"][k])})
    return out


def fit(fit_table, floor_px: float = 0.02) -> dict:
    """{method: {spacing_m: fit}}: one fit per method and landmark tier, its bias removed per method and tier, from
    the published table ``descent_landmark_fit`` (:func:`fit_rows` of a campaign's kept landmarks,
    :func:`renderlab.studies.descent_navigation.publish.publish_tables`)."""
    out: dict = {}
    for r in fit_table.to_pylist():
        out.setdefault(r["method"], {})[float(r["spacing_m"])] = fit_sums(r, floor_px)
    return out


def toml_rows(res: dict) -> str:
    """``landmark_error_by_method`` of the fit, as a TOML inline table (spacing, σ_px, σ_map_h; 3 significant
    figures)."""
    parts = []
    for meth, by in res.items():
        rows = ", ".join(f"[{sp:g}, {f['sigma_px']:.3g}, {f['sigma_map_h_m']:.3g}]" for sp, f in by.items())
        parts.append(f"{meth} = [{rows}]")
    return "landmark_error_by_method = {" + ", ".join(parts) + "}"


def main(argv=None) -> int:
    import pyarrow.parquet as pq

    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 1 or not (Path(args[0]) / "tables" / "descent_landmark_fit.parquet").is_file():
        print("usage: python -m renderlab.studies.descent_navigation.calibrate FOLDER (a published descent campaign "
              "with tables/descent_landmark_fit.parquet)", file=sys.stderr)
        return 2
    res = fit(pq.read_table(Path(args[0]) / "tables" / "descent_landmark_fit.parquet"))
    print(json.dumps({m: {str(sp): {k: (round(v, 6) if isinstance(v, float) else v) for k, v in f.items()}
                          for sp, f in by.items()} for m, by in res.items()}, indent=2))
    print(toml_rows(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
