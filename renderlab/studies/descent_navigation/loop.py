"""One landmark method or measurement source driving the descent filter closed-loop over the images of one run
(per image: propagate, measure at the a-priori pose, update; docs/descent_navigation.md, "One run")."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from renderlab.contracts.landmark import CameraPose
from renderlab.errors import UserError
from renderlab.geometry.rotations import quat_xyzw
from renderlab.studies.descent_navigation.sources import LandmarkMethodSource


@dataclass
class RunInputs:
    """What every method of one run shares: images, truth, draws."""

    ts: object                 # the re-exposed truth set
    truth: object              # TrueDescent
    maplets: list
    centres: np.ndarray
    spacing: np.ndarray
    R_site: np.ndarray         # body ← site (east, north, up)
    times: np.ndarray          # (K,) image times
    R_true: np.ndarray         # (K, 3, 3) true body ← camera
    pos_true: np.ndarray       # (K, 3) true camera position (the manifest's)
    cameras: list              # (K,) the camera model of each image
    R_star: np.ndarray         # (K, 3, 3) star tracker's body ← camera
    accel: list                # per image interval: [(t0, t1, u_meas)]
    x0: np.ndarray
    P0: np.ndarray
    sigma_st_rad: float
    campaign: str
    run: int
    _images: dict = field(default_factory=dict)

    def image(self, k: int) -> np.ndarray:
        """The DN image k of this run, loaded once and shared by every method."""
        if k not in self._images:
            self._images[k] = self.ts.load(k).dn
        return self._images[k]


def _error_cols(x, P, x_true, R_site) -> dict:
    """Errors and 1σ in the site frame (east, north, up), NEES, and the whitened error L⁻¹e (P = LLᵀ, site frame),
    whose mean over the runs shows the part of the error common to all runs (:mod:`.independence`)."""
    B = np.zeros((6, 6))
    B[:3, :3] = B[3:, 3:] = R_site.T
    e = B @ (x - x_true)
    sig = np.sqrt(np.diag(B @ P @ B.T))
    d = x - x_true
    out = {"nees": float(d @ np.linalg.solve(P, d))}
    y = np.linalg.solve(np.linalg.cholesky(B @ P @ B.T), e)     # whitened error (site frame): NEES = |y|²
    out.update({f"white_{k}": float(v) for k, v in enumerate(y)})
    for k, name in enumerate(("e_m", "n_m", "u_m", "ve_mps", "vn_mps", "vu_mps")):
        out[f"err_{name}"], out[f"sig_{name}"] = float(e[k]), float(sig[k])
    return out


def _landmark_rows(inp, method, k, sel, results, upd, cam, true_pose) -> list[dict]:
    rows = []
    xc = true_pose.to_camera(inp.centres[sel]) if len(sel) else np.zeros((0, 3))
    truth_px = cam.project(xc) if len(sel) else np.zeros((0, 2))
    j = 0
    for idx, res, tp, depth in zip(sel, results, truth_px, xc[:, 2]):
        ok = res.has_result
        ms, ml = (res.meas_s, res.meas_l) if ok else (math.nan, math.nan)
        kept = gated = False
        d2 = math.nan
        if ok and upd is not None:
            kept, gated, d2 = bool(upd.kept[j]), bool(upd.gated[j]), float(upd.d2[j])
        j += int(ok)
        rows.append({"campaign": inp.campaign, "run": inp.run, "method": method, "frame": k,
                     "item": int(inp.maplets[idx].landmark_id), "pred_s": float(res.pred_s),
                     "pred_l": float(res.pred_l), "meas_s": ms, "meas_l": ml, "truth_s": float(tp[0]),
                     "truth_l": float(tp[1]), "err_s": ms - float(tp[0]), "err_l": ml - float(tp[1]),
                     "gsd_m": float(depth / cam.fx), "spacing_m": float(inp.spacing[idx]),
                     "has_result": bool(ok), "reason": res.reason, "outlier": bool(res.outlier), "kept": kept,
                     "gated": gated, "gate_d2": d2, "search_px": int(res.search_px), "t_ms": float(res.t_ms)})
    return rows


def _prior_cols(filt, R_star) -> dict:
    """The a-priori pose the method gets (body frame) and the filter's largest position σ at that time."""
    from scipy.spatial.transform import Rotation

    q = quat_xyzw(Rotation.from_matrix(R_star))
    return {**{f"apriori_pos_{a}_m": float(v) for a, v in zip("xyz", filt.x[:3])},
            **{f"star_quat_body_from_cam_{a}": float(v) for a, v in zip("xyzw", q)},
            "apriori_sigma_pos_max_m": float(np.sqrt(np.linalg.eigvalsh(filt.P[:3, :3])[-1]))}


