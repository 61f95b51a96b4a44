"""What a published ``descent_navigation`` folder ships (``Study.publish_tables``) and the only form the report
reads: the report applies :func:`publish_tables` to whatever tables it is given (a raw campaign's or a published
folder's; on published tables it changes nothing), so both give one report (docs/descent_navigation.md,
"Published tables").

* ``descent_filter``: per row the columns that are drawn or averaged per run (errors, NEES, NIS, counts, injected
  error); the 1σ ``sig_e/n/u_m`` only at the last image (``error_flights.rendered_touchdown``);
* ``descent_images`` (per method and image, runs that kept track): the means of the squared 1σ, ρ of the whitened
  errors, the landmark common shares and the similarity pattern;
* ``descent_landmark_runs`` / ``descent_landmark_tiers`` (per method and run [and maplet tier], kept landmarks of
  the runs that kept track): counts and sums of the landmark errors (bias bootstraps over runs, rms, std);
* ``descent_landmark_fit`` (per method and tier, every kept landmark): the sums of the calibration fit
  (:func:`.calibrate.track_sums`).
"""

from __future__ import annotations

import math

import numpy as np

from renderlab.stats.consistency import columns, tracked
from renderlab.stats.independence import (
    WHITE,
    landmark_shares,
    similarity_pattern,
    state_common_share,
    tracked_landmarks,
)
from renderlab.studies.descent_navigation.calibrate import fit_rows
from renderlab.studies.descent_navigation.scoring import POS, VEL

IMAGES, RUNS, TIERS, FIT = "descent_images", "descent_landmark_runs", "descent_landmark_tiers", "descent_landmark_fit"
SIG = tuple(c.replace("err_", "sig_") for c in POS + VEL)
INJ = ("inj_bias_s_px", "inj_bias_l_px", "inj_sigma_bias_px", "inj_scale", "inj_sigma_noise_px",
       "inj_map_offset_h_m", "inj_map_offset_v_m")
#: the per-row filter columns a published folder keeps (``sig_*_m`` of position at the last image only)
FILTER_KEEP = ("run", "method", "frame", "t_s", "nees", "nis", "dof", "n_results", "n_flagged", "n_gated", "n_kept",
               "track_lost", *POS, *VEL, *SIG[:3], "src_kind", *INJ)
LANDMARKS = ("run", "method", "frame", "item", "kept", "err_s", "err_l", "meas_s", "meas_l", "pred_s", "pred_l",
             "truth_s", "truth_l", "gsd_m", "spacing_m")


def publish_tables(tables: dict) -> dict:
    """Raw campaign tables → the published ones (module docstring); tables already published come back as given."""
    out = dict(tables)
    ftab = out.get("descent_filter")
    if ftab is None or ftab.num_rows == 0 or IMAGES in out:
        return out
    import pyarrow.compute as pc

    ltab = out.pop("descent_landmarks", None)
    if ltab is not None:
        ltab = ltab.filter(pc.field("kept"))
        ltab = ltab.select([c for c in ltab.column_names if c in LANDMARKS])
    out[IMAGES] = _table(image_rows(ftab, ltab))
    if ltab is not None:
        lt = tracked_landmarks(ftab, ltab)
        out[RUNS] = _table(landmark_sums(lt, ("method", "run")))
        if "spacing_m" in ltab.column_names:
            out[TIERS] = _table(landmark_sums(lt, ("method", "spacing_m", "run")))
            if "gsd_m" in ltab.column_names:
                out[FIT] = _table(fit_rows(columns(ltab, ("method", "run", "item", "kept", "err_s", "err_l", "gsd_m",
                                                          "spacing_m"))))
    last = pc.equal(ftab.column("frame"), pc.max(ftab.column("frame")))
    f = ftab.select([c for c in ftab.column_names if c in FILTER_KEEP])
    for name in SIG[:3]:
        if name in f.column_names:
            col = f.column(name)
            f = f.set_column(f.column_names.index(name), name, pc.if_else(last, col, None))
    out["descent_filter"] = f
    return out


def image_index(tables: dict) -> dict:
    """``{(method, frame): row}`` of the ``descent_images`` table of published tables."""
    return {(r["method"], int(r["frame"])): r for r in tables[IMAGES].to_pylist()}


def _table(rows: list[dict]):
    import pyarrow as pa

    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    return pa.table({k: [r.get(k) for r in rows] for k in cols})


