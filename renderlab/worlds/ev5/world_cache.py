"""The built EV5 world (cut global shape + landing site) cached on disk by a content key.

Building the full world (1.3 M global facets, a 3201² site DEM) takes about a minute; its arrays depend
only on the world keys that shape the body and the site and on the code that builds them. The cache key
is the SHA-256 (first 24 hex digits) of

* the canonical JSON of ``world`` without the keys that do not change the built arrays (the landmark
  catalog, photometry, the levels-of-detail keys ``site.lod/tile_cells/lod_pixels/facets_per_pixel/static_max_facets`` and ``build_cache``),
* the content hash of ``world.shape_file`` (a changed file under the same name is a new key),
* the builder's code version: the sources of ``worlds/ev5/{__init__,shape,site,terrain,world_cache}.py``
  and ``render/mesh_io.py``, the numpy version and :data:`FORMAT`.

Layout: ``<lab cache>/ev5_world/<key>/`` with one ``.npy`` file per array (read back memory-mapped, so a
process touches only the pages it uses: the tiles of :mod:`.tiles` load lazily) and ``world.json``
(scalars, the SHA-256 of every array file, the key's inputs). No pickle: ``np.load(allow_pickle=False)``.
The lab cache is ``$RENDERLAB_CACHE`` or ``~/.cache/renderlab`` (as :func:`renderlab.cli.cache_root`).
A folder is written under a temporary name and renamed into place, so concurrent builders of one key
leave one complete folder. A cached folder whose ``world.json`` is unreadable or whose array files do not
match their recorded hashes (a corrupt or truncated file) is removed and the world rebuilt.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import uuid
from pathlib import Path

import numpy as np

FORMAT = "ev5-world-1"
_CODE = ("worlds/ev5/__init__.py", "worlds/ev5/shape.py", "worlds/ev5/site.py", "worlds/ev5/terrain.py",
         "worlds/ev5/world_cache.py", "render/mesh_io.py")
#: world keys that do not change the built shape or site
_NOT_BUILT = ("landmarks", "law", "law_params", "albedo", "mapping_error_m", "mapping_error_corr_cells",
              "albedo_error_rms", "build_cache")
_NOT_BUILT_SITE = ("lod", "tile_cells", "lod_pixels", "facets_per_pixel", "static_max_facets")
_SHAPE = ("vertices", "faces", "vertex_albedo")
_SITE = ("heights_m", "albedo", "origin_m", "R_body_from_site", "target_center_xy")


def cache_folder() -> Path:
    """``<lab cache>/ev5_world``."""
    root = os.environ.get("RENDERLAB_CACHE") or Path("~/.cache/renderlab").expanduser()
    return Path(root).absolute() / "ev5_world"


def code_version() -> str:
    """SHA-256 (hex, 16) of the builder's sources, the numpy version and the format."""
    pkg = Path(__file__).resolve().parents[2]
    h = hashlib.sha256(f"{FORMAT}\0numpy={np.__version__}\0".encode())
    for rel in _CODE:
        h.update(rel.encode() + b"\0" + (pkg / rel).read_bytes() + b"\0")
    return h.hexdigest()[:16]


def _file_sha(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 22), b""):
            h.update(block)
    return h.hexdigest()


def world_key(world, base_dir: Path) -> tuple[str, dict]:
    """(key, the JSON-able inputs it hashes) of a validated :class:`~.config.EV5World`."""
    d = world.model_dump(mode="json")
    for k in _NOT_BUILT:
        d.pop(k, None)
    for k in _NOT_BUILT_SITE:
        d["site"].pop(k, None)
    if world.shape_file:
        path = (Path(base_dir) / world.shape_file).resolve()
        d["shape_file_sha256"] = _file_sha(path) if path.is_file() else "missing"
    inputs = {"world": d, "code": code_version()}
    text = json.dumps(inputs, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:24], inputs


def save(folder: Path, key: str, inputs: dict, shape, site, stats: dict) -> Path:
    """Write the world into ``folder/key`` atomically (temporary name, then rename) and return that path."""
    final = Path(folder) / key
    tmp = Path(folder) / f".{key}.{uuid.uuid4().hex[:8]}.tmp"
    tmp.mkdir(parents=True)
    try:
        arrays = {f"shape_{k}": getattr(shape, k) for k in _SHAPE} | {f"site_{k}": getattr(site, k) for k in _SITE}
        sha = {}
        for name, a in arrays.items():
            np.save(tmp / f"{name}.npy", np.ascontiguousarray(a), allow_pickle=False)
            sha[name] = _file_sha(tmp / f"{name}.npy")
        meta = {"format": FORMAT, "key": key, "inputs": inputs, "sha256": sha, "full_shape_stats": stats,
                "site": {"x0_m": site.x0_m, "cell_m": site.cell_m, "target_diameter_m": site.target_diameter_m,
                         "n_boulders": int(site.n_boulders), "n_craters": int(site.n_craters)}}
        (tmp / "world.json").write_text(json.dumps(meta, indent=1))
        try:
            tmp.rename(final)
        except OSError:  # another process finished the same key first: keep its folder
            if not (final / "world.json").is_file():
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return final


def load(path: Path):
    """(shape, site, full_shape_stats) of a cached folder, arrays memory-mapped read-only; None when the
    folder is missing, unreadable or any array file does not match its recorded SHA-256."""
    from renderlab.worlds.ev5.shape import GlobalShape
    from renderlab.worlds.ev5.site import Site

    try:
        meta = json.loads((Path(path) / "world.json").read_text())
        if meta.get("format") != FORMAT:
            return None
        arr = {}
        for name, digest in meta["sha256"].items():
            f = Path(path) / f"{name}.npy"
            if _file_sha(f) != digest:
                return None
            arr[name] = np.asarray(np.load(f, mmap_mode="r", allow_pickle=False))
        s = meta["site"]
        shape = GlobalShape(*(arr[f"shape_{k}"] for k in _SHAPE))
        site = Site(arr["site_origin_m"], arr["site_R_body_from_site"], float(s["x0_m"]), float(s["cell_m"]),
                    arr["site_heights_m"], arr["site_albedo"], arr["site_target_center_xy"],
                    float(s["target_diameter_m"]), int(s["n_boulders"]), int(s["n_craters"]))
        return shape, site, meta["full_shape_stats"]
    except (OSError, ValueError, KeyError, TypeError):
        return None


def cached_build(world, base_dir: Path, build):
    """(shape, site, stats, status) from the cache or from ``build()`` (then stored); status is ``"hit"``,
    ``"miss"`` or ``"rebuilt"`` (a corrupt folder was replaced)."""
    key, inputs = world_key(world, base_dir)
    folder = cache_folder()
    path = folder / key
    status = "miss"
    if path.exists():
        got = load(path)
        if got is not None:
            return (*got, "hit")
        shutil.rmtree(path, ignore_errors=True)
        status = "rebuilt"
    shape, site, stats = build()
    try:
        saved = save(folder, key, inputs, shape, site, stats)
    except OSError:  # an unwritable cache costs the next process a rebuild, not this run
        return shape, site, stats, status
    got = load(saved)
    return (*got, status) if got is not None else (shape, site, stats, status)
