"""``"module:attr"`` references: the one place the lab turns such a string into the object it names (the
registries' lazy targets, study hooks, world models)."""

from __future__ import annotations

import importlib
from typing import Any, Callable


def load(target: Any) -> Any:
    """``"module:attr"`` (``attr`` may be dotted) → the object; anything that is not a string is returned as it is.
    Raises ImportError or AttributeError."""
    if not isinstance(target, str):
        return target
    mod_name, _, attr = target.partition(":")
    obj = importlib.import_module(mod_name)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


def lazy(target: str) -> Callable:
    """A callable that imports ``"module:function"`` on first call (keeps registration light)."""
    def call(*args, **kwargs):
        return load(target)(*args, **kwargs)

    call.__name__ = target.partition(":")[2]
    call.__qualname__ = target
    return call
