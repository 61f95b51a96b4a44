"""Retina's error on rendered EV5 frames: truth photometry (McEwen = Retina's own model, or the EV5
default Hapke) × Retina's photometry (``fixed`` β = exp(−α/60°), or ``fitted`` L(α) to the catalogued law)
× peak finder, on the landmarks selected by ``tests/test_measure_ev5.py`` (well lit, unoccluded, ≥ 300
template pixels, maplet spacing ≤ 2 px) and on the rest.

Same two 128 × 128 frames (65 m, 45 m) and perfect maplets as the test; a-priori pose = true pose.
``--seeds`` renders more EV5 worlds (the scenario's ``world.seed``; the test's is 5) and pools them; the
last table compares ``fitted`` with ``fixed`` landmark by landmark on the pooled selection.

    NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/bench_retina_ev5_accuracy.py [--laws mcewen hapke]
        [--seeds 5] [--out DIR]
"""

from __future__ import annotations

import argparse
import copy
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_measure_ev5 import SCENARIO, select_well_measurable  # noqa: E402

FINDERS = ("retina_3x3", "upsampled", "quadric_2d", "gaussian", "parabola_1d")
PHOTOMETRY = ("fixed", "fitted")


def _row(label, es, er):
    return (f"{label} {es.size:5d} {np.nanmax(es):8.3f} {np.sqrt(np.nanmean(es ** 2)):8.3f} "
            f"{int(np.sum(es >= 0.3)):8d}   {er.size:6d} {np.median(er):11.3f}")


def main():
    from renderlab.files.truthset import TruthSet
    from renderlab.measurement.runner import MeasureOptions, measure_truthset
    from renderlab.pipeline import render_truthset
    from renderlab.scenario import scenario_from_dict
    from renderlab.worlds.ev5.catalog import read_catalog

    ap = argparse.ArgumentParser()
    ap.add_argument("--out", help="folder for the truth sets (default: a temporary one)")
    ap.add_argument("--laws", nargs="+", default=["mcewen", "hapke"], choices=["mcewen", "hapke"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[int(SCENARIO["world"]["seed"])],
                    help="EV5 world seeds (default: the test's)")
    args = ap.parse_args()
    root = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="retina_ev5_"))
    head = (f"{'n sel':>5s} {'max sel':>8s} {'rms sel':>8s} {'n >= 0.3':>8s}   {'n rest':>6s} {'median rest':>11s}")
    print(f"{'law':8s} {'seed':>4s} {'photometry':13s} {'finder':12s} " + head)
    pooled = {}  # (law, photometry, finder) -> (errors of the selection, errors of the rest)
    for law in args.laws:
        for seed in args.seeds:
            sc = copy.deepcopy(SCENARIO)
            sc["world"]["law"] = law
            sc["world"]["seed"] = seed
            path = render_truthset(scenario_from_dict(sc), ".", root / f"{law}_{seed}", progress=False)
            ts, maplets = TruthSet.open(path), read_catalog(path)
            truth = ts.read_table("landmark_truth").to_pydict()
            sel = select_well_measurable(truth, {int(m.landmark_id): int(m.n) for m in maplets})
            keys = list(zip(truth["frame"], truth["landmark_id"]))
            for photometry, finder in [(p, f) for p in PHOTOMETRY for f in FINDERS]:
                opts = MeasureOptions(sigma_pos_m=(0.0,) * 3, sigma_att_rad=(0.0,) * 3, peak=finder, supersample=2,
                                      photometry=photometry)
                m = measure_truthset(ts, maplets, "retina", opts, np.random.default_rng(0)).to_pydict()
                row = {(f, i): k for k, (f, i) in enumerate(zip(m["frame"], m["item"]))}
                e = np.array([np.hypot(m["err_s"][row[k]], m["err_l"][row[k]]) if k in row else np.nan for k in keys])
                es, er = e[sel], e[~sel & np.isfinite(e)]
                a, b = pooled.setdefault((law, photometry, finder), ([], []))
                a.append(es)
                b.append(er)
                print(f"{law:8s} {seed:4d} {m['photometry'][0]:13s} {finder:12s} " + _row("", es, er)[1:])
    if len(args.seeds) > 1:
        print(f"\npooled over seeds {args.seeds}")
        print(f"{'law':8s} {'photometry':13s} {'finder':12s} " + head)
        for (law, photometry, finder), (a, b) in pooled.items():
            print(f"{law:8s} {photometry:13s} {finder:12s} " + _row("", np.concatenate(a), np.concatenate(b))[1:])
    print("\nfitted vs fixed, landmark by landmark on the pooled selection (error in px)")
    print(f"{'law':8s} {'finder':12s} {'fitted better':>13s} {'median fixed':>12s} {'median fitted':>13s}")
    for law in args.laws:
        for finder in FINDERS:
            fx = np.concatenate(pooled[law, "fixed", finder][0])
            ft = np.concatenate(pooled[law, "fitted", finder][0])
            ok = np.isfinite(fx) & np.isfinite(ft)
            print(f"{law:8s} {finder:12s} {int(np.sum(ft[ok] < fx[ok])):6d} / {int(ok.sum()):4d} "
                  f"{np.median(fx[ok]):12.3f} {np.median(ft[ok]):13.3f}")
    print(f"truth sets in {root}")


if __name__ == "__main__":
    main()
