"""Pydantic building blocks shared by every scenario section (strict models, finite numbers).

Numbers are strict about booleans and strings: TOML's ``true``/``false`` is never taken as ``1``/``0`` for an
``int`` or ``float`` key (pydantic's lax mode would, so ``camera.width = true`` rendered a 1-pixel image), nor
``"64"`` as 64. Every :class:`Strict` model checks each field before validation: a boolean (also inside a list or
a table of numbers) is refused unless the field's type admits ``bool`` itself, a string where only numbers fit.
"""

from __future__ import annotations

import types
import typing
from typing import Annotated, Any, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

Finite = Annotated[float, Field(allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Vec3 = Annotated[list[Finite], Field(min_length=3, max_length=3)]
Vec2 = Annotated[list[Positive], Field(min_length=2, max_length=2)]
Seed = Annotated[int, Field(ge=0)]
#: a name looked up in a registry (:mod:`renderlab.plugins`): a method, filter, guidance law
RegisteredName = Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_.-]*$")]


def accepts_bool(tp: Any) -> bool:
    """Whether the type annotation ``tp`` admits a boolean value as such (``bool``, ``Any``, a bool Literal)."""
    if tp is bool or tp is Any or tp is object:
        return True
    origin = typing.get_origin(tp)
    if origin is Annotated:
        return accepts_bool(typing.get_args(tp)[0])
    if origin is Union or origin is types.UnionType:
        return any(accepts_bool(a) for a in typing.get_args(tp))
    if origin is Literal:
        return any(isinstance(a, bool) for a in typing.get_args(tp))
    return False


def bool_misuse(tp: Any, value: Any) -> bool:
    """Whether ``value`` holds a boolean where the annotation ``tp`` expects a number (or a list/table of them).

    Nested models are not entered: they check their own fields.
    """
    if isinstance(value, bool):
        return not accepts_bool(tp)
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin is Annotated:
        return bool_misuse(args[0], value)
    if origin is Union or origin is types.UnionType:
        arms = [a for a in args if _container_fits(a, value)]
        return bool(arms) and all(bool_misuse(a, value) for a in arms)
    if origin in (list, set, frozenset) and isinstance(value, (list, tuple)) and args:
        return any(bool_misuse(args[0], v) for v in value)
    if origin is tuple and isinstance(value, (list, tuple)) and args:
        items = args[:1] * len(value) if args[-1] is Ellipsis else args
        return any(bool_misuse(t, v) for t, v in zip(items, value))
    if origin is dict and isinstance(value, dict) and len(args) == 2:
        return any(bool_misuse(args[1], v) for v in value.values())
    return False


def _numbers_only(tp: Any) -> bool:
    """Whether the annotation ``tp`` admits numbers (``int``/``float``) and nothing else but None."""
    origin = typing.get_origin(tp)
    if origin is Annotated:
        return _numbers_only(typing.get_args(tp)[0])
    if origin is Union or origin is types.UnionType:
        arms = [a for a in typing.get_args(tp) if a is not type(None)]
        return bool(arms) and all(_numbers_only(a) for a in arms)
    return tp is int or tp is float


def str_misuse(tp: Any, value: Any) -> bool:
    """Whether ``value`` holds a string where the annotation ``tp`` expects only numbers (or a list/table of them):
    ``width = "64"`` is refused, not read as 64 (pydantic's lax mode would)."""
    if isinstance(value, str):
        return _numbers_only(tp)
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin is Annotated:
        return str_misuse(args[0], value)
    if origin is Union or origin is types.UnionType:
        arms = [a for a in args if _container_fits(a, value)]
        return bool(arms) and all(str_misuse(a, value) for a in arms)
    if origin in (list, set, frozenset) and isinstance(value, (list, tuple)) and args:
        return any(str_misuse(args[0], v) for v in value)
    if origin is tuple and isinstance(value, (list, tuple)) and args:
        items = args[:1] * len(value) if args[-1] is Ellipsis else args
        return any(str_misuse(t, v) for t, v in zip(items, value))
    if origin is dict and isinstance(value, dict) and len(args) == 2:
        return any(str_misuse(args[1], v) for v in value.values())
    return False


def _container_fits(tp: Any, value: Any) -> bool:
    """Whether a union arm could take ``value``'s container kind (a list for a list, a table for a dict)."""
    while typing.get_origin(tp) is Annotated:
        tp = typing.get_args(tp)[0]
    origin = typing.get_origin(tp) or tp
    if isinstance(value, (list, tuple)):
        return origin in (list, tuple, set, frozenset)
    if isinstance(value, dict):
        return origin is dict
    return True


class Strict(BaseModel):
    """A scenario section: unknown keys, non-finite numbers and booleans given for numbers are refused;
    defaults are validated."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, validate_default=True)

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_for_number(cls, value: Any, info: ValidationInfo) -> Any:
        """Refuse ``true``/``false`` for a number field (pydantic's lax mode would read them as 1/0)."""
        field = cls.model_fields.get(info.field_name) if info.field_name else None
        if field is not None and bool_misuse(field.annotation, value):
            raise ValueError("Input should be a number, not a boolean")
        if field is not None and str_misuse(field.annotation, value):
            raise ValueError("Input should be a number, not a string (no quotes around numbers)")
        return value

