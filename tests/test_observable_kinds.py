"""Observable kinds are registered (``renderlab.plugins.observables``) and everything that lists kinds reads the
registry: the lab's own kinds are registry objects; a kind registered at run time is detected, checked and reported
like them; the toy kind of ``examples/toy_kind`` (installed by setup.sh, found through its entry points, named nowhere
under ``renderlab/``) runs end to end: campaign (its study, a ``--plugin`` method), the executor's table check, the
report section, ``renderlab check-method``; and a scan finds no list of kind names outside the registry.

The toy frames are pixel-integrated Gaussian spots drawn from each run's seed: their exact positions are the oracle.
"""

from __future__ import annotations

import ast
import csv
from importlib.metadata import entry_points
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest

from renderlab import plugins
from renderlab.cli import main
from renderlab.contracts.observable import ObservableKind

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "scenes" / "analytic_sphere_box.toml"
TINY = ["--set", "camera.width=64", "--set", "camera.height=48", "--set", "render.spp=4",
        "--set", "trajectory.frames=1"]
LAB_KINDS = ("landmark", "filter", "pose", "centre_limb")
SHIFT_PX = 0.3


class ShiftedCentroid:
    """The toy kind's window centroid moved SHIFT_PX in s (a ``--plugin`` method with a known bias)."""

    name = "shifted_centroid"

    def __init__(self):
        from renderlab_toy_kind.methods import WindowCentroid

        self.inner = WindowCentroid()

    def locate(self, frame):
        res = self.inner.locate(frame)
        res.spot_s += SHIFT_PX
        return res


class MutatingCentroid(ShiftedCentroid):
    """Writes into the image it is given (breaks rule (d))."""

    name = "mutating"

    def locate(self, frame):
        frame.image[0, 0] += 1.0
        return self.inner.locate(frame)


class NoReasonCentroid(ShiftedCentroid):
    """No spot found but reason 'ok' (breaks rules (b) and (e))."""

    name = "no_reason"

    def locate(self, frame):
        res = self.inner.locate(frame)
        res.reason = "ok"
        return res


def test_the_labs_kinds_are_registry_objects():
    kinds = {k.name: k for k in plugins.observable_kinds()}
    assert set(LAB_KINDS) <= set(kinds)
    for k in kinds.values():
        assert isinstance(k, ObservableKind) and k.reason_values()[0] == "ok"
    assert [k for k in kinds if k in LAB_KINDS] == list(LAB_KINDS)  # the lab's own first, in their order
    assert plugins.method_registry("landmark") is plugins.landmark_methods
    assert plugins.method_registry("filter") is plugins.filters
    from renderlab.contracts.reasons import FilterReason, LandmarkReason, reason_values

    assert reason_values("landmark") == tuple(r.value for r in LandmarkReason)
    assert reason_values("filter") == tuple(r.value for r in FilterReason)


@pytest.mark.parametrize("name", plugins.observables.names())
def test_every_registered_kinds_references_load(name):
    """Every part a kind names loads and is what the lab will call (a typo in a reference fails here, not in a
    report); its protocol's methods tell it apart from every other kind's (``--plugin`` needs that)."""
    kind = plugins.observable(name)
    core, known = kind.core_schema(), kind.known_columns()
    assert core is None or (isinstance(core, pa.Schema) and isinstance(known, pa.Schema)
                            and set(core.names) <= set(known.names) and {"has_result", "reason"} <= set(core.names))
    for part in ("runner", "scorer", "report_section", "conformance"):
        assert kind.part(part) is None or callable(kind.part(part)), part
    need = plugins.protocol_methods(kind.protocol)
    assert need
    others = [k.name for k in plugins.observable_kinds() if k.name != name
              and plugins.protocol_methods(k.protocol) == need]
    assert not others, f"{name} and {others} have the same protocol methods {sorted(need)}"


