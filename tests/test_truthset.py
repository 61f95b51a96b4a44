"""Tests for renderlab.files.truthset: EXR/PNG I/O, atomic truth-set writing, reading, errors."""

import json
import os

import numpy as np
import OpenEXR
import pyarrow as pa
import pytest

from renderlab.errors import UserError
from renderlab.files import truthset
from renderlab.files.truthset import (
    FORMAT,
    TruthFrame,
    TruthSet,
    TruthSetWriter,
    read_dn_png,
    read_exr,
    write_dn_png,
    write_exr,
)

H, W = 24, 32


def make_frame(index, rgb=False):
    rng = np.random.default_rng(index)
    hit = np.ones((H, W), bool)
    hit[:, :5] = False  # a strip of sky
    ch = {}
    if rgb:
        for c in "RGB":
            ch[c] = rng.uniform(0, 30, (H, W)).astype(np.float32)
    else:
        ch["Y"] = rng.uniform(0, 30, (H, W)).astype(np.float32)
    for prefix in ("P", "N"):
        for axis in "XYZ":
            a = rng.normal(0, 100, (H, W)).astype(np.float32)
            a[~hit] = np.nan
            ch[f"{prefix}.{axis}"] = a
    ch["range"] = np.where(hit, rng.uniform(10, 50, (H, W)), np.inf).astype(np.float32)
    ch["id"] = np.where(hit, rng.integers(0, 5000, (H, W)), -1).astype(np.float32)
    dn = rng.integers(0, 1024, (H, W)).astype(np.uint16)
    meta = {"camera": {"width": W, "height": H, "fx": 1000.0, "fy": 1000.0, "cx": 15.5,
                       "cy": 11.5, "skew": 0.0, "model": "pinhole",
                       "distortion": {"k1": 0.0, "k2": 0.0, "k3": 0.0, "p1": 0.0, "p2": 0.0}},
            "pose": {"position_m": np.array([1.0, 2.0, 3.0 + index]),
                     "quat_render_from_cam_xyzw": [0.0, 0.0, 0.0, 1.0]},
            "sun": {"direction_render": [1.0, 0.0, 0.0], "irradiance_w_m2": np.float32(1361.0)},
            "bodies": {"ev5": {"spin_angle_rad": 0.1 * index}}}
    return ch, dn, meta


HEAD = {"renderer": {"name": "mitsuba", "version": "3.9.1", "variant": "llvm_ad_mono"},
        "scenario": {"name": "unit", "frames": 2}}


def write_set(out, frames=(0, 1), rgb=False, **kw):
    with TruthSetWriter(out, HEAD, **kw) as w:
        for i in frames:
            ch, dn, meta = make_frame(i, rgb)
            w.add_frame(i, 0.5 * i, ch, dn, meta)
        w.add_table("landmarks", pa.table({"landmark_id": [1, 2], "spacing_m": [0.1, 0.2]}))
        w.add_file("maplets/000001.bin", b"\x00\x01\x02")
    return out


def siblings(path):
    return sorted(p.name for p in path.parent.iterdir())


def test_exr_round_trip_exact_with_nan_and_header(tmp_path):
    ch, _, _ = make_frame(3)
    write_exr(tmp_path / "a.exr", ch, {"renderlab_units": "SI", "renderlab_frame": 3})
    back = read_exr(tmp_path / "a.exr")
    assert set(back) == set(ch)
    with OpenEXR.File(str(tmp_path / "a.exr"), separate_channels=True) as f:
        hdr = f.header()
        assert hdr["compression"] == OpenEXR.ZIP_COMPRESSION
        assert hdr["type"] == OpenEXR.scanlineimage
        assert hdr["renderlab_units"] == "SI" and hdr["renderlab_frame"] == 3
        assert {c.type() for c in f.channels().values()} == {OpenEXR.FLOAT}
    for name in ch:
        assert back[name].dtype == np.float32
        assert np.array_equal(back[name], ch[name], equal_nan=True), name


def test_exr_casts_float64_and_fortran_order(tmp_path):
    a = np.asfortranarray(np.random.default_rng(0).normal(size=(H, W)))
    write_exr(tmp_path / "f.exr", {"Y": a})
    assert np.array_equal(read_exr(tmp_path / "f.exr")["Y"], a.astype(np.float32))


