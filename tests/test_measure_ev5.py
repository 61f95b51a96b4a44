"""Retina end to end on rendered EV5 descent frames (the acceptance of the Retina and SPC methods).

The real pipeline and Mitsuba backend render two small frames of the procedural EV5 landing site
(65 m: the regional tier at ~0.54 px per maplet spacing; 45 m: the site tier at ~0.74); Retina measures
every landmark with the true pose as its a-priori pose (search ±2 px), and its error against the
truth table (the true pose's projection of the landmark centre) must stay under 0.3 px for well-lit,
unoccluded landmarks with enough template pixels.

The selection comes from the truth table alone, fixed before looking at any measurement:

* in view, visible, not occluded;
* well lit: 20° ≤ incidence ≤ 70° (under 20° the shading has little contrast, over 70° long shadows),
  shadow_fraction ≤ 0.05, emission ≤ 30° (no strong foreshortening);
* enough template pixels: the maplet spans ≥ 300 px ((size − 1) / gsd_ratio)², and its spacing is at
  most 2 px (gsd_ratio ≥ 0.5): the template cannot show terrain detail finer than the maplet grid.

The truth is rendered with McEwen's law, Retina's own photometric model, from maplets without mapping
error: the test pins Retina's geometry (projection eqs. 1–4, ray casting, shadow rays, eq. 9, peak),
not the catalog or the photometric calibration. With the EV5 default (Hapke truth) and with the paper's
3×3 peak interpolation the errors are larger; ``benchmarks/bench_retina_ev5_accuracy.py`` prints them.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

SCENARIO = {
    "name": "ev5_retina",
    "world": {
        "kind": "ev5", "seed": 5, "facet_m": 4.0, "law": "mcewen", "mapping_error_m": 0.0, "albedo_error_rms": 0.0,
        "site": {"extent_m": 30.0, "cell_m": 0.05, "taper_m": 1.0, "crater_max_m": 3.0, "boulder_min_m": 0.3},
        "landmarks": [{"name": "regional", "count": 8, "spacing_m": 0.2, "size": 15, "radius_m": 6.0},
                      {"name": "site", "count": 10, "spacing_m": 0.1, "size": 15, "radius_m": 2.5}],
    },
    "trajectory": {"kind": "ev5_descent", "altitudes_m": [65.0, 45.0]},
    "camera": {"width": 128, "height": 128, "fx": 610.0, "fy": 610.0, "cx": 63.5, "cy": 63.5},
    "render": {"spp": 2, "seed": 3, "near_clip_m": 0.01},
}


def select_well_measurable(truth: dict, sizes: dict) -> np.ndarray:
    """Boolean mask over the truth-table rows: the module docstring's selection."""
    t = {k: np.asarray(v) for k, v in truth.items()}
    size = np.array([sizes[int(i)] for i in t["landmark_id"]], float)
    area_px = ((size - 1) / t["gsd_ratio"]) ** 2
    return (t["in_view"] & t["visible"] & ~t["occluded"]
            & (t["incidence_deg"] >= 20) & (t["incidence_deg"] <= 70) & (t["shadow_fraction"] <= 0.05)
            & (t["emission_deg"] <= 30) & (area_px >= 300) & (t["gsd_ratio"] >= 0.5))


@pytest.fixture(scope="module")
def ev5_set(tmp_path_factory):
    from renderlab.files.truthset import TruthSet
    from renderlab.pipeline import render_truthset
    from renderlab.scenario import scenario_from_dict
    from renderlab.worlds.ev5.catalog import read_catalog

    path = render_truthset(scenario_from_dict(copy.deepcopy(SCENARIO)), ".",
                           tmp_path_factory.mktemp("ev5r") / "set", progress=False)
    ts = TruthSet.open(path)
    return ts, read_catalog(path), ts.read_table("landmark_truth").to_pydict()


def _errors(ev5_set, peak):
    from renderlab.measurement.runner import MeasureOptions, measure_truthset

    ts, maplets, truth = ev5_set
    opts = MeasureOptions(sigma_pos_m=(0.0,) * 3, sigma_att_rad=(0.0,) * 3, peak=peak, supersample=2)
    m = measure_truthset(ts, maplets, "retina", opts, np.random.default_rng(0)).to_pydict()
    row = {(f, i): k for k, (f, i) in enumerate(zip(m["frame"], m["item"]))}
    keys = list(zip(truth["frame"], truth["landmark_id"]))
    err = np.array([np.hypot(m["err_s"][row[k]], m["err_l"][row[k]]) if k in row else np.nan for k in keys])
    return err, m


def test_retina_error_under_0p3_px_on_rendered_ev5_frames(ev5_set):
    ts, maplets, truth = ev5_set
    sizes = {int(mp.landmark_id): int(mp.n) for mp in maplets}
    sel = select_well_measurable(truth, sizes)
    tiers = set(np.asarray(truth["tier"])[sel])
    assert sel.sum() >= 10 and tiers == {"regional", "site"}, (sel.sum(), tiers)  # both tiers, both frames
    assert set(np.asarray(truth["frame"])[sel]) == {0, 1}

    err, m = _errors(ev5_set, "upsampled")
    assert np.all(np.isfinite(err[sel])), "every selected landmark gets a result"
    assert np.nanmax(err[sel]) < 0.3, np.round(err[sel], 3)
    # not the whole story: at least one landmark outside the selection is measured worse, so the
    # selection is not vacuous (steep, low-sun or under-sampled landmarks)
    assert np.nanmax(np.where(sel, np.nan, err)) > np.nanmax(err[sel])

    # the paper's 3×3 interpolation on the same surfaces: its pixel locking costs accuracy, still sub-pixel
    err3, _ = _errors(ev5_set, "retina_3x3")
    assert np.all(np.isfinite(err3[sel])) and np.sqrt(np.mean(err3[sel] ** 2)) < 0.3
    assert np.nanmax(err3[sel]) < 0.5, np.round(err3[sel], 3)