def _probe_kind():
    """A kind registered at run time (no entry point, no lab edit): schema, reasons and a protocol of its own."""
    from enum import Enum

    class ProbeReason(str, Enum):
        OK = "ok"
        DARK = "dark"

    class ProbeMethod:
        def probe(self, frame): ...

    schema = pa.schema([("campaign", pa.string()), ("run", pa.int64()), ("probe_value", pa.float64()),
                        ("has_result", pa.bool_()), ("reason", pa.string())])
    import sys
    import types

    mod = types.ModuleType("_probe_kind_schema")
    mod.SCHEMA = schema
    sys.modules["_probe_kind_schema"] = mod
    return ObservableKind(name="probe", description="probe", reasons=ProbeReason, frame=dict, result=dict,
                          protocol=ProbeMethod, result_schema="_probe_kind_schema:SCHEMA", table_names=("probes",))


def test_a_kind_registered_at_run_time_is_detected_checked_and_refused_like_the_labs():
    from renderlab.campaign.executors import _validate_tables
    from renderlab.contracts.schemas import check_campaign_table, expected_kind, table_from_rows, table_kind

    kind = _probe_kind()
    rows = [{"campaign": "c", "run": 0, "probe_value": 1.0, "has_result": True, "reason": "ok"}]
    before = pa.table({k: [v] for k, v in rows[0].items()})
    assert table_kind(before) == "other"
    plugins.observables.register("probe", kind)
    try:
        assert table_kind(before) == "probe" and expected_kind("probes", before.drop(["probe_value"])) == "probe"
        assert check_campaign_table("x", before, "x") == "probe"
        with pytest.raises(ValueError, match="'dark!' is not a probe reason"):
            table_from_rows([{**rows[0], "reason": "dark!"}], kind.core_schema(), "probe")
        task = type("Task", (), {"study": "s", "index": 0, "campaign": "c"})()
        with pytest.raises(ValueError, match="probes lack columns probe_value"):
            _validate_tables({"probes": before.drop(["probe_value"])}, task)
        assert plugins.kind_of_method(kind.protocol) is kind
    finally:
        plugins.observables.unregister("probe")
    assert table_kind(before) == "other"


def test_the_labs_kinds_are_read_from_the_registry_too():
    """Unregistering the filter kind makes a filter table another kind: detection has no list of its own."""
    from renderlab.contracts.schemas import table_kind

    t = pa.table({"campaign": ["c"], "run": [0], "t_s": [0.0], "has_result": [True], "reason": ["ok"],
                  "diagnostics": [""]})
    assert table_kind(t) == "filter"
    target = plugins.BUILTIN["observables"][1]["filter"]
    plugins.observables.unregister("filter")
    try:
        assert table_kind(t) == "pose"
    finally:
        plugins.observables.register("filter", target=target)
    assert table_kind(t) == "filter"


# ------------------------------------------------------------------------------------------------ the toy kind
def test_toy_kind_is_found_through_its_entry_points():
    eps = {ep.name: ep.value for ep in entry_points(group="renderlab.observables")}
    assert eps.get("bright_spot") == "renderlab_toy_kind.kind:BRIGHT_SPOT", \
        f"pip install --no-deps -e examples/toy_kind ({eps})"
    from renderlab_toy_kind.kind import BRIGHT_SPOT

    assert plugins.observables.get("bright_spot") is BRIGHT_SPOT
    assert {"peak_pixel", "window_centroid"} <= set(plugins.method_registry("bright_spot").names())
    assert "bright_spot" in plugins.studies.names()


def test_toy_kind_needs_no_edit_under_renderlab():
    hits = [p.relative_to(REPO).as_posix() for p in (REPO / "renderlab").rglob("*")
            if p.is_file() and p.suffix in (".py", ".toml", ".j2", ".md", ".json")
            and any(w in p.read_text(encoding="utf-8", errors="ignore") for w in ("bright_spot", "toy_kind"))]
    assert not hits