def test_same_inputs_give_bit_identical_files(tmp_path):
    ch, dn, _ = make_frame(0)
    for k in (1, 2):
        write_exr(tmp_path / f"{k}.exr", ch)
        write_dn_png(tmp_path / f"{k}.png", dn)
    assert (tmp_path / "1.exr").read_bytes() == (tmp_path / "2.exr").read_bytes()
    assert (tmp_path / "1.png").read_bytes() == (tmp_path / "2.png").read_bytes()
    a, b = write_set(tmp_path / "s1"), write_set(tmp_path / "s2")
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    assert [f.as_posix() for f in files] == [
        "dn_preview/000000.png", "dn_preview/000001.png",
        "frames/000000.exr", "frames/000000.png", "frames/000001.exr", "frames/000001.png",
        "landmarks.parquet", "manifest.json", "maplets/000001.bin"]
    for f in files:
        assert (a / f).read_bytes() == (b / f).read_bytes(), f


def test_png_round_trip_and_dtype_check(tmp_path):
    dn = np.arange(H * W, dtype=np.uint16).reshape(H, W) % 1024
    write_dn_png(tmp_path / "d.png", dn)
    back = read_dn_png(tmp_path / "d.png")
    assert back.dtype == np.uint16 and np.array_equal(back, dn)
    write_dn_png(tmp_path / "full.png", np.array([[0, 65535]], np.int64))
    assert read_dn_png(tmp_path / "full.png").tolist() == [[0, 65535]]
    import cv2
    cv2.imwrite(str(tmp_path / "u8.png"), dn.astype(np.uint8))
    with pytest.raises(UserError, match="16-bit"):
        read_dn_png(tmp_path / "u8.png")
    (tmp_path / "bad.png").write_bytes((tmp_path / "d.png").read_bytes()[:40])
    with pytest.raises(UserError, match="bad.png"):
        read_dn_png(tmp_path / "bad.png")


def test_truth_set_round_trip(tmp_path):
    out = write_set(tmp_path / "set")
    manifest = json.loads((out / "manifest.json").read_text())
    assert list(manifest) == ["format", "renderer", "scenario", "frames"]
    assert manifest["format"] == FORMAT == "renderlab.truthset/1"
    ts = TruthSet.open(out)
    assert len(ts) == 2 and ts.manifest == manifest
    assert ts.frames[1]["exr"] == "frames/000001.exr" and ts.frames[1]["dn"] == "frames/000001.png"
    for i in (0, 1):
        ch, dn, meta = make_frame(i)
        fr = ts.load(i)
        assert isinstance(fr, TruthFrame) and fr.index == i and fr.time_s == 0.5 * i
        assert fr.rgb is None and np.array_equal(fr.radiance, ch["Y"])
        pos = np.stack([ch["P.X"], ch["P.Y"], ch["P.Z"]], -1)
        nrm = np.stack([ch["N.X"], ch["N.Y"], ch["N.Z"]], -1)
        assert fr.position.shape == (H, W, 3)
        assert np.array_equal(fr.position, pos, equal_nan=True)
        assert np.array_equal(fr.normal, nrm, equal_nan=True)
        assert np.array_equal(fr.range, ch["range"])
        assert fr.id.dtype == np.int32 and np.array_equal(fr.id, ch["id"].astype(np.int32))
        assert (fr.id[:, :5] == -1).all()
        assert fr.dn.dtype == np.uint16 and np.array_equal(fr.dn, dn)
        assert ts.camera(i) == meta["camera"]
        assert fr.meta["pose"]["position_m"] == [1.0, 2.0, 3.0 + i]
        assert fr.meta["sun"]["irradiance_w_m2"] == 1361.0
    assert ts.read_table("landmarks").column("landmark_id").to_pylist() == [1, 2]
    assert (out / "maplets" / "000001.bin").read_bytes() == b"\x00\x01\x02"
    assert siblings(out) == ["set"]  # no staging leftovers


def test_rgb_set(tmp_path):
    ts = TruthSet.open(write_set(tmp_path / "rgb", rgb=True, frames=(0,)))
    fr = ts.load(0)
    ch, _, _ = make_frame(0, rgb=True)
    assert fr.radiance is None and fr.rgb.shape == (H, W, 3)
    assert np.array_equal(fr.rgb[..., 1], ch["G"])


def test_failure_inside_writer_leaves_nothing(tmp_path):
    out = tmp_path / "set"
    with pytest.raises(RuntimeError, match="boom"):
        with TruthSetWriter(out, HEAD) as w:
            ch, dn, meta = make_frame(0)
            w.add_frame(0, 0.0, ch, dn, meta)
            assert w.staging_dir.is_dir() and w.staging_dir.parent == out.parent
            assert w.staging_dir.name.startswith(".")
            raise RuntimeError("boom")
    assert not out.exists()
    assert os.listdir(tmp_path) == []


