"""Report figures are scaled by what they show: robust axis limits (quantiles, the scale of a typical time) with the
points outside counted on the plot, checked on the published descent table whose panels a single run's first
sample (−4 m) and the first seconds' velocity used to scale; truth-set previews resampled with an anti-aliasing
filter (a one-pixel checkerboard reads as flat grey, not as nearest-neighbour moiré)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from renderlab.report import axes

REPO = Path(__file__).resolve().parents[1]
MAP_STATES = REPO / "results" / "descent_navigation_map_states" / "tables" / "descent_filter.parquet"


def test_limits_against_numpy_quantiles():
    rng = np.random.default_rng(1)
    v = np.r_[rng.normal(0, 0.01, 999), -4.0]
    lim = axes.symmetric_limit(v)
    assert lim == pytest.approx(1.25 * np.quantile(np.abs(v), 0.98))
    assert axes.count_outside(v, -lim, lim) == (int(np.sum(np.abs(v) > lim)), 1000)
    assert axes.count_outside(v, -lim, lim)[0] >= 1 and lim < 0.05
    t = np.repeat(np.arange(20.0), 50)  # 20 times x 50 runs, the first two times 20x larger (a filter's start)
    x = rng.normal(0, 1.0, t.size) * np.where(t < 2, 20.0, 1.0)
    per = [np.quantile(np.abs(x[t == k]), 0.98) for k in range(20)]
    assert axes.typical_limit(x, t) == pytest.approx(1.2 * np.quantile(per, 0.8))
    assert axes.typical_limit(x, t) < 5.0 < axes.symmetric_limit(x)
    lo, hi = axes.limits(v)
    q = np.quantile(v, [0.01, 0.99])
    assert lo == pytest.approx(q[0] - 0.1 * (q[1] - q[0])) and hi == pytest.approx(q[1] + 0.1 * (q[1] - q[0]))


@pytest.fixture()
def captured(monkeypatch):
    """The figures drawn (``style.save`` keeps them instead of writing them)."""
    from renderlab.report import style

    figs = []

    def keep(fig, stem):
        figs.append(fig)
        return [Path(stem).with_suffix(".png").name, Path(stem).with_suffix(".svg").name]

    import sys

    import renderlab.studies.descent_navigation.report  # noqa: F401  (bound names patched below)
    import renderlab.studies.unknown_satellite.figures  # noqa: F401

    original = style.save
    for mod in [m for name, m in sys.modules.items() if name.startswith("renderlab.")]:
        if getattr(mod, "save", None) is original:  # modules that imported the name itself
            monkeypatch.setattr(mod, "save", keep)
    monkeypatch.setattr(style, "save", keep)
    yield figs
    style.plt().close("all")


@pytest.mark.skipif(not MAP_STATES.is_file(), reason="published descent table not present")
def test_descent_panels_not_scaled_by_one_sample(captured, tmp_path):
    import pyarrow.parquet as pq

    from renderlab.studies.descent_navigation.publish import image_index, publish_tables
    from renderlab.studies.descent_navigation.report import error_figure

    tables = publish_tables({p.stem: pq.read_table(p) for p in MAP_STATES.parent.glob("*.parquet")})
    t, images = tables["descent_filter"], image_index(tables)
    error_figure(t, images, "position", tmp_path)
    error_figure(t, images, "velocity", tmp_path)
    pos, vel = captured
    lims_pos = [abs(a.get_ylim()[0]) for a in pos.axes]
    assert max(lims_pos) < 0.6, lims_pos  # one spc run's first N sample is at -4 m: it is counted, not the scale
    texts = [t.get_text() for a in pos.axes for t in a.texts]
    assert any("outside the axes" in s for s in texts)
    lims_vel = [abs(a.get_ylim()[0]) for a in vel.axes]
    assert max(lims_vel) < 0.004, lims_vel  # the first seconds reach 0.03 m/s; the rest is < 0.002 m/s
    assert any("all before t =" in t.get_text() for a in vel.axes for t in a.texts)


def test_preview_antialiases_a_checkerboard(tmp_path):
    import cv2

    from renderlab.report.preview import truthset_preview

    n = 1024
    board = ((np.indices((n, n)).sum(axis=0) % 2) * 1023).astype(np.uint16)  # 1-px checkerboard, 10-bit

    class Frame:
        dn, meta = board, {"sensor": {"bits": 10}}
        id = np.zeros((n, n), np.int32)
        range = np.full((n, n), 5.0)
        normal = np.dstack([np.zeros((n, n)), np.zeros((n, n)), np.ones((n, n))])

    class Set:
        def __len__(self):
            return 1

        def load(self, i):
            return Frame()

    out = truthset_preview(Set(), tmp_path / "p.png")
    img = cv2.imread(str(out), cv2.IMREAD_GRAYSCALE)
    h, w = img.shape
    panel = img[int(0.15 * h):int(0.40 * h), int(0.04 * w):int(0.20 * w)]  # inside the first DN panel
    assert abs(float(panel.mean()) - 127.5) < 20 and float(panel.std()) < 12, (panel.mean(), panel.std())


US_30S = REPO / "results" / "unknown_satellite" / "campaign_30s" / "tables"


@pytest.mark.skipif(not (US_30S / "scores.parquet").is_file(), reason="published unknown-satellite tables not present")
def test_inertia_panel_has_no_crlb_bar_across_it(captured, tmp_path):
    """On the 30 s arc the inertia ratios are not observable (CRLB σ ≈ 1.4 on a panel 1.4 wide): such bars would
    cross the whole panel; they are left out and counted instead."""
    import pyarrow.parquet as pq
    from matplotlib.collections import LineCollection

    from renderlab.studies.unknown_satellite.figures import fig6_inertia

    fig6_inertia(pq.read_table(US_30S / "stage1_history.parquet"), pq.read_table(US_30S / "scores.parquet"), tmp_path)
    panel = captured[0].axes[1]
    span = np.diff(panel.get_xlim())[0]
    for coll in panel.collections:
        if isinstance(coll, LineCollection):
            for seg in coll.get_segments():
                assert np.ptp(seg[:, 0]) <= 0.5 * span + 1e-9 and np.ptp(seg[:, 1]) <= 0.5 * span + 1e-9
    assert any("not drawn" in t.get_text() for t in panel.texts)
