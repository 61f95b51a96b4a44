"""Trajectory sources: the user's own camera trajectory from files, and the truth set's poses back to files.

Readers return a :class:`PoseSeries` (times or epochs, positions (n, 3) m, quaternions (n, 4) scalar-last of
``R_frame_from_cam``, frame name), validated (increasing time, finite values, unit quaternions, required
columns and units):

* :func:`read_table` — CSV or Parquet (:mod:`.table`);
* :func:`read_oem`, :func:`read_aem` — CCSDS OEM / AEM in KVN, own parser for the subset (:mod:`.ccsds`);
  :func:`write_oem`, :func:`write_aem` write them, :func:`export_truthset` from a truth set (:mod:`.export`);
* :func:`read_spice` — SPK / CK / FK … through ``spiceypy`` (:mod:`.spice`).

:func:`frame_poses` samples a scenario's file trajectory at its frame times (:mod:`.sources`); interpolation is
cubic (Hermite with velocities) or linear for positions and SLERP for attitude (:mod:`.series`). Epochs and
time scales: :mod:`.timescales` (UTC → TDB as SPICE's leapseconds kernel). Every name is imported on first use
(the package itself is light: the scenario validator imports :mod:`.timescales`).
"""

from __future__ import annotations

__all__ = ["PoseSeries", "Epoch", "parse_epoch", "read_table", "read_oem", "read_aem", "write_oem", "write_aem",
           "read_spice", "frame_poses", "truthset_pose_series", "export_truthset"]


def __getattr__(name: str):
    import importlib

    where = {"PoseSeries": "series", "Epoch": "timescales", "parse_epoch": "timescales", "read_table": "table", "read_oem": "ccsds", "read_aem": "ccsds", "write_oem": "ccsds",
             "write_aem": "ccsds", "read_spice": "spice", "frame_poses": "sources",
             "truthset_pose_series": "export", "export_truthset": "export"}
    if name in where:
        return getattr(importlib.import_module(f"renderlab.trajectory_io.{where[name]}"), name)
    raise AttributeError(f"module 'renderlab.trajectory_io' has no attribute {name!r}")