@pytest.fixture(scope="module")
def toy_campaign(tmp_path_factory):
    d = tmp_path_factory.mktemp("toy")
    rc = main(["campaign", str(SCENE), "--runs", "4", "--seed", "11", "--workers", "0", "--quiet", *TINY,
               "--set", "campaign.study=bright_spot", "--plugin", "test_observable_kinds:ShiftedCentroid",
               "--out", str(d / "c")])
    assert rc == 0
    assert main(["report", str(d / "c"), "--out", str(d / "r")]) == 0
    from renderlab.campaign import store

    return d, store.load_tables(d / "c")


def test_toy_campaign_measures_against_the_exact_truth(toy_campaign):
    from renderlab.campaign.scoring import score_table, table_kind

    _, tables = toy_campaign
    t = tables["spots"]
    assert table_kind(t) == "bright_spot"
    d = t.to_pydict()
    method = np.array(d["method"])
    assert set(method) == {"peak_pixel", "window_centroid", "shifted_centroid"}
    assert sorted(set(d["run"])) == [0, 1, 2, 3] and len(t) == 3 * 4 * 8
    blank = ~np.isfinite(np.array(d["truth_s"], float))
    ok = np.array(d["has_result"])
    assert 0 < blank.sum() < len(t)
    assert np.array_equal(ok, ~blank)  # exactly the frames without a spot have no result, for every method
    assert set(np.array(d["reason"])[blank]) == {"no_spot"}
    err = np.hypot(np.array(d["err_s"], float), np.array(d["err_l"], float))
    win, peak = (method == "window_centroid") & ok, (method == "peak_pixel") & ok
    assert np.max(np.abs(np.array(d["err_s"])[peak])) <= 0.75 and np.max(np.abs(np.array(d["err_l"])[peak])) <= 0.75
    assert np.sqrt(np.mean(err[win] ** 2)) < 0.1 < np.sqrt(np.mean(err[peak] ** 2))
    rows = {(r["method"], r["axis"]): r for r in score_table(t)}
    shifted, plain = rows[("shifted_centroid", "s")], rows[("window_centroid", "s")]
    assert shifted["bias_px"] - plain["bias_px"] == pytest.approx(SHIFT_PX, abs=1e-9)
    assert shifted["bias_px_lo"] <= shifted["bias_px"] <= shifted["bias_px_hi"]


def test_toy_report_section_comes_from_the_registry(toy_campaign):
    d, _ = toy_campaign
    page = (d / "r" / "index.html").read_text(encoding="utf-8")
    assert "Bright spot: spots" in page and "Why there is no result" in page
    with open(d / "r" / "summary.csv", newline="") as fh:
        summary = {(r["method"], r["axis"]): r for r in csv.DictReader(fh)}
    assert float(summary[("shifted_centroid", "s")]["bias_px"]) == pytest.approx(
        float(summary[("window_centroid", "s")]["bias_px"]) + SHIFT_PX, abs=1e-5)  # CSV: 6 digits
    assert (d / "r" / "spots_spot_summary.csv").is_file()
    assert "FAIL" in page and "PASS" in page  # the shifted method fails the 0.05 px band, the centroid passes it


@pytest.mark.parametrize("method", ["peak_pixel", "window_centroid"])
def test_check_method_runs_the_toy_kinds_harness(method, capsys):
    assert main(["check-method", "bright_spot", method]) == 0
    assert f"bright_spot method {method} conforms" in capsys.readouterr().out


@pytest.mark.parametrize("ref, rules", [("test_observable_kinds:ShiftedCentroid", ["rule (a)"]),
                                        ("test_observable_kinds:MutatingCentroid", ["rule (d)"]),
                                        ("test_observable_kinds:NoReasonCentroid", ["rule (e)", "rule (b)"])])
def test_check_method_names_the_broken_rule(ref, rules, capsys):
    assert main(["check-method", "bright_spot", ref]) == 1
    out = capsys.readouterr().out
    assert all(r in out for r in rules), out


