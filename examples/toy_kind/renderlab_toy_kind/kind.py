"""The ``bright_spot`` kind: where is the one bright spot (a star, a beacon) in an image?

A method has a ``name`` and ``locate(frame) -> SpotResult`` (:class:`SpotMethod`). Pixels follow renderlab's
convention: ``(0, 0)`` is the centre of the top-left pixel, ``s`` the column, ``l`` the row. Rules (checked by
:func:`renderlab_toy_kind.parts.check_spot_method`): (a) on a noiseless spot the error per axis is at most
3 × the claimed σ + 0.05 px; (b) no spot → no result with a :class:`SpotReason` other than ``ok``; (c) same frame →
same result (``t_ms`` excepted); (d) the frame is not modified; (e) ``ok`` exactly with a finite position.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from typing import Protocol, runtime_checkable

import numpy as np
import pyarrow as pa

from renderlab.contracts.observable import ObservableKind


class SpotReason(str, Enum):
    """Why a frame has no spot position, in priority order."""

    OK = "ok"                    #: a located spot
    NO_SPOT = "no_spot"          #: nothing above the detection threshold
    AT_BORDER = "at_border"      #: the peak is too close to the image border to measure
    METHOD_ERROR = "method_error"  #: the method raised


@dataclass(frozen=True)
class SpotFrame:
    """One image (``(H, W)`` float64, not modified), the σ of its background noise (DN), index and seed."""

    image: np.ndarray
    noise_dn: float = 1.0
    index: int = 0
    seed: int = 0


@dataclass
class SpotResult:
    """The spot's position (px, NaN without result), the method's claimed 1σ per axis (px), reason, timing."""

    spot_s: float = math.nan
    spot_l: float = math.nan
    sigma_px: float = math.nan
    reason: str = SpotReason.OK.value
    diagnostics: str = ""
    t_ms: float = 0.0

    @property
    def has_result(self) -> bool:
        return bool(np.isfinite(self.spot_s) and np.isfinite(self.spot_l))


@runtime_checkable
class SpotMethod(Protocol):
    """A bright-spot method (module docstring)."""

    name: str

    def locate(self, frame: SpotFrame) -> SpotResult:
        """The spot in ``frame.image``."""
        ...


F64, I64, STR, BOOL = pa.float64(), pa.int64(), pa.string(), pa.bool_()
#: the columns every bright_spot table has (one row per frame and method)
SPOT_CORE = pa.schema([
    ("campaign", STR), ("run", I64), ("frame", I64), ("method", STR), ("spot_s", F64), ("spot_l", F64),
    ("sigma_px", F64), ("has_result", BOOL), ("reason", pa.dictionary(pa.int32(), STR)), ("diagnostics", STR),
    ("t_ms", F64),
])
#: every column the kind's readers know: the core and the truth a study adds
SPOT_KNOWN = pa.schema(list(SPOT_CORE) + [("truth_s", F64), ("truth_l", F64), ("err_s", F64), ("err_l", F64)])

BRIGHT_SPOT = ObservableKind(
    name="bright_spot", description="position of one bright spot in an image (toy kind)",
    reasons=SpotReason, frame=SpotFrame, result=SpotResult, protocol=SpotMethod,
    result_schema="renderlab_toy_kind.kind:SPOT_CORE", known_schema="renderlab_toy_kind.kind:SPOT_KNOWN",
    table_names=("spots",), runner="renderlab_toy_kind.parts:run_spots",
    scorer="renderlab_toy_kind.parts:score_spots", report_section="renderlab_toy_kind.parts:spot_section",
    conformance="renderlab_toy_kind.parts:check_spot_method",
)
