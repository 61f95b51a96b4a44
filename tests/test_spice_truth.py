"""SPICE truth: a leapseconds kernel from astropy when none is given, the sun from the kernels, light time and stellar
aberration on the positions, a missing PCK named as such.

Before the change: no LSK among the kernels was refused, the sun was ``[sun] direction`` whatever the kernels said,
positions were geometric only and a body-fixed frame without its PCK was reported as "outside the SPK coverage".

Oracles: astropy (UTC → TT, TDB; its leap-second table), spiceypy's own ``str2et``/``spkpos``/``spkgeo`` on an SPK the
test writes (``spkw09``: Sun and Earth about the barycentre, a spacecraft 10⁶ km from the Earth), and a Newtonian
light-time iteration written here from the geometric states."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

sp = pytest.importorskip("spiceypy")
from astropy.time import Time  # noqa: E402
from astropy.utils import iers  # noqa: E402

from renderlab.cli import main  # noqa: E402
from renderlab.errors import UserError  # noqa: E402
from renderlab.scenario import load_scenario, scenario_from_dict  # noqa: E402
from renderlab.trajectory_io.spice import read_spice  # noqa: E402
from renderlab.trajectory_io.timescales import LEAP_SECONDS, naif_lsk_text  # noqa: E402
from renderlab.worlds.base import make_plan  # noqa: E402

MONTHS = "JAN FEB MAR APR MAY JUN JUL AUG SEP OCT NOV DEC".split()
C_KM_S = 299792.458
AU_KM = 149597870.7
SC = -999
FK = f"KPL/FK\n\\begindata\nNAIF_BODY_NAME += ( 'RL_PROBE' )\nNAIF_BODY_CODE += ( {SC} )\n\\begintext\n"
# IAU 2009 Earth orientation (pck00010's BODY399 constants), enough for IAU_EARTH
PCK = ("KPL/PCK\n\\begindata\nBODY399_RADII = ( 6378.1366 6378.1366 6356.7519 )\n"
       "BODY399_POLE_RA = ( 0. -0.641 0. )\nBODY399_POLE_DEC = ( 90. -0.557 0. )\n"
       "BODY399_PM = ( 190.147 360.9856235 0. )\n\\begintext\n")
EPOCH = "2030-01-01T00:00:00"
TIMES = [0.0, 150.0, 300.0]


def astropy_lsk() -> str:
    """A NAIF LSK (naif0012.tls layout, D exponents) written here from astropy's IERS leap-second table."""
    table = iers.LeapSeconds.open(iers.IERS_LEAP_SECOND_FILE)
    rows = "\n".join(f"                           {int(r['tai_utc'])},   @{int(r['year'])}-"
                     f"{MONTHS[int(r['month']) - 1]}-{int(r['day'])}" for r in table)
    return ("KPL/LSK\n\n\\begindata\n\nDELTET/DELTA_T_A       =   32.184\nDELTET/K               =    1.657D-3\n"
            "DELTET/EB              =    1.671D-2\nDELTET/M               = (     6.239996D0   1.99096871D-7 )\n\n"
            f"DELTET/DELTA_AT        = ({rows.lstrip()} )\n\n\\begintext\n")


EPOCHS = ["1972-06-30T23:59:59.5", "1972-07-01T00:00:00", "1999-12-31T23:59:59.999", "2005-12-31T23:59:60.25",
          "2016-12-31T23:59:59", "2017-01-01T00:00:00", "2024-06-21T10:00:00.123456", "2030-01-01T00:00:00",
          "2045-03-01T06:00:00"]


def _str2et(kernel_path) -> np.ndarray:
    sp.furnsh(str(kernel_path))
    try:
        return np.array([sp.str2et(e) for e in EPOCHS])
    finally:
        sp.unload(str(kernel_path))