def test_check_method_bad_input_is_one_line(capsys):
    assert main(["check-method", "bright_spott", "peak_pixel"]) == 2
    assert "did you mean 'bright_spot'" in capsys.readouterr().err
    assert main(["check-method", "pose", "anything"]) == 2
    assert "has no conformance harness" in capsys.readouterr().err
    assert main(["check-method", "bright_spot", "renderlab.measurement.builtin_methods:RetinaMethod"]) == 2
    assert "is not a bright_spot method" in capsys.readouterr().err
    assert main(["check-method", "bright_spot", "peak_pixle"]) == 2
    err = capsys.readouterr().err
    assert "unknown bright_spot method 'peak_pixle'" in err and "did you mean 'peak_pixel'" in err


def test_a_broken_kind_registration_is_one_line(capsys):
    """An entry point naming something else than an ObservableKind of its name: one line, exit 2."""
    plugins.observables.register("wrong", target="renderlab_toy_kind.kind:SpotReason")
    try:
        assert main(["check-method", "wrong", "x"]) == 2
        assert "observable kind 'wrong': the registered object is EnumType" in capsys.readouterr().err
    finally:
        plugins.observables.unregister("wrong")
    from renderlab_toy_kind.kind import BRIGHT_SPOT

    plugins.observables.register("renamed", BRIGHT_SPOT)
    try:
        assert main(["check-method", "renamed", "x"]) == 2
        assert "not an ObservableKind named 'renamed'" in capsys.readouterr().err
    finally:
        plugins.observables.unregister("renamed")


# ------------------------------------------------------------------------------------------------ no kind lists
def kind_lists(source: str, kinds) -> list[int]:
    """Lines of ``source`` that list kind names (a literal holding two or more, or a ``kind == "name"`` test)."""
    out = []
    for node in ast.walk(ast.parse(source)):
        items = node.keys if isinstance(node, ast.Dict) else getattr(node, "elts", None) \
            if isinstance(node, (ast.List, ast.Tuple, ast.Set)) else None
        if items is not None:
            names = {e.value for e in items if isinstance(e, ast.Constant) and e.value in kinds}
            if len(names) >= 2:
                out.append(node.lineno)
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any("kind" in _name(s).lower() for s in sides) \
                    and any(isinstance(s, ast.Constant) and s.value in kinds for s in sides):
                out.append(node.lineno)
    return out


def _name(node) -> str:
    """The identifier of a name, an attribute or a call's function ("" otherwise)."""
    node = node.func if isinstance(node, ast.Call) else node
    return node.id if isinstance(node, ast.Name) else node.attr if isinstance(node, ast.Attribute) else ""


def test_the_scan_finds_the_old_kind_lists():
    """The scanner on the shapes the lab had before the registry (so a clean scan means something)."""
    old = ('REASONS = {"landmark": LandmarkReason, "filter": FilterReason, "pose": PoseReason}\n'
           'for kind in ("landmark", "filter", "pose"):\n    pass\n'
           'if kind == "landmark":\n    pass\n'
           'if scoring.table_kind(t) == "filter" or task.kind != "pose":\n    pass\n'
           'if kind == "other" or world.kind == "planet":\n    pass\n')  # not kind names: not found
    assert kind_lists(old, LAB_KINDS) == [1, 2, 4, 6, 6]


def test_no_kind_list_outside_the_registry():
    kinds = set(plugins.observables.names())
    found = []
    for path in sorted((REPO / "renderlab").rglob("*.py")):
        if path.relative_to(REPO).as_posix() == "renderlab/plugins.py":  # the registry itself
            continue
        found += [f"{path.relative_to(REPO)}:{n}" for n in kind_lists(path.read_text(encoding="utf-8"), kinds)]
    assert not found, "kinds listed outside renderlab.plugins.observables: " + ", ".join(found)
