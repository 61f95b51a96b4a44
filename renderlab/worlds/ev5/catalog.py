"""Landmark catalog files of an EV5 truth set: ``landmarks.parquet`` + ``maplets/NNNNNN.exr``.

``landmarks.parquet``, one row per landmark: ``landmark_id, center_x_m, center_y_m, center_z_m``
(body frame), ``spacing_m``, ``size_px`` (grid points per side, n), the maplet frame as
``q_body_from_maplet_x/_y/_z/_w`` (scalar-last; columns of R are the maplet x, y, z axes in the
body frame), ``maplet_file`` (relative path) and ``tier``. Each maplet file is a float32 EXR with
channels ``height`` (m, along maplet +z) and ``albedo`` (relative), row j / column i as in
:class:`renderlab.geometry.maplet.Maplet`. Readable without a renderer.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from renderlab.errors import UserError
from renderlab.geometry.maplet import Maplet

COLUMNS = ("landmark_id", "center_x_m", "center_y_m", "center_z_m", "spacing_m", "size_px",
           "q_body_from_maplet_x", "q_body_from_maplet_y", "q_body_from_maplet_z", "q_body_from_maplet_w",
           "maplet_file")


def maplet_relpath(landmark_id: int) -> str:
    return f"maplets/{int(landmark_id):06d}.exr"


def write_catalog(writer, maplets: list[Maplet], tiers: dict[int, str] | None = None) -> None:
    """Write ``landmarks.parquet`` and one ``maplets/NNNNNN.exr`` per maplet into an open
    :class:`renderlab.files.truthset.TruthSetWriter`. ``tiers`` optionally names each landmark's tier."""
    import pyarrow as pa
    from scipy.spatial.transform import Rotation

    from renderlab.files.imageio import write_exr

    ids = [int(m.landmark_id) for m in maplets]
    if len(set(ids)) != len(ids):
        raise ValueError("write_catalog: landmark ids must be unique")
    q = np.array([Rotation.from_matrix(m.R_body_from_maplet).as_quat(canonical=True) for m in maplets]).reshape(-1, 4)
    c = np.array([m.center_m for m in maplets], float).reshape(-1, 3)
    cols = {
        "landmark_id": pa.array(ids, pa.int64()),
        "center_x_m": c[:, 0], "center_y_m": c[:, 1], "center_z_m": c[:, 2],
        "spacing_m": np.array([m.spacing_m for m in maplets], float),
        "size_px": pa.array([m.n for m in maplets], pa.int64()),
        "q_body_from_maplet_x": q[:, 0], "q_body_from_maplet_y": q[:, 1],
        "q_body_from_maplet_z": q[:, 2], "q_body_from_maplet_w": q[:, 3],
        "maplet_file": [maplet_relpath(i) for i in ids],
    }
    if tiers is not None:
        cols["tier"] = [tiers.get(i, "") for i in ids]
    writer.add_table("landmarks", pa.table(cols))
    with tempfile.TemporaryDirectory() as tmp:
        for m in maplets:
            path = Path(tmp) / "m.exr"
            write_exr(path, {"height": m.heights_m, "albedo": m.albedo})
            writer.add_file(maplet_relpath(m.landmark_id), path.read_bytes())


def read_catalog(truthset_dir) -> list[Maplet]:
    """The maplets of a truth set (sorted by landmark id). UserError names a missing or bad file."""
    import pyarrow.parquet as pq

    from renderlab.files.imageio import read_exr
    from renderlab.files.truthset import _safe_relpath
    from renderlab.geometry.rotations import rotation_from_quat_xyzw

    root = Path(truthset_dir)
    table_path = root / "landmarks.parquet"
    if not table_path.is_file():
        raise UserError(f"truth set {root} has no landmark catalog (landmarks.parquet)")
    try:
        table = pq.read_table(str(table_path)).to_pydict()
    except Exception as exc:  # pyarrow raises several types for corrupt files
        raise UserError(f"corrupt landmark catalog {table_path}: {exc}") from None
    missing = [c for c in COLUMNS if c not in table]
    if missing:
        raise UserError(f"landmark catalog {table_path} lacks columns {', '.join(missing)}")
    out = []
    for k in range(len(table["landmark_id"])):
        lid = table["landmark_id"][k]
        rel = _safe_relpath(table["maplet_file"][k], f"{table_path}: maplet_file of landmark {lid}")
        ch = read_exr(root / rel)
        if "height" not in ch or "albedo" not in ch:
            raise UserError(f"maplet {root / rel} lacks the 'height' and 'albedo' channels")
        n = int(table["size_px"][k])
        if ch["height"].shape != (n, n):
            raise UserError(f"maplet {root / rel} is {ch['height'].shape}, catalog says size_px {n}")
        q = [table[f"q_body_from_maplet_{a}"][k] for a in "xyzw"]
        R = rotation_from_quat_xyzw(q, f"landmark {lid} frame").as_matrix()
        centre = np.array([table[f"center_{a}_m"][k] for a in "xyz"], float)
        try:
            out.append(Maplet(int(lid), centre, R, float(table["spacing_m"][k]),
                              ch["height"].astype(np.float64), ch["albedo"].astype(np.float64)))
        except (ValueError, TypeError) as exc:
            raise UserError(f"landmark catalog {table_path}: {exc}") from None
    return sorted(out, key=lambda m: m.landmark_id)
