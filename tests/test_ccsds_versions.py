"""CCSDS message versions: the ``CCSDS_AEM_VERS`` / ``CCSDS_OEM_VERS`` line decides how a file is read.

AEM 2.0 (ADM 504.0-B-2) has no ``ATTITUDE_DIR`` (always A2B) and no ``QUATERNION_TYPE`` (``Q1 Q2 Q3 QC``); it used
to be refused with "no ATTITUDE_DIR". The independent writer is the ``ccsds-ndm`` package (KVN, AEM 2.0 and OEM
2.0/3.0) and its own reader; it writes AEM 2.0 quaternions scalar first with a lower-case ``ATTITUDE_TYPE``, which the
lab refuses unless ``QUATERNION_TYPE`` says the order (ccsds-ndm 3.1.1's reader does not read its own AEM 2.0 KVN). The standard's own layout (504.0-B-2 table 4-4, annex G) is
written here by hand."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from renderlab.errors import UserError
from renderlab.trajectory_io import read_aem, read_oem

ndm = pytest.importorskip("ccsds_ndm")
from ccsds_ndm.mapping import NDMFileFormats  # noqa: E402
from ccsds_ndm.models import ndmxml2, ndmxml4  # noqa: E402
from ccsds_ndm.ndm_io import NdmIo  # noqa: E402

EPOCHS = ["2024-06-21T10:00:00.000", "2024-06-21T10:00:10.000", "2024-06-21T10:00:20.000"]
TRUTH = Rotation.from_quat(np.random.default_rng(31).normal(size=(3, 4)))  # R_GCRF_from_cam


def _ndm_aem(path):
    """AEM 2.0 in KVN by ccsds-ndm: REF_FRAME_A = GCRF, REF_FRAME_B = the camera, quaternions R_A_from_B."""
    m = ndmxml4
    states = [m.AttitudeStateType(quaternion_ephemeris=m.QuaternionEphemerisType(
        epoch=e, quaternion=m.QuaternionType(q1=q[0], q2=q[1], q3=q[2], qc=q[3])))
        for e, q in zip(EPOCHS, TRUTH.as_quat())]
    meta = m.AemMetadata(object_name="NAVCAM SAT", object_id="2024-001A", center_name="EARTH", ref_frame_a="GCRF",
                         ref_frame_b="SC_BODY_1", time_system="UTC", start_time=EPOCHS[0], stop_time=EPOCHS[-1],
                         attitude_type=m.AttitudeTypeType.QUATERNION)
    aem = m.Aem(header=m.AdmHeader(creation_date="2024-06-21T00:00:00", originator="TEST"),
                body=m.AemBody(segment=[m.AemSegment(metadata=meta, data=m.AemData(attitude_state=states))]))
    path.write_text(NdmIo().to_string(aem, NDMFileFormats.KVN))
    return path


def _angle(a: Rotation, b: Rotation) -> float:
    return float(np.max((a.inv() * b).magnitude()))


def test_ccsds_ndm_aem_2_is_read_by_version_not_refused_for_attitude_dir(tmp_path):
    """Fails before the change ("has no ATTITUDE_DIR"). ccsds-ndm's AEM 2.0 puts QC first with a lower-case
    ATTITUDE_TYPE: refused with a line naming the order; with QUATERNION_TYPE = FIRST added it is read, and each
    component matches what ccsds-ndm's own reader finds in the file, and the rotation the truth (< 1e-12 rad)."""
    path = _ndm_aem(tmp_path / "att.aem")
    text = path.read_text()
    assert text.startswith("CCSDS_AEM_VERS") and "ATTITUDE_DIR" not in text and "QUATERNION_TYPE" not in text
    with pytest.raises(UserError, match=r"^att.aem: ATTITUDE_TYPE = quaternion in lower case is how ccsds-ndm 3.1 "
                                        r"writes AEM 2.0, .* add QUATERNION_TYPE = FIRST"):
        read_aem(path)
    path.write_text(text.replace("META_STOP", "QUATERNION_TYPE          = FIRST\nMETA_STOP"))
    s = read_aem(path)
    assert np.abs(s.quat_xyzw - TRUTH.as_quat()).max() < 1e-15  # the Q1 Q2 Q3 QC handed to ccsds-ndm
    assert _angle(Rotation.from_quat(s.quat_xyzw), TRUTH) < 1e-12
    assert s.frame == "GCRF" and s.attitude_frame == "SC_BODY_1"
    assert np.abs(s.times_s - [0.0, 10.0, 20.0]).max() < 1e-8  # TDB seconds: 20 UTC s are 20 - 6.3e-9 TDB s here