@pytest.mark.filterwarnings("ignore:ERFA function")  # 2045: "dubious year" (leap seconds not yet known), as meant
def test_generated_lsk_is_the_naif_lsk_of_astropys_table(tmp_path):
    """The LSK the lab writes gives str2et identical to a NAIF-layout LSK written here from astropy's table; UTC → TT
    is astropy's to < 1 µs and TDB − TT is SPICE's K·sin E; astropy's full TDB is within 30 µs (SPICE's two-term
    model); the lab's own leap-second list is astropy's."""
    (tmp_path / "lab.tls").write_text(naif_lsk_text())
    (tmp_path / "ref.tls").write_text(astropy_lsk())
    lab, ref = _str2et(tmp_path / "lab.tls"), _str2et(tmp_path / "ref.tls")
    assert np.abs(lab - ref).max() < 1e-9
    tt = Time(EPOCHS, scale="utc").tt
    tt_sec = (tt.jd1 - 2451545.0) * 86400.0 + tt.jd2 * 86400.0
    m = 6.239996 + 1.99096871e-7 * lab
    tdb_tt = 1.657e-3 * np.sin(m + 1.671e-2 * np.sin(m))
    assert np.abs(lab - tdb_tt - tt_sec).max() < 1e-6
    tdb = Time(EPOCHS, scale="utc").tdb
    full = (tdb.jd1 - 2451545.0) * 86400.0 + tdb.jd2 * 86400.0
    print(f"str2et - astropy TDB: max {np.abs(lab - full).max() * 1e6:.1f} us")
    assert np.abs(lab - full).max() < 30e-6
    table = iers.LeapSeconds.open(iers.IERS_LEAP_SECOND_FILE)
    assert [(int(r["year"]), int(r["month"]), int(r["day"]), int(r["tai_utc"])) for r in table] == list(LEAP_SECONDS)


def _states(et, t0):
    """Geometric states (km, km/s) about the barycentre: Sun, Earth (1 AU circle), probe relative to the Earth."""
    dt = et - t0
    sun = np.array([7.0e5 + 0.012 * dt, -3.0e5 + 0.008 * dt, 1.0e4, 0.012, 0.008, 0.0])
    w = 2 * math.pi / (365.25 * 86400.0)
    earth = AU_KM * np.array([math.cos(w * dt + 1.0), math.sin(w * dt + 1.0), 0.0,
                              -w * math.sin(w * dt + 1.0), w * math.cos(w * dt + 1.0), 0.0])
    probe = np.array([1.0e6 + 0.5 * dt, 2.0e5 + 1.1 * dt, 5.0e4 - 0.2 * dt, 0.5, 1.1, -0.2])
    return sun, earth, probe


@pytest.fixture(scope="module")
def kernels(tmp_path_factory):
    d = tmp_path_factory.mktemp("spice_truth")
    (d / "probe.tf").write_text(FK)
    (d / "earth.tpc").write_text(PCK)
    (d / "ref.tls").write_text(astropy_lsk())
    sp.furnsh(str(d / "ref.tls"))
    try:
        t0 = sp.str2et(EPOCH)
        ets = t0 + np.arange(-1200.0, 1201.0, 100.0)
        rows = np.array([_states(et, t0) for et in ets])
        h = sp.spkopn(str(d / "system.bsp"), "renderlab test", 0)
        for body, center, k in ((10, 0, 0), (399, 0, 1), (SC, 399, 2)):
            sp.spkw09(h, body, center, "J2000", ets[0], ets[-1], "seg", 7, len(ets), np.ascontiguousarray(rows[:, k]), ets)
        sp.spkcls(h)
        h = sp.spkopn(str(d / "nosun.bsp"), "renderlab test", 0)
        for body, center, k in ((399, 0, 1), (SC, 399, 2)):
            sp.spkw09(h, body, center, "J2000", ets[0], ets[-1], "seg", 7, len(ets), np.ascontiguousarray(rows[:, k]), ets)
        sp.spkcls(h)
    finally:
        sp.unload(str(d / "ref.tls"))
    return d


def _scene(d, kernel_names, aberration="NONE", frame="J2000", sun_source="spice", name="probe.toml"):
    text = f"""[world]
kind = "analytic"
[[world.bodies]]
name = "earth"
shape = "sphere"
radius_m = 6378136.6
[sun]
source = "{sun_source}"
[camera]
width = 32
height = 24
fov_deg = 2.0
[render]
near_clip_m = 1.0
far_clip_m = 1e12
[trajectory]
kind = "spice"
kernels = {json.dumps(kernel_names)}
observer = "RL_PROBE"
center = "EARTH"
frame = "{frame}"
epoch_utc = "{EPOCH}Z"
times_s = {TIMES}
attitude = "look_at"
target_m = [0.0, 0.0, 0.0]
aberration = "{aberration}"
"""
    (d / name).write_text(text)
    return d / name


