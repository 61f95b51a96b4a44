"""A headless Basilisk closed loop with renderlab as the camera: Mars orbit → renderlab camera → ``houghCircles`` →
``pixelLineConverter`` → ``relativeODuKF``, the filter scored against Basilisk's own truth.

Full size (512² images, 16 spp, 90 camera steps of 60 s: 1.5 h of a 8.4 h orbit, about two minutes)::

    .venv/bin/python examples/basilisk_mars_opnav.py

Tiny (what ``tests/test_basilisk_camera.py`` runs)::

    .venv/bin/python examples/basilisk_mars_opnav.py --size 64 --steps 4 --spp 1

What runs (Basilisk 2.12, the ``basilisk`` extra: ``bsk`` + ``bsk-opnav``):

* dynamics (10 s task): a rigid ``spacecraft`` in Mars' point-mass gravity (``gravBodyFactory.createMars``, central
  body), on a circular orbit of 10 000 km radius (inclination 35°); it points its camera at Mars by spinning about
  its orbit normal at the orbit rate (a torque-free spin about the largest principal axis: the camera stays on the
  nadir); ``simpleNav`` (no noise) gives the attitude ``pixelLineConverter`` uses; a small module writes Mars' state
  (at the origin, turning about the IAU pole at its sidereal rate: ``J20002Pfix`` from the IAU 2015 elements,
  Archinal et al. 2018, doi:10.1007/s10569-017-9805-5); the Sun is a fixed message 1.524 AU away, placed so the
  phase angle starts at 31° and passes 10°;
* camera (60 s task, in priority order): ``RenderlabCamera`` (the ``planet`` world's Mars, ``basilisk_mars_opnav.toml``:
  55° field of view, the lab's sensor model with per-frame auto exposure, an 8-bit PNG in ``CameraImageMsg``) →
  ``houghCircles`` → ``pixelLineConverter`` (camera config from the renderlab camera, mount ``sigma_CB``: boresight
  along the body's x axis) → ``relativeODuKF`` (the tuning of Basilisk's ``scenario_OpNavOD``: α = 0.02, β = 2,
  κ = 0, noiseSF = 7.5, its process noise), started at the truth plus a draw from its own initial covariance
  (seeded).

Printed per camera step: the Hough circle's centre and radius against the lab's truth limb conic (the planet world's
``centre_truth`` of the rendered pose), the range error of ``pixelLineConverter``, the filter's position error and
its NEES (6 states, against Basilisk's spacecraft state); then the time average of that one run's NEES — successive
NEES of one run are correlated, so its band ``[χ²₆ₙ(0.025), χ²₆ₙ(0.975)]/n`` (n steps) is no test.

The consistency test is ``--runs N`` (:func:`monte_carlo`): N independent runs (seeds ``seed … seed+N−1``: render,
sensor noise and the filter's initial error), the NEES of each step averaged over the runs, ANEES_k, against the
two-sided 95 % band of N independent 6-dof values ``[χ²₆N(0.025), χ²₆N(0.975)]/N``, PASS/FAIL per step::

    .venv/bin/python examples/basilisk_mars_opnav.py --size 256 --steps 30 --runs 8 --spp 4
    .venv/bin/python examples/basilisk_mars_opnav.py --size 256 --steps 30 --runs 8 --spp 4 --noise-sf 1
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SCENARIO = HERE / "basilisk_mars_opnav.toml"
AU_M = 1.495978707e11
#: Mars' IAU 2015 rotation elements: pole right ascension and declination (J2000), prime meridian at J2000, rate
MARS_POLE_RA_DEG, MARS_POLE_DEC_DEG, MARS_W0_DEG, MARS_RATE_DEG_DAY = 317.68143, 52.88650, 176.630, 350.89198226


@dataclass
class Options:
    """The loop's settings (the command line's)."""

    size: int = 512
    steps: int = 90
    dt_camera_s: float = 60.0
    dt_dynamics_s: float = 10.0
    spp: int = 16
    fov_deg: float = 55.0
    radius_m: float = 10.0e6
    inclination_deg: float = 35.0
    sigma_r0_m: float = 100.0e3
    sigma_v0_mps: float = 10.0
    noise_sf: float = 7.5
    seed: int = 0


@dataclass
class Result:
    """Per camera step: the rows printed; the ANEES and its band."""

    rows: list = field(default_factory=list)
    anees: float = math.nan
    band: tuple = (math.nan, math.nan)
    n_valid_circles: int = 0


def mars_state_class():
    """A Python SysModel writing Mars' ``SpicePlanetStateMsg``: at the origin, ``J20002Pfix`` = 3-1-3 rotation
    (α₀ + 90°, 90° − δ₀, W₀ + Ẇ t)."""
    from Basilisk.architecture import messaging, sysModel
    from Basilisk.utilities import RigidBodyKinematics as rbk

    class MarsState(sysModel.SysModel):
        def __init__(self):
            super().__init__()
            self.planetOutMsg = messaging.SpicePlanetStateMsg()

        def payload(self, t_s: float):
            p = messaging.SpicePlanetStateMsgPayload()
            w = math.radians(MARS_W0_DEG + MARS_RATE_DEG_DAY * t_s / 86400.0)
            p.J20002Pfix = rbk.euler3132C([math.radians(MARS_POLE_RA_DEG + 90.0),
                                           math.radians(90.0 - MARS_POLE_DEC_DEG), w]).tolist()
            p.PositionVector, p.J2000Current, p.computeOrient, p.PlanetName = [0.0, 0.0, 0.0], t_s, 1, "mars"
            return p

        def Reset(self, CurrentSimNanos=0):
            self.planetOutMsg.write(self.payload(CurrentSimNanos * 1e-9), CurrentSimNanos, self.moduleID)

        def UpdateState(self, CurrentSimNanos):
            self.planetOutMsg.write(self.payload(CurrentSimNanos * 1e-9), CurrentSimNanos, self.moduleID)

    return MarsState


def initial_state(opts: Options, mu: float):
    """(r, v, [BN], ω_B, sun position): the circular orbit, the nadir-pointing body frame (b1 nadir, b3 orbit
    normal), its spin, and the Sun 10° out of the orbit plane, 30° ahead of the spacecraft."""
    from Basilisk.utilities import orbitalMotion

    oe = orbitalMotion.ClassicElements()
    oe.a, oe.e, oe.i, oe.Omega, oe.omega, oe.f = opts.radius_m, 0.0, math.radians(opts.inclination_deg), \
        math.radians(20.0), 0.0, 0.0
    r, v = (np.asarray(x, float).reshape(3) for x in orbitalMotion.elem2rv(mu, oe))
    rh = r / np.linalg.norm(r)
    h = np.cross(r, v)
    h /= np.linalg.norm(h)
    th = np.cross(h, rh)
    BN = np.vstack([-rh, np.cross(h, -rh), h])
    n = math.sqrt(mu / opts.radius_m**3)
    beta, phi = math.radians(10.0), math.radians(30.0)
    sun = 1.524 * AU_M * (math.cos(beta) * (math.cos(phi) * rh + math.sin(phi) * th) + math.sin(beta) * h)
    return r, v, BN, np.array([0.0, 0.0, n]), sun


def build(opts: Options):
    """The simulation and its modules (a dict)."""
    from Basilisk.architecture import messaging
    from Basilisk.fswAlgorithms import houghCircles, pixelLineConverter
    from Basilisk.simulation import simpleNav, spacecraft
    from Basilisk.utilities import SimulationBaseClass, macros, simIncludeGravBody

    from renderlab import Renderer
    from renderlab.basilisk import frames
    from renderlab.basilisk.camera import RenderlabCamera

    sim = SimulationBaseClass.SimBaseClass()
    dyn = sim.CreateNewProcess("dynamics", 10)
    dyn.addTask(sim.CreateNewTask("dynTask", macros.sec2nano(opts.dt_dynamics_s)))
    fsw = sim.CreateNewProcess("camera", 5)
    fsw.addTask(sim.CreateNewTask("camTask", macros.sec2nano(opts.dt_camera_s)))
    m = {"sim": sim, "gravity": simIncludeGravBody.gravBodyFactory()}
    mars = m["gravity"].createMars()
    mars.isCentralBody = True
    r, v, BN, w, sun = initial_state(opts, mars.mu)
    sc = m["sc"] = spacecraft.Spacecraft()
    sc.ModelTag = "opnavSat"
    sc.hub.mHub, sc.hub.IHubPntBc_B = 500.0, np.diag([600.0, 800.0, 900.0]).tolist()  # spin axis b3: largest
    sc.hub.r_CN_NInit, sc.hub.v_CN_NInit = r.tolist(), v.tolist()
    sc.hub.sigma_BNInit, sc.hub.omega_BN_BInit = frames.dcm_to_mrp(BN).tolist(), w.tolist()
    m["gravity"].addBodiesTo(sc)
    nav = m["nav"] = simpleNav.SimpleNav()
    nav.scStateInMsg.subscribeTo(sc.scStateOutMsg)
    planet = m["planet"] = mars_state_class()()
    sun_payload = messaging.SpicePlanetStateMsgPayload()
    sun_payload.PositionVector, sun_payload.PlanetName = sun.tolist(), "sun"
    m["sun"] = messaging.SpicePlanetStateMsg().write(sun_payload)
    for k, mod in enumerate((sc, nav, planet)):
        mod.ModelTag = mod.ModelTag or f"dyn{k}"
        sim.AddModelToTask("dynTask", mod, 100 - k)
    m["renderer"] = Renderer(SCENARIO, overrides=[f"render.spp={opts.spp}"], seed=opts.seed)
    sigma_CB = frames.dcm_to_mrp(np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]))  # c3 = b1 (nadir)
    cam = m["camera"] = RenderlabCamera(m["renderer"], fieldOfView=math.radians(opts.fov_deg),
                                        resolution=(opts.size, opts.size), sigma_CB=sigma_CB, cameraID=1)
    cam.scStateInMsg.subscribeTo(sc.scStateOutMsg)
    cam.planetInMsg.subscribeTo(planet.planetOutMsg)
    cam.sunInMsg.subscribeTo(m["sun"])
    hough = m["hough"] = houghCircles.HoughCircles()
    hough.imageInMsg.subscribeTo(cam.imageOutMsg)
    hough.expectedCircles, hough.cannyThresh, hough.voteThresh, hough.houghMinDist = 1, 200, 20, 50
    hough.houghMinRadius, hough.houghMaxRadius, hough.blurrSize, hough.dpValue = opts.size // 16, 0, 3, 1
    hough.noiseSF = 0.5  # scenario_OpNavOD's: the circle's variance is noiseSF · votes / voteThresh (px²)
    pix = m["pixelLine"] = pixelLineConverter.pixelLineConverter()
    pix.circlesInMsg.subscribeTo(hough.opnavCirclesOutMsg)
    pix.cameraConfigInMsg.subscribeTo(cam.cameraConfigOutMsg)
    pix.attInMsg.subscribeTo(nav.attOutMsg)
    pix.planetTarget = 2
    m["filter"] = make_filter(opts, pix, r, v)
    for k, (name, mod) in enumerate((("renderlab", cam), ("hough", hough), ("pixelLine", pix),
                                     ("relativeOD", m["filter"]))):
        mod.ModelTag = name
        sim.AddModelToTask("camTask", mod, 100 - 10 * k)
    return m


def make_filter(opts: Options, pix, r, v):
    """``relativeODuKF`` with Basilisk's ``scenario_OpNavOD`` tuning, started at the truth plus a seeded draw from
    its initial covariance."""
    from Basilisk.fswAlgorithms import relativeODuKF

    f = relativeODuKF.relativeODuKF()
    f.opNavInMsg.subscribeTo(pix.opNavOutMsg)
    f.planetIdInit, f.alpha, f.beta, f.kappa, f.noiseSF = 2, 0.02, 2.0, 0.0, opts.noise_sf
    P0 = np.diag([opts.sigma_r0_m**2] * 3 + [opts.sigma_v0_mps**2] * 3)
    x0 = np.concatenate([r, v]) + np.random.default_rng(opts.seed).multivariate_normal(np.zeros(6), P0)
    f.stateInit, f.covarInit = x0.tolist(), P0.reshape(-1).tolist()
    q = np.diag([1e-3**2] * 3 + [1e-4**2] * 3)  # km², km²/s² per update (the filter's internal units)
    f.qNoise = q.reshape(-1).tolist()
    return f


def step_row(m, k: int, t_s: float) -> dict:
    """One camera step's numbers: Hough vs the truth limb conic, measured range, filter error and NEES."""
    sc = m["sc"].scStateOutMsg.read()
    x_true = np.concatenate([np.asarray(sc.r_BN_N, float), np.asarray(sc.v_BN_N, float)])  # Mars at the origin
    filt = m["filter"].filtDataOutMsg.read()
    x, P = np.asarray(filt.state, float), np.asarray(filt.covar, float).reshape(6, 6)
    e = x - x_true
    circles, opnav = m["hough"].opnavCirclesOutMsg.read(), m["pixelLine"].opNavOutMsg.read()
    truth = m["camera"].last_frame.truth["centre_truth"][0]
    valid = bool(circles.valid) and int(circles.timeTag) == int(round(t_s * 1e9))
    row = {"step": k, "t_s": t_s, "phase_deg": truth["phase_deg"], "circle": valid,
           "ds_px": math.nan, "dl_px": math.nan, "dr_px": math.nan, "range_err_m": math.nan, "meas_sig_m": math.nan,
           "pos_err_m": float(np.linalg.norm(e[:3])), "vel_err_mps": float(np.linalg.norm(e[3:])),
           "sig_pos_m": float(math.sqrt(np.trace(P[:3, :3]))), "nees": float(e @ np.linalg.solve(P, e))}
    if valid:
        row.update(ds_px=circles.circlesCenters[0] - truth["limb_centre_s"],
                   dl_px=circles.circlesCenters[1] - truth["limb_centre_l"],
                   dr_px=circles.circlesRadii[0] - truth["apparent_radius_px"])
    if valid and opnav.valid:
        row["range_err_m"] = float(np.linalg.norm(opnav.r_BN_N) - truth["range_m"])
        row["meas_sig_m"] = float(math.sqrt(np.trace(np.asarray(opnav.covar_N, float).reshape(3, 3))))
    return row