def image_rows(ftab, ltab) -> list[dict]:
    """One row per method and image of the runs that kept track: the means of the squared 1σ over the runs with a
    finite NEES (``sig2_*``, the consistency tables) and over every run (``sig2_fig_*``, the error figures),
    the squared 1σ position norm (``sig2_pos``), ρ of the whitened errors and, from the kept landmarks, the common
    shares and the similarity pattern (:mod:`renderlab.stats.independence`)."""
    white = "white_0" in ftab.column_names
    c = columns(tracked(ftab), ("method", "frame", "t_s", "nees", *SIG, *(WHITE if white else ())))
    lc = None
    if ltab is not None:
        lc = columns(tracked_landmarks(ftab, ltab), [n for n in LANDMARKS if n in ltab.column_names])
    out = []
    for m in sorted(set(c["method"].tolist())):
        sel = (c["method"] == m) & (c["frame"] >= 0)
        for k in sorted(set(c["frame"][c["method"] == m].tolist())):
            s = (c["method"] == m) & (c["frame"] == k)
            ok = s & np.isfinite(c["nees"])
            n = int(ok.sum())
            sig = np.stack([c[a][ok] for a in SIG[:3]], 1)
            row = {"method": m, "frame": int(k),
                   **{f"sig2_{a}": float(np.mean(sig[:, j] ** 2)) if n else math.nan for j, a in enumerate("enu")},
                   "sig2_pos": float(np.mean(np.sqrt(sum(c[a][ok] ** 2 for a in SIG[:3])) ** 2)) if n else math.nan}
            at = sel & (c["t_s"] == c["t_s"][s][0]) if k >= 0 else None
            row.update({f"sig2_fig_{a[4:]}": float(np.nanmean(c[a][at] ** 2)) if k >= 0 else math.nan for a in SIG})
            if white:
                row["rho_state"] = state_common_share(np.stack([c[w][ok] for w in WHITE], 1))
            if lc is not None and k >= 0:
                row.update(landmark_shares(lc, m, k))
                if "spacing_m" in lc:
                    row.update(_pattern(lc, m, k))
            out.append(row)
    return out


def _pattern(lc: dict, m: str, k: int) -> dict:
    sel = (lc["method"] == m) & (lc["frame"] == k) & lc["kept"]
    p = similarity_pattern(lc["truth_s"][sel], lc["truth_l"][sel], lc["err_s"][sel], lc["err_l"][sel])
    keys = ("n_landmarks", "scale", "rotation_rad", "shift_s_px", "shift_l_px", "radius_max_px")
    return {f"pattern_{key}": (p[key] if p else None) for key in keys}


def landmark_sums(lt, keys: tuple[str, ...]) -> list[dict]:
    """Per group of ``keys`` (the last one the bootstrap cluster, ``run``) of the kept landmarks ``lt``: rows, and
    per axis the finite rows and their sum (made as :func:`renderlab.stats.bootstrap.cluster_bootstrap` makes its
    cluster sums), the sums of the squared error in px and on the ground (× GSD), and the sum of the GSD."""
    names = ["kept", "err_s", "err_l", *keys, *(["gsd_m"] if "gsd_m" in lt.column_names else [])]
    c = columns(lt, names)
    out = []
    head = keys[:-1]
    groups = sorted(set(zip(*(c[k].tolist() for k in head))), key=lambda g: (g[0], *(-v for v in g[1:])))
    for g in groups:
        k = c["kept"].copy()
        for name, v in zip(head, g):
            k &= c[name] == v
        runs = c[keys[-1]][k]
        uniq, inv = np.unique(runs, return_inverse=True)
        inv = inv.ravel()
        sums = {}
        for ax in ("s", "l"):
            e = c[f"err_{ax}"][k]
            fin = np.isfinite(e)
            sums[f"n_{ax}"] = np.bincount(inv[fin], minlength=len(uniq))
            sums[f"sum_{ax}"] = np.bincount(inv[fin], e[fin], minlength=len(uniq))
            sums[f"sumsq_{ax}"] = np.array([np.sum(e[inv == j] ** 2) for j in range(len(uniq))])
            if "gsd_m" in c:
                sums[f"sumsq_{ax}_m"] = np.array([np.sum((e * c["gsd_m"][k])[inv == j] ** 2)
                                                  for j in range(len(uniq))])
        if "gsd_m" in c:
            sums["sum_gsd_m"] = np.array([np.sum(c["gsd_m"][k][inv == j]) for j in range(len(uniq))])
        rows_per = np.bincount(inv, minlength=len(uniq))
        for j, r in enumerate(uniq.tolist()):
            out.append({**dict(zip(head, (v.item() if hasattr(v, "item") else v for v in g))), keys[-1]: r,
                        "n_rows": int(rows_per[j]), **{n: (int(v[j]) if n.startswith("n_") else float(v[j]))
                                                       for n, v in sums.items()}})
    return out