def _spice_ref(d, fn):
    names = [d / "ref.tls", d / "probe.tf", d / "earth.tpc", d / "system.bsp"]
    for n in names:
        sp.furnsh(str(n))
    try:
        tt0 = sp.unitim(sp.str2et(EPOCH), "TDB", "TDT")  # frame times: SI seconds on the TT scale
        return fn(np.array([sp.unitim(tt0 + t, "TDT", "TDB") for t in TIMES]))
    finally:
        for n in names:
            sp.unload(str(n))


@pytest.mark.parametrize("aberration", ["NONE", "LT", "LT+S"])
def test_positions_and_sun_with_aberration_match_spkpos(kernels, aberration):
    """No LSK in the scenario (the lab writes one); positions are the camera relative to the Earth it sees, the sun the
    Sun from that Earth, as spiceypy's spkpos computes them with the same correction (< 1 mm, < 1e-12 rad)."""
    sc, base = load_scenario(_scene(kernels, ["probe.tf", "system.bsp"], aberration))
    specs = make_plan(sc, base).frames
    pos = np.array([s.pose.position_m for s in specs])
    sun = np.array([s.sun.direction_render for s in specs])
    irr = np.array([s.sun.irradiance_w_m2 for s in specs])

    def ref(ets):
        out_p, out_s = [], []
        for et in ets:
            p, lt = sp.spkpos("EARTH", et, "J2000", aberration, "RL_PROBE")
            et_c = et if aberration == "NONE" else et - lt  # spkpos returns the light time under NONE too
            s, _ = sp.spkpos("SUN", et_c, "J2000", aberration, "EARTH")
            out_p.append(-np.asarray(p) * 1e3)
            out_s.append(np.asarray(s) * 1e3)
        return np.array(out_p), np.array(out_s)

    p_ref, s_ref = _spice_ref(kernels, ref)
    assert np.abs(pos - p_ref).max() < 1e-3
    d_ref = s_ref / np.linalg.norm(s_ref, axis=1, keepdims=True)
    assert np.abs(sun - d_ref).max() < 1e-12
    assert np.allclose(irr, 1361.0 * (AU_KM * 1e3 / np.linalg.norm(s_ref, axis=1)) ** 2, rtol=1e-12)
    geo = _spice_ref(kernels, lambda ets: np.array([sp.spkpos("RL_PROBE", et, "J2000", "NONE", "EARTH")[0]
                                                    for et in ets]) * 1e3)
    shift = np.linalg.norm(pos - geo, axis=1).max()
    print(f"{aberration}: camera shift from the geometric position {shift / 1e3:.1f} km")
    assert (shift == 0.0) if aberration == "NONE" else (shift > 50e3)


def test_light_time_is_the_newtonian_light_time_of_the_geometric_states(kernels):
    """LT positions against a light-time solution written here from spkgeo's barycentric states: SPICE's ``LT`` is one
    Newtonian step (lt₀ = |T(t) − O(t)|/c, the target at t − lt₀: T(t − lt₀) − O(t)): |Δ| < 1 mm; the converged
    solution differs by metres (printed; SPICE's ``CN`` would be the converged one)."""
    sc, base = load_scenario(_scene(kernels, ["probe.tf", "system.bsp"], "LT", name="lt.toml"))
    pos = np.array([s.pose.position_m for s in make_plan(sc, base).frames])

    def newton(iterations):
        def solve(ets):
            out = []
            for et in ets:
                obs = np.asarray(sp.spkgeo(SC, et, "J2000", 0)[0][:3])
                lt = np.linalg.norm(np.asarray(sp.spkgeo(399, et, "J2000", 0)[0][:3]) - obs) / C_KM_S
                for _ in range(iterations):
                    lt = np.linalg.norm(np.asarray(sp.spkgeo(399, et - lt, "J2000", 0)[0][:3]) - obs) / C_KM_S
                out.append((obs - np.asarray(sp.spkgeo(399, et - lt, "J2000", 0)[0][:3])) * 1e3)
            return np.array(out)
        return solve

    assert np.abs(pos - _spice_ref(kernels, newton(0))).max() < 1e-3
    converged = np.abs(pos - _spice_ref(kernels, newton(6))).max()
    print(f"LT (one Newtonian step) - converged light time: {converged:.2f} m")
    assert 0.1 < converged < 20.0


