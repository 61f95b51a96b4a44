"""The measurement runner (`renderlab.measurement.runner`) on a small truth set written with TruthSetWriter from
Mitsuba renders of the test terrain, and the `renderlab measure` command's error cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from terrain_fixtures import (
    CAMERA,
    truthset,  # noqa: F401  (the module-scoped fixture: two Mitsuba frames, three maplets)
)

from renderlab.contracts.schemas import LANDMARK_RUNNER


def _measure(path, maplets, method, seed, **kw):
    from renderlab.files.truthset import TruthSet
    from renderlab.measurement.runner import MeasureOptions, measure_truthset

    opts = MeasureOptions(sigma_pos_m=(0.2, 0.2, 0.2), sigma_att_rad=(1e-3,) * 3, campaign="t", **kw)
    return measure_truthset(TruthSet.open(path), maplets, method, opts, np.random.default_rng(seed)).to_pydict()


@pytest.mark.parametrize("method", ["retina", "spc"])
def test_measure_truthset_rows(truthset, method):  # noqa: F811
    from renderlab.contracts.reasons import reason_values
    from renderlab.measurement.runner import MeasureOptions, draw_apriori

    path, maplets = truthset
    t = _measure(path, maplets, method, seed=5)
    assert list(t)[:len(LANDMARK_RUNNER)] == LANDMARK_RUNNER.names
    n = len(t["frame"])
    assert n == 6 and set(t["method"]) == {method} and set(t["campaign"]) == {"t"}
    err_s, err_l = np.array(t["err_s"]), np.array(t["err_l"])
    np.testing.assert_allclose(err_s, np.array(t["meas_s"]) - np.array(t["truth_s"]), equal_nan=True)
    good = np.array(t["has_result"], bool)
    assert good.sum() >= 5, t["diagnostics"]
    assert set(t["reason"]) <= set(reason_values("landmark"))
    assert all((r == "ok") == g for r, g in zip(t["reason"], good))
    assert np.all(np.isfinite(err_s[good])) and np.all(np.isnan(err_s[~good]))
    limit = 0.3 if method == "retina" else 0.5
    assert np.hypot(err_s[good], err_l[good]).max() < limit, (err_s, err_l)
    # the occluded landmark (frame 1, id 2) is flagged from the truth table, and still measured
    k = [i for i in range(n) if t["frame"][i] == 1 and t["item"][i] == 2][0]
    assert not t["truth_visible"][k]
    assert t["gsd_ratio"][k] == pytest.approx(0.9)
    # the a-priori perturbation is one seeded draw per frame, recorded on every row
    rng = np.random.default_rng(5)
    for frame in (0, 1):
        _, _, dpos, drot = draw_apriori(np.eye(3), np.zeros(3), MeasureOptions(sigma_pos_m=(0.2,) * 3,
                                                                               sigma_att_rad=(1e-3,) * 3), rng)
        i = t["frame"].index(frame)
        np.testing.assert_allclose([t[f"apriori_dpos_{a}_m"][i] for a in "xyz"], dpos)
        np.testing.assert_allclose([t[f"apriori_drot_{a}_rad"][i] for a in "xyz"], drot)
    # and the covariance it was drawn from, with the search distance's n_sigma
    assert {t[f"apriori_sigma_pos_{a}_m"][k] for a in "xyz" for k in range(n)} == {0.2}
    assert {t[f"apriori_sigma_att_{a}_rad"][k] for a in "xyz" for k in range(n)} == {1e-3}
    assert set(t["n_sigma"]) == {3.0}


def test_search_distance_is_n_sigma_of_the_projected_apriori_covariance(truthset):  # noqa: F811
    """``search_px`` = ceil(n_σ · sqrt(λ_max)) of the pixel covariance at the a-priori pose (rebuilt from
    the recorded perturbation), for the default 3σ and a set 6σ."""
    from scipy.spatial.transform import Rotation

    from estimators.retina import CameraPoseEstimate, pixel_covariance
    from renderlab.files.truthset import TruthSet

    path, maplets = truthset
    ts = TruthSet.open(path)
    centre = {int(m.landmark_id): m.center_m for m in maplets}
    sig_p, sig_r = 0.2, 1e-3
    got = {}
    for n_sigma in (3.0, 6.0):
        t = _measure(path, maplets, "spc", 5, n_sigma=n_sigma)
        for i in range(len(t["frame"])):
            rec = ts.frames[t["frame"][i]]
            R = Rotation.from_quat(rec["pose"]["quat_render_from_cam_xyzw"]).as_matrix()
            drot = [t[f"apriori_drot_{a}_rad"][i] for a in "xyz"]
            dpos = [t[f"apriori_dpos_{a}_m"][i] for a in "xyz"]
            ap = CameraPoseEstimate(R @ Rotation.from_rotvec(drot).as_matrix(),
                                    np.asarray(rec["pose"]["position_m"]) + dpos)
            cov = pixel_covariance(CAMERA, ap, centre[t["item"][i]], np.eye(3) * sig_p ** 2, np.eye(3) * sig_r ** 2)
            want = int(np.clip(math.ceil(n_sigma * math.sqrt(np.linalg.eigvalsh(cov)[-1])), 2, 48))
            assert t["search_px"][i] == want, (n_sigma, i, t["search_px"][i], want)
            got[n_sigma, i] = want
    assert all(got[6.0, i] > got[3.0, i] for i in range(6))


def test_measure_is_deterministic(truthset):  # noqa: F811
    path, maplets = truthset
    a, b = _measure(path, maplets, "spc", 11), _measure(path, maplets, "spc", 11)
    c = _measure(path, maplets, "spc", 12)
    for key in a:
        if key != "t_ms":
            np.testing.assert_array_equal(np.array(a[key], dtype=object), np.array(b[key], dtype=object), err_msg=key)
    assert a["apriori_dpos_x_m"] != c["apriori_dpos_x_m"]


def _cli(*argv):
    from renderlab.cli import main

    return main(list(argv))


def test_cli_errors(truthset, tmp_path, capsys):  # noqa: F811
    import shutil

    path, _ = truthset
    bare = tmp_path / "bare"
    shutil.copytree(path, bare)
    for p in (bare / "landmarks.parquet", bare / "maplets"):
        shutil.rmtree(p) if p.is_dir() else p.unlink(missing_ok=True)
    assert _cli("measure", str(tmp_path / "nope"), "--method", "retina") == 2
    assert "truth set not found" in capsys.readouterr().err
    assert _cli("measure", str(path), "--method", "sift") == 2
    err = capsys.readouterr().err
    assert "unknown landmark method 'sift' (registered: " in err and "retina" in err and err.count("\n") == 1
    assert _cli("measure", str(bare), "--method", "retina") == 2
    err = capsys.readouterr().err
    assert "no landmark catalog" in err and err.count("\n") == 1
    assert _cli("measure", str(path), "--method", "spc", "--sigma-pos-m", "-1") == 2
    assert "--sigma-pos-m" in capsys.readouterr().err
    for d in (path, bare, path.parent, tmp_path):
        assert not any(p.suffix == ".parquet" and "_" in p.stem and p.stem.split("_")[-1] in ("retina", "spc")
                       or ".tmp-" in p.name for p in d.iterdir()), "nothing half-written"


def test_cli_measure_end_to_end(truthset, tmp_path, capsys):  # noqa: F811
    import pyarrow.parquet as pq

    path, _ = truthset
    if not (path / "landmarks.parquet").is_file():
        pytest.skip("renderlab.worlds.ev5.catalog (write_catalog) is not available")
    out = tmp_path / "m.parquet"
    argv = ["measure", str(path), "--method", "retina", "--out", str(out), "--seed", "3", "--sigma-pos-m", "0.2",
            "--quiet"]
    assert _cli(*argv) == 0
    printed = capsys.readouterr().out
    assert "6 retina measurements" in printed
    t = pq.read_table(out).to_pydict()
    good = np.array(t["has_result"], bool)
    e = np.array(t["err_s"])[good]
    assert f"{good.sum()}/6 with a result" in printed and f"sample median {np.median(e):+.3f} px" in printed
    assert good.sum() >= 5
    assert np.hypot(np.array(t["err_s"])[good], np.array(t["err_l"])[good]).max() < 0.3
    assert _cli(*argv) == 2 and "exists" in capsys.readouterr().err  # no silent overwrite
    assert _cli(*argv, "--overwrite") == 0
    capsys.readouterr()
    assert _cli("measure", str(path), "--method", "spc", "--quiet") == 0  # default: TRUTHSET_spc.parquet beside it
    default = path.parent / f"{path.name}_spc.parquet"
    assert default.is_file() and pq.read_table(default).num_rows == 6
    default.unlink()


def test_options_validation():
    from renderlab.errors import UserError
    from renderlab.measurement.runner import MeasureOptions

    with pytest.raises(UserError, match="sigma_pos_m"):
        MeasureOptions(sigma_pos_m=(1.0, math.nan, 1.0))
    with pytest.raises(UserError, match="peak"):
        MeasureOptions(peak="centroid")


def test_same_seed_gives_byte_identical_measure_files_with_separate_timings(truthset, tmp_path):  # noqa: F811
    path, _ = truthset
    if not (path / "landmarks.parquet").is_file():
        pytest.skip("no catalog writer")
    outs = []
    for k in range(2):
        out = tmp_path / f"m{k}.parquet"
        assert _cli("measure", str(path), "--method", "retina", "--out", str(out), "--seed", "3", "--quiet",
                    "--timings", "separate") == 0
        outs.append(out)
    assert outs[0].read_bytes() == outs[1].read_bytes()
    import pyarrow.parquet as pq

    side = pq.read_table(tmp_path / "m0.timings.parquet").to_pydict()
    assert set(side["column"]) == {"t_ms"} and all(v >= 0 for v in side["value"])