def run(opts: Options, out=None) -> Result:
    """Run the loop (``opts.steps`` camera steps) and score the filter; prints the rows to ``out`` if given."""
    from Basilisk.utilities import macros
    from scipy.stats import chi2

    m = build(opts)
    m["sim"].InitializeSimulation()
    res = Result()
    if out is not None:
        print(" step    t_s  phase  circle   ds_px   dl_px   dr_px  range_err_km  meas_sig_km  pos_err_km  sig_pos_km"
              "    NEES",
              file=out)
    for k in range(opts.steps):
        t_s = k * opts.dt_camera_s
        m["sim"].ConfigureStopTime(macros.sec2nano(t_s))
        m["sim"].ExecuteSimulation()
        row = step_row(m, k, t_s)
        res.rows.append(row)
        if out is not None:
            print(f"{k:5d} {t_s:6.0f} {row['phase_deg']:6.1f} {'yes' if row['circle'] else 'no':>7} "
                  f"{row['ds_px']:+7.2f} {row['dl_px']:+7.2f} {row['dr_px']:+7.2f} {row['range_err_m'] / 1e3:+13.2f} "
                  f"{row['meas_sig_m'] / 1e3:12.2f} "
                  f"{row['pos_err_m'] / 1e3:11.2f} {row['sig_pos_m'] / 1e3:11.2f} {row['nees']:7.2f}", file=out)
    m["renderer"].close()
    nees = np.array([r["nees"] for r in res.rows])
    n = len(nees)
    res.anees = float(nees.mean())
    res.band = (float(chi2.ppf(0.025, 6 * n) / n), float(chi2.ppf(0.975, 6 * n) / n))
    res.n_valid_circles = sum(r["circle"] for r in res.rows)
    if out is not None:
        inside = res.band[0] <= res.anees <= res.band[1]
        print(f"circles found in {res.n_valid_circles} of {n} images; ANEES {res.anees:.2f} over {n} steps "
              f"(6 states), 95 % chi-square band [{res.band[0]:.2f}, {res.band[1]:.2f}]: "
              f"{'inside' if inside else 'outside'} (one run's correlated steps: no test; use --runs N)", file=out)
    return res


