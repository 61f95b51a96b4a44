"""Why a row has no result: one documented enum per kind of observable (the ``reason`` column).

Each enum belongs to one registered observable kind (:mod:`renderlab.contracts.observable`, ``reasons``); the
allowed values of a kind are read from the registry :data:`renderlab.plugins.observables` (:func:`reason_values`).

The values are plain strings (``str`` enums), stored as a Parquet dictionary column. ``ok`` is the only value
allowed when ``has_result`` is true. A producer gives the reason that stopped it; when it knows several at once, the
first in the enum's order (the order below). Its own detailed flags go to the free-text ``diagnostics`` column.
"""

from __future__ import annotations

from enum import Enum


class LandmarkReason(str, Enum):
    """Landmark-shift measurement (one row per landmark attempted per image)."""

    OK = "ok"                        #: a measured shift
    OFF_IMAGE = "off_image"          #: behind the camera, template off the image or too large to make
    FACING_AWAY = "facing_away"      #: the landmark faces away from the camera or the sun at the a-priori pose
    TOO_FEW_PIXELS = "too_few_pixels"  #: fewer valid overlapping pixels than the method's minimum
    FLAT_TEMPLATE = "flat_template"  #: predicted (or extracted) image without contrast
    SEARCH_BORDER = "search_border"  #: correlation peak on the border of the search area
    LOW_CORRELATION = "low_correlation"  #: peak correlation under the threshold
    NO_DETECTION = "no_detection"    #: the method found nothing (e.g. no blob)
    METHOD_ERROR = "method_error"    #: the method raised; the message is in ``diagnostics``


class FilterReason(str, Enum):
    """Navigation-filter time step (one row per run and time)."""

    OK = "ok"                        #: the filter updated with at least one measurement
    PRIOR = "prior"                  #: the initial estimate (before any measurement)
    NO_MEASUREMENT = "no_measurement"  #: propagated only: no measurement at this time
    ALL_GATED = "all_gated"          #: every measurement of this time was rejected by the χ² gate
    DIVERGED = "diverged"            #: non-finite state or covariance


class PoseReason(str, Enum):
    """Pose / inertia estimate (one row per run, or per frame for stage 2)."""

    OK = "ok"
    TOO_FEW_POINTS = "too_few_points"   #: fewer than the minimum tracked points
    COPLANAR_POINTS = "coplanar_points"  #: the points span a plane only (PnP degenerate)
    PNP_FAILED = "pnp_failed"           #: the PnP solver returned no pose
    NOT_CONVERGED = "not_converged"     #: the batch solve stopped on its budget without a usable estimate
    LOST_TRACK = "lost_track"           #: tracks lost before the arc was complete


def reason_values(kind: str) -> tuple[str, ...]:
    """The allowed ``reason`` strings of a registered observable kind, in priority order."""
    from renderlab import plugins

    return plugins.observable(kind).reason_values()
