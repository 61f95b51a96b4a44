"""Truth-set files are viewable and self-describing, checked with independent oracles.

* DN PNG: 16-bit and bit-exact on reading, with an ``sBIT`` chunk saying the sensor's N bits (the
  chunks are parsed and their CRCs checked here, not with the writer's code); beside it an 8-bit
  preview ``dn_preview/NNNNNN.png`` scaled so that full scale 2^N - 1 is 255.
* EXR: the ``id`` channel is UINT (-1 = no hit stored as 0xFFFFFFFF), and old float32-id files still
  read. The header holds the standard ``worldToCamera`` / ``worldToNDC`` (OpenEXR convention: row
  vectors, ``[x y z 1] · M``; OpenEXR camera space is +x right, +y up, +z viewing direction, so it is
  the renderlab camera frame (+y down) with y negated; NDC (0, 0) / (1, 1) are the top-left /
  bottom-right image corners), checked by transforming points against scipy's rotation of the
  manifest quaternion and against the pixel each rendered P-AOV point came from.
"""

from __future__ import annotations

import io
import json
import struct
import zlib

import numpy as np
import OpenEXR
import pytest
from PIL import Image
from scipy.spatial.transform import Rotation

from renderlab.files.imageio import read_dn_png, write_dn_png, write_dn_preview, write_exr
from renderlab.files.truthset import TruthSet, TruthSetWriter

H, W = 12, 16
CAM = {"width": W, "height": H, "fx": 20.0, "fy": 18.0, "cx": 7.25, "cy": 5.5, "skew": 0.0,
       "model": "pinhole", "distortion": {}}
Q = Rotation.from_euler("zyx", [30.0, -20.0, 110.0], degrees=True).as_quat().tolist()
POS = [3.0, -4.0, 12.5]


def png_chunks(data: bytes) -> list[tuple[bytes, bytes]]:
    """(type, data) of every chunk of a PNG, each CRC checked with zlib."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    out, i = [], 8
    while i < len(data):
        (n,) = struct.unpack(">I", data[i:i + 4])
        kind, body = data[i + 4:i + 8], data[i + 8:i + 8 + n]
        (crc,) = struct.unpack(">I", data[i + 8 + n:i + 12 + n])
        assert crc == zlib.crc32(kind + body), f"bad CRC on {kind!r}"
        out.append((kind, body))
        i += 12 + n
    assert out[-1][0] == b"IEND"
    return out


def ihdr(data: bytes) -> tuple[int, int, int, int]:
    """(width, height, bit depth, colour type) from the IHDR chunk."""
    kind, body = png_chunks(data)[0]
    assert kind == b"IHDR"
    w, h, depth, colour = struct.unpack(">IIBB", body[:10])
    return w, h, depth, colour


def sbit(data: bytes):
    """The sBIT chunk's data (None if absent); asserts it comes before the first IDAT."""
    kinds = [k for k, _ in png_chunks(data)]
    if b"sBIT" not in kinds:
        return None
    assert kinds.index(b"sBIT") < kinds.index(b"IDAT")
    return dict(png_chunks(data))[b"sBIT"]


# ------------------------------------------------------------------------------------------ PNG
def test_dn_png_is_bit_exact_and_carries_sbit(tmp_path):
    dn = np.random.default_rng(1).integers(0, 1024, (H, W)).astype(np.uint16)
    dn[0, 0], dn[0, 1] = 0, 1023
    write_dn_png(tmp_path / "d.png", dn, bits=10)
    data = (tmp_path / "d.png").read_bytes()
    assert ihdr(data) == (W, H, 16, 0)              # 16-bit greyscale, as before
    assert sbit(data) == bytes([10])                # 10 significant bits
    back = read_dn_png(tmp_path / "d.png")
    assert back.dtype == np.uint16 and np.array_equal(back, dn)   # not shifted by sBIT
    with Image.open(io.BytesIO(data)) as im:        # an independent decoder agrees
        assert np.array_equal(np.asarray(im, dtype=np.uint16), dn)
    write_dn_png(tmp_path / "16.png", dn)           # 16 significant bits: no sBIT needed
    assert sbit((tmp_path / "16.png").read_bytes()) is None
    with pytest.raises(ValueError, match="0..1023"):
        write_dn_png(tmp_path / "x.png", dn + 1024, bits=10)


def test_preview_is_8_bit_and_scaled_to_full_scale(tmp_path):
    rng = np.random.default_rng(2)
    dn = np.minimum(rng.normal(900, 200, (H, W)), 1023).clip(0).astype(np.uint16)  # bright, saturating
    write_dn_preview(tmp_path / "p.png", dn, bits=10)
    data = (tmp_path / "p.png").read_bytes()
    assert ihdr(data)[2:] == (8, 0)
    with Image.open(io.BytesIO(data)) as im:
        assert im.mode == "L"
        prev = np.asarray(im)
    assert prev.max() == 255 and dn.max() == 1023
    np.testing.assert_array_equal(prev, np.floor(dn * 255.0 / 1023.0 + 0.5).astype(np.uint8))


