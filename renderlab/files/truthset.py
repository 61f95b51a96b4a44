"""Truth sets on disk: write and read them exactly as the design's "Files on disk" says.

A truth set is a folder with ``manifest.json`` (``"format": "renderlab.truthset/1"``) and,
per frame, ``frames/NNNNNN.exr`` (float32 radiance + AOVs: ``Y`` or ``R G B``, ``P.X P.Y P.Z``,
``N.X N.Y N.Z``, ``range``; ``id`` as a UINT channel; camera, pose, units and time in the header, see
:func:`renderlab.files.imageio.frame_exr_header`), ``frames/NNNNNN.png`` (16-bit DN, exact, with an ``sBIT``
chunk) and ``dn_preview/NNNNNN.png`` (8-bit view of the DN, full scale → 255), plus optional Parquet
tables and files. :class:`TruthSetWriter` stages everything in a hidden sibling folder and renames
it into place only on success; :class:`TruthSet` reads a set without mitsuba or bpy. The same
inputs give bit-identical files.
"""

from __future__ import annotations

import functools
import json
import math
import os
import secrets
import shutil
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

import numpy as np

from renderlab.contracts.file_models import TruthManifest
from renderlab.contracts.schemas import TRUTH_TABLES, read_parquet
from renderlab.errors import UserError
from renderlab.files.background import BackgroundJobs
from renderlab.files.imageio import (  # noqa: F401
    _MAX_EXACT_ID,
    _check_dn,
    decode_ids,
    encode_ids,
    frame_exr_header,
    read_dn_png,
    read_exr,
    write_dn_png,
    write_dn_preview,
    write_exr,
    write_frame_files,
)
from renderlab.inputs import read_checked, short, shown

FORMAT = "renderlab.truthset/1"
MANIFEST = "manifest.json"
AOV_CHANNELS = ("P.X", "P.Y", "P.Z", "N.X", "N.Y", "N.Z", "range", "id")
RGB_CHANNELS = ("R", "G", "B")


# ------------------------------------------------------------------------------------ metadata
def _jsonable(obj, where: str):
    """Plain-JSON copy of ``obj`` (numpy scalars/arrays converted); NaN/inf → UserError."""
    if isinstance(obj, np.ndarray):
        obj = obj.tolist()
    elif isinstance(obj, np.generic):
        obj = obj.item()
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, int):
        return int(obj)
    if isinstance(obj, float):
        if not math.isfinite(obj):
            raise UserError(f"truth-set metadata {where} is {obj} (NaN/inf are not allowed)")
        return float(obj)
    if isinstance(obj, dict):
        out = {}
        for k, v in obj.items():
            if not isinstance(k, str):
                raise UserError(f"truth-set metadata {where} has a non-string key {k!r}")
            out[k] = _jsonable(v, f"{where}.{k}")
        return out
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v, f"{where}[{i}]") for i, v in enumerate(obj)]
    raise UserError(f"truth-set metadata {where} has unsupported type {type(obj).__name__}")


def _safe_relpath(relpath: str, what: str) -> str:
    s = str(relpath).replace("\\", "/")
    parts = PurePosixPath(s).parts
    if not s or s.startswith("/") or not parts or any(p in ("..", ".", "") for p in parts):
        raise UserError(f"{what} must be a relative path inside the truth set, got {short(relpath)}")
    return "/".join(parts)


