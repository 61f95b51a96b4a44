"""``budget run --methods``: one more method's rows merged into an existing error budget (the other methods' rows,
the configurations and the draws kept), refused when its truth or draws differ from the table's; and, end to
end on the real scenario, the published all-off rows re-made for one method (truth renders reproduced)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from renderlab.campaign import oat_tables as T
from renderlab.errors import UserError
from renderlab.studies.retina_vs_spc.budget import plan as P
from renderlab.studies.retina_vs_spc.budget import runner as B

REPO = Path(__file__).resolve().parents[1]
PUBLISHED = REPO / "results" / "error_budget"


def _meas(cfg, method, n, err=0.0, crlb=0.01):
    base = {c: [0.0] * n for c in P.BUDGET_TABLES.columns}
    base.update(config=[cfg] * n, run=[0] * n, frame=[0] * n, item=list(range(n)), method=[method] * n,
                peak=["x"] * n, reason=["ok"] * n, has_result=[True] * n, outlier=[False] * n,
                truth_visible=[True] * n, search_px=[2] * n, n_pixels=[9] * n, err_s=[err] * n,
                truth_s=[10.0 + i for i in range(n)], crlb_s=[crlb] * n, crlb_l=[crlb] * n)
    return pa.table({c: base[c] for c in P.BUDGET_TABLES.columns})


def _folder(tmp_path):
    cfgs = [{"config": c, "source": "", "description": c, "runs": 1, "overrides": {}} for c in ("all_off", "b")]
    meas = pa.concat_tables([_meas(c, m, 3, err=v) for c, v in (("all_off", 1.0), ("b", 2.0)) for m in ("r", "s")])
    pert = pa.table({"config": ["all_off", "b"], "run": [0, 0], "dfocal": [0.0, 0.5], "campaign": ["x", "x"]})
    P.BUDGET_TABLES.write(tmp_path, cfgs, meas, pert, {"command": "test"})
    return cfgs, pert


def _rows(folder):
    t = pq.read_table(folder / "tables" / "budget_measurements.parquet").to_pydict()
    return sorted(zip(t["config"], t["method"], t["item"], t["err_s"]))


def test_methods_merge_adds_one_method_and_keeps_everything_else(tmp_path):
    cfgs, pert = _folder(tmp_path)
    before = {n: (tmp_path / "tables" / f"{n}.parquet").read_bytes() for n in (T.CONFIGS, T.PERTURBATIONS)}
    new = pa.concat_tables([_meas(c, "ml", 3, err=v) for c, v in (("all_off", 7.0), ("b", 8.0))])
    P.BUDGET_TABLES.merge(tmp_path, cfgs, new, pert, {"command": "again"}, methods=["ml"])
    got = _rows(tmp_path)
    assert [r for r in got if r[1] != "ml"] == sorted((c, m, i, v) for c, v in (("all_off", 1.0), ("b", 2.0))
                                                      for m in ("r", "s") for i in range(3))
    assert [r for r in got if r[1] == "ml"] == sorted((c, "ml", i, v) for c, v in (("all_off", 7.0), ("b", 8.0))
                                                      for i in range(3))
    for n, b in before.items():   # configurations and draws untouched
        assert (tmp_path / "tables" / f"{n}.parquet").read_bytes() == b
    inc = json.loads((tmp_path / "budget.json").read_text())["incremental"][0]
    assert inc["methods"] == ["ml"] and inc["paired_max_abs_diff"]["crlb_s"] == 0.0
    P.BUDGET_TABLES.merge(tmp_path, cfgs[:1], _meas("all_off", "ml", 3, err=9.0), pert.slice(0, 1), {"command": "3"},
                   methods=["ml"])   # a re-run replaces that method's rows of that configuration only
    assert [r[3] for r in _rows(tmp_path) if r[1] == "ml"] == [9.0] * 3 + [8.0] * 3


@pytest.mark.parametrize("change", ["crlb", "truth_s", "rows", "draws"])
def test_methods_merge_refuses_rows_of_another_truth_or_draw(tmp_path, change):
    cfgs, pert = _folder(tmp_path)
    before = _rows(tmp_path)
    new = pa.concat_tables([_meas(c, "ml", 3, crlb=0.01 * (1 + 1e-6 * (change == "crlb"))) for c in ("all_off", "b")])
    if change == "truth_s":
        new = new.set_column(new.column_names.index("truth_s"), "truth_s",
                             pa.array(np.asarray(new.column("truth_s")) + 1e-6))
    if change == "rows":
        new = new.slice(0, 5)
    if change == "draws":
        pert = pert.set_column(pert.column_names.index("dfocal"), "dfocal", pa.array([0.0, 0.25]))
    with pytest.raises(UserError, match="--methods"):
        P.BUDGET_TABLES.merge(tmp_path, cfgs, new, pert, {"command": "again"}, methods=["ml"])
    assert _rows(tmp_path) == before


def test_methods_refuses_an_unknown_or_repeated_method(tmp_path, capsys):
    for bad, msg in ((["nope"], "nope"), (["retina", "retina"], "named twice")):
        assert B.main(["run", "--out", str(tmp_path), "--methods", *bad]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and msg in err[0]
    assert not any(tmp_path.iterdir())


def _published_subset(folder: Path, configs: tuple, methods: tuple) -> None:
    """The published budget's measurement, configuration and perturbation tables cut to ``configs`` and ``methods``
    (the report after the merge then runs in seconds; the re-made rows are the same)."""
    import pyarrow.compute as pc

    (folder / "tables").mkdir(parents=True)
    for name in (T.MEASUREMENTS, T.CONFIGS, T.PERTURBATIONS):
        t = pq.read_table(PUBLISHED / "tables" / f"{name}.parquet")
        keep = pc.is_in(t.column("config"), value_set=pa.array(configs))
        if name == T.MEASUREMENTS:
            keep = pc.and_(keep, pc.is_in(t.column("method"), value_set=pa.array(methods)))
        pq.write_table(t.filter(keep), folder / "tables" / f"{name}.parquet")
    shutil.copy(PUBLISHED / T.MANIFEST, folder)


@pytest.mark.skipif(not PUBLISHED.is_dir(), reason="results/error_budget not published yet")
def test_methods_run_remakes_the_published_all_off_rows(tmp_path, monkeypatch):
    """Real renders: ``--methods retina --only all_off`` (the all-off truth rendered again, with the ray path it
    was published with) gives the published retina rows to rounding, and the merge's paired check passes."""
    from renderlab.render.mitsuba_backend import MitsubaBackend

    monkeypatch.setenv("RENDERLAB_MITSUBA_RAYS", "drjit_grid")
    monkeypatch.setattr(MitsubaBackend, "ray_path", "drjit_grid")
    # and with the one-scene tile design: the two-scene design differs on 0-3 shadow-edge pixels of these 65 536-px
    # frames (measured), enough to move a CRLB by 0.003
    monkeypatch.setenv("RENDERLAB_MITSUBA_TILE_DESIGN", "merged")
    monkeypatch.setattr(MitsubaBackend, "tile_design", "merged")
    folder = tmp_path / "budget"
    _published_subset(folder, ("all_off", "all_on"), ("retina", "spc"))  # spc: the rows retina's are paired with
    # the folder's scenario pins the then-defaults (tiled site, single-stream sensor noise) that made the tables
    assert B.main(["run", "--out", str(folder), "--only", "all_off", "--methods", "retina", "--workers", "1",
                   "--runs", "10", "--workdir", str(tmp_path / "work"), "--scenario",
                   str(PUBLISHED / "scenario.toml")]) == 0
    key = ("config", "run", "frame", "item", "method")
    old = pq.read_table(PUBLISHED / "tables" / "budget_measurements.parquet")
    new = pq.read_table(folder / "tables" / "budget_measurements.parquet")
    assert new.num_rows == sum(1 for c, m in zip(old.column("config").to_pylist(), old.column("method").to_pylist())
                               if c in ("all_off", "all_on") and m in ("retina", "spc"))

    def rows(t):
        d = t.to_pydict()
        sel = [j for j in range(t.num_rows) if d["config"][j] == "all_off" and d["method"][j] == "retina"]
        return {tuple(d[k][j] for k in key): (d["err_s"][j], d["err_l"][j], d["crlb_s"][j]) for j in sel}

    a, b = rows(old), rows(new)
    assert a.keys() == b.keys() and len(a) > 100
    diff = np.array([[x - y for x, y in zip(a[k], b[k])] for k in a], float)
    assert np.nanmax(np.abs(diff)) < 1e-9
    inc = json.loads((folder / "budget.json").read_text())["incremental"][-1]
    assert inc["methods"] == ["retina"] and max(inc["paired_max_abs_diff"].values()) < 1e-9


@pytest.mark.parametrize("workers", ["100000", "0"])
def test_budget_run_caps_its_worker_processes(tmp_path, workers, capsys):
    """--workers is refused beyond 4 per core (each is a process) and below 1, before anything is made."""
    assert B.main(["run", "--out", str(tmp_path / "b"), "--runs", "2", "--workers", workers,
                   "--workdir", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--workers" in err[0] and not any(tmp_path.iterdir())