def _propagate(filt, intervals) -> None:
    for _t0, t1, u in intervals:
        filt.set_input(u)
        filt.propagate(t1)


def run_method(source, inp: RunInputs, filt, cfg, mopts) -> tuple[list[dict], list[dict]]:
    """(filter rows, landmark rows) of one measurement source (:mod:`.sources`; a bare landmark method is wrapped
    in :class:`~renderlab.studies.descent_navigation.sources.LandmarkMethodSource`) over the run's images (module
    docstring); the source's constant ``columns()`` are added to its filter rows."""
    if not hasattr(source, "measure"):
        source = LandmarkMethodSource(source, cfg, mopts)
    filt.initialize(float(inp.times[0]), inp.x0, inp.P0)
    base = {"campaign": inp.campaign, "run": inp.run, "method": source.name, **source.columns()}
    frows = [{**base, "frame": -1, "t_s": float(inp.times[0]), "has_result": False, "reason": "prior",
              **_error_cols(filt.x, filt.P, inp.truth.state(inp.times[0]), inp.R_site), "nis": math.nan, "dof": 0,
              "n_attempted": 0, "n_results": 0, "n_flagged": 0, "n_gated": 0, "n_kept": 0, "search_px_mean": math.nan,
              "track_lost": False, "n_map_states": 0, **_prior_cols(filt, inp.R_star[0]),
              **{f"est_pos_{a}_m": float(v) for a, v in zip("xyz", filt.x[:3])}}]
    lrows, misses, lost, diverged = [], 0, False, False
    for k, t in enumerate(inp.times):
        row = {**base, "frame": k, "t_s": float(t)}
        if diverged:
            frows.append({**frows[-1], **row, "reason": "diverged"})
            continue
        _propagate(filt, inp.accel[k])
        prior = _prior_cols(filt, inp.R_star[k])
        sel, results, meas = source.measure(inp, k, filt)
        upd = None
        try:
            if meas is not None:
                filt.update(float(t), meas)
                upd = filt.last
        except UserError:
            diverged = True
        kept = int(upd.kept.sum()) if upd is not None else 0
        misses = misses + 1 if kept == 0 else 0
        lost = lost or misses >= cfg.track_loss_frames
        reason = "diverged" if diverged else ("ok" if kept else ("all_gated" if upd is not None else "no_measurement"))
        errs = _error_cols(filt.x, filt.P, inp.truth.state(t), inp.R_site) if not diverged else \
            {c: math.nan for c in frows[0] if c.startswith(("err_", "sig_", "white_")) or c == "nees"}
        frows.append({**row, "has_result": bool(kept), "reason": reason, **errs,
                      "nis": float(upd.nis) if kept else math.nan, "dof": int(upd.dof) if upd is not None else 0,
                      "n_attempted": int(len(sel)), "n_results": int(sum(r.has_result for r in results)),
                      "n_flagged": int(upd.flagged.sum()) if upd is not None else 0,
                      "n_gated": int(upd.gated.sum()) if upd is not None else 0, "n_kept": kept,
                      "search_px_mean": float(np.mean([r.search_px for r in results])) if results else math.nan,
                      "track_lost": bool(lost), "n_map_states": len(getattr(filt, "map_ids", [])), **prior,
                      **{f"est_pos_{a}_m": float(v) for a, v in zip("xyz", filt.x[:3])}})
        lrows += _landmark_rows(inp, source.name, k, sel, results, upd, inp.cameras[k],
                                CameraPose(inp.R_true[k], inp.pos_true[k]))
    return frows, lrows
