"""``renderlab report FOLDER`` on result folders of registered kinds (renderlab.contracts.result_folder): the
error budget regenerates from its committed tables into --out (``--tables-only``: no figure drawn) and equals the
committed report; a kind registered at run time is used with no edit of the command; a missing folder is one line, exit 2."""

from __future__ import annotations

import filecmp
from pathlib import Path

import pytest

from renderlab.cli import main
from renderlab.plugins import result_folders

REPO = Path(__file__).resolve().parents[1]


def test_builtin_kinds_are_registered():
    assert {"crosscheck", "error_budget"} <= set(result_folders.names())
    assert result_folders.get("error_budget").recognises(REPO / "results" / "error_budget")
    assert not result_folders.get("error_budget").recognises(REPO / "results" / "retina_vs_spc")
    assert not result_folders.get("crosscheck").recognises(REPO / "results" / "error_budget")


@pytest.mark.published
def test_error_budget_regenerates_through_renderlab_report(tmp_path, capsys):
    src = REPO / "results" / "error_budget"
    assert main(["report", str(src), "--out", str(tmp_path / "rep"), "--tables-only"]) == 0
    committed = sorted(p.name for p in (src / "report").iterdir() if p.suffix in (".csv", ".md"))
    assert committed and "budget_summary.csv" in committed
    _, mismatch, errors = filecmp.cmpfiles(src / "report", tmp_path / "rep", committed, shallow=False)
    assert mismatch == [] and errors == []
    assert sorted(p.name for p in (tmp_path / "rep").iterdir()) == committed, "tables and text only, no figure"
    assert {p.name for p in (src / "report").glob("error_budget.*")} == {"error_budget.png"}  # SVG with --svg


def test_a_kind_registered_at_run_time_is_dispatched(tmp_path):
    class Marker:
        name = "marker_kind"

        def recognises(self, folder):
            return (Path(folder) / "MARKER").is_file()

        def write_report(self, folder, out_dir):
            out = Path(out_dir or folder) / "page.txt"
            out.write_text((Path(folder) / "MARKER").read_text().upper())
            return [out]

    (tmp_path / "MARKER").write_text("hello")
    result_folders.register("marker_kind", Marker())
    try:
        assert main(["report", str(tmp_path)]) == 0
    finally:
        result_folders.unregister("marker_kind")
    assert (tmp_path / "page.txt").read_text() == "HELLO"


def test_missing_folder_is_one_line(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        rc = main(["report", str(tmp_path / "nowhere")])
        raise SystemExit(rc)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "no such folder" in err
