"""The request's inputs checked at the command boundary, before anything runs or is created (``--dry-run``
included): what the scenario schema cannot see.

* Every file the scenario names (:func:`renderlab.campaign.cache.referenced_files`: meshes, albedo maps,
  trajectory tables, CCSDS messages, SPICE kernels) is a regular file (no FIFO, device, folder or link to one) of
  bounded size, so nothing blocks or streams forever when it is read or hashed for the plan; albedo maps' headers
  give a sane image size (:func:`renderlab.contracts.image_headers.image_header`).
* Every epoch lies inside :data:`renderlab.inputs.EPOCH_YEARS` (the time scales are undefined outside it).
* The camera is a valid :class:`renderlab.geometry.camera.CameraModel` (bounded intrinsics).
* Worker counts: every ``--workers`` option is capped as ``campaign``'s (:func:`check_workers`).
"""

from __future__ import annotations

import datetime
import os
from pathlib import Path

from renderlab.errors import UserError
from renderlab.inputs import LIMITS, check_regular, epoch_text, short, shown

#: scenario keys holding images (checked by their header), by the key's last component
IMAGE_KEYS = ("albedo_map",)
#: the largest file a scenario key may name, by the key's last component (others: only hashed, streamed)
KEY_LIMITS = {"file": LIMITS["trajectory"], "oem": LIMITS["trajectory"], "aem": LIMITS["trajectory"],
              "shape_file": LIMITS["mesh"], "calibration_file": LIMITS["calibration"]}


def _epochs(data, where: str = ""):
    """``(dotted key, value)`` of every key that names an epoch (``epoch``, ``*_epoch``, ``epoch_*``)."""
    items = data.items() if isinstance(data, dict) else enumerate(data) if isinstance(data, list) else ()
    for k, v in items:
        key = f"{where}.{k}" if where else str(k)
        if isinstance(k, str) and "epoch" in k.lower() and isinstance(v, (str, datetime.date)):
            yield key, v
        elif isinstance(v, (dict, list)):
            yield from _epochs(v, key)


def check_epochs(data: dict) -> None:
    """Every epoch of a scenario dict inside :data:`renderlab.inputs.EPOCH_YEARS` (one UserError line otherwise)."""
    for key, v in _epochs(data):
        epoch_text(v.isoformat() if isinstance(v, datetime.date) else v, key)


def check_files(data: dict, base_dir) -> None:
    """Every file a scenario dict names: a regular file of bounded size (images: a sane header). Missing files are
    left to the reader that names them."""
    from renderlab.campaign.cache import referenced_files
    from renderlab.contracts.image_headers import image_header

    for key, rel in referenced_files(data):
        if "\x00" in rel:
            raise UserError(f"{key}: a file name must not contain NUL, got {short(rel)}")
        p = Path(base_dir) / rel
        if not os.path.lexists(p):
            continue
        last = key.rsplit(".", 1)[-1]
        if last in IMAGE_KEYS:
            image_header(p, key)
        else:
            check_regular(p, key, KEY_LIMITS.get(last, LIMITS["hashed"]))


def check_camera(camera) -> None:
    """The scenario's camera as the lab's camera model (bounded intrinsics: one UserError line otherwise)."""
    from renderlab.geometry.camera import CameraModel

    d = camera.model_dump() if hasattr(camera, "model_dump") else camera
    keys = ("width", "height", "fx", "fy", "cx", "cy", "skew", "skew_yx", "model", "distortion")
    if isinstance(d, dict) and all(d.get(k) is not None for k in ("width", "height", "fx", "fy", "cx", "cy")):
        CameraModel.from_dict({k: d[k] for k in keys if d.get(k) is not None})


def check_scenario_inputs(scenario, base_dir) -> None:
    """All of the above for a validated scenario (module docstring)."""
    data = scenario.to_dict()
    check_epochs(data)
    check_files(data, base_dir)
    check_camera(scenario.camera)


def check_workers(workers, flag: str = "--workers") -> None:
    """A worker count: 0 or more and at most :data:`renderlab.campaign.executors.WORKERS_PER_CORE` per core."""
    from renderlab.campaign.executors import WORKERS_PER_CORE, default_workers

    limit = WORKERS_PER_CORE * default_workers()
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 0):
        raise UserError(f"{flag} must be a non-negative integer, got {short(workers)}")
    if workers is not None and workers > limit:
        raise UserError(f"{flag} {workers} is more than {WORKERS_PER_CORE} per core ({limit} on this machine, "
                        f"{default_workers()} cores); each worker is a process")


def existing_input(path, what: str) -> Path:
    """A path argument naming something to read: it must exist (file or folder; a FIFO or device is refused)."""
    import stat

    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise UserError(f"{what} not found: {shown(p)}") from None
    except OSError as exc:
        raise UserError(f"cannot open {what} {shown(p)}: {exc.strerror or type(exc).__name__}") from None
    if not (stat.S_ISREG(st.st_mode) or stat.S_ISDIR(st.st_mode)):
        raise UserError(f"{what} {shown(p)} is not a regular file or folder (a FIFO, socket or device)")
    return p
