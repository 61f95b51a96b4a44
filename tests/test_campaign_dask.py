"""Dask executors: a LocalCluster with 1 and with 2 worker processes gives tables identical (timings
excluded) to each other and to the in-process executor, for the same seed."""

from __future__ import annotations

from campaign_fixtures import SCENE, TINY, tables_equal

from renderlab.campaign import store
from renderlab.campaign.executors import DaskExecutor, InProcessExecutor
from renderlab.campaign.plan import make_plan
from renderlab.campaign.runner import run_campaign
from renderlab.scenario import load_scenario


def test_local_cluster_1_and_2_workers_identical(tmp_path):
    sc, base = load_scenario(SCENE, TINY)
    plan = make_plan(sc, base, runs=3, seed=21)
    out = {}
    for name, ex in (("inproc", InProcessExecutor()), ("dask1", DaskExecutor(workers=1)),
                     ("dask2", DaskExecutor(workers=2))):
        res = run_campaign(plan, tmp_path / name, executor=ex, progress=False)
        assert (res.executed, res.failed) == (3, [])
        out[name] = store.load_tables(tmp_path / name)
    for name in ("dask1", "dask2"):
        assert sorted(out[name]) == sorted(out["inproc"])
        for t in out[name]:
            assert tables_equal(out[name][t], out["inproc"][t]), (name, t)


def test_local_cluster_caps_every_thread_pool_per_worker(monkeypatch):
    """Without the cap a worker's Dr.Jit pool has one thread per core and numba NUMBA_NUM_THREADS = cores."""
    from renderlab.campaign.executors import THREAD_ENV, thread_report

    for key in THREAD_ENV:  # not "1" here (tests/conftest.py sets OPENBLAS_NUM_THREADS=1): the workers' 1 is the cap's
        monkeypatch.setenv(key, "2")
    with DaskExecutor(workers=1, threads_per_run=1) as ex:
        (rep,) = list(ex.map_unordered(thread_report, [0]))
    assert rep == {"limit": 1, "drjit": 1, "numba": 1, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
                   "MKL_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}