def _standard_aem(path, version="2.0", extra_meta="", attitude_type="QUATERNION/ANGVEL", rates=True):
    """A 504.0-B-2 AEM as its annex G example lays it out: two segments, Q1 Q2 Q3 QC (+ ANGVEL_X..Z)."""
    lines = [f"CCSDS_AEM_VERS = {version}", "COMMENT written from CCSDS 504.0-B-2 table 4-4",
             "CREATION_DATE = 2024-06-21T00:00:00", "ORIGINATOR = HAND", "MESSAGE_ID = T-0001", ""]
    for _seg, idx in ((0, [0, 1]), (1, [1, 2])):
        lines += ["META_START", "OBJECT_NAME = NAVCAM SAT", "OBJECT_ID = 2024-001A", "CENTER_NAME = EARTH",
                  "REF_FRAME_A = GCRF", "REF_FRAME_B = SC_BODY_1", "TIME_SYSTEM = UTC",
                  f"START_TIME = {EPOCHS[idx[0]]}", f"USEABLE_START_TIME = {EPOCHS[idx[0]]}",
                  f"USEABLE_STOP_TIME = {EPOCHS[idx[-1]]}", f"STOP_TIME = {EPOCHS[idx[-1]]}",
                  f"ATTITUDE_TYPE = {attitude_type}", *(["ANGVEL_FRAME = SC_BODY_1"] if rates else []), *extra_meta,
                  "INTERPOLATION_METHOD = LINEAR", "INTERPOLATION_DEGREE = 1", "META_STOP", "", "DATA_START"]
        for k in idx:
            q = TRUTH[k].as_quat()
            lines.append(" ".join([EPOCHS[k], *(f"{v:.17g}" for v in q), *(["0.01 -0.02 0.003"] if rates else [])]))
        lines += ["DATA_STOP", ""]
    path.write_text("\n".join(lines))
    return path


def test_a_standard_aem_2_is_read_scalar_last_a2b(tmp_path):
    s = read_aem(_standard_aem(tmp_path / "std.aem"))
    assert _angle(Rotation.from_quat(s.quat_xyzw), TRUTH) < 1e-15 and len(s.times_s) == 3
    s = read_aem(_standard_aem(tmp_path / "q.aem", attitude_type="QUATERNION", rates=False))
    assert _angle(Rotation.from_quat(s.quat_xyzw), TRUTH) < 1e-15
    s = read_aem(_standard_aem(tmp_path / "a.aem", attitude_type="QUATERNION", rates=False,
                               extra_meta=["ATTITUDE_DIR = A2B"]))
    assert _angle(Rotation.from_quat(s.quat_xyzw), TRUTH) < 1e-15


