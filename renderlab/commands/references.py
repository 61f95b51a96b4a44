"""``module:attr`` references typed on the command line (``measure --method``, ``campaign --plugin``): the form
checked, the module imported, the object checked against the registry's protocol — all before anything calls it.

``--method os:system`` names a function, not a landmark-method class: refused here, so ``os.system`` is never
called with the method options. A relative module (``..x:y``), an empty part or anything but dotted identifiers is
one line; so is a module that fails to import, whatever it raises.
"""

from __future__ import annotations

import importlib
import inspect
import re

from renderlab.errors import UserError
from renderlab.inputs import short

_DOTTED = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*")
PROTOCOL_DOC = "renderlab.contracts.landmark"


def parse_reference(text: str, what: str) -> tuple[str, str]:
    """``"module:attr"`` → (module, attr): absolute dotted identifiers on both sides (no relative ``..x``)."""
    if not isinstance(text, str) or len(text) > 300 or text.count(":") != 1:
        raise UserError(f"{what}: {short(text)} is not of the form module:attr")
    module, attr = text.split(":")
    if module.startswith("."):
        raise UserError(f"{what}: {short(text)} names a relative module; give the absolute module path")
    if not _DOTTED.fullmatch(module) or not _DOTTED.fullmatch(attr):
        raise UserError(f"{what}: {short(text)} is not of the form module:attr (dotted Python names)")
    return module, attr


def load_reference(text: str, what: str):
    """The object ``module:attr`` names (:func:`parse_reference`), imported; any failure is one UserError line."""
    module, attr = parse_reference(text, what)
    try:
        obj = importlib.import_module(module)
    except Exception as exc:  # noqa: BLE001 - whatever the user's module raises while importing
        raise UserError(f"{what}: cannot import {short(module)} ({type(exc).__name__}: {short(str(exc))})") from None
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise UserError(f"{what}: {short(module)} has no attribute {short(attr)}") from None
    return obj


def is_landmark_method_class(obj) -> bool:
    """A class that follows :class:`renderlab.contracts.landmark.LandmarkMethod`: a ``measure_frame`` method and a
    ``name`` (a class attribute, or set by its constructor from the options)."""
    return (inspect.isclass(obj) and callable(getattr(obj, "measure_frame", None))
            and not getattr(obj, "_is_protocol", False) and not inspect.isabstract(obj))


def check_landmark_method(text: str, what: str = "--method"):
    """The class a user-typed ``module:attr`` names, checked as a landmark method before it is called."""
    obj = load_reference(text, what)
    if not is_landmark_method_class(obj):
        raise UserError(f"{what}: {short(text)} is {_kind(obj)}, not a landmark-method class (a class with "
                        f"measure_frame(frame); see {PROTOCOL_DOC})")
    return obj


def check_plugin(text: str) -> None:
    """A ``--plugin [NAME=]module:attr``: a study object or a method class of a registered observable kind (its
    protocol's methods there, :func:`renderlab.plugins.kind_of_method`), checked, not called."""
    from renderlab.contracts.study import Study
    from renderlab.plugins import kind_of_method, observables

    name, sep, ref = text.partition("=")
    if sep and not (name.isidentifier() and len(name) <= 64):
        raise UserError(f"--plugin {short(text)}: NAME must be an identifier")
    ref = ref if sep else text
    obj = load_reference(ref, "--plugin")
    if not (isinstance(obj, Study) or (inspect.isclass(obj) and kind_of_method(obj) is not None)):
        raise UserError(f"--plugin: {short(ref)} is {_kind(obj)}, neither a Study nor a method class of an "
                        f"observable kind ({', '.join(observables.names())}; see renderlab.contracts.study, "
                        "renderlab.contracts.observable)")


def _kind(obj) -> str:
    if inspect.ismodule(obj):
        return "a module"
    if inspect.isclass(obj):
        return "a protocol or abstract class" if callable(getattr(obj, "measure_frame", None)) \
            else "a class without measure_frame"
    if callable(obj):
        return "a function"
    return f"a {type(obj).__name__}"
