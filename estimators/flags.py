"""Measurement flags shared by the landmark estimators (a bit mask; 0 = good measurement).

A row with any of ``NO_RESULT_MASK`` set has no measured shift (``meas_s``/``meas_l`` are NaN).
``OUTLIER`` rows keep their shift: the final output phase flags, it does not drop.
"""

from __future__ import annotations

OFF_IMAGE = 1          # predicted landmark behind the camera, template off the image or too large to make
TOO_FEW_PIXELS = 2     # fewer valid overlapping pixels than the minimum at the peak
FLAT_TEMPLATE = 4      # predicted (or extracted) image has no contrast (all shadow / uniform)
LOW_CORRELATION = 8    # peak correlation under the threshold
SEARCH_BORDER = 16     # integer peak on the border of the search area
OUTLIER = 32           # final output phase: shift inconsistent with the frame's median shift
NOT_VISIBLE_TRUTH = 64  # truth says the landmark is not visible / occluded in this frame (set by the runner)
FACING_AWAY = 128      # maplet normal faces away from the camera or the sun at the a-priori pose

NO_RESULT_MASK = OFF_IMAGE | TOO_FEW_PIXELS | FLAT_TEMPLATE | LOW_CORRELATION | SEARCH_BORDER | FACING_AWAY

NAMES = {OFF_IMAGE: "off_image", TOO_FEW_PIXELS: "too_few_pixels", FLAT_TEMPLATE: "flat_template",
         LOW_CORRELATION: "low_correlation", SEARCH_BORDER: "search_border", OUTLIER: "outlier",
         NOT_VISIBLE_TRUTH: "not_visible_truth", FACING_AWAY: "facing_away"}


def describe(flags: int) -> str:
    """Short text for a flag mask: names joined by ``|``, or ``ok``."""
    names = [name for bit, name in NAMES.items() if int(flags) & bit]
    return "|".join(names) if names else "ok"
