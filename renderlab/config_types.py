"""Pydantic building blocks shared by every scenario section (strict models, finite numbers)."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

Finite = Annotated[float, Field(allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Vec3 = Annotated[list[Finite], Field(min_length=3, max_length=3)]
Vec2 = Annotated[list[Positive], Field(min_length=2, max_length=2)]
Seed = Annotated[int, Field(ge=0)]


class Strict(BaseModel):
    """A scenario section: unknown keys and non-finite numbers are refused; defaults are validated."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, validate_default=True)
