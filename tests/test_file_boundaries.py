"""The boundary readers themselves (renderlab.inputs, renderlab.contracts.{schemas,image_headers}, the Strict models)
and the outputs the fuzz families cannot see: quoting is bounded and cheap, alias bombs and compressed-table bombs are
refused before they are expanded, headers are checked before any pixel is decoded, strings are never numbers, a
published report names no absolute path and an interrupted publish leaves nothing, the local cluster listens on the
loopback only, and a KVN value the lab writes reads back the same through an independent reader."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from renderlab.cli import main
from renderlab.errors import UserError

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fuzz_files import alias_bomb, png_header, tiny_scene_text  # noqa: E402


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """A tiny campaign (2 runs) and a tiny truth set, made by the lab."""
    root = tmp_path_factory.mktemp("boundaries")
    os.environ.setdefault("RENDERLAB_CACHE", str(root / "cache"))
    (root / "scene.toml").write_text(tiny_scene_text(), encoding="utf-8")
    assert main(["campaign", str(root / "scene.toml"), "--runs", "2", "--out", str(root / "camp"), "--workers", "0",
                 "--quiet"]) == 0
    assert main(["render", str(root / "scene.toml"), "--out", str(root / "ts"), "--quiet"]) == 0
    return root


def test_short_is_bounded_and_cheap():
    from renderlab.inputs import QUOTE_CHARS, short

    loop: list = []
    loop.append(loop)
    deep: list = []
    for _ in range(100_000):
        deep = [deep]
    shared = [[1.0] * 10]
    for _ in range(60):  # 10 ** 60 leaves when walked naively (what an alias bomb parses into)
        shared = [shared] * 10

    class Bad:
        def __repr__(self):
            raise RuntimeError("no repr")
    for v in (loop, deep, shared, "x" * 10 ** 7, 10 ** 5000, {i: i for i in range(10 ** 5)}, Bad()):
        t0 = time.perf_counter()
        text = short(v)
        assert len(text) <= QUOTE_CHARS and time.perf_counter() - t0 < 0.5, (text, time.perf_counter() - t0)


def test_user_error_keeps_a_bounded_line():
    from renderlab.errors import MAX_MESSAGE

    err = UserError("value " + "x" * 10 ** 6 + "\nsecond line")
    assert len(str(err)) == MAX_MESSAGE and "\n" not in str(err) and str(err).endswith("…")


def test_yaml_alias_bomb_refused_before_it_is_built():
    """A billion-node alias bomb (PyYAML composes it as shared nodes) is counted on the composed graph and refused in
    well under a second; the same document one level shallower (10^4 leaves) still loads, equal to PyYAML's own."""
    import yaml

    from renderlab.inputs import load_yaml

    t0 = time.perf_counter()
    with pytest.raises(UserError, match="alias"):
        load_yaml(alias_bomb(10, 9).split("\n", 1)[1], yaml.SafeLoader, "bomb.yaml")  # without OpenCV's %YAML:1.0
    assert time.perf_counter() - t0 < 1.0
    small = alias_bomb(10, 3).split("\n", 1)[1]
    assert load_yaml(small, yaml.SafeLoader, "ok.yaml") == yaml.safe_load(small)


def test_special_files_are_never_opened_for_reading(tmp_path):
    from renderlab.inputs import read_bytes

    os.mkfifo(tmp_path / "fifo")
    os.symlink("/dev/zero", tmp_path / "zero")
    for name, word in (("fifo", "FIFO"), ("zero", "character device")):
        t0 = time.perf_counter()
        with pytest.raises(UserError, match=word):
            read_bytes(tmp_path / name, "file", 1 << 20)
        assert time.perf_counter() - t0 < 1.0
    (tmp_path / "big").write_bytes(b"\0" * 2048)
    with pytest.raises(UserError, match="more than"):
        read_bytes(tmp_path / "big", "file", 1024)


def test_table_bomb_refused_from_its_footer(tmp_path, monkeypatch):
    """A table whose column run-length-encodes 10 000:1 is refused by the size its footer says it decodes into
    (rows × value width: pyarrow's own metadata the oracle), before any column is decoded."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from renderlab import inputs
    from renderlab.contracts import schemas

    p = tmp_path / "bomb.parquet"
    pq.write_table(pa.table({"x": np.zeros(2_000_000, np.int64)}), p, compression="zstd")
    meta = pq.read_metadata(p)
    assert meta.num_rows * 8 > 10_000 * p.stat().st_size  # what the footer says it decodes into, vs the file
    monkeypatch.setitem(inputs.LIMITS, "table", 4 * p.stat().st_size)
    monkeypatch.setattr(pq.ParquetFile, "read", lambda *a, **k: pytest.fail("decoded"))
    with pytest.raises(UserError, match="unpacked"):
        schemas.read_parquet(p, "bomb")


def test_png_header_checked_before_decoding(tmp_path, monkeypatch):
    """A 200-byte PNG claiming 60000 × 60000 px is refused from its IHDR; cv2.imdecode is never reached."""
    import cv2

    from renderlab.files.imageio import read_dn_png

    (tmp_path / "b.png").write_bytes(png_header(60000, 60000))
    monkeypatch.setattr(cv2, "imdecode", lambda *a: pytest.fail("decoded"))
    with pytest.raises(UserError, match="60000 × 60000 px"):
        read_dn_png(tmp_path / "b.png")


def test_truth_frame_sizes_against_the_camera(made, tmp_path, monkeypatch):
    """A truth set whose DN PNG or EXR is not the camera's size is refused from the headers, naming both sizes."""
    import shutil

    import cv2

    from renderlab.files.imageio import read_exr, write_exr
    from renderlab.files.truthset import TruthSet

    ts_dir = tmp_path / "ts"
    shutil.copytree(made / "ts", ts_dir)
    rec = TruthSet.open(ts_dir).frames[0]
    cam = rec["camera"]
    cv2.imwrite(str(ts_dir / rec["dn"]), np.zeros((cam["height"] + 1, cam["width"]), np.uint16))
    monkeypatch.setattr(cv2, "imdecode", lambda *a: pytest.fail("decoded"))
    with pytest.raises(UserError, match=f"{cam['width']} × {cam['height'] + 1} px, but the camera is"):
        TruthSet.open(ts_dir).load(0)
    monkeypatch.undo()
    ch = {k: np.zeros((cam["height"], cam["width"] + 2), v.dtype) for k, v in read_exr(made / "ts" / rec["exr"]).items()}
    write_exr(ts_dir / rec["exr"], ch)
    with pytest.raises(UserError, match=f"{cam['width'] + 2} × {cam['height']} px, but the camera is"):
        TruthSet.open(ts_dir).load(0)


