"""The landmark-measurement runner: a truth set + maplets → the measurement table (one row per landmark
attempted per frame, :data:`renderlab.contracts.schemas.LANDMARK_RUNNER`) for any registered landmark method
(:data:`renderlab.plugins.landmark_methods`: ``retina``, ``spc``, entry points, or ``module:attr`` typed by
the user).

Per frame: the true camera pose (manifest ``pose``) is perturbed by a seeded draw from the a-priori
covariance (position δt ~ N(0, Σ_t) in the body/render frame; attitude δθ ~ N(0, Σ_θ), a rotation of the
camera frame, ``R_apriori = R_true · exp([δθ]×)``). With that a-priori pose each landmark is predicted
(``pred``); landmarks whose predicted centre falls outside the image are not attempted (as onboard).
The search distance is n_σ times the projected covariance (``estimators.retina.search_radius_px``).
Every row records the draw (``apriori_dpos_*_m``, ``apriori_drot_*_rad``), the covariance it was drawn
from (``apriori_sigma_pos_*_m``, ``apriori_sigma_att_*_rad``, 1σ per axis) and ``n_sigma``.
``meas = pred + (Δs, Δl)``; ``truth`` is the landmark_truth table's (s, l) when the set has one, else the
projection with the true pose; ``err = meas − truth``. Rows with no result have NaN ``meas``/``err``.

The onboard photometric model (``photometry`` column), the same for both methods: McEwen with L(α)
fitted to the body's catalogued law (``fitted:<law>``, default) or with β = exp(−α/60°) (``fixed``).
Both methods get the same ground knowledge, so what separates them is how they predict the image
(Retina: ray-traced facets and shadows in image space; SPC: grid shading, approximate shadows, maplet frame).

``has_result`` and ``reason`` (:class:`~renderlab.contracts.reasons.LandmarkReason`) say whether and why not a
shift was measured; ``outlier`` is the method's own consistency flag (kept); ``truth_visible`` is false where the
truth says the landmark is hidden or occluded; ``diagnostics`` is the method's own flag text.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from estimators.landmarks.peaks import FINDERS
from estimators.onboard_photometry import fit_lunar_lambert_L
from estimators.retina import search_radius_px
from renderlab import plugins
from renderlab.contracts.landmark import CameraPose, LandmarkFrame, LandmarkMethod, LandmarkMethodOptions
from renderlab.contracts.schemas import LANDMARK_RUNNER, table_from_rows
from renderlab.errors import UserError
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.rotations import rotation_from_quat_xyzw
from renderlab.photometry import make_law

PHOTOMETRY = ("fitted", "fixed")


@dataclass(frozen=True)
class MeasureOptions:
    """Runner options (SI units).

    Attributes
    ----------
    sigma_pos_m : tuple of 3 float
        A-priori position 1σ per body axis, m.
    sigma_att_rad : tuple of 3 float
        A-priori attitude 1σ per camera axis, rad.
    n_sigma : float
        Search distance in σ of the projected covariance.
    min_search_px, max_search_px : int
        Clamp of the search distance.
    peak : str or None
        Peak finder (None: the method's own — Retina ``retina_3x3``, SPC ``quadric_2d``).
    min_correlation : float
        Correlation threshold for a result.
    supersample : int
        Retina's k×k rays per pixel.
    photometry : {"fitted", "fixed"}
        The McEwen weight of both methods: ``fitted`` — L(α) least-squares fitted to the body's catalogued law
        (``scenario.world`` law, law_params, albedo in the truth set's manifest, what the ground knows;
        :func:`estimators.onboard_photometry.fit_lunar_lambert_L`), falling back to ``fixed`` when the
        manifest names no law; ``fixed`` — β = exp(−α/60°) (Retina eq. 5). Column ``photometry`` records
        which was used.
    psf_sigma_px : float
        Retina's PSF σ, px.
    campaign : str
        Campaign name written in every row.
    run : int
        Run number written in every row.
    """

    sigma_pos_m: tuple = (0.5, 0.5, 0.5)
    sigma_att_rad: tuple = (math.radians(0.05),) * 3
    n_sigma: float = 3.0
    min_search_px: int = 2
    max_search_px: int = 48
    peak: str | None = None
    min_correlation: float = 0.3
    supersample: int = 3
    psf_sigma_px: float = 0.0
    photometry: str = "fitted"
    campaign: str = ""
    run: int = 0

    def __post_init__(self):
        for name in ("sigma_pos_m", "sigma_att_rad"):
            v = np.asarray(getattr(self, name), float)
            if v.shape == ():
                v = np.full(3, float(v))
            if v.shape != (3,) or not np.all(np.isfinite(v)) or np.any(v < 0):
                raise UserError(f"{name} must be 3 finite non-negative numbers, got {getattr(self, name)!r}")
            object.__setattr__(self, name, tuple(float(x) for x in v))
        if not (self.n_sigma > 0 and math.isfinite(self.n_sigma)):
            raise UserError(f"n_sigma must be positive, got {self.n_sigma!r}")
        if not 1 <= self.min_search_px <= self.max_search_px:
            raise UserError(f"search distance bounds must satisfy 1 <= min <= max, got "
                            f"{self.min_search_px}, {self.max_search_px}")
        if not -1.0 <= self.min_correlation <= 1.0:
            raise UserError(f"min_correlation must be in [-1, 1], got {self.min_correlation!r}")
        if self.supersample < 1:
            raise UserError(f"supersample must be >= 1, got {self.supersample!r}")
        if self.photometry not in PHOTOMETRY:
            raise UserError(f"photometry must be one of {', '.join(PHOTOMETRY)}, got {self.photometry!r}")
        if self.psf_sigma_px < 0:
            raise UserError(f"psf_sigma_px must be >= 0, got {self.psf_sigma_px!r}")
        if self.peak is not None:

            if self.peak not in FINDERS:
                raise UserError(f"peak must be one of {', '.join(FINDERS)}, got {self.peak!r}")


@dataclass
class _Frame:
    index: int
    camera: object
    R: np.ndarray
    position: np.ndarray
    sun: np.ndarray
    adc_max: int | None
    extra: dict = field(default_factory=dict)


def _frame_record(ts, i: int) -> _Frame:
    rec = ts.frames[i]
    where = f"truth set {ts.path}: frames[{i}]"
    try:
        cam = CameraModel.from_dict(rec["camera"])
        pose, sun = rec["pose"], rec["sun"]["direction_render"]
        R = rotation_from_quat_xyzw(pose["quat_render_from_cam_xyzw"], f"{where}.pose").as_matrix()
        pos = np.asarray(pose["position_m"], float)
        sun = np.asarray(sun, float)
    except KeyError as exc:
        raise UserError(f"{where} has no {exc.args[0]!r} (camera, pose and sun are needed)") from None
    if pos.shape != (3,) or sun.shape != (3,) or not np.all(np.isfinite(pos)) or not np.linalg.norm(sun) > 0:
        raise UserError(f"{where}: pose.position_m and sun.direction_render must be finite 3-vectors")
    bits = (rec.get("sensor") or {}).get("bits")
    return _Frame(int(rec["index"]), cam, R, pos, sun / np.linalg.norm(sun), (1 << int(bits)) - 1 if bits else None)


def _truth_lookup(ts) -> dict:
    """{(frame, landmark_id): row dict} from landmark_truth.parquet, or {} when the set has none."""
    if not (ts.path / "landmark_truth.parquet").is_file():
        return {}
    t = ts.read_table("landmark_truth").to_pydict()
    need = ("frame", "landmark_id", "s", "l")
    missing = [k for k in need if k not in t]
    if missing:
        raise UserError(f"truth set {ts.path}: landmark_truth.parquet lacks column {missing[0]!r}")
    keys = list(t)
    return {(int(t["frame"][k]), int(t["landmark_id"][k])): {c: t[c][k] for c in keys} for k in range(len(t["frame"]))}


def body_law(ts):
    """(PhotometricLaw, mean albedo) of the body from the truth set's manifest (``scenario.world``), or
    None when the manifest names no law (the ground's catalog knowledge for :func:`onboard_photometry`)."""
    import json


    path = ts.path / "manifest.json"
    try:
        world = (json.loads(path.read_text(encoding="utf-8")).get("scenario") or {}).get("world") or {}
    except (OSError, ValueError, AttributeError):
        return None
    if not isinstance(world, dict) or "law" not in world:
        return None
    try:
        law = make_law(world["law"], **(world.get("law_params") or {}))
    except UserError as err:
        raise UserError(f"truth set {ts.path}: scenario.world law: {err}") from None
    return law, float(world.get("albedo", 0.1))


def onboard_photometry(ts, options: MeasureOptions) -> tuple[tuple, str]:
    """(L_table, label) for the methods' McEwen weight (``MeasureOptions.photometry``)."""
    found = body_law(ts) if options.photometry == "fitted" else None
    if found is None:
        return (), "fixed"
    law, albedo = found
    fit = fit_lunar_lambert_L(lambda mu0, mu, g: law.radiance_factor(mu0, mu, g, albedo))
    return tuple(float(v) for v in fit.L), f"fitted:{law.name}"


def draw_apriori(R_true: np.ndarray, pos_true: np.ndarray, options: MeasureOptions, rng: np.random.Generator):
    """(R_apriori, pos_apriori, dpos, drot): the true pose perturbed by one draw (module docstring)."""
    from scipy.spatial.transform import Rotation

    dpos = rng.normal(0.0, 1.0, 3) * np.asarray(options.sigma_pos_m)
    drot = rng.normal(0.0, 1.0, 3) * np.asarray(options.sigma_att_rad)
    return R_true @ Rotation.from_rotvec(drot).as_matrix(), pos_true + dpos, dpos, drot


def make_method(method, options: MeasureOptions, L_table: tuple = (), *, allow_reference: bool = False):
    """A landmark-method object from a registered name (or a user-typed ``module:attr`` with
    ``allow_reference``), an already made method, or a factory; UserError naming the registered ones."""
    if isinstance(method, LandmarkMethod) and not isinstance(method, type):
        return method
    if isinstance(method, str):
        factory = plugins.landmark_methods.get(method, allow_reference=allow_reference, where="--method: ")
    else:
        factory = method
    mopts = LandmarkMethodOptions(peak=options.peak, min_correlation=options.min_correlation,
                                  supersample=options.supersample, psf_sigma_px=options.psf_sigma_px, L_table=L_table)
    obj = factory(mopts)
    if not isinstance(obj, LandmarkMethod) or not isinstance(getattr(obj, "name", None), str):
        raise UserError(f"landmark method {method!r} does not follow the contract (needs a 'name' string and "
                        "measure_frame(frame); see renderlab.contracts.landmark)")
    if isinstance(method, str) and ":" not in method and obj.name != method:
        raise UserError(f"landmark method registered as '{method}' names itself '{obj.name}'; the two must agree "
                        "(the name fills the table's 'method' column)")
    return obj


def _row(fr, lid, res, method_name, photometry, peak, tp, trow, cam, draw, sigma_cols, options) -> dict:
    """One measurement-table row (:data:`renderlab.contracts.schemas.LANDMARK_RUNNER`)."""
    dpos, drot = draw
    ts_, tl_ = (float(trow["s"]), float(trow["l"])) if trow else (float(tp[0]), float(tp[1]))
    if trow is None:
        visible = bool(cam.in_image(tp))
    else:
        visible = bool(trow.get("visible", True)) and not bool(trow.get("occluded", False))
    ok = res.has_result
    ms, ml = (res.meas_s, res.meas_l) if ok else (math.nan, math.nan)
    row = {"campaign": options.campaign, "run": int(options.run), "frame": fr.index, "item": lid,
           "method": method_name, "pred_s": float(res.pred_s), "pred_l": float(res.pred_l), "meas_s": ms,
           "meas_l": ml, "truth_s": ts_, "truth_l": tl_, "err_s": ms - ts_, "err_l": ml - tl_,
           "score": float(res.score), "has_result": bool(ok), "reason": res.reason, "outlier": bool(res.outlier),
           "diagnostics": res.diagnostics, "t_ms": float(res.t_ms), "peak": peak, "search_px": int(res.search_px),
           "n_pixels": int(res.n_pixels), "pred_shadow_fraction": float(res.shadow_fraction),
           "truth_visible": visible,
           **{f"apriori_dpos_{a}_m": float(v) for a, v in zip("xyz", dpos)},
           **{f"apriori_drot_{a}_rad": float(v) for a, v in zip("xyz", drot)}, **sigma_cols}
    for c in ("gsd_ratio", "phase_deg", "incidence_deg", "emission_deg", "shadow_fraction"):
        row[c] = float(trow[c]) if trow and c in trow and trow[c] is not None else math.nan
    row["photometry"] = photometry
    return row


@dataclass
class _RunContext:
    """What every frame of one :func:`measure_truthset` call shares."""

    impl: object
    options: MeasureOptions
    truth: dict
    photometry: str
    peak: str
    sigma_cols: dict
    centres: np.ndarray


def run_method_on_image(impl, image: np.ndarray, adc_max, cam, apriori, sun_body, maplets: list, centres: np.ndarray,
                        cov_p: np.ndarray, cov_r: np.ndarray, options: MeasureOptions, index: int) -> tuple:
    """The landmarks the a-priori pose predicts inside the image, each with its search distance (n σ of the
    projected 6×6 a-priori covariance blocks ``cov_p`` m², ``cov_r`` rad²), measured by ``impl``; returns
    (attempted indices, checked results). The image and its mask reach the method read-only (contract rule 2)."""
    attempt = np.flatnonzero(cam.in_image(cam.project(apriori.to_camera(centres))))
    if attempt.size == 0:
        return attempt, []
    image = np.array(image, dtype=np.float64)
    a_valid = image < adc_max if adc_max is not None else None
    image.flags.writeable = False
    if a_valid is not None:
        a_valid.flags.writeable = False
    radii = np.array([search_radius_px(cam, apriori, centres[k], cov_p, cov_r, options.n_sigma,
                                       options.min_search_px, options.max_search_px) for k in attempt], int)
    frame = LandmarkFrame(image=image, valid=a_valid, camera=cam, pose=apriori, sun_body=sun_body,
                          landmarks=[maplets[k] for k in attempt], search_px=radii, index=index,
                          seed=int(options.run) * 1_000_003 + index)
    results = impl.measure_frame(frame)
    if len(results) != attempt.size:
        raise UserError(f"landmark method '{impl.name}' returned {len(results)} results for "
                        f"{attempt.size} landmarks in frame {index}")
    for res in results:
        try:
            res.check(f"landmark method '{impl.name}', frame {index}: ")
        except ValueError as err:
            raise UserError(str(err)) from None
    return attempt, results


def _measure_one_frame(ts, i: int, maplets: list, ctx: _RunContext, rng: np.random.Generator) -> list[dict]:
    """Rows of frame ``i``: one a-priori draw, the landmarks predicted inside the image, the method, the truth."""
    options, impl, centres = ctx.options, ctx.impl, ctx.centres
    fr = _frame_record(ts, i)
    R_ap, p_ap, dpos, drot = draw_apriori(fr.R, fr.position, options, rng)
    apriori, true_pose = CameraPose(R_ap, p_ap), CameraPose(fr.R, fr.position)
    cam = fr.camera
    if not np.any(cam.in_image(cam.project(apriori.to_camera(centres)))):
        return []
    cov_p, cov_r = np.diag(np.square(options.sigma_pos_m)), np.diag(np.square(options.sigma_att_rad))
    attempt, results = run_method_on_image(impl, ts.load(i).dn, fr.adc_max, cam, apriori, fr.sun, maplets, centres,
                                           cov_p, cov_r, options, fr.index)
    truth_px = cam.project(true_pose.to_camera(centres[attempt]))
    rows = []
    for k, res, tp in zip(attempt, results, truth_px):
        lid = int(maplets[k].landmark_id)
        rows.append(_row(fr, lid, res, impl.name, ctx.photometry, ctx.peak, tp, ctx.truth.get((fr.index, lid)), cam,
                         (dpos, drot), ctx.sigma_cols, options))
    return rows


def measure_truthset(ts, maplets: list, method, options: MeasureOptions = MeasureOptions(),
                     rng: np.random.Generator | None = None, progress: bool = False, *,
                     allow_reference: bool = False):
    """Measure every landmark of every frame of an open :class:`~renderlab.files.truthset.TruthSet`.

    Parameters
    ----------
    ts : TruthSet
        The truth set (frames with camera, pose, sun; DN images).
    maplets : list of Maplet
        The landmark catalog (in memory).
    method : str or LandmarkMethod or factory
        A registered landmark-method name (``retina``, ``spc``, ...), a method object or its factory.
    options : MeasureOptions
    rng : numpy.random.Generator
        Source of the a-priori pose draws (one draw of 6 normals per frame, in frame order).
    progress : bool
        Show a tqdm bar over frames.
    allow_reference : bool
        Accept ``module:attr`` for ``method`` (only for a name the user typed on the command line).

    Returns
    -------
    pyarrow.Table
        One row per landmark attempted per frame (:data:`renderlab.contracts.schemas.LANDMARK_RUNNER`).
    """
    from tqdm import tqdm


    if not maplets:
        raise UserError(f"truth set {ts.path}: the landmark catalog is empty")
    rng = np.random.default_rng(0) if rng is None else rng
    L_table, photometry = onboard_photometry(ts, options)
    impl = make_method(method, options, L_table, allow_reference=allow_reference)
    peak = str(getattr(impl, "peak", "") or "")
    truth = _truth_lookup(ts)
    sigma_cols = {**{f"apriori_sigma_pos_{a}_m": v for a, v in zip("xyz", options.sigma_pos_m)},
                  **{f"apriori_sigma_att_{a}_rad": v for a, v in zip("xyz", options.sigma_att_rad)},
                  "n_sigma": float(options.n_sigma)}
    ctx = _RunContext(impl, options, truth, photometry, peak, sigma_cols, np.array([m.center_m for m in maplets], float))
    rows: list[dict] = []
    for i in tqdm(range(len(ts)), desc=f"measure {impl.name}", unit="frame", disable=not progress):
        rows += _measure_one_frame(ts, i, maplets, ctx, rng)
    if not rows:
        return LANDMARK_RUNNER.empty_table()
    return table_from_rows(rows, LANDMARK_RUNNER, "landmark")


def write_table(table, out_path, overwrite: bool = False) -> None:
    """Write a Parquet table atomically (temporary sibling, then rename)."""
    import os
    from pathlib import Path

    import pyarrow.parquet as pq

    out = Path(out_path)
    if out.exists() and not overwrite:
        raise UserError(f"output {out} exists (use --overwrite to replace it)")
    if not out.parent.is_dir():
        raise UserError(f"cannot write {out}: directory {out.parent} does not exist")
    tmp = out.with_name(f".{out.name}.tmp-{os.getpid()}")
    try:
        pq.write_table(table, str(tmp))
        os.replace(tmp, out)
    except OSError as exc:
        raise UserError(f"cannot write {out}: {exc.strerror or exc}") from None
    finally:
        if tmp.exists():
            tmp.unlink()
