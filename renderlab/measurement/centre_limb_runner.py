"""The centre/limb kind's runner: images (a :class:`~renderlab.pipeline.frame_api.Frame` of the ``planet`` world, or
a :class:`~renderlab.contracts.centre_limb.CentreLimbFrame` with its truth row) through a method → result-table rows
(:mod:`renderlab.contracts.centre_limb_table`).

``runner(method, frames)`` is the kind's ``runner`` (:data:`renderlab.contracts.centre_limb.CENTRE_LIMB`): each item
of ``frames`` is a :class:`MeasuredImage`; every result is checked against the contract (a method that raises, or
breaks rule 1, gives a ``method_error`` row with the message, never a half-filled row).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from renderlab.contracts.centre_limb import BodyModel, CentreLimbFrame, CentreLimbReason, CentreLimbResult
from renderlab.contracts.centre_limb_table import RESULT_COLUMNS


@dataclass(frozen=True)
class MeasuredImage:
    """One image to measure: the method's input, the ``centre_truth`` row of the rendered pose, and extra columns
    (a study's grid: ``cell``, ``law``, ...)."""

    frame: CentreLimbFrame
    truth: dict
    extra: dict = field(default_factory=dict)


def from_render(f, apriori_position_m, body: BodyModel, *, seed: int = 0, extra: dict | None = None) -> MeasuredImage:
    """A :class:`MeasuredImage` of a rendered planet-world frame (``f.dn``, ``f.spec``, ``f.truth``): the true
    attitude, the a-priori position given (render frame = body frame, the body at its origin)."""
    from renderlab.contracts.landmark import CameraPose

    frame = CentreLimbFrame(image=np.asarray(f.dn, float), valid=None, camera=f.spec.camera,
                            pose=CameraPose(R_body_from_cam=f.spec.pose.rotation.as_matrix(),
                                            position_m=np.asarray(apriori_position_m, float)),
                            sun_body=np.asarray(f.spec.sun.direction_render, float), body=body,
                            index=int(f.index), seed=int(seed))
    return MeasuredImage(frame, f.truth["centre_truth"][0], dict(extra or {}))


def result_row(res: CentreLimbResult) -> dict:
    """The result columns of one measurement."""
    C, P, r = (np.asarray(x, float) for x in (res.cov_centre_px2, res.cov_r_cam_m2, res.r_cam_m))
    row = {"has_result": bool(res.has_result), "reason": res.reason, "diagnostics": str(res.diagnostics)[:500],
           "t_ms": float(res.t_ms), "centre_s": res.centre_s, "centre_l": res.centre_l,
           "cov_ss": C[0, 0], "cov_sl": C[0, 1], "cov_ll": C[1, 1], "limb_centre_s": res.limb_centre_s,
           "limb_centre_l": res.limb_centre_l, "limb_a_px": res.limb_a_px, "limb_b_px": res.limb_b_px,
           "r_x": r[0], "r_y": r[1], "r_z": r[2], "range_m": float(np.linalg.norm(r)),
           **{f"cov_r_{a}{b}": P[i, j] for a, b, i, j in (("x", "x", 0, 0), ("x", "y", 0, 1), ("x", "z", 0, 2),
                                                          ("y", "y", 1, 1), ("y", "z", 1, 2), ("z", "z", 2, 2))},
           "n_limb_points": int(np.asarray(res.limb_points).reshape(-1, 2).shape[0])}
    for c in RESULT_COLUMNS:
        row[c] = float(row[c])
    return row


def truth_columns(truth: dict, camera) -> dict:
    """The truth columns of one image from its ``centre_truth`` row."""
    return {"true_centre_s": float(truth["centre_s"]), "true_centre_l": float(truth["centre_l"]),
            "true_limb_centre_s": float(truth["limb_centre_s"]), "true_limb_centre_l": float(truth["limb_centre_l"]),
            "true_radius_px": float(truth["apparent_radius_px"]), "true_range_m": float(truth["range_m"]),
            "true_los_x": float(truth["los_cam_x"]), "true_los_y": float(truth["los_cam_y"]),
            "true_los_z": float(truth["los_cam_z"]), "phase_deg": float(truth["phase_deg"]), "fx": float(camera.fx)}


def measure_one(method, frame: CentreLimbFrame) -> CentreLimbResult:
    """``method.measure(frame)``, checked; a raise or a broken rule 1 becomes ``method_error``."""
    try:
        res = method.measure(frame)
        res.check(f"{getattr(method, 'name', '?')}: ")
    except Exception as exc:  # noqa: BLE001 - any failure of a method is a reported no-result
        return CentreLimbResult(reason=CentreLimbReason.METHOD_ERROR.value,
                                diagnostics=f"{type(exc).__name__}: {exc}"[:500])
    return res


def runner(method, frames) -> list[dict]:
    """One row per :class:`MeasuredImage` of ``frames`` (module docstring)."""
    rows = []
    name = getattr(method, "name", type(method).__name__)
    for item in frames:
        res = measure_one(method, item.frame)
        rows.append({"frame": int(item.frame.index), "cell": int(item.extra.get("cell", item.frame.index)),
                     "method": name, **result_row(res), **truth_columns(item.truth, item.frame.camera),
                     **{k: v for k, v in item.extra.items() if k != "cell"}})
    return rows