# ----------------------------------------------------------------------------------- truth set
def _frame():
    """Channels whose P points are exact back-projections of known pixels at known depths."""
    R, t = Rotation.from_quat(Q), np.asarray(POS)
    ll, ss = np.mgrid[0:H, 0:W].astype(float)
    depth = 5.0 + 0.1 * ss + 0.2 * ll
    p_cam = np.stack([(ss - CAM["cx"]) / CAM["fx"], (ll - CAM["cy"]) / CAM["fy"], np.ones_like(ss)], -1)
    p_cam *= depth[..., None]
    P = R.apply(p_cam.reshape(-1, 3)).reshape(H, W, 3) + t
    ids = np.where(ss < 3, -1, (ll * W + ss) % 7).astype(np.int32)
    ch = {"Y": np.full((H, W), 2.0, np.float32), "range": np.linalg.norm(P - t, axis=-1)}
    for k, a in enumerate("XYZ"):
        ch[f"P.{a}"] = P[..., k]
        ch[f"N.{a}"] = np.full((H, W), [0.0, 0.0, 1.0][k])
    ch["id"] = ids
    dn = np.minimum(np.arange(H * W).reshape(H, W) * 8, 1023).astype(np.uint16)
    meta = {"camera": CAM, "pose": {"position_m": POS, "quat_render_from_cam_xyzw": Q},
            "epoch_utc": "2024-06-21T15:00:10Z", "sensor": {"bits": 10, "exposure_s": 0.004}}
    return ch, dn, meta, P, ids


@pytest.fixture(scope="module")
def truthset(tmp_path_factory):
    out = tmp_path_factory.mktemp("viewable") / "set"
    ch, dn, meta, _, _ = _frame()
    with TruthSetWriter(out, {"render_frame": {"name": "TEST_FRAME"}}) as w:
        w.add_frame(0, 10.0, ch, dn, meta)
    return out


def _exr(path):
    with OpenEXR.File(str(path), separate_channels=True) as f:
        return dict(f.header()), {n: (c.type(), np.array(c.pixels)) for n, c in f.channels().items()}


def test_manifest_lists_the_preview_and_the_files_are_viewable(truthset):
    rec = json.loads((truthset / "manifest.json").read_text())["frames"][0]
    assert rec["dn_preview"] == "dn_preview/000000.png"
    exact, prev = (truthset / rec["dn"]).read_bytes(), (truthset / rec["dn_preview"]).read_bytes()
    assert ihdr(exact)[2] == 16 and sbit(exact) == bytes([10])
    assert ihdr(prev)[2] == 8 and sbit(prev) is None
    dn = _frame()[1]
    assert np.array_equal(TruthSet.open(truthset).load(0).dn, dn)
    with Image.open(truthset / rec["dn_preview"]) as im:
        assert np.asarray(im).max() == 255   # the frame reaches full scale 1023


def test_id_channel_is_uint_and_reads_back(truthset):
    _, ch = _exr(truthset / "frames/000000.exr")
    kind, raw = ch["id"]
    ids = _frame()[4]
    assert kind == OpenEXR.UINT and raw.dtype == np.uint32
    assert np.all(raw[ids == -1] == 0xFFFFFFFF) and np.array_equal(raw[ids >= 0], ids[ids >= 0])
    assert {k for n, (k, _) in ch.items() if n != "id"} == {OpenEXR.FLOAT}
    fr = TruthSet.open(truthset).load(0)
    assert fr.id.dtype == np.int32 and np.array_equal(fr.id, ids)


def test_old_float_id_files_still_read(tmp_path, truthset):
    import shutil

    old = tmp_path / "old"
    shutil.copytree(truthset, old)
    exr = old / "frames/000000.exr"
    _, ch = _exr(exr)
    ch["id"] = (OpenEXR.FLOAT, ch["id"][1].view(np.int32).astype(np.float32))  # -1.0 = no hit, as before
    write_exr(exr, {n: a for n, (_, a) in ch.items()})
    assert _exr(exr)[1]["id"][0] == OpenEXR.FLOAT
    assert np.array_equal(TruthSet.open(old).load(0).id, _frame()[4])