# -------------------------------------------------------------------------------------- writer
class TruthSetWriter:
    """Write a truth set atomically: stage in a hidden sibling folder, rename on success.

    Parameters
    ----------
    out_dir : str or os.PathLike
        Final folder. If it exists and is non-empty, UserError unless ``overwrite``.
    manifest_head : dict
        Top-level manifest entries (``renderer``, ``scenario``, ``render_frame``, ...);
        ``format`` and ``frames`` are set by the writer.
    overwrite : bool, optional
        Replace an existing non-empty ``out_dir`` (only at the final rename).
    exr_compression : str, optional
        Lossless EXR compression (:data:`renderlab.files.imageio.EXR_COMPRESSIONS`).
    background : bool, optional
        Write each frame's files in a thread (:mod:`renderlab.files.background`) while the caller renders the next
        frame: the same bytes; a write's error raised by a later call; :meth:`add_frame`'s arrays kept unmodified.

    Examples
    --------
    >>> with TruthSetWriter("out/set", {"renderer": {"name": "mitsuba"}}) as w:  # doctest: +SKIP
    ...     w.add_frame(0, 0.0, channels, dn, {"camera": cam, "pose": pose})
    """

    def __init__(self, out_dir, manifest_head: dict, *, overwrite: bool = False, exr_compression: str = "zip",
                 background: bool = False):
        self.out_dir = Path(out_dir).absolute()
        self.background = bool(background)
        self._jobs: BackgroundJobs | None = None
        self.exr_compression = exr_compression  # lossless (renderlab.files.imageio.EXR_COMPRESSIONS)
        if not isinstance(manifest_head, dict):
            raise TypeError("manifest_head must be a dict")
        for key in ("format", "frames"):
            if key in manifest_head:
                raise ValueError(f"manifest_head must not set {key!r}; the writer does")
        self._head = _jsonable(manifest_head, "manifest")
        self.overwrite = bool(overwrite)
        self._frames: dict[int, dict] = {}
        self._names: set[str] = set()
        self._staging: Path | None = None
        self._check_target()

    def _check_target(self) -> None:
        d = self.out_dir
        if d.exists() and not d.is_dir():
            raise UserError(f"output {d} exists and is not a directory")
        if d.is_dir() and any(d.iterdir()) and not self.overwrite:
            raise UserError(f"output directory {d} exists and is not empty (use --overwrite to replace it)")
        anc = d.parent
        while not os.path.lexists(anc) and anc != anc.parent:
            anc = anc.parent  # nearest existing ancestor; missing ones are created
        if not anc.is_dir():
            raise UserError(f"cannot write {d}: {anc} is not a directory")
        if not os.access(anc, os.W_OK | os.X_OK):
            raise UserError(f"cannot write {d}: directory {anc} is not writable")

    @property
    def staging_dir(self) -> Path | None:
        """The hidden folder being written, while the context is open."""
        return self._staging

    def __enter__(self) -> "TruthSetWriter":
        parent = self.out_dir.parent
        name = f".{self.out_dir.name}.staging-{os.getpid()}-{secrets.token_hex(4)}"
        try:
            parent.mkdir(parents=True, exist_ok=True)
            (parent / name).mkdir()
            (parent / name / "frames").mkdir()
        except OSError as exc:
            shutil.rmtree(parent / name, ignore_errors=True)
            raise UserError(f"cannot create output directory next to {self.out_dir}: "
                            f"{exc.strerror or exc}") from None
        self._staging = parent / name
        if self.background:
            self._jobs = BackgroundJobs(depth=1)
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        staging, self._staging = self._staging, None
        jobs, self._jobs = self._jobs, None
        if staging is None:
            return False
        try:
            if jobs is not None:  # the frames' files written (or, after an error, nothing more started)
                jobs.close(cancel=exc_type is not None)
            if exc_type is None:
                self._commit(staging)
        finally:
            if jobs is not None:
                jobs.close(cancel=True)  # stopped before the staging folder goes
            shutil.rmtree(staging, ignore_errors=True)  # no-op after a successful rename
        return False

    def flush(self) -> None:
        """Wait for the frame files being written in the background; raise the first error of a write."""
        if self._jobs is not None:
            self._jobs.flush()

    def _require_open(self) -> Path:
        if self._staging is None:
            raise RuntimeError("TruthSetWriter is not open; use it as a context manager")
        return self._staging

    def _claim(self, rel: str) -> None:
        if rel in self._names or rel == MANIFEST:
            raise ValueError(f"truth-set file {rel!r} is already written or reserved")
        self._names.add(rel)

    def add_frame(self, index: int, time_s: float, channels: dict, dn: np.ndarray,
                  frame_meta: dict, *, dn_bits: int | None = None) -> dict:
        """Write ``frames/NNNNNN.exr``, ``frames/NNNNNN.png``, ``dn_preview/NNNNNN.png``; record the frame.

        Parameters
        ----------
        index : int
            Frame index (>= 0, unique).
        time_s : float
            Frame time, s.
        channels : dict of str to numpy.ndarray
            ``Y`` (or ``R``, ``G``, ``B``) and ``P.X P.Y P.Z N.X N.Y N.Z range id``, (H, W) each.
        dn : numpy.ndarray
            Sensor image, integer (H, W).
        frame_meta : dict
            More frame record keys (``camera``, ``pose``, ``sun``, ``bodies``, ...).
        dn_bits : int, optional
            Significant bits of ``dn`` (the PNG's sBIT and the preview's full scale); default
            ``frame_meta["sensor"]["bits"]``, else 16.

        Returns
        -------
        dict
            The frame record as it will appear in the manifest.
        """
        if not isinstance(frame_meta, dict):
            raise TypeError("frame_meta must be a dict")
        staging = self._require_open()
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or index < 0:
            raise ValueError(f"frame index must be a non-negative int, got {index!r}")
        index = int(index)
        if index in self._frames:
            raise ValueError(f"frame {index} was already added")
        missing = [c for c in AOV_CHANNELS if c not in channels]
        if "Y" not in channels and not all(c in channels for c in RGB_CHANNELS):
            missing.insert(0, "Y (or R, G, B)")
        if missing:
            raise ValueError(f"frame {index}: missing channels {', '.join(missing)}")
        try:
            ids = encode_ids(channels["id"])
        except ValueError as exc:
            raise ValueError(f"frame {index}: {exc}") from None
        bits = (frame_meta.get("sensor") or {}).get("bits", 16) if dn_bits is None else dn_bits
        shape = np.shape(channels["P.X"])
        if np.shape(dn) != shape:
            raise ValueError(f"frame {index}: dn shape {np.shape(dn)} differs from EXR {shape}")
        dn = _check_dn(dn, bits)  # here, in the caller's thread, also when the files are written in the background
        clash = {"index", "time_s", "exr", "dn", "dn_preview"} & set(frame_meta)
        if clash:
            raise ValueError(f"frame_meta must not set {sorted(clash)}")
        rels = {"exr": f"frames/{index:06d}.exr", "dn": f"frames/{index:06d}.png",
                "dn_preview": f"dn_preview/{index:06d}.png"}
        record = _jsonable({"index": index, "time_s": time_s, **rels, **frame_meta}, f"frames[{index}]")
        rf = self._head.get("render_frame")
        header = frame_exr_header(index, record["time_s"], record, channels,
                                  render_frame=rf.get("name") if isinstance(rf, dict) else None)
        for rel in rels.values():
            self._claim(rel)
        job = functools.partial(write_frame_files, staging, rels, {**channels, "id": ids}, header,
                                self.exr_compression, dn, bits)
        if self._jobs is None:
            job()
        else:
            self._jobs.submit(job)
        self._frames[index] = record
        return record

    def _new_file(self, rel: str) -> Path:
        path = self._require_open() / rel
        self._claim(rel)
        path.parent.mkdir(parents=True, exist_ok=True)
        return path

    def add_table(self, name: str, table) -> str:
        """Write a ``pyarrow.Table`` as ``<name>.parquet``; returns the relative path."""
        import pyarrow.parquet as pq

        rel = _safe_relpath(f"{name}.parquet", "table name")
        pq.write_table(table, str(self._new_file(rel)))
        return rel

    def add_file(self, relpath: str, data: bytes) -> str:
        """Write raw bytes at ``relpath`` inside the set; returns the normalised relative path."""
        rel = _safe_relpath(relpath, "file path")
        self._new_file(rel).write_bytes(bytes(data))
        return rel

    def manifest(self) -> dict:
        """The manifest as it would be written now (frames sorted by index), once the frames' files are written."""
        self.flush()
        return {"format": FORMAT, **self._head,
                "frames": [self._frames[i] for i in sorted(self._frames)]}

    def _commit(self, staging: Path) -> None:
        text = json.dumps(self.manifest(), indent=1, sort_keys=False, allow_nan=False)
        (staging / MANIFEST).write_text(text + "\n", encoding="utf-8")
        self._check_target()
        old = None
        if self.out_dir.is_dir() and any(self.out_dir.iterdir()):
            old = staging.with_name(staging.name.replace(".staging-", ".old-"))
            os.rename(self.out_dir, old)
        try:
            os.rename(staging, self.out_dir)  # replaces an empty directory too
        except OSError as exc:
            if old is not None:
                os.rename(old, self.out_dir)
            raise UserError(f"cannot move truth set into {self.out_dir}: "
                            f"{exc.strerror or exc}") from None
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)