@pytest.mark.parametrize("version, meta, attitude_type, rates, message", [
    ("3.0", [], "QUATERNION", False, r"std.aem: CCSDS_AEM_VERS = 3.0 is not a version this lab reads \(AEM 1.0 "
                                     r"\(504.0-B-1\), 2.0 \(504.0-B-2\)\)"),
    ("2.0", ["ATTITUDE_DIR = B2A"], "QUATERNION", False, r"CCSDS_AEM_VERS 2.0 rotates from REF_FRAME_A to "
                                                         r"REF_FRAME_B; ATTITUDE_DIR = B2A is ADM 1.0 only"),
    ("2.0", [], "QUATERNION/RATE", True, r"ATTITUDE_TYPE 'QUATERNION/RATE' is not supported in CCSDS_AEM_VERS 2.0"),
    ("1.0", ["ATTITUDE_DIR = A2B"], "QUATERNION", False, r"the META block at line \d+ has no QUATERNION_TYPE"),
])
def test_versions_and_their_keywords_are_checked(tmp_path, version, meta, attitude_type, rates, message):
    with pytest.raises(UserError, match=message) as info:
        read_aem(_standard_aem(tmp_path / "std.aem", version, meta, attitude_type, rates))
    assert "\n" not in str(info.value)


def _ndm_oem(path, version):
    m, header, P, V = ((ndmxml2, ndmxml2.NdmHeader, ndmxml2.PositionType, ndmxml2.VelocityType) if version == "2.0"
                       else (ndmxml4, ndmxml4.OdmHeader, ndmxml4.PositionTypeUo, ndmxml4.VelocityTypeUo))
    rows = np.array([[7000.123456789, 1.5, -2.25, 0.001, 7.5, 0.0], [7000.2, 76.5, -2.25, 0.0005, 7.49, 1e-4],
                     [7000.1, 151.4, -2.2, -0.001, 7.48, 2e-4]])
    sv = [m.StateVectorAccType(epoch=e, x=P(value=r[0]), y=P(value=r[1]), z=P(value=r[2]), x_dot=V(value=r[3]),
                               y_dot=V(value=r[4]), z_dot=V(value=r[5])) for e, r in zip(EPOCHS, rows)]
    meta = m.OemMetadata(object_name="NAVCAM SAT", object_id="2024-001A", center_name="EARTH", ref_frame="GCRF",
                         time_system="UTC", start_time=EPOCHS[0], stop_time=EPOCHS[-1])
    oem = m.Oem(header=header(creation_date="2024-06-21T00:00:00", originator="TEST"),
                body=m.OemBody(segment=[m.OemSegment(metadata=meta, data=m.OemData(state_vector=sv))]))
    path.write_text(NdmIo().to_string(oem, NDMFileFormats.KVN))
    return path, rows


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_oem_versions_2_and_3_from_ccsds_ndm(tmp_path, version):
    path, rows = _ndm_oem(tmp_path / "orbit.oem", version)
    assert path.read_text().split("\n")[0].split("=")[1].strip() == version
    s = read_oem(path)
    assert np.array_equal(s.positions_m, rows[:, :3] * 1e3) and np.array_equal(s.velocities_m_s, rows[:, 3:] * 1e3)
    assert (s.frame, s.center_name, s.object_name) == ("GCRF", "EARTH", "NAVCAM SAT")


def test_oem_version_1_reads_and_unknown_versions_are_refused_by_number(tmp_path):
    path, rows = _ndm_oem(tmp_path / "orbit.oem", "2.0")
    text = path.read_text()
    (tmp_path / "v1.oem").write_text(text.replace("CCSDS_OEM_VERS           = 2.0", "CCSDS_OEM_VERS = 1.0"))
    assert np.array_equal(read_oem(tmp_path / "v1.oem").positions_m, rows[:, :3] * 1e3)
    for bad in ("4.0", "0.9", "two"):
        (tmp_path / "bad.oem").write_text(text.replace("CCSDS_OEM_VERS           = 2.0", f"CCSDS_OEM_VERS = {bad}"))
        with pytest.raises(UserError, match=rf"^bad.oem: CCSDS_OEM_VERS = {bad} is not a version this lab reads "
                                            r"\(OEM 1.0 \(502.0-B-1\), 2.0 \(502.0-B-2\), 3.0 \(502.0-B-3\)\)$"):
            read_oem(tmp_path / "bad.oem")
