"""Every registered landmark method against the conformance harness (renderlab.measurement.conformance); the
harness against deliberately broken methods; the worked plug-in example (examples/ncc_baseline, installed by
setup.sh) found through its real entry point and run by ``renderlab measure`` on a tiny rendered EV5 truth set."""

from __future__ import annotations

import math
from importlib.metadata import entry_points

import numpy as np
import pytest
from terrain_fixtures import truthset  # noqa: F401  (the module-scoped fixture: two Mitsuba frames, three maplets)

from renderlab import plugins
from renderlab.contracts.landmark import LandmarkMethodOptions, LandmarkResult
from renderlab.measurement.conformance import check_landmark_method, check_landmark_method_name

NCC_TARGET = "renderlab_ncc_baseline.method:NccBaseline"

#: failures a method is known to have today, by a fragment of the failure line; each must still occur
#: (so a fix is noticed and the entry removed). None today: SPC gained its image-size check (SpcOptions.min_image_px)
#: after this harness found it returning shifts for 2 × 2 px landmarks.
KNOWN_GAPS: dict[str, tuple[str, ...]] = {}


def test_ncc_baseline_is_found_through_its_entry_point():
    eps = {ep.name: ep.value for ep in entry_points(group="renderlab.landmark_methods")}
    assert eps.get("ncc_baseline") == NCC_TARGET, f"pip install --no-deps -e examples/ncc_baseline ({eps})"
    assert {"retina", "spc", "ncc_baseline"} <= set(plugins.landmark_methods.names())
    from renderlab_ncc_baseline.method import NccBaseline

    assert plugins.landmark_methods.get("ncc_baseline") is NccBaseline


@pytest.mark.parametrize("name", plugins.landmark_methods.names())
def test_registered_method_conforms(name):
    failures = check_landmark_method_name(name)
    known = KNOWN_GAPS.get(name, ())
    unexpected = [f for f in failures if not any(k in f for k in known)]
    assert not unexpected, "\n".join(unexpected)
    for k in known:
        assert any(k in f for f in failures), f"{name}: known gap {k!r} no longer occurs: remove it from KNOWN_GAPS"
    if failures:
        pytest.xfail("known gap: " + "; ".join(failures))


class _Delegate:
    """A conforming method (ncc_baseline) with one thing broken by a subclass."""

    name = "broken"

    def __init__(self, options: LandmarkMethodOptions = LandmarkMethodOptions()):
        from renderlab_ncc_baseline.method import NccBaseline

        self.inner = NccBaseline(options)

    def measure_frame(self, frame):
        return self.inner.measure_frame(frame)


class _SilentNaN(_Delegate):
    """Returns NaN shifts with reason 'ok' wherever it has no result."""

    def measure_frame(self, frame):
        out = super().measure_frame(frame)
        for r in out:
            r.reason = "ok"
        return out


class _MutatesImage(_Delegate):
    def measure_frame(self, frame):
        frame.image[0, 0] += 1.0
        return super().measure_frame(frame)


class _Unstable(_Delegate):
    """Adds a draw from an unseeded generator to every shift."""

    def measure_frame(self, frame):
        out = super().measure_frame(frame)
        for r in out:
            r.ds += float(np.random.default_rng().normal(0.0, 1e-9))
        return out


class _Reversed(_Delegate):
    def measure_frame(self, frame):
        return super().measure_frame(frame)[::-1]


def test_harness_catches_a_silent_nan():
    failures = check_landmark_method(_SilentNaN)
    assert failures and all("rule (b) no silent NaN" in f for f in failures), failures
    assert any("[off_image]" in f and "landmark 23" in f and "has_result=False" in f for f in failures)
    assert any("[shadowed]" in f for f in failures) and any("[too_small]" in f for f in failures)


def test_harness_catches_a_mutated_image():
    failures = check_landmark_method(_MutatesImage)
    assert failures, "a method writing into frame.image must fail"
    assert all("rule (d) inputs unchanged: image was modified" in f for f in failures), failures
    assert len(failures) == 4  # once per case


def test_harness_catches_unstable_results_and_a_wrong_order():
    failures = check_landmark_method(_Unstable)
    assert failures and all("rule (c) bit-identical replay" in f and ": ds differs" in f for f in failures), failures
    failures = check_landmark_method(_Reversed)
    assert any("[clean] rule (e) one result per landmark: result 0 has landmark_id 9, landmark 0 is 17" in f
               for f in failures), failures


def test_harness_catches_a_factory_that_breaks_the_protocol():
    class NoName:
        def __init__(self, options):
            pass

        def measure_frame(self, frame):
            return []

    failures = check_landmark_method(NoName)
    assert len(failures) == 1 and "does not follow the LandmarkMethod protocol" in failures[0]
    failures = check_landmark_method(lambda o: (_ for _ in ()).throw(RuntimeError("boom")))
    assert len(failures) == 1 and "the factory raised RuntimeError: boom" in failures[0]


def test_silent_nan_result_is_what_the_contract_rejects():
    r = LandmarkResult(landmark_id=3, pred_s=1.0, pred_l=2.0)
    with pytest.raises(ValueError, match="a NaN shift needs a reason"):
        r.check()


def _same(a, b) -> bool:
    return a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))


def _cli_table(path, tmp_path, method, tag):
    import pyarrow.parquet as pq

    from renderlab.cli import main

    out = tmp_path / f"{tag}.parquet"
    assert main(["measure", str(path), "--method", method, "--out", str(out), "--seed", "3", "--sigma-pos-m", "0.2",
                 "--quiet"]) == 0
    return pq.read_table(out).to_pydict()


def test_ncc_baseline_through_renderlab_measure(truthset, tmp_path, capsys):  # noqa: F811
    path, _ = truthset
    if not (path / "landmarks.parquet").is_file():
        pytest.skip("renderlab.worlds.ev5.catalog (write_catalog) is not available")
    by_name = _cli_table(path, tmp_path, "ncc_baseline", "name")
    by_ref = _cli_table(path, tmp_path, NCC_TARGET, "ref")
    retina = _cli_table(path, tmp_path, "retina", "retina")
    printed = capsys.readouterr().out
    assert printed.count("6 ncc_baseline measurements") == 2
    for key in by_name:  # the entry-point name and the module:attr reference run the same class
        if key != "t_ms":
            assert all(_same(a, b) for a, b in zip(by_name[key], by_ref[key], strict=True)), key
    t = by_name
    assert set(t["method"]) == {"ncc_baseline"} and set(t["peak"]) == {"quadric_ncc"}
    good = np.array(t["has_result"], bool)
    assert good.sum() >= 5, list(zip(t["reason"], t["diagnostics"]))
    err = np.hypot(np.array(t["err_s"])[good], np.array(t["err_l"])[good])
    rgood = np.array(retina["has_result"], bool)
    rerr = np.hypot(np.array(retina["err_s"])[rgood], np.array(retina["err_l"])[rgood])
    print("ncc_baseline errors (px):", np.round(err, 3).tolist(), "retina:", np.round(rerr, 3).tolist())
    # measured (seed 3): ncc_baseline max 0.32 px, median 0.06; retina max 0.15, median 0.12. Over a-priori
    # seeds 0-11 through the runner: ncc_baseline max 0.50 / median 0.06, retina 0.53 / 0.12, spc 0.40 / 0.10.
    # Bounds with modest margin over the seed-3 numbers:
    assert err.max() < 0.45, err
    assert np.median(err) < np.median(rerr) + 0.1, (err, rerr)
