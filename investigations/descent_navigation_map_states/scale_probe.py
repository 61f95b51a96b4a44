"""Probe of the image-scale part of the landmark errors (``descent_pattern.csv``): one landmark method at the
*true* pose on one truth set's cached DN images, every landmark in view whose GSD ratio is in the study's range,
with the truth set's maplet catalogue and with error-free maplets (the catalogue rebuilt with ``mapping_error_m =
albedo_error_rms = 0``, :mod:`renderlab.campaign.maplets`); prints per image the similarity fit of the errors
(:func:`renderlab.stats.independence.pattern_rows`' model: scale about the landmarks' centroid)
and their rms. A diagnostic, not a study: search distance 8 px, no filter. With a campaign's
``descent_landmarks.parquet`` (LANDMARKS), only the landmarks that campaign's METHOD kept at the image in at least
half its runs (the few the study selects, :func:`kept_items`): the true-pose share of that campaign's
``descent_pattern.csv`` scale. It explains part of ``results/descent_navigation_map_states/README.md``; an
investigation, not part of the lab (nothing imports it).

    .venv/bin/python investigations/descent_navigation_map_states/scale_probe.py SCENARIO TRUTHSET METHOD FRAMES \
        [LANDMARKS]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def similarity_scale(truth: np.ndarray, err: np.ndarray) -> float:
    """Least-squares scale a of err = a·(p − p̄) + b·J(p − p̄) + t over landmarks (truth (n, 2) px, err (n, 2))."""
    x, y = truth[:, 0] - truth[:, 0].mean(), truth[:, 1] - truth[:, 1].mean()
    n = len(x)
    A = np.zeros((2 * n, 4))
    A[:n, 0], A[n:, 0], A[:n, 1], A[n:, 1], A[:n, 2], A[n:, 3] = x, y, -y, x, 1.0, 1.0
    return float(np.linalg.lstsq(A, np.r_[err[:, 0], err[:, 1]], rcond=None)[0][0])


def kept_items(landmarks_path: Path, method: str) -> dict[int, set]:
    """{frame: landmark ids} that ``method`` kept in at least half the runs of a campaign's ``descent_landmarks``."""
    import pyarrow.parquet as pq

    t = pq.read_table(landmarks_path, columns=["run", "method", "frame", "item", "kept"]).to_pydict()
    m, f, i, k = (np.asarray(t[c]) for c in ("method", "frame", "item", "kept"))
    runs = len(set(np.asarray(t["run"])[m == method].tolist()))
    out: dict[int, set] = {}
    for fr in sorted(set(f[m == method].tolist())):
        ids, n = np.unique(i[(m == method) & (f == fr) & k], return_counts=True)
        out[int(fr)] = {int(v) for v in ids[n >= 0.5 * runs]}
    return out


def in_view(camera, pose, centres: np.ndarray, spacing: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Indices of the landmarks in front of the camera, inside the image, with GSD ratio (depth / fx / spacing) in
    [lo, hi] — the study's range."""
    xc = pose.to_camera(centres)
    ratio = xc[:, 2] / camera.fx / spacing
    return np.flatnonzero(camera.in_image(camera.project(xc)) & (xc[:, 2] > 0) & (ratio >= lo) & (ratio <= hi))


def probe(scenario_path: Path, ts_dir: Path, method: str, frames: list[int], kept: dict | None = None) -> list[str]:
    from renderlab.campaign.maplets import respaced_maplets
    from renderlab.contracts.landmark import CameraPose
    from renderlab.files.truthset import TruthSet
    from renderlab.measurement.runner import (
        MeasureOptions,
        _frame_record,
        make_method,
        onboard_photometry,
        run_method_on_image,
    )
    from renderlab.scenario import load_scenario
    from renderlab.studies.descent_navigation.run import section
    from renderlab.worlds.ev5.catalog import read_catalog

    sc, _ = load_scenario(scenario_path)
    lo, hi = section(sc).gsd_ratio_range
    ts = TruthSet.open(ts_dir)
    cat = read_catalog(ts_dir)
    exact = respaced_maplets(cat, sc.world.model_copy(update={"mapping_error_m": 0.0, "albedo_error_rms": 0.0}),
                             scenario_path.parent, 1.0, np.random.default_rng(0))
    mopts = MeasureOptions(n_sigma=3.0, min_search_px=8, max_search_px=8)
    impl = make_method(method, mopts, onboard_photometry(ts, mopts)[0])
    cen = np.array([m.center_m for m in cat])
    spacing = np.array([m.spacing_m for m in cat])
    out = []
    for k in frames:
        fr = _frame_record(ts, k)
        pose = CameraPose(fr.R, fr.position)
        xc = pose.to_camera(cen)
        sel = in_view(fr.camera, pose, cen, spacing, lo, hi)
        if kept is not None:
            sel = np.array([i for i, m in enumerate(cat) if m.landmark_id in kept.get(k, set())], int)
        cells = []
        for label, maplets in (("catalogue", cat), ("error-free maplets", exact)):
            _, res = run_method_on_image(impl, ts.load(k).dn, fr.adc_max, fr.camera, pose, fr.sun,
                                         [maplets[i] for i in sel], cen[sel], np.eye(3) * 1e-4, np.eye(3) * 1e-10,
                                         mopts, k)
            ok = [j for j, r in enumerate(res) if r.has_result]
            truth = fr.camera.project(xc[sel[ok]])
            err = np.array([[res[j].meas_s, res[j].meas_l] for j in ok]) - truth
            cells.append(f"{label}: {len(ok)} landmarks, scale {similarity_scale(truth, err):+.2e}, "
                         f"rms {np.sqrt(np.mean(err**2)):.3f} px")
        out.append(f"{method} image {k}: " + " | ".join(cells))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenario", metavar="SCENARIO", type=Path, help="the campaign's scenario.toml")
    ap.add_argument("truthset", metavar="TRUTHSET", type=Path, help="the campaign's truth set (its truth cache)")
    ap.add_argument("method", metavar="METHOD", help="a registered landmark method (retina, spc, ...)")
    ap.add_argument("frames", metavar="FRAMES", help="comma-separated image indices, e.g. 0,3,12")
    ap.add_argument("landmarks", metavar="LANDMARKS", type=Path, nargs="?",
                    help="a campaign's descent_landmarks.parquet: probe only the landmarks it kept")
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    kept = kept_items(a.landmarks, a.method) if a.landmarks is not None else None
    for line in probe(a.scenario, a.truthset, a.method, [int(v) for v in a.frames.split(",")], kept):
        print(line, flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
