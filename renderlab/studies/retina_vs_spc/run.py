"""Study ``retina_vs_spc``: Retina and the SPC-style method on the same EV5 frames (Wright et al., Fig. 12).

Without truth perturbations the truth render depends only on the nominal scenario, so it is rendered once
and served by the truth cache (:mod:`renderlab.campaign.cache`, keyed by the scenario without its
``perturbations`` and ``campaign`` sections). With them (``position_sigma_m``, ``position_cov_m2``,
``velocity_sigma_mps``, ``attitude_sigma_deg``) each run renders its own truth at its perturbed true poses,
cached by the content of those poses, the world loaded once per worker process
(:mod:`renderlab.campaign.run_truth`). What else differs between runs is what the onboard system
*believes* and the sensor noise:

* a-priori pose per frame: position δt ~ N(0, diag σ_t²) (``apriori_position_sigma_m``, or the position
  block of ``apriori_cov``) and attitude δθ ~ N(0, σ_θ²) per camera axis (``apriori_attitude_sigma_deg``),
  drawn by :func:`renderlab.measurement.runner.draw_apriori`; the search distance is 3σ of its projection;
* camera knowledge (the pixel map, eq. 4): ``fx, fy ← (1+δf)·(fx, fy)``, ``(cx, cy) += δc`` and
  distortion ``k += δk`` — the estimator projects (eqs. 1–4) with the believed camera, the image was
  taken with the true one;
* Sun-direction knowledge: the estimator shades its templates (eq. 9 / SPC's shading) with a rotated Sun;
* landmark resolution: the maplets are rebuilt from the site DEM at ``spacing·(1+δs)`` (same centres and
  frames, fresh mapping error), so the GSD ratio of the run is ``gsd_ratio/(1+δs)``;
* sensor noise: the DN image is re-exposed from the cached radiance with the run's own Poisson + read noise
  (:func:`renderlab.sensor.model.expose`), so noise statistics are over independent realisations;
  ``[retina_vs_spc] sensor_noise = false`` measures the noise-free expected DN instead (rounded to integers,
  :func:`renderlab.sensor.model.expected_dn`; the switch of an error budget).

The a-priori pose is drawn around the run's (perturbed) true pose. All methods see the same image, the same
a-priori draw and the same believed camera/Sun/maplets. Truth (s, l) is ``landmark_truth.parquet`` of the
run's truth set (the true centre projected with the true camera and the run's true pose; occlusion-aware),
independent of the beliefs.

Breakdown columns: ``phase_deg``, ``gsd_ratio`` (image GSD / maplet spacing), ``shadow_fraction`` (truth
table), ``range_m`` (camera to landmark centre), ``albedo_contrast`` (Michelson contrast (p95−p5)/(p95+p5)
of the maplet's albedo) and the registration Cramér–Rao bound ``crlb_s``/``crlb_l`` (px) of the continuous truth over
the pixels the methods read (:mod:`renderlab.studies.retina_vs_spc.crlb_truth`: the truth rendered again at
:data:`~renderlab.studies.retina_vs_spc.crlb_truth.FINE_K` × FINE_K sub-pixels, cached like the truth, Retina's
template footprint at the true pose), with ``crlb_bound = "continuous"``; tables without that column (every
published one made before it) carry the finite-difference bound of the truth pixels over a square window
(:func:`renderlab.campaign.scoring.registration_crlb`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from renderlab import plugins
from renderlab.campaign.maplets import respaced_maplets
from renderlab.campaign.perturb import draw_perturbation, perturb_camera, perturb_sun
from renderlab.campaign.reexpose import ReexposedTruthSet
from renderlab.campaign.run_truth import run_truthset
from renderlab.campaign.scoring import dn_variance, registration_crlb
from renderlab.errors import UserError
from renderlab.files.truthset import TruthSet
from renderlab.measurement.runner import MeasureOptions, measure_truthset, onboard_photometry
from renderlab.scenario import scenario_from_dict, truth_dict
from renderlab.sensor.model import SensorOptions, expected_dn
from renderlab.studies.retina_vs_spc import crlb_truth as CT
from renderlab.studies.retina_vs_spc.config import RetinaVsSpcConfig
from renderlab.worlds.ev5.catalog import read_catalog


def truth_scenario_dict(sc_dict: dict) -> dict:
    """The nominal scenario (what is rendered): the campaign-only sections removed."""
    return truth_dict(sc_dict)


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
    """A truth set as the onboard system sees it: believed camera and Sun in the frame records
    (:func:`believed_record`), and the DN images re-exposed with this run's noise (one seed per frame,
    :class:`renderlab.campaign.reexpose.ReexposedTruthSet`, each frame's DN kept). What
    :func:`renderlab.measurement.runner.measure_truthset` reads (``path``, ``frames``, ``len``, ``load``,
    ``read_table``)."""

    no_radiance = "truth set {path}: retina_vs_spc needs a mono (radiance) truth set"

    def __init__(self, ts, draw, sensor_options, noise_seeds, *, noise: bool = True):
        super().__init__(ts, sensor_options, noise_seeds, cache=True)
        self.frames = [believed_record(rec, draw) for rec in ts.frames]
        self.noise = bool(noise)

    def load(self, i: int):
        """Frame ``i`` re-exposed with the run's noise, or (``noise`` false) its expected DN, rounded."""
        if self.noise:
            return super().load(i)
        import dataclasses


        fr = self._ts.load(i)
        if fr.radiance is None:
            raise UserError(self.no_radiance.format(path=self.path, i=i))
        dn = np.rint(expected_dn(np.asarray(fr.radiance, np.float64), self.sensor_options(i)))
        return dataclasses.replace(fr, dn=dn.astype(np.uint16))


def landmark_extras(ts, believed: BelievedTruthSet, maplets, truth: dict, fine) -> dict:
    """{(frame, landmark_id): (range_m, albedo_contrast, crlb_s, crlb_l)} from the truth images; the bound from
    ``fine``, the truth rendered at FINE_K × FINE_K sub-pixels (:mod:`.crlb_truth`), over the exact maplet's footprint,
    or, with ``fine=None``, the finite-difference bound of the truth pixels over a square window
    (:func:`window_crlb`, the bound of every table published before the continuous one)."""
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


def window_crlb(edn, var, s, l, g, maplet_size: int) -> tuple[float, float]:
    """Finite-difference registration bound of the truth pixels ``edn`` over a square window around (s, l) that spans
    the maplet at GSD ratio ``g`` (:func:`renderlab.campaign.scoring.registration_crlb`); NaN where undefined."""
    if not (np.isfinite(s) and np.isfinite(l) and g is not None and np.isfinite(g) and g > 0):
        return (math.nan, math.nan)
    half = int(max(3, math.ceil(0.5 * (maplet_size - 1) / g)))
    c0, r0 = int(round(s)), int(round(l))
    win = (slice(max(r0 - half, 0), min(r0 + half + 1, edn.shape[0])),
           slice(max(c0 - half, 0), min(c0 + half + 1, edn.shape[1])))
    if min(edn[win].shape) < 7:
        return (math.nan, math.nan)
    return registration_crlb(edn[win], var[win])


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
    import pyarrow as pa


    check(scenario)
    p = scenario.perturbations
    ss_pert, ss_apriori, ss_noise, ss_map = seed_sequence.spawn(4)
    draw = draw_perturbation(p, ss_pert)
    # the a-priori pose is drawn per frame inside measure_truthset around the (perturbed) true pose
    truth_sc = scenario_from_dict(truth_scenario_dict(scenario.to_dict()), "retina_vs_spc truth scenario")
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