@dataclass
class MonteCarlo:
    """Per step: ANEES over the runs and its band; the share of steps inside it; the mean of the ANEES over steps."""

    anees: np.ndarray
    band: tuple
    inside: np.ndarray
    runs: int


def monte_carlo(opts: Options, runs: int, out=None) -> MonteCarlo:
    """``runs`` independent runs (seeds ``opts.seed + k``), NEES per step averaged over runs (module docstring)."""
    from scipy.stats import chi2

    results = [run(Options(**{**opts.__dict__, "seed": opts.seed + k})) for k in range(runs)]
    nees = np.array([[r["nees"] for r in res.rows] for res in results])
    err = np.array([[r["pos_err_m"] for r in res.rows] for res in results])
    sig = np.array([[r["sig_pos_m"] for r in res.rows] for res in results])
    anees = nees.mean(axis=0)
    band = (float(chi2.ppf(0.025, 6 * runs) / runs), float(chi2.ppf(0.975, 6 * runs) / runs))
    inside = (anees >= band[0]) & (anees <= band[1])
    if out is not None:
        for k, (a, ok) in enumerate(zip(anees, inside)):
            print(f"step {k:3d}  ANEES over {runs} runs {a:9.3f}  {'PASS' if ok else 'FAIL'}", file=out)
        print(f"{runs} runs, noiseSF {opts.noise_sf:g}: ANEES per step inside the 95 % chi-square band "
              f"[{band[0]:.2f}, {band[1]:.2f}] at {int(inside.sum())} of {len(anees)} steps; median ANEES "
              f"{float(np.median(anees)):.3g}, last step {anees[-1]:.3g}; position error RMS over runs "
              f"{np.sqrt(np.mean(err[:, 0] ** 2)) / 1e3:.1f} km at the first step, "
              f"{np.sqrt(np.mean(err[:, -1] ** 2)) / 1e3:.1f} km at the last, the filter's own 1σ (√trace, mean) "
              f"{sig[:, 0].mean() / 1e3:.1f} → {sig[:, -1].mean() / 1e3:.1f} km", file=out)
    return MonteCarlo(anees=anees, band=band, inside=inside, runs=runs)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    d = Options()
    p.add_argument("--size", type=int, default=d.size, help="image width and height, px (default %(default)s)")
    p.add_argument("--steps", type=int, default=d.steps, help="camera steps (default %(default)s)")
    p.add_argument("--dt", type=float, default=d.dt_camera_s, help="camera step, s (default %(default)s)")
    p.add_argument("--spp", type=int, default=d.spp, help="samples per pixel (default %(default)s)")
    p.add_argument("--seed", type=int, default=d.seed, help="seed of the render, the sensor noise and the filter's "
                   "initial error (default %(default)s)")
    p.add_argument("--runs", type=int, default=1, help="independent runs; > 1: ANEES per step over the runs with its "
                   "chi-square band (default %(default)s)")
    p.add_argument("--noise-sf", type=float, default=d.noise_sf, help="relativeODuKF noiseSF (default %(default)s, "
                   "Basilisk's scenario_OpNavOD; 1: the measurement covariance as pixelLineConverter states it)")
    a = p.parse_args(argv)
    if a.size < 16 or a.steps < 1 or a.dt <= 0 or a.spp < 1 or a.seed < 0 or a.runs < 1 or not a.noise_sf > 0:
        p.error("--size >= 16, --steps >= 1, --dt > 0, --spp >= 1, --seed >= 0, --runs >= 1, --noise-sf > 0")
    opts = Options(size=a.size, steps=a.steps, dt_camera_s=a.dt, spp=a.spp, seed=a.seed, noise_sf=a.noise_sf)
    if a.runs > 1:
        monte_carlo(opts, a.runs, out=sys.stdout)
    else:
        run(opts, out=sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