def test_nan_metadata_is_refused_and_cleaned_up(tmp_path):
    out = tmp_path / "set"
    with pytest.raises(UserError, match=r"frames\[0\]\.pose\.position_m\[1\]"):
        with TruthSetWriter(out, HEAD) as w:
            ch, dn, meta = make_frame(0)
            meta["pose"]["position_m"] = [1.0, float("nan"), 2.0]
            w.add_frame(0, 0.0, ch, dn, meta)
    assert os.listdir(tmp_path) == []
    with pytest.raises(UserError, match="NaN"):
        TruthSetWriter(out, {"scenario": {"x": float("nan")}})


def test_existing_non_empty_out_dir_refused_unless_overwrite(tmp_path):
    out = tmp_path / "set"
    out.mkdir()
    (out / "keep.txt").write_text("old")
    with pytest.raises(UserError, match="not empty"):
        TruthSetWriter(out, HEAD)
    assert (out / "keep.txt").read_text() == "old"
    # overwrite: the old folder survives a failure ...
    with pytest.raises(RuntimeError):
        with TruthSetWriter(out, HEAD, overwrite=True):
            raise RuntimeError("fail")
    assert (out / "keep.txt").read_text() == "old" and siblings(out) == ["set"]
    # ... and is replaced only by a successful write
    write_set(out, overwrite=True)
    assert not (out / "keep.txt").exists() and len(TruthSet.open(out)) == 2
    assert siblings(out) == ["set"]
    empty = tmp_path / "empty"
    empty.mkdir()
    assert len(TruthSet.open(write_set(empty))) == 2  # an empty existing folder is fine


def test_unwritable_parent(tmp_path, monkeypatch):
    (tmp_path / "file").write_text("x")
    for bad in (tmp_path / "file" / "set", tmp_path / "file" / "a" / "set", tmp_path / "file"):
        with pytest.raises(UserError) as ei:
            with TruthSetWriter(bad, HEAD):
                pass
        assert "\n" not in str(ei.value)
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if os.geteuid() != 0:  # root ignores permissions: simulate with os.access below
            with pytest.raises(UserError, match="not writable"):
                TruthSetWriter(ro / "set", HEAD)
        with monkeypatch.context() as m:
            m.setattr(truthset.os, "access", lambda *a, **k: False)
            with pytest.raises(UserError, match="not writable"):
                TruthSetWriter(ro / "set", HEAD)
    finally:
        ro.chmod(0o700)


def test_missing_parents_are_created(tmp_path):
    out = write_set(tmp_path / "a" / "b" / "set", frames=(0,))
    assert len(TruthSet.open(out)) == 1


