"""The tables of study ``descent_gnc``: one row per image (``gnc_images``) and one per flight (``gnc_runs``), in the
site frame (east, north, up; origin the site centre). Errors are estimate − truth (``err_*``) with the filter's 1σ
(``sig_*``) and NEES; ``ctl_*`` = true minus nominal position; ``td_*`` = touchdown minus the target waypoint,
``nav_*`` the navigation error at contact with the filter's claimed covariance there; wall times ``t_*_ms``.
Column list: ``docs/descent_gnc.md``.
"""

from __future__ import annotations

import math

import numpy as np

AXES = ("e", "n", "u")
MISSES = ("no_match", "all_gated", "nis_rejected", "diverged")


def _site(R: np.ndarray, x: np.ndarray, P: np.ndarray | None = None):
    """(position, velocity) of a body-frame 6-vector in the site frame and, with P, the 6×6 site-frame covariance."""
    T = np.zeros((6, 6))
    T[:3, :3] = T[3:, 3:] = R.T
    return (T @ x, None) if P is None else (T @ x, T @ P @ T.T)


def _pv(name: str, v) -> dict:
    """``{name_e_m, name_n_m, name_u_m, name_ve_mps, name_vn_mps, name_vu_mps}`` of a site-frame 6-vector."""
    return {**{f"{name}_{a}_m": float(v[i]) for i, a in enumerate(AXES)},
            **{f"{name}_v{a}_mps": float(v[3 + i]) for i, a in enumerate(AXES)}}


class Recorder:
    """Collects the rows of one run (module docstring)."""

    def __init__(self, campaign: str, run: int, setup, nominal, opts):
        self.campaign, self.run, self.setup, self.opts = campaign, int(run), setup, opts
        self.R = np.asarray(setup.site.R_body_from_site, float)
        self.o = np.asarray(setup.site.origin_m, float)
        self.nominal, self.image_rows, self.run_rows = nominal, [], []
        wp = setup.waypoints[-1]
        self.target = np.r_[np.asarray(wp.r_m, float), np.asarray(wp.v_mps, float)]

    def _nominal_at(self, t: float) -> np.ndarray:
        f = self.nominal
        return f.x_true[min(max(int(round((t - f.t_s[0]) / self.opts.control_period_s)), 0), len(f.t_s) - 1)]

    def add(self, method: str, mode: str, flown, thrusters, wall_s: float) -> None:
        base = {"campaign": self.campaign, "run": self.run, "method": method, "mode": mode}
        n_miss = 0
        for j, im in enumerate(flown.images):
            k = int(np.flatnonzero(np.isclose(flown.flight.t_s, im["t_s"]))[0])
            x_true = flown.flight.x_true[k]
            e, P = _site(self.R, im["x_est"] - x_true, im["P"])
            ctl = self.R.T @ (x_true[:3] - self._nominal_at(im["t_s"])[:3])
            n_miss += im["status"] in MISSES
            row = {**base, "image": j, "t_s": float(im["t_s"]),
                   "altitude_m": float((x_true[:3] - self.o) @ self.R[:, 2]), "status": im["status"],
                   "n_candidates": im["n_candidates"], "n_attempted": im["n_attempted"],
                   "n_results": im["n_results"], "n_kept": im["n_kept"], "nis": float(im["nis"]),
                   "nis_dof": int(im["nis_dof"]), "widen": float(im["widen"]), "search_px": float(im["search_px"]),
                   "nees": float(e @ np.linalg.solve(P, e))}
            row.update({**_pv("err", e), **_pv("sig", [math.sqrt(P[i, i]) for i in range(6)]),
                        **{f"ctl_{a}_m": float(ctl[i]) for i, a in enumerate(AXES)},
                        "t_render_ms": 1e3 * im["t_render_s"], "t_measure_ms": 1e3 * im["t_measure_s"],
                        "t_filter_ms": 1e3 * im["t_filter_s"]})
            self.image_rows.append(row)
        self.run_rows.append(self._run_row(base, flown, thrusters, wall_s, n_miss))

    def _run_row(self, base: dict, flown, thrusters, wall_s: float, n_miss: int) -> dict:
        f = flown.flight
        x_td = f.x_true[-1]
        td, _ = _site(self.R, x_td - self.target)
        nav, P = _site(self.R, flown.x_end - x_td, flown.P_end)
        sig0 = np.r_[np.full(3, self.opts.initial_position_sigma_m), np.full(3, self.opts.initial_velocity_sigma_mps)]
        d0 = (flown.x0_est - f.x_true[0]) / sig0
        loss = flown.loss or {}
        row = {**base, "touchdown": bool(f.touchdown), "t_end_s": float(f.t_s[-1]), **_pv("td", td), **_pv("nav", nav)}
        for off, pre, unit in ((0, "", "m"), (3, "v", "mps")):
            se, sn = math.sqrt(P[off, off]), math.sqrt(P[off + 1, off + 1])
            row.update({f"sig_{pre}e_{unit}": se, f"sig_{pre}n_{unit}": sn,
                        f"sig_{pre}u_{unit}": math.sqrt(P[off + 2, off + 2]),
                        f"rho_{pre}en": float(P[off, off + 1] / (se * sn))})
        row.update({"delta_v_mps": float(thrusters.delta_v_mps), "propellant_kg": float(thrusters.propellant_kg),
                    "n_images": len(flown.images), "n_misses": int(n_miss), "track_lost": bool(flown.loss),
                    "loss_cause": str(loss.get("cause", "")), "loss_t_s": float(loss.get("t_s", math.nan)),
                    "loss_altitude_m": float(loss.get("altitude_m", math.nan)),
                    "reacquired": bool(loss.get("reacquired", False)),
                    "init_pos_err_max_sigma": float(np.abs(d0[:3]).max()),
                    "init_vel_err_max_sigma": float(np.abs(d0[3:]).max())})
        row.update({f"t_{k}_ms": 1e3 * float(sum(i[f"t_{k}_s"] for i in flown.images)) for k in ("render", "measure",
                                                                                              "filter")})
        row["t_flight_ms"] = 1e3 * wall_s
        return row

    def tables(self) -> dict:
        import pyarrow as pa

        def table(rows: list[dict], categorical: tuple) -> pa.Table:
            return pa.table({k: pa.array([r[k] for r in rows]).dictionary_encode() if k in categorical else
                             [r[k] for r in rows] for k in rows[0]})

        return {"gnc_images": table(self.image_rows, ("method", "mode", "status")),
                "gnc_runs": table(self.run_rows, ("method", "mode", "loss_cause"))}
