"""The error budget's shadow term (renderlab.studies.retina_vs_spc.budget.shadows): the onboard predictions with
cast shadows off, checked against an independent computation of the attached-shadow mask, and the incremental
``budget run --only`` merge."""

from __future__ import annotations

import json
import math

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from renderlab.contracts.landmark import LandmarkMethodOptions
from renderlab.errors import UserError
from renderlab.geometry.maplet import Maplet
from renderlab.studies.retina_vs_spc.budget import plan as P
from renderlab.studies.retina_vs_spc.budget import runner as B
from renderlab.studies.retina_vs_spc.budget import shadows as SH


def _ridge_maplet(n=31, s=0.1):
    """A flat maplet with a 1 m high ridge across it: at a 10° Sun elevation it casts a long shadow."""
    h = np.zeros((n, n))
    h[:, 10:12] = 1.0
    return Maplet(1, np.zeros(3), np.eye(3), s, h, np.ones((n, n)))


def test_spc_without_cast_shadows_keeps_only_the_attached_shadow():
    from estimators.spc.method import SpcOptions, predict_maplet

    m = _ridge_maplet()
    el = math.radians(10.0)
    sun = np.array([-math.cos(el), 0.0, math.sin(el)])          # low in −x: the ridge shadows cells on its +x side
    to_cam = np.array([0.0, 0.0, 100.0])
    img_on, use_on = predict_maplet(m, to_cam, sun, SpcOptions())
    img_off, use_off = predict_maplet(m, to_cam, sun, SpcOptions(cast_shadows=False))
    gy, gx = np.gradient(m.heights_m, m.spacing_m)               # independent: attached shadow = cos i <= 0
    nrm = np.stack([-gx, -gy, np.ones_like(gx)], -1)
    attached = (nrm @ sun) <= 0
    assert np.array_equal(use_off, ~attached)
    assert (use_on.sum() < use_off.sum() - 31) and np.all(use_on <= use_off)   # the march shadows whole columns
    assert np.all(img_off[~attached] > 0)


def test_every_budget_method_gets_its_cast_shadows_switched_off():
    from renderlab import plugins

    for name in P.METHODS:
        obj = SH.factories([name])[0](LandmarkMethodOptions())
        assert obj.name == name
        opts = getattr(obj, "template_options", None) or getattr(obj.options, "template", None) or obj.options
        flag = getattr(opts, "shadow_rays", getattr(opts, "cast_shadows", None))
        assert flag is False, name
        fresh = plugins.landmark_methods.get(name)(LandmarkMethodOptions())   # the registered one is untouched
        fo = getattr(fresh, "template_options", None) or getattr(fresh.options, "template", None) or fresh.options
        assert getattr(fo, "shadow_rays", getattr(fo, "cast_shadows", None)) is True
    with pytest.raises(UserError, match="no cast-shadow switch"):
        SH.without_cast_shadows(type("M", (), {"name": "plain"})())


def test_merge_replaces_only_the_named_configuration(tmp_path):
    COLUMNS, write_tables = P.BUDGET_TABLES.columns, P.BUDGET_TABLES.write

    def meas(cfg, v, n):
        base = {c: [0.0] * n for c in COLUMNS}
        base.update(config=[cfg] * n, run=[0] * n, frame=[0] * n, item=list(range(n)), method=["retina"] * n,
                    peak=["x"] * n, reason=["ok"] * n, has_result=[True] * n, outlier=[False] * n,
                    truth_visible=[True] * n, search_px=[2] * n, n_pixels=[9] * n, err_s=[v] * n)
        return pa.table({c: base[c] for c in COLUMNS})

    cfgs = [{"config": c, "source": "", "description": c, "runs": 1, "overrides": {}} for c in ("all_off", "no_shadows")]
    write_tables(tmp_path, cfgs, pa.concat_tables([meas("all_off", 1.0, 3), meas("no_shadows", 2.0, 3)]),
                 pa.table({"config": ["all_off", "no_shadows"], "run": [0, 0]}), {"command": "test"})
    (tmp_path / "tables" / "other.parquet").write_bytes(b"kept")
    new_cfg = [{"config": "no_shadows", "source": "", "description": "new", "runs": 1, "overrides": {"a": 1}}]
    P.BUDGET_TABLES.merge(tmp_path, new_cfg, meas("no_shadows", 5.0, 4), pa.table({"config": ["no_shadows"], "run": [0]}),
             {"command": "again"})
    t = pq.read_table(tmp_path / "tables" / "budget_measurements.parquet").to_pydict()
    got = sorted(zip(t["config"], t["err_s"]))
    assert got == [("all_off", 1.0)] * 3 + [("no_shadows", 5.0)] * 4
    c = pq.read_table(tmp_path / "tables" / "budget_configs.parquet").to_pydict()
    assert c["config"] == ["all_off", "no_shadows"] and c["description"][1] == "new"
    assert (tmp_path / "tables" / "other.parquet").read_bytes() == b"kept"
    man = json.loads((tmp_path / "budget.json").read_text())
    assert man["command"] == "test" and man["incremental"][0]["configs"] == ["no_shadows"]


def test_only_refuses_an_unknown_configuration(tmp_path, capsys):
    assert B.main(["run", "--out", str(tmp_path), "--only", "nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no configuration 'nope'" in err[0]