def test_corrupt_exr_gives_user_error(tmp_path):
    out = write_set(tmp_path / "set")
    exr = out / "frames" / "000001.exr"
    data = exr.read_bytes()
    exr.write_bytes(data[: len(data) // 2])
    ts = TruthSet.open(out)
    ts.load(0)
    with pytest.raises(UserError, match="000001.exr"):
        ts.load(1)
    exr.write_bytes(b"not an exr")
    with pytest.raises(UserError, match="000001.exr"):
        read_exr(exr)
    with pytest.raises(UserError, match="nothing.exr"):
        read_exr(tmp_path / "nothing.exr")


def test_missing_manifest_files_or_bad_format(tmp_path):
    out = write_set(tmp_path / "set")
    (out / "frames" / "000001.png").unlink()
    with pytest.raises(UserError, match="000001.png"):
        TruthSet.open(out)
    m = json.loads((out / "manifest.json").read_text())
    m["format"] = "something/2"
    (out / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(UserError, match="format"):
        TruthSet.open(out)
    (out / "manifest.json").write_text("{not json")
    with pytest.raises(UserError, match="manifest.json"):
        TruthSet.open(out)
    (out / "manifest.json").unlink()
    with pytest.raises(UserError, match="manifest.json"):
        TruthSet.open(out)
    with pytest.raises(UserError, match="not a directory"):
        TruthSet.open(tmp_path / "absent")


def test_writer_rejects_misuse(tmp_path):
    with TruthSetWriter(tmp_path / "set", HEAD) as w:
        ch, dn, meta = make_frame(0)
        w.add_frame(0, 0.0, ch, dn, meta)
        with pytest.raises(ValueError, match="already"):
            w.add_frame(0, 0.0, ch, dn, meta)
        with pytest.raises(ValueError, match="range"):
            w.add_frame(1, 0.0, {k: v for k, v in ch.items() if k != "range"}, dn, meta)
        with pytest.raises(ValueError, match="shape"):
            w.add_frame(2, 0.0, ch, dn[:-1], meta)
        with pytest.raises(UserError, match="relative"):
            w.add_file("../escape.bin", b"")
        with pytest.raises(ValueError, match="reserved"):
            w.add_file("manifest.json", b"{}")
    with pytest.raises(RuntimeError, match="context"):
        w.add_file("late.bin", b"")
    assert [f["index"] for f in TruthSet.open(tmp_path / "set").frames] == [0]
    with pytest.raises(ValueError, match="format"):
        TruthSetWriter(tmp_path / "x", {"format": "mine"})


def test_frames_sorted_by_index_and_camera_shape_checked(tmp_path):
    out = write_set(tmp_path / "set", frames=(2, 0))
    ts = TruthSet.open(out)
    assert [f["index"] for f in ts.frames] == [0, 2]
    m = json.loads((out / "manifest.json").read_text())
    m["frames"][0]["camera"]["width"] = W + 1
    (out / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(UserError, match="camera"):
        TruthSet.open(out).load(0)


@pytest.mark.parametrize("name,code", [("rle", "RLE_COMPRESSION"), ("none", "NO_COMPRESSION")])
def test_exr_compression_choice_is_lossless(tmp_path, name, code):
    """render.exr_compression: every choice reads back bit for bit (OpenEXR's own reader) with its header code."""
    ch, _, _ = make_frame(5)
    write_exr(tmp_path / "z.exr", ch)
    write_exr(tmp_path / f"{name}.exr", ch, compression=name)
    with OpenEXR.File(str(tmp_path / f"{name}.exr"), separate_channels=True) as f:
        assert f.header()["compression"] == getattr(OpenEXR, code)
        back = {k: np.asarray(c.pixels) for k, c in f.channels().items()}
    for k in ch:
        assert np.array_equal(back[k], ch[k], equal_nan=True), k
    with pytest.raises(ValueError, match="compression"):
        write_exr(tmp_path / "bad.exr", ch, compression="lzma")


def _zip_chunk_flevels(data: bytes) -> set[int]:
    """FLEVEL bits (RFC 1950: 0 = fastest ... 3 = slowest) of the zlib header of every chunk of a single-part scanline
    ZIP EXR, parsed here from the file layout (header attributes, offset table, chunks of 16 scanlines)."""
    import struct

    assert data[:4] == b"\x76\x2f\x31\x01"
    i, attrs = 8, {}
    while data[i] != 0:
        j = data.index(b"\0", i)
        k = data.index(b"\0", j + 1)
        (n,) = struct.unpack("<i", data[k + 1:k + 5])
        attrs[data[i:j].decode()] = data[k + 5:k + 5 + n]
        i = k + 5 + n
    assert attrs["compression"][0] == 3  # ZIP_COMPRESSION
    _, y0, _, y1 = struct.unpack("<4i", attrs["dataWindow"])
    count = -(-(y1 - y0 + 1) // 16)
    offsets = struct.unpack(f"<{count}Q", data[i + 1:i + 1 + 8 * count])
    flevels = set()
    for o in offsets:
        _, size = struct.unpack("<ii", data[o:o + 8])
        cmf, flg = data[o + 8], data[o + 9]
        assert cmf & 0x0F == 8 and (cmf * 256 + flg) % 31 == 0, "chunk is not a zlib stream"
        flevels.add(flg >> 6)
    return flevels


@pytest.mark.parametrize("level,flevel", [(None, 0), (4, 1)])
def test_exr_zip_level_is_applied_and_lossless(tmp_path, monkeypatch, level, flevel):
    """ZIP EXRs are deflated at imageio.EXR_ZIP_LEVEL (1: zlib header FLEVEL 0, "fastest"; OpenEXR's own default 4
    gives FLEVEL 1), read off each chunk's zlib header, and read back bit for bit with OpenEXR's own reader."""
    from renderlab.files import imageio

    if level is not None:
        monkeypatch.setattr(imageio, "EXR_ZIP_LEVEL", level)
    yy, xx = np.mgrid[0:40, 0:64]
    ch = {"Y": (0.25 * xx + yy).astype(np.float32), "id": (xx // 8).astype(np.uint32)}  # compressible
    write_exr(tmp_path / "z.exr", ch)
    assert _zip_chunk_flevels((tmp_path / "z.exr").read_bytes()) == {flevel}
    with OpenEXR.File(str(tmp_path / "z.exr"), separate_channels=True) as f:
        back = {k: np.asarray(c.pixels) for k, c in f.channels().items()}
    assert all(np.array_equal(back[k], ch[k]) and back[k].dtype == ch[k].dtype for k in ch)