def test_strings_are_not_numbers():
    """Strict models refuse ``"64"`` for a number (and a list or table of numbers); a field that takes strings keeps
    them."""
    from typing import Literal

    from pydantic import ValidationError

    from renderlab.contracts.config_types import Strict

    class M(Strict):
        n: int = 1
        f: float | None = None
        v: list[float] = []
        d: dict[str, float] = {}
        s: str = ""
        either: int | str = 0
        choice: Literal["a", "64"] = "a"

    for bad in ({"n": "64"}, {"f": "1.5"}, {"v": [1.0, "2"]}, {"d": {"k": "3"}}):
        with pytest.raises(ValidationError, match="not a string"):
            M(**bad)
    ok = M(s="64", either="64", choice="64", n=64)
    assert (ok.s, ok.either, ok.choice, ok.n) == ("64", "64", "64", 64)


def test_report_names_the_missing_column(made, tmp_path, capsys):
    import shutil

    import pyarrow.parquet as pq

    camp = tmp_path / "camp"
    shutil.copytree(made / "camp", camp)
    for run in ("000000", "000001"):
        p = camp / "runs" / run / "measurements.parquet"
        pq.write_table(pq.read_table(p).drop_columns(["err_l"]), p)
    assert main(["report", str(camp), "--out", str(tmp_path / "rep")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "lacks column 'err_l'" in err
    assert not (tmp_path / "rep").exists()


def test_published_report_holds_no_absolute_path(made, tmp_path, monkeypatch, capsys):
    out = tmp_path / "elsewhere" / "study"
    out.parent.mkdir()
    monkeypatch.chdir(made)  # the study folder is outside the current folder: named by its name
    assert main(["publish", str(made / "camp"), "--out", str(out)]) == 0
    texts = [p for p in out.rglob("*") if p.is_file() and p.suffix in (".md", ".html", ".json", ".csv", ".svg")]
    assert texts
    for p in texts:
        text = p.read_text(encoding="utf-8")
        assert str(tmp_path) not in text and str(made) not in text, p
    assert "renderlab report study" in (out / "report" / "README.md").read_text()
    capsys.readouterr()


def test_interrupted_publish_leaves_nothing(made, tmp_path, monkeypatch, capsys):
    """The report is written inside the publish stage: an interrupt while it is written leaves no study folder
    (before: tables, campaign.json and runs.json without report/)."""
    from renderlab.report import campaign_report

    real = campaign_report.make_report

    def interrupted(campaign_dir, out_dir, **kw):
        real(campaign_dir, out_dir, **kw)
        raise KeyboardInterrupt

    monkeypatch.setattr(campaign_report, "make_report", interrupted)
    assert main(["publish", str(made / "camp"), "--out", str(tmp_path / "study")]) == 130
    assert list(tmp_path.iterdir()) == []
    capsys.readouterr()


def test_local_cluster_listens_on_loopback_only():
    from renderlab.campaign.executors import DaskExecutor

    with DaskExecutor(workers=1) as ex:
        info = ex._client.scheduler_info()
        addresses = [info["address"], *info["workers"]]
    assert all(a.startswith("tcp://127.0.0.1:") for a in addresses), addresses


def test_object_name_reads_back_through_an_independent_reader(made, tmp_path, capsys):
    """Every printable ASCII character the lab accepts in --object-name is written so that the ``oem`` package reads
    the same OBJECT_NAME back."""
    oem = pytest.importorskip("oem")
    name = "".join(chr(c) for c in range(33, 127) if chr(c) not in "#")[:60] + " X"
    assert main(["export", str(made / "ts"), "--oem", str(tmp_path / "c.oem"), "--epoch-utc", "2024-01-01T00:00:00",
                 "--object-name", name]) == 0
    parsed = oem.OrbitEphemerisMessage.open(str(tmp_path / "c.oem"))
    assert parsed.segments[0].metadata["OBJECT_NAME"] == name
    capsys.readouterr()
