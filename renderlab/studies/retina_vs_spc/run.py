"""Study ``retina_vs_spc``: Retina and the SPC-style method on the same EV5 frames (Wright et al., Fig. 12).

One run (:func:`run`): the truth rendered once through the truth cache (with truth perturbations, each run its own,
:mod:`renderlab.campaign.run_truth`); what differs between runs is what the onboard system believes — the a-priori
pose, camera, Sun-direction and maplet-spacing knowledge (:func:`believed_record`, respaced maplets) — and the sensor
noise (:class:`BelievedTruthSet`). Every method sees the same image, a-priori draw and beliefs; truth (s, l) is the
truth set's ``landmark_truth``. Breakdown columns and the registration CRLB (``crlb_s``/``crlb_l``: the continuous
truth's over the template's pixels, :mod:`.crlb_truth`, or the finite-difference window bound of every table
published before it): ``docs/retina_vs_spc.md``.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pyarrow as pa

from renderlab import plugins
from renderlab.campaign.crlb import window_crlb
from renderlab.campaign.maplets import respaced_maplets
from renderlab.campaign.perturb import draw_perturbation, perturb_camera, perturb_sun
from renderlab.campaign.reexpose import ReexposedTruthSet
from renderlab.campaign.run_truth import run_truthset
from renderlab.campaign.scoring import dn_variance
from renderlab.errors import UserError
from renderlab.files.truthset import TruthSet
from renderlab.measurement.runner import MeasureOptions, measure_truthset, onboard_photometry
from renderlab.scenario import scenario_from_dict, truth_dict
from renderlab.sensor.model import SensorOptions, expected_dn
from renderlab.studies.retina_vs_spc import crlb_truth as CT
from renderlab.studies.retina_vs_spc.config import RetinaVsSpcConfig
from renderlab.worlds.ev5.catalog import read_catalog


def apriori_sigmas(p) -> tuple[tuple, tuple]:
    """(σ position m, σ attitude rad) per axis of the a-priori draw."""
    pos = np.sqrt(np.clip(np.diag(np.asarray(p.apriori_cov, float))[:3], 0, None)) if p.apriori_cov is not None \
        else np.asarray(p.apriori_position_sigma_m, float)
    return tuple(float(v) for v in pos), (math.radians(p.apriori_attitude_sigma_deg),) * 3


def believed_record(rec: dict, draw) -> dict:
    """A frame record as the onboard system believes it: the run's camera and Sun-direction knowledge errors."""
    r = dict(rec)
    r["camera"] = perturb_camera(rec["camera"], draw)
    r["sun"] = {**rec["sun"], "direction_render": [float(v) for v in perturb_sun(rec["sun"]["direction_render"], draw)]}
    return r


class BelievedTruthSet(ReexposedTruthSet):
    """A truth set as the onboard system sees it (what :func:`renderlab.measurement.runner.measure_truthset`
    reads): believed camera and Sun in the frame records, the DN re-exposed with this run's noise (a seed per frame)."""

    no_radiance = "truth set {path}: retina_vs_spc needs a mono (radiance) truth set"

    def __init__(self, ts, draw, sensor_options, noise_seeds, *, noise: bool = True):
        super().__init__(ts, sensor_options, noise_seeds, cache=True)
        self.frames = [believed_record(rec, draw) for rec in ts.frames]
        self.noise = bool(noise)

    def load(self, i: int):
        """Frame ``i`` re-exposed with the run's noise, or (``noise`` false) its expected DN, rounded."""
        if self.noise:
            return super().load(i)
        fr = self._ts.load(i)
        if fr.radiance is None:
            raise UserError(self.no_radiance.format(path=self.path, i=i))
        dn = np.rint(expected_dn(np.asarray(fr.radiance, np.float64), self.sensor_options(i)))
        return dataclasses.replace(fr, dn=dn.astype(np.uint16))


def landmark_extras(ts, believed: BelievedTruthSet, maplets, truth: dict, fine) -> dict:
    """{(frame, landmark_id): (range_m, albedo_contrast, crlb_s, crlb_l)}; the bound of ``fine`` (:mod:`.crlb_truth`)
    over the exact maplet's footprint, or (None) the finite-difference window bound of the truth pixels."""
    by_id = {int(m.landmark_id): m for m in maplets}
    exact = {int(m.landmark_id): m for m in read_catalog(ts.path)}
    L_table = onboard_photometry(ts, MeasureOptions())[0]
    out, pos_of, img = {}, {}, {}
    index_of = {int(rec["index"]): k for k, rec in enumerate(ts.frames)}
    for f, lid, s, l, g in zip(truth["frame"], truth["landmark_id"], truth["s"], truth["l"], truth["gsd_ratio"]):
        f, lid = int(f), int(lid)
        m, k = by_id.get(lid), index_of.get(f)
        if m is None or k is None:
            continue
        if k not in img:
            opts = believed.sensor_options(k)
            rad = np.asarray(ts.load(k).radiance, np.float64)
            src = rad if fine is None else np.asarray(fine.load(k).radiance, np.float64)
            img[k] = (expected_dn(src, opts), dn_variance(rad, opts))
            pos_of[k] = np.asarray(ts.frames[k]["pose"]["position_m"], float)
        rng_m = float(np.linalg.norm(m.center_m - pos_of[k]))
        p5, p95 = np.percentile(m.albedo, [5, 95])
        contrast = float((p95 - p5) / (p95 + p5)) if p95 + p5 > 0 else math.nan
        crlb = (math.nan, math.nan)
        if fine is None:
            crlb = window_crlb(*img[k], s, l, g, m.heights_m.shape[0])
        elif np.isfinite(s) and np.isfinite(l) and lid in exact:
            fine_dn, var = img[k]
            fp = CT.maplet_footprint(ts.frames[k], exact[lid], L_table)
            crlb = CT.sigma_or_nan(CT.footprint_bound(fine_dn, CT.FINE_K, var, fp))
        out[(f, lid)] = (rng_m, contrast, float(crlb[0]), float(crlb[1]))
    return out


