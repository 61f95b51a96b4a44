"""Cross-renderer truth check: the same frames rendered by Mitsuba 3 and Blender Cycles must agree.

Two independent renderers (different ray tracers, samplers, shading code: Dr.Jit BSDF plugins vs OSL
shaders, analytic sphere vs tessellated sphere) render the same scenario; truth is trusted where they
agree. Per frame (both truth sets read back from disk):

* radiometric: over lit pixels (radiance ≥ ``LIT_FRACTION`` × the frame's 99.9th percentile in both),
  the median and 99th percentile of |L_cycles / L_mitsuba − 1|; and the count of pixels lit in one
  renderer but below 10 % of it in the other (shadow disagreements the ratio statistics exclude). Interior pixels are noise-free (direct
  sunlight); pixels straddling an edge carry each renderer's own sampling noise, which the p99 shows.
* geometric: at every pixel both renderers hit the same body, the gap between the hit points split
  into its part across the line of sight, in pixels f·|ΔP⊥|/range (what moves an image point), and its
  part along it, |Δrange|/range (surface depth: the analytic sphere vs its tessellation shows here,
  largest at grazing rays near the silhouette); plus the re-projection error of each renderer's P
  through the lab's :class:`CameraModel` (the AOV must lie on the ray through the pixel centre: this
  pins Cycles' camera built from the intrinsics); on EV5 sets also at the landmark truth pixels
  (``landmark_truth.parquet``, visible landmarks, nearest pixel).
* shadow edges: pixels on a cast-shadow edge (a bright pixel and a dark pixel whose normal faces the
  sun nearby, all on one body): the edge shift between the renderers from the change of lit fraction
  (see :func:`shadow_edge_shift_px`). Median and 99th percentile.
* the referee (:mod:`renderlab.render.ray_oracle`, float64 ray casting against the exact geometry,
  no renderer code): at every pixel lit in one renderer only it decides which renderer agrees with
  the truth within sampling noise (:func:`~renderlab.render.ray_oracle.consistent`; a verdict against
  a renderer is confirmed with 64² sub-samples): ``oracle_mitsuba_off``, ``oracle_cycles_off``, and
  ``oracle_both_ok`` (sub-pixel slivers that both renderers sample correctly), and at the shadow-edge pixels it gives
  each renderer's own edge error |L − L_oracle|/step in px (``edge_vs_oracle_*_p99_px``). Scenes
  with albedo maps or mesh files are not refereed (NaN).

Targets (issue 4): median radiometric ≤ 1 %, geometric ≤ 0.05 px, shadow edges ≤ 0.5 px.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

LIT_FRACTION = 0.02
ORACLE_K = 16  # oracle sub-samples per pixel side
ORACLE_MAX_PX = 300  # refereed pixels per frame and kind (evenly spaced in raster order beyond this)
TARGETS = {"rad_median_rel": 0.01, "geo_max_px": 0.05, "shadow_p99_px": 0.5}


@dataclass
class FrameAgreement:
    """Agreement of one frame (NaN where a check has no pixels)."""

    frame: int
    time_s: float
    id_agreement: float
    n_lit: int
    n_lit_one_only: int
    rad_median_rel: float
    rad_p99_rel: float
    n_geo: int
    geo_median_px: float
    geo_max_px: float
    range_rel_median: float
    range_rel_max: float
    reproj_mitsuba_max_px: float
    reproj_cycles_max_px: float
    n_landmarks: int
    lmk_max_px: float
    n_shadow_edge: int
    shadow_median_px: float
    shadow_p99_px: float
    n_oracle: int = 0
    oracle_mitsuba_off: int = -1
    oracle_cycles_off: int = -1
    oracle_both_ok: int = -1
    edge_vs_oracle_mitsuba_p99_px: float = float("nan")
    edge_vs_oracle_cycles_p99_px: float = float("nan")


def _stat(x, fn) -> float:
    return float(fn(x)) if len(x) else float("nan")


def _luminance(tf) -> np.ndarray:
    return (tf.radiance if tf.radiance is not None else tf.rgb.mean(axis=-1)).astype(np.float64)


def radiometric_agreement(Lm: np.ndarray, Lc: np.ndarray, lit_fraction: float = LIT_FRACTION):
    """(lit mask, relative differences |Lc/Lm − 1| over it)."""
    ref = np.percentile(Lm, 99.9)
    lit = (Lm >= lit_fraction * ref) & (Lc >= lit_fraction * ref) & (ref > 0)
    return lit, np.abs(Lc[lit] / Lm[lit] - 1.0)


def reprojection_px(P: np.ndarray, camera, pose, sl: np.ndarray) -> np.ndarray:
    """Pixel distance between the projection of render-frame points P (N, 3) and pixels sl (N, 2)."""
    R = pose["R_render_from_cam"]
    pc = (P - pose["position_m"]) @ R
    return np.linalg.norm(camera.project(pc) - sl, axis=1)


def position_gap(Pm: np.ndarray, Pc: np.ndarray, camera, pose) -> tuple[np.ndarray, np.ndarray]:
    """Gap between two renderers' hit points: (f·|ΔP⊥|/range in px across the line of sight,
    |Δrange|/range along it)."""
    ray = Pm - pose["position_m"]
    rng = np.linalg.norm(ray, axis=1)
    u = ray / rng[:, None]
    d = Pc - Pm
    along = np.einsum("ij,ij->i", d, u)
    perp = np.linalg.norm(d - along[:, None] * u, axis=1)
    f = max(float(camera.fx), float(camera.fy))
    return f * perp / rng, np.abs(along) / rng


def shadow_edge_shift_px(Lm, Lc, ids_m, ids_c, normal, sun_dir):
    """(edge mask, shift in px) of cast-shadow edges between two box-filtered images.

    An edge pixel has, within its 5×5 neighbourhood (all on one body in both images), a bright pixel
    (> ½ of the local maximum) and a dark pixel (< 0.1 of it) whose normal faces the sun (cast shadow,
    not the terminator), and a lit fraction f = (L − min)/(max − min) strictly inside (0.02, 0.98) in
    either image. Its shift is |Σ (L_c − L_m)| / (max − min) summed over the pixel and its two
    neighbours along the dominant gradient axis: exact for an edge along a pixel axis moved by less
    than 1 px (the moved area is split over at most two adjacent pixels), an overestimate by up to √2
    for oblique edges.
    """
    same = (ids_m == ids_c) & (ids_m >= 0)
    one_body = (ndimage.minimum_filter(ids_m, 5) == ndimage.maximum_filter(ids_m, 5)) & \
        (ndimage.minimum_filter(np.where(same, 1, 0), 5) > 0)
    hi, lo = ndimage.maximum_filter(Lm, 5), ndimage.minimum_filter(Lm, 5)
    step = hi - lo
    mu0 = np.nan_to_num(normal @ np.asarray(sun_dir, float), nan=-1.0)
    dark_facing = (Lm < 0.1 * hi) & (mu0 > 0.2)
    near_dark = ndimage.maximum_filter(dark_facing.astype(np.uint8), 5) > 0
    near_bright = ndimage.maximum_filter((Lm > 0.5 * hi).astype(np.uint8), 5) > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        fm, fc = (Lm - lo) / step, (Lc - lo) / step
    partial = ((fm > 0.02) & (fm < 0.98)) | ((fc > 0.02) & (fc < 0.98))
    edge = one_body & near_dark & near_bright & partial & (step > 0)
    edge[:2, :] = edge[-2:, :] = False
    edge[:, :2] = edge[:, -2:] = False
    diff = Lc - Lm
    gy, gx = np.gradient(Lm)
    sum_x = np.roll(diff, 1, 1) + diff + np.roll(diff, -1, 1)
    sum_y = np.roll(diff, 1, 0) + diff + np.roll(diff, -1, 0)
    moved = np.where(np.abs(gx) >= np.abs(gy), sum_x, sum_y)
    return edge, np.abs(moved[edge]) / step[edge]


def frame_agreement(fm, fc, landmarks=None) -> tuple[FrameAgreement, dict]:
    """Agreement of one frame of the Mitsuba (``fm``) and Cycles (``fc``) truth sets (TruthFrame)."""
    from scipy.spatial.transform import Rotation

    from renderlab.geometry.camera import CameraModel

    meta = fm.meta
    camera = CameraModel.from_dict(meta["camera"])
    pose = {"position_m": np.asarray(meta["pose"]["position_m"], float),
            "R_render_from_cam": Rotation.from_quat(meta["pose"]["quat_render_from_cam_xyzw"]).as_matrix()}
    Lm, Lc = _luminance(fm), _luminance(fc)
    lit, rel = radiometric_agreement(Lm, Lc)
    ref = np.percentile(Lm, 99.9)
    one_only = ((Lm >= LIT_FRACTION * ref) & (Lc < 0.1 * Lm)) | ((Lc >= LIT_FRACTION * ref) & (Lm < 0.1 * Lc))

    H, W = fm.id.shape
    ll, ss = np.mgrid[0:H, 0:W]
    hit = (fm.id == fc.id) & (fm.id >= 0)
    sl = np.column_stack([ss[hit], ll[hit]]).astype(float)
    Pm, Pc = fm.position[hit].astype(np.float64), fc.position[hit].astype(np.float64)
    gap, depth = position_gap(Pm, Pc, camera, pose)
    rep_m = reprojection_px(Pm, camera, pose, sl)
    rep_c = reprojection_px(Pc, camera, pose, sl)
    gap_img = np.full((H, W), np.nan)
    gap_img[hit] = gap

    lmk = np.zeros(0)
    if landmarks is not None and len(landmarks):
        s = np.clip(np.rint(landmarks["s"]).astype(int), 0, W - 1)
        line = np.clip(np.rint(landmarks["l"]).astype(int), 0, H - 1)
        ok = hit[line, s]
        lmk = gap_img[line[ok], s[ok]]

    sun = np.asarray(meta["sun"]["direction_render"], float)
    edge, shift = shadow_edge_shift_px(Lm, Lc, fm.id, fc.id, fm.normal.astype(np.float64), sun)
    rel_img = np.full((H, W), np.nan)
    rel_img[lit] = Lc[lit] / Lm[lit] - 1.0
    shift_img = np.full((H, W), np.nan)
    shift_img[edge] = shift
    row = FrameAgreement(
        frame=int(fm.index), time_s=float(fm.time_s), id_agreement=float(np.mean(fm.id == fc.id)),
        n_lit=int(lit.sum()), n_lit_one_only=int(one_only.sum()), rad_median_rel=_stat(rel, np.median), rad_p99_rel=_stat(rel, lambda x: np.percentile(x, 99)),
        n_geo=int(hit.sum()), geo_median_px=_stat(gap, np.median), geo_max_px=_stat(gap, np.max),
        range_rel_median=_stat(depth, np.median), range_rel_max=_stat(depth, np.max),
        reproj_mitsuba_max_px=_stat(rep_m, np.max), reproj_cycles_max_px=_stat(rep_c, np.max),
        n_landmarks=int(len(lmk)), lmk_max_px=_stat(lmk, np.max),
        n_shadow_edge=int(edge.sum()), shadow_median_px=_stat(shift, np.median),
        shadow_p99_px=_stat(shift, lambda x: np.percentile(x, 99)),
    )
    step = ndimage.maximum_filter(Lm, 5) - ndimage.minimum_filter(Lm, 5)
    return row, {"Lm": Lm, "Lc": Lc, "rel": rel_img, "gap": gap_img, "shift": shift_img, "one_only": one_only,
                 "edge": edge, "step": step}


def _spread(mask: np.ndarray, n_max: int) -> tuple[np.ndarray, np.ndarray]:
    line, s = np.nonzero(mask)
    if len(line) > n_max:
        keep = np.linspace(0, len(line) - 1, n_max).round().astype(int)
        line, s = line[keep], s[keep]
    return line, s


def referee(row: FrameAgreement, images: dict, oracle, spec, spp: int) -> None:
    """Fill the ``oracle_*`` and ``edge_vs_oracle_*`` fields of ``row`` (see the module docstring)."""
    from renderlab.render.ray_oracle import consistent, pixel_truth

    Lm, Lc = images["Lm"], images["Lc"]
    line, s = _spread(images["one_only"], ORACLE_MAX_PX)
    row.n_oracle = int(len(line))
    if len(line):
        sl = np.column_stack([s, line]).astype(float)
        truth = pixel_truth(oracle, spec, sl, k=ORACLE_K)
        ok_m, ok_c = consistent(Lm[line, s], truth, spp, ORACLE_K), consistent(Lc[line, s], truth, spp, ORACLE_K)
        redo = ~(ok_m & ok_c)  # a verdict against a renderer is confirmed with 4x finer sub-samples
        if redo.any():
            fine = pixel_truth(oracle, spec, sl[redo], k=4 * ORACLE_K)
            ok_m[redo] = consistent(Lm[line, s][redo], fine, spp, 4 * ORACLE_K)
            ok_c[redo] = consistent(Lc[line, s][redo], fine, spp, 4 * ORACLE_K)
        row.oracle_mitsuba_off, row.oracle_cycles_off = int((~ok_m).sum()), int((~ok_c).sum())
        row.oracle_both_ok = int((ok_m & ok_c).sum())
    else:
        row.oracle_mitsuba_off = row.oracle_cycles_off = row.oracle_both_ok = 0
    line, s = _spread(images["edge"], ORACLE_MAX_PX // 3)
    if len(line):
        # the shadow-edge metric of shadow_edge_shift_px with the oracle as the second image: the
        # difference summed over the pixel and its two neighbours along the dominant gradient axis
        gy, gx = np.gradient(Lm)
        along_x = np.abs(gx[line, s]) >= np.abs(gy[line, s])
        k = np.array([-1, 0, 1])
        nl = (line[:, None] + np.where(along_x[:, None], 0, k[None, :])).ravel()
        ns = (s[:, None] + np.where(along_x[:, None], k[None, :], 0)).ravel()
        px, inv = np.unique(np.column_stack([ns, nl]), axis=0, return_inverse=True)
        truth = pixel_truth(oracle, spec, px.astype(float), k=ORACLE_K)
        L_or = truth.radiance[inv.ravel()].reshape(-1, 3)
        step = images["step"][line, s]
        for name, L in (("mitsuba", Lm), ("cycles", Lc)):
            moved = np.abs((L[nl, ns].reshape(-1, 3) - L_or).sum(axis=1)) / step
            setattr(row, f"edge_vs_oracle_{name}_p99_px", float(np.percentile(moved, 99)))


def compare_truthsets(path_m: Path, path_c: Path) -> tuple[list[FrameAgreement], list[dict]]:
    """Per-frame agreement rows and images of two truth sets of the same scenario."""
    from renderlab.errors import UserError
    from renderlab.truthset import TruthSet

    tm, tc = TruthSet.open(path_m), TruthSet.open(path_c)
    if len(tm) != len(tc):
        raise UserError(f"truth sets differ in frame count: {len(tm)} vs {len(tc)}")
    lmk_table = None
    if (tm.path / "landmark_truth.parquet").is_file():
        lmk_table = {k: np.asarray(v) for k, v in tm.read_table("landmark_truth").to_pydict().items()}
    rows, images = [], []
    for i in range(len(tm)):
        fm, fc = tm.load(i), tc.load(i)
        lm = None
        if lmk_table is not None:
            sel = (lmk_table["frame"] == fm.index) & lmk_table["visible"].astype(bool)
            lm = {"s": lmk_table["s"][sel].astype(float), "l": lmk_table["l"][sel].astype(float)}
        row, imgs = frame_agreement(fm, fc, lm)
        rows.append(row)
        images.append(imgs)
    return rows, images


def markdown_table(rows: list[FrameAgreement], title: str) -> str:
    """The Markdown page of the agreement rows: the targets with PASS/FAIL, then one row per frame
    (:func:`renderlab.crosscheck_figures.markdown_table`)."""
    from renderlab.crosscheck_figures import markdown_table as table

    return table(rows, title, TARGETS)


def figure(rows: list[FrameAgreement], images: list[dict], path: Path, max_frames: int = 6) -> list[str]:
    """Difference images (:func:`renderlab.crosscheck_figures.figure`, PNG + SVG); returns the notes of panels left
    out (a frame without a cast-shadow edge has no shadow-edge panel)."""
    from renderlab.crosscheck_figures import figure as draw

    return draw(rows, images, path, TARGETS, max_frames=max_frames)


def _referee_all(scenario, base_dir, rows, images) -> None:
    from renderlab.render.ray_oracle import oracle_scene
    from renderlab.worlds.base import make_plan

    plan = make_plan(scenario, base_dir)
    specs = {spec.index: spec for spec in plan.frames}
    cache: dict = {}
    for row, imgs in zip(rows, images):
        spec = specs[row.frame]
        key = plan.scene_key(spec)
        if key not in cache:  # the exact geometry: tiled surfaces (EV5 levels of detail) at full resolution
            cache[key] = oracle_scene(plan.scene(key).untiled())
        if cache[key] is not None:
            referee(row, imgs, cache[key], spec, scenario.render.spp)


def run_crosscheck(scenario, base_dir: Path, out_dir: Path, *, frames: int | None = None,
                   keep_truthsets: bool = False, progress: bool = True) -> list[FrameAgreement]:
    """Render ``scenario`` with both renderers and write ``crosscheck.parquet`` (one row per frame),
    ``crosscheck_images.parquet`` (the drawn frames' images), and from those two tables alone ``crosscheck.md`` and
    ``crosscheck.png`` / ``.svg`` into ``out_dir`` (truth sets in ``out_dir/truthsets/`` if ``keep_truthsets``);
    ``renderlab report out_dir`` remakes the last two (:func:`renderlab.crosscheck_figures.write_report`)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from renderlab.errors import UserError
    from renderlab.extras import require
    from renderlab.pipeline import render_truthset

    require("bpy", "cycles", load=False)  # before out_dir is made
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise UserError(f"--out {out_dir} exists and is not a folder")
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="renderlab-crosscheck-") as tmp:
        root = out_dir / "truthsets" if keep_truthsets else Path(tmp)
        paths = {}
        for renderer in ("mitsuba", "cycles"):
            paths[renderer] = render_truthset(scenario, base_dir, root / renderer, frames=frames,
                                              renderer=renderer, progress=progress, overwrite=True)
        rows, images = compare_truthsets(paths["mitsuba"], paths["cycles"])
    if scenario.render.pixel_filter == "box":  # the oracle gives box-filtered pixels
        _referee_all(scenario, base_dir, rows, images)
    from renderlab.crosscheck_figures import TABLE, TITLE_KEY, write_images, write_report

    cols = list(FrameAgreement.__dataclass_fields__)
    table = pa.table({c: [getattr(r, c) for r in rows] for c in cols})
    table = table.replace_schema_metadata({TITLE_KEY: f"Mitsuba vs Cycles: {scenario.name}"})
    pq.write_table(table, out_dir / TABLE)
    write_images(rows, images, out_dir)
    write_report(out_dir, out_dir)  # crosscheck.md and the figure from the two tables just written
    return rows
