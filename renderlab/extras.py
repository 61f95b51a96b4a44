"""Optional extras: a feature whose packages are not installed is a one-line error that names the extra.

``pip install renderlab`` installs the core (Mitsuba, numpy, scipy, OpenCV, pyarrow, ...): enough to render
with Mitsuba, measure, score and report. What not everyone needs is an extra (``./setup.sh`` installs them all):

=========  =================================  ===============================================================
extra      packages                           needed by
=========  =================================  ===============================================================
cycles     bpy (≈ 820 MB)                     the Blender Cycles renderer (``--renderer cycles``, crosscheck)
earth      roaring-landmask, shapely          the Earth world (GSHHG coastlines): coastline EKF, visibility
cluster    dask[distributed]                  campaigns on Dask workers (``--workers N``, ``--scheduler``)
spice      spiceypy                           SPICE trajectories (``trajectory.kind = "spice"``)
basilisk   bsk, bsk-opnav (Basilisk 2.12)     renderlab as Basilisk's camera (``renderlab.basilisk``)
all        all of the above
test       pytest, hypothesis, ...            the lab's tests
=========  =================================  ===============================================================

At the place a feature first needs its package, :func:`require` imports it (or, with ``load=False``, only
checks that it is installed) and raises :class:`~renderlab.errors.UserError` otherwise, e.g.
``the Cycles renderer needs the 'cycles' extra (pip install "renderlab[cycles]")``.
"""

from __future__ import annotations

import importlib
import importlib.util

from renderlab.errors import UserError

#: extra → what needs it (the subject of the error message)
FEATURES = {
    "cycles": "the Cycles renderer",
    "earth": "the Earth world (GSHHG coastlines)",
    "cluster": "a campaign on Dask workers",
    "spice": "a SPICE trajectory",
    "basilisk": "renderlab as Basilisk's camera",
}

#: importable module → the extra that installs it
MODULE_EXTRA = {
    "bpy": "cycles",
    "roaring_landmask": "earth",
    "shapely": "earth",
    "dask": "cluster",
    "distributed": "cluster",
    "spiceypy": "spice",
    "Basilisk": "basilisk",
}


def missing_message(extra: str, what: str | None = None, hint: str | None = None) -> str:
    """``<what> needs the '<extra>' extra (pip install "renderlab[<extra>]")``, plus ``; <hint>`` if given."""
    msg = f"{what or FEATURES[extra]} needs the '{extra}' extra (pip install \"renderlab[{extra}]\")"
    return f"{msg}; {hint}" if hint else msg


def _is_missing(exc: ImportError, module: str) -> bool:
    """Whether ``exc`` says ``module`` itself (or its top package) is not installed."""
    name = getattr(exc, "name", None) or ""
    return isinstance(exc, ModuleNotFoundError) and (module == name or module.startswith(name + "."))


def require(module: str, extra: str | None = None, what: str | None = None, *, hint: str | None = None,
            load: bool = True):
    """Import and return ``module``, or raise a one-line UserError naming the extra that installs it.

    Parameters
    ----------
    module : str
        The module to import, e.g. ``"distributed"``.
    extra : str, optional
        The extra that installs it; default :data:`MODULE_EXTRA` of its top-level package.
    what : str, optional
        What needs it (the error's subject); default :data:`FEATURES` of the extra.
    hint : str, optional
        A way around it, appended to the message (e.g. ``"--workers 0 runs the campaign in this process"``).
    load : bool
        False: only check that it is installed (``importlib.util.find_spec``), do not import it (bpy takes
        seconds and is imported in the Cycles worker) and return None.

    Raises
    ------
    UserError
        The module is not installed, or its import fails (a broken or partial install of the extra).
    """
    extra = extra or MODULE_EXTRA[module.partition(".")[0]]
    if not load:
        try:
            found = importlib.util.find_spec(module) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            raise UserError(missing_message(extra, what, hint))
        return None
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        if _is_missing(exc, module):
            raise UserError(missing_message(extra, what, hint)) from None
        raise UserError(f"{missing_message(extra, what, hint)}: import {module} failed ({exc})") from None