# -------------------------------------------------------------------------------------- reader
@dataclass
class TruthFrame:
    """One frame of a truth set, loaded.

    ``radiance`` is float32 (H, W) ``Y`` in W m⁻² sr⁻¹ (None for RGB sets), ``rgb`` float32
    (H, W, 3) (None for mono sets); ``position`` (render frame, m; NaN where nothing was hit)
    and ``normal`` are float32 (H, W, 3); ``range`` float32 (H, W) in m; ``id`` int32 (H, W)
    with -1 for no hit (from a UINT channel, or a float32 one in older sets); ``dn`` uint16 (H, W);
    ``meta`` is the manifest's frame record (camera, pose, sun, bodies, ...).
    """

    index: int
    time_s: float
    radiance: np.ndarray | None
    rgb: np.ndarray | None
    position: np.ndarray
    normal: np.ndarray
    range: np.ndarray
    id: np.ndarray
    dn: np.ndarray
    meta: dict = field(default_factory=dict)


class TruthSet:
    """A truth set on disk, read-only. Use :meth:`open`."""

    def __init__(self, path: Path, manifest: dict):
        self.path = path
        self.manifest = manifest
        self.frames: list[dict] = manifest["frames"]

    @classmethod
    def open(cls, path) -> "TruthSet":
        """Open and validate a truth set folder (manifest format, listed files exist)."""
        root = Path(path)
        mpath = root / MANIFEST
        if not root.is_dir():
            raise UserError(f"truth set not found: {shown(root)} is not a directory")
        if not os.path.lexists(mpath):
            raise UserError(f"truth set {shown(root)} has no {MANIFEST}")
        manifest = read_checked(mpath, TruthManifest, "truth-set manifest")
        for k, rec in enumerate(manifest["frames"]):
            for key in ("exr", "dn", "dn_preview"):
                if key not in rec:  # dn_preview: optional (sets written before it existed)
                    continue
                rel = _safe_relpath(rec[key], f"{shown(mpath)}: frames[{k}].{key}")
                if not (root / rel).is_file():
                    raise UserError(f"truth set {shown(root)}: frames[{k}].{key} file {short(rel)} is missing")
        return cls(root, manifest)

    def __len__(self) -> int:
        return len(self.frames)

    def camera(self, i: int) -> dict:
        """The camera dict of frame ``i`` (position in :attr:`frames`)."""
        rec = self.frames[i]
        if "camera" not in rec:
            raise UserError(f"truth set {self.path}: frames[{i}] has no camera")
        return rec["camera"]

    def read_table(self, name: str):
        """Read ``<name>.parquet`` as a ``pyarrow.Table`` (boundaries checked, and the schema its readers rely on for
        the tables of :data:`renderlab.contracts.schemas.TRUTH_TABLES`)."""
        p = self.path / _safe_relpath(f"{name}.parquet", "table name")
        if not os.path.lexists(p):
            raise UserError(f"truth set {shown(self.path)} has no table {short(name)}.parquet")
        return read_parquet(p, f"truth-set table {shown(p)}", schema=TRUTH_TABLES.get(name))

    def load(self, i: int) -> TruthFrame:
        """Load frame ``i`` (position in :attr:`frames`): EXR channels, DN image and record."""
        rec = self.frames[i]
        exr_path, dn_path = self.path / rec["exr"], self.path / rec["dn"]
        cam = rec.get("camera") or {}
        size = (cam["width"], cam["height"]) if "width" in cam and "height" in cam else None
        ch = read_exr(exr_path, size)  # headers checked against the camera before any pixel is decoded
        missing = [c for c in AOV_CHANNELS if c not in ch]
        has_rgb = all(c in ch for c in RGB_CHANNELS)
        if "Y" not in ch and not has_rgb:
            missing.insert(0, "Y (or R, G, B)")
        if missing:
            raise UserError(f"EXR {shown(exr_path)} lacks channels {', '.join(missing)}")
        shape = ch["P.X"].shape
        if any(a.shape != shape for a in ch.values()):
            raise UserError(f"EXR {shown(exr_path)}: channels of different sizes")
        dn = read_dn_png(dn_path, (shape[1], shape[0]))
        ids = decode_ids(ch["id"], str(exr_path))
        return TruthFrame(
            index=int(rec["index"]), time_s=float(rec["time_s"]),
            radiance=ch.get("Y"),
            rgb=np.stack([ch[c] for c in RGB_CHANNELS], axis=-1) if has_rgb else None,
            position=np.stack([ch["P.X"], ch["P.Y"], ch["P.Z"]], axis=-1),
            normal=np.stack([ch["N.X"], ch["N.Y"], ch["N.Z"]], axis=-1),
            range=ch["range"], id=ids, dn=dn, meta=dict(rec))