def test_header_describes_camera_pose_units_time(truthset):
    hdr, _ = _exr(truthset / "frames/000000.exr")
    assert hdr["worldToCamera"].dtype == np.float32 and hdr["worldToCamera"].shape == (4, 4)
    assert hdr["worldToNDC"].dtype == np.float32 and hdr["worldToNDC"].shape == (4, 4)
    K = hdr["renderlab:K"]
    assert K.dtype == np.float64
    np.testing.assert_array_equal(K, [[20.0, 0.0, 7.25], [0.0, 18.0, 5.5], [0.0, 0.0, 1.0]])
    assert json.loads(hdr["renderlab:camera"]) == CAM
    assert hdr["renderlab:frame"] == "TEST_FRAME" and hdr["renderlab:frame_index"] == 0
    assert hdr["renderlab:epoch"] == "2024-06-21T15:00:10Z" and float(hdr["renderlab:time_s"]) == 10.0
    assert hdr["expTime"] == pytest.approx(0.004, rel=1e-7)
    units = dict(item.split("=") for item in hdr["renderlab:units"].split("; "))
    assert units["Y"] == "W m^-2 sr^-1" and units["P.X"] == units["range"] == "m" and units["id"] == "1"
    assert json.loads(hdr["renderlab:quat_render_from_cam_xyzw"]) == Q
    assert "scalar-last" in hdr["renderlab:quat_convention"]
    np.testing.assert_array_equal(hdr["renderlab:position_m"], POS)


def test_world_to_camera_is_the_inverse_pose_in_openexr_camera_space(truthset):
    """Row-vector convention: [x y z 1] · worldToCamera = OpenEXR camera coordinates (y up)."""
    hdr, _ = _exr(truthset / "frames/000000.exr")
    p = np.array([[1.0, 2.0, 3.0], [-7.5, 0.25, 40.0], POS])
    p_cam = Rotation.from_quat(Q).inv().apply(p - POS)         # renderlab camera frame (y down)
    h = np.hstack([p, np.ones((3, 1))]) @ hdr["worldToCamera"].astype(np.float64)
    np.testing.assert_allclose(h[:, 3], 1.0, atol=1e-12)
    np.testing.assert_allclose(h[:, :3], p_cam * [1.0, -1.0, 1.0], atol=2e-5 * 40)
    np.testing.assert_allclose(h[2, :3], 0.0, atol=1e-5)        # the camera centre is the origin
    M = hdr["renderlab:camFromRender"]                         # column vectors, renderlab axes, double
    np.testing.assert_allclose((M @ np.hstack([p, np.ones((3, 1))]).T).T[:, :3], p_cam, atol=1e-12)


def test_world_to_ndc_maps_points_onto_their_pixels(truthset):
    hdr, _ = _exr(truthset / "frames/000000.exr")
    _, _, _, P, _ = _frame()
    h = np.concatenate([P, np.ones((H, W, 1))], -1) @ hdr["worldToNDC"].astype(np.float64)
    ndc = h[..., :2] / h[..., 3:4]
    ll, ss = np.mgrid[0:H, 0:W]
    np.testing.assert_allclose(ndc[..., 0], (ss + 0.5) / W, atol=1e-5)
    np.testing.assert_allclose(ndc[..., 1], (ll + 0.5) / H, atol=1e-5)


def test_rendered_truth_set(tmp_path):
    """A real tiny render: P AOV rays through pixel centres land there through worldToNDC, sit in
    front of the camera in worldToCamera, the DN PNG carries the sensor's bits and the preview scales it."""
    from pathlib import Path

    from renderlab.cli import main

    scene = Path(__file__).resolve().parents[1] / "scenes" / "analytic_sphere_box.toml"
    sets = ["camera.width=24", "camera.height=18", "camera.fx=26", "camera.fy=25", "camera.cx=11.5",
            "camera.cy=8.5", "render.spp=2"]
    out = tmp_path / "r"
    assert main(["render", str(scene), "--out", str(out), "--frames", "1", "--quiet",
                 *[a for kv in sets for a in ("--set", kv)]]) == 0
    rec = json.loads((out / "manifest.json").read_text())["frames"][0]
    hdr, ch = _exr(out / rec["exr"])
    assert ch["id"][0] == OpenEXR.UINT
    P = np.stack([ch[f"P.{a}"][1] for a in "XYZ"], -1).astype(np.float64)
    hit = np.isfinite(P).all(-1)
    assert hit.sum() > hit.size // 2
    assert np.all((ch["id"][1] != 0xFFFFFFFF) == hit)
    ph = np.concatenate([P[hit], np.ones((hit.sum(), 1))], -1)
    assert np.all((ph @ hdr["worldToCamera"].astype(np.float64))[:, 2] > 0)
    h = ph @ hdr["worldToNDC"].astype(np.float64)
    ll, ss = np.nonzero(hit)
    np.testing.assert_allclose(h[:, 0] / h[:, 3] * 24 - 0.5, ss, atol=2e-3)
    np.testing.assert_allclose(h[:, 1] / h[:, 3] * 18 - 0.5, ll, atol=2e-3)
    assert hdr["renderlab:frame"] == "SCENE" and hdr["expTime"] == pytest.approx(rec["sensor"]["exposure_s"])
    bits = rec["sensor"]["bits"]
    assert sbit((out / rec["dn"]).read_bytes()) == bytes([bits])
    dn = read_dn_png(out / rec["dn"])
    with Image.open(out / rec["dn_preview"]) as im:
        prev = np.asarray(im)
    full = 2 ** bits - 1
    np.testing.assert_array_equal(prev, np.floor(dn * 255.0 / full + 0.5).astype(np.uint8))