def test_body_fixed_frame_without_its_pck_is_named_a_missing_pck(kernels, capsys):
    """Fails before the change ("outside the SPK coverage"); with the PCK the same scenario reads, light time and
    the frame at et − lt included (pxfrm2), as spkpos gives it."""
    path = _scene(kernels, ["probe.tf", "system.bsp"], "LT", frame="IAU_EARTH", sun_source="direction",
                  name="pck.toml")
    assert main(["show", str(path)]) == 0
    capsys.readouterr()
    sc, base = load_scenario(path)
    with pytest.raises(UserError, match=r"frame 0 at 2030-01-01T00:00:00.000Z: a body-fixed frame has no orientation "
                                        r"data — add the PCK .* to trajectory.kernels \(SPICE\(FRAMEDATANOTFOUND\)")\
            as info:
        _ = make_plan(sc, base).frames    # the frames are planned lazily: reading them raises
    assert "coverage" not in str(info.value) and "\n" not in str(info.value)
    sc, base = load_scenario(_scene(kernels, ["probe.tf", "earth.tpc", "system.bsp"], "LT", frame="IAU_EARTH",
                                    sun_source="direction", name="pck2.toml"))
    pos = np.array([s.pose.position_m for s in make_plan(sc, base).frames])
    ref = _spice_ref(kernels, lambda ets: np.array([-np.asarray(sp.spkpos("EARTH", et, "IAU_EARTH", "LT",
                                                                          "RL_PROBE")[0]) for et in ets]) * 1e3)
    assert np.abs(pos - ref).max() < 1e-3


def test_sun_source_refusals_are_one_line(kernels):
    sc, base = load_scenario(_scene(kernels, ["probe.tf", "nosun.bsp"], name="nosun.toml"))
    with pytest.raises(UserError, match=r"frame 0 at .*: sun.source = \"spice\" needs the Sun relative to 'EARTH' in "
                                        r"the SPKs"):
        _ = make_plan(sc, base).frames    # the frames are planned lazily: reading them raises
    with pytest.raises(UserError, match=r"sun.source = \"spice\" needs world.kind 'analytic' and trajectory.kind "
                                        r"'spice' \(got 'analytic' / 'orbit'"):
        scenario_from_dict({"world": {"kind": "analytic", "bodies": [{"name": "s", "shape": "sphere",
                                                                      "radius_m": 1.0}]},
                            "sun": {"source": "spice"}})
    with pytest.raises(UserError, match="kind 'ccsds' does not use 'aberration'"):
        scenario_from_dict({"world": {"kind": "analytic", "bodies": [{"name": "s", "shape": "sphere",
                                                                      "radius_m": 1.0}]},
                            "trajectory": {"kind": "ccsds", "oem": "x.oem", "aberration": "LT"}})
    sc, _ = load_scenario(_scene(kernels, ["probe.tf", "system.bsp"], "LT+S", name="rt.toml"))
    assert scenario_from_dict(sc.to_dict()).to_dict() == sc.to_dict()  # a manifest's scenario reloads as it was


def test_read_spice_without_lsk_equals_with_one(kernels):
    args = dict(observer="RL_PROBE", center="EARTH", frame="J2000", camera_frame=None, epoch_utc=EPOCH,
                times_s=TIMES)
    without = read_spice([kernels / "probe.tf", kernels / "system.bsp"], **args)
    with_ref = read_spice([kernels / "ref.tls", kernels / "probe.tf", kernels / "system.bsp"], **args)
    assert np.array_equal(without.positions_m, with_ref.positions_m) and without.epoch0 == with_ref.epoch0
    assert sp.ktotal("ALL") == 0  # everything unloaded, the generated LSK included