def section(scenario):
    """The scenario's ``[retina_vs_spc]`` section (defaults when absent)."""
    return getattr(scenario, "retina_vs_spc", None) or RetinaVsSpcConfig()


def check(scenario) -> None:
    """Validate before anything runs: world kind, every method name registered."""
    if scenario.world.kind != "ev5":
        raise UserError(f"study retina_vs_spc needs world.kind 'ev5', got '{scenario.world.kind}'")
    for name in section(scenario).methods:
        plugins.landmark_methods.get(name, where="retina_vs_spc.methods: ")


def run(scenario, base_dir, run_index: int, seed_sequence, workdir, methods=None) -> dict:
    """One run of ``retina_vs_spc`` → ``{"measurements": table, "perturbations": table}``. ``methods``: landmark
    methods (names, objects or factories, :func:`renderlab.measurement.runner.make_method`) instead of the
    section's names (the error budget's shadow-free onboard variants, :mod:`.budget.shadows`)."""
    check(scenario)
    p = scenario.perturbations
    ss_pert, ss_apriori, ss_noise, ss_map = seed_sequence.spawn(4)
    draw = draw_perturbation(p, ss_pert)
    # the a-priori pose is drawn per frame inside measure_truthset around the (perturbed) true pose
    truth_sc = scenario_from_dict(truth_dict(scenario.to_dict()), "retina_vs_spc truth scenario")
    path, _ = run_truthset(truth_sc, base_dir, Path(workdir) / "truth_cache", p, draw)
    ts = TruthSet.open(path)
    fine = None
    if section(scenario).crlb == "continuous":
        fine_sc = scenario_from_dict(CT.fine_truth_dict(truth_sc.to_dict()), "retina_vs_spc truth, sub-pixels (CRLB)")
        fine = TruthSet.open(run_truthset(fine_sc, base_dir, Path(workdir) / "crlb_cache", p, draw)[0])
    maplets = read_catalog(path)
    if draw.spacing_scale != 1.0:
        maplets = respaced_maplets(maplets, scenario.world, base_dir, draw.spacing_scale, np.random.default_rng(ss_map))
    noise_seeds = [int(s.generate_state(1)[0]) for s in ss_noise.spawn(len(ts))]
    believed = BelievedTruthSet(ts, draw, SensorOptions(**scenario.sensor.options_dict()), noise_seeds,
                                noise=section(scenario).sensor_noise)
    sig_p, sig_r = apriori_sigmas(p)
    opts = MeasureOptions(sigma_pos_m=sig_p, sigma_att_rad=sig_r, campaign=scenario.name, run=int(run_index))
    apriori_state = ss_apriori.generate_state(4)
    tables = [measure_truthset(believed, maplets, m, opts, np.random.default_rng(apriori_state))
              for m in (section(scenario).methods if methods is None else methods)]
    meas = pa.concat_tables(tables)
    truth = ts.read_table("landmark_truth").to_pydict()
    extras = landmark_extras(ts, believed, maplets, truth, fine)
    keys = list(zip(meas.column("frame").to_pylist(), meas.column("item").to_pylist()))
    for j, name in enumerate(("range_m", "albedo_contrast", "crlb_s", "crlb_l")):
        meas = meas.append_column(name, pa.array([extras.get((int(f), int(i)), (math.nan,) * 4)[j] for f, i in keys],
                                                 pa.float64()))
    if fine is not None:  # tables without the column carry the finite-difference window bound
        meas = meas.append_column("crlb_bound", pa.array(["continuous"] * meas.num_rows, pa.string()))
    if draw.spacing_scale != 1.0:  # the run's maplets are coarser/finer: GSD / spacing changes
        g = np.asarray(meas.column("gsd_ratio").to_numpy(zero_copy_only=False), float) / draw.spacing_scale
        meas = meas.set_column(meas.column_names.index("gsd_ratio"), "gsd_ratio", pa.array(g, pa.float64()))
    drawn = {k: v for k, v in draw.to_row().items() if not k.startswith("apriori_d")}  # per frame: measurements
    prow = {"campaign": scenario.name, "run": int(run_index), **drawn,
            "apriori_sigma_pos_m": float(max(sig_p)), "apriori_sigma_att_rad": float(sig_r[0])}
    return {"measurements": meas, "perturbations": pa.table({k: [v] for k, v in prow.items()})}
