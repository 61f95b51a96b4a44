"""Frame epochs of UTC inputs are exact: frame times are SI seconds on the TT scale (as UTC counts them), so a UTC
OEM sampled every minute gives frames on its own samples, labelled ``13:00:00.000000Z`` — not ``12:59:59.999999Z``,
1.2 µs (9 mm at 7.5 km/s) early, as when frame times were TDB seconds.

Oracles: the OEM is written by the ``oem`` package from astropy ``Time`` stamps; astropy's UTC arithmetic (TAI
seconds) for the labels; spiceypy's ``unitim`` (TDT ↔ TDB) for the TDB the lab hands SPICE."""

from __future__ import annotations

from datetime import datetime, timedelta

import numpy as np
import pytest

from renderlab.scenario import load_scenario
from renderlab.trajectory_io import read_oem, write_oem
from renderlab.trajectory_io.sources import frame_poses
from renderlab.trajectory_io.timescales import parse_epoch

pytest.importorskip("oem")

START = "2024-06-21T12:00:00"
STEP, N = 60.0, 121  # 12:00 to 14:00 UTC


def _states(t):
    w = 7.5e3 / 7.0e6
    return np.stack([7.0e6 * np.cos(w * t), 7.0e6 * np.sin(w * t), 1e3 + 0 * t,
                     -7.5e3 * np.sin(w * t), 7.5e3 * np.cos(w * t), 0 * t], 1)


def _stamps():
    t0 = datetime.fromisoformat(START)
    return [(t0 + timedelta(seconds=STEP * k)).isoformat(timespec="microseconds") for k in range(N)]


def _write_oem_package(path):
    from astropy.time import Time
    from oem import OrbitEphemerisMessage
    from oem.components import EphemerisSegment, HeaderSection, MetaDataSection

    stamps = _stamps()
    meta = MetaDataSection({"OBJECT_NAME": "SAT", "OBJECT_ID": "2024-000A", "CENTER_NAME": "EARTH",
                            "REF_FRAME": "GCRF", "TIME_SYSTEM": "UTC", "START_TIME": stamps[0],
                            "STOP_TIME": stamps[-1]}, version="2.0")
    x = _states(STEP * np.arange(N)) / 1e3
    seg = EphemerisSegment(meta, (tuple(Time(stamps, scale="utc")), *(tuple(c) for c in x.T)), version="2.0")
    OrbitEphemerisMessage(HeaderSection({"CCSDS_OEM_VERS": "2.0", "CREATION_DATE": START, "ORIGINATOR": "test"}),
                          [seg]).save_as(str(path))


def test_frames_of_a_utc_oem_land_on_its_samples_with_exact_labels(tmp_path):
    """Fails before the change: frame 60 (3600 s) was labelled 12:59:59.999999Z and sat 1.2 µs before the 13:00
    sample."""
    _write_oem_package(tmp_path / "orbit.oem")
    (tmp_path / "leo.toml").write_text(
        '[world]\nkind = "analytic"\n[[world.bodies]]\nname = "s"\nshape = "sphere"\nradius_m = 6.0e6\n'
        f'[trajectory]\nkind = "ccsds"\noem = "orbit.oem"\nframes = {N}\ndt_s = {STEP}\nattitude = "look_at"\n'
        'interpolation = "linear"\n')
    sc, base = load_scenario(tmp_path / "leo.toml")
    fp = frame_poses(sc.trajectory, base)
    want = [s + "Z" for s in _stamps()]
    assert fp.epochs_utc == want
    assert np.abs(fp.positions_m - _states(STEP * np.arange(N))[:, :3]).max() < 1e-6  # on the samples


def test_oem_round_trip_keeps_every_epoch_text(tmp_path):
    _write_oem_package(tmp_path / "a.oem")
    s = read_oem(tmp_path / "a.oem")
    assert np.abs(s.times_s - STEP * np.arange(N)).max() < 1e-9  # SI seconds between the UTC stamps
    write_oem(tmp_path / "b.oem", s)
    again = read_oem(tmp_path / "b.oem")
    lines = [ln.split()[0] for ln in (tmp_path / "b.oem").read_text().splitlines() if ln[:4] == "2024"]
    assert lines == [st + "000" for st in _stamps()]  # 9 decimals, every one exact
    assert np.array_equal(again.times_s, s.times_s)


@pytest.mark.filterwarnings("ignore:ERFA function")  # 2030: "dubious year" (future leap seconds unknown), as meant
def test_labels_agree_with_astropy_and_spice_across_years(tmp_path):
    """UTC + seconds: the lab's label is astropy's UTC arithmetic (leap seconds included, 2016-12-31 → 2017) to the
    printed microsecond, and the TDB it gives SPICE is spiceypy's unitim of TT + seconds (< 10 ns)."""

    sp = pytest.importorskip("spiceypy")
    (tmp_path / "deltet.tls").write_text("KPL/LSK\n\\begindata\nDELTET/DELTA_T_A = 32.184\nDELTET/K = 1.657D-3\n"
                                         "DELTET/EB = 1.671D-2\nDELTET/M = ( 6.239996D0 1.99096871D-7 )\n"
                                         "DELTET/DELTA_AT = ( 37, @2017-JAN-1 )\n\\begintext\n")
    sp.furnsh(str(tmp_path / "deltet.tls"))  # the TDT <-> TDB constants of NAIF's LSK (unitim needs no leap here)
    try:
        _compare(sp)
    finally:
        sp.unload(str(tmp_path / "deltet.tls"))


def _compare(sp):
    from astropy.time import Time, TimeDelta

    for start, dt in (("2016-12-31T12:00:00", 86400.0), ("2024-06-21T12:00:00", 3600.0),
                      ("2030-01-01T00:00:00", 7 * 86400.0 + 0.25), ("2001-03-04T05:06:07.89", 1e6)):
        e = parse_epoch(start).plus(dt)
        ref = (Time(start, scale="utc") + TimeDelta(dt, format="sec", scale="tai")).isot
        assert e.iso("UTC", 6) == ref[:19] + "." + (ref[20:] + "000000")[:6] + "Z", start
        tdb = sp.unitim(sp.unitim(parse_epoch(start).et, "TDB", "TDT") + dt, "TDT", "TDB")
        assert abs(e.et - tdb) < 1e-8, start
