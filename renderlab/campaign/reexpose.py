"""A cached truth render re-exposed with one run's sensor noise.

A truth set's DN images hold the noise realisation of its render, which every run sharing the render (the
truth cache, :mod:`renderlab.campaign.cache`) would otherwise see. A study that wants noise statistics over
independent realisations re-exposes the frame's radiance (:func:`renderlab.sensor.model.expose`: Poisson + read
noise) with the run's :class:`~renderlab.sensor.model.SensorOptions` — the exposure time taken from the frame's
manifest record, as auto-exposure chose it at render time — and one seed per frame, drawn by
``numpy.random.default_rng(seed)`` (an int or a :class:`numpy.random.SeedSequence`), so a run replays alone.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from renderlab.errors import UserError
from renderlab.sensor.model import expose

__all__ = ["ReexposedTruthSet", "frame_sensor_options", "reexposed_dn"]

#: error text when a frame has nothing to re-expose (``{path}``, ``{i}`` filled in)
NO_RADIANCE = "truth set {path}: frame {i} holds no radiance to re-expose"


def frame_sensor_options(ts, i: int, sensor_options):
    """``sensor_options`` with the exposure time of frame ``i`` of ``ts`` (its manifest record)."""
    return dataclasses.replace(sensor_options, exposure_s=float(ts.frames[i]["sensor"]["exposure_s"]))


def _luminance(frame, rgb_fallback: bool) -> np.ndarray | None:
    """The frame's radiance; without one, the mean of its RGB channels if ``rgb_fallback`` (else None)."""
    if frame.radiance is not None:
        return frame.radiance
    return frame.rgb.mean(-1) if rgb_fallback and frame.rgb is not None else None


def reexposed_dn(ts, i: int, sensor_options, seed, *, frame=None, rgb_fallback: bool = False,
                 no_radiance: str = NO_RADIANCE) -> np.ndarray:
    """DN image (uint16) of frame ``i`` of ``ts`` re-exposed with ``sensor_options`` and ``default_rng(seed)``.

    Parameters
    ----------
    ts
        A truth set (``path``, ``frames``, ``load``), e.g. :class:`renderlab.files.truthset.TruthSet`.
    i : int
        Frame position in ``ts.frames``.
    sensor_options : renderlab.sensor.model.SensorOptions
        The run's sensor; its exposure time is replaced by the frame's recorded one.
    seed : int or numpy.random.SeedSequence
        Seed of the frame's noise generator.
    frame : renderlab.files.truthset.TruthFrame, optional
        Frame ``i`` already loaded (default: ``ts.load(i)``).
    rgb_fallback : bool
        Re-expose the mean of the RGB channels of a frame without radiance (default: refuse it).
    no_radiance : str
        UserError text when there is nothing to re-expose (``{path}`` and ``{i}`` are filled in).

    Returns
    -------
    numpy.ndarray
        The frame's new DN image.
    """
    fr = ts.load(i) if frame is None else frame
    lum = _luminance(fr, rgb_fallback)
    if lum is None:
        raise UserError(no_radiance.format(path=ts.path, i=i))
    return expose(lum, frame_sensor_options(ts, i, sensor_options), np.random.default_rng(seed)).dn


class ReexposedTruthSet:
    """A truth set whose DN images are re-exposed with one run's sensor noise (:func:`reexposed_dn`).

    What the estimators' drivers read of a truth set: ``path``, ``frames``, ``len``, ``load``, ``read_table``,
    plus :meth:`sensor_options` (the run's sensor with frame ``i``'s exposure).

    Parameters
    ----------
    ts
        The cached truth set (:class:`renderlab.files.truthset.TruthSet` or the same interface).
    sensor_options : renderlab.sensor.model.SensorOptions
        The run's sensor.
    seeds : sequence of int or numpy.random.SeedSequence
        One noise seed per frame.
    rgb_fallback : bool
        Re-expose the RGB mean of frames without radiance (default: UserError).
    cache : bool
        Keep each frame's re-exposed DN (every ``load(i)`` returns the same array object).
    """

    #: UserError text of a frame without radiance (``{path}``, ``{i}``)
    no_radiance = NO_RADIANCE

    def __init__(self, ts, sensor_options, seeds: Sequence, *, rgb_fallback: bool = False, cache: bool = False):
        self._ts, self.path, self.frames = ts, ts.path, ts.frames
        self._opts, self._seeds, self._rgb_fallback = sensor_options, seeds, rgb_fallback
        self._dn: dict[int, np.ndarray] | None = {} if cache else None

    def __len__(self) -> int:
        return len(self.frames)

    def read_table(self, name: str):
        return self._ts.read_table(name)

    def sensor_options(self, i: int):
        """The run's sensor options with the exposure time of frame ``i``."""
        return frame_sensor_options(self._ts, i, self._opts)

    def load(self, i: int):
        """Frame ``i`` of the truth set with its DN image re-exposed."""
        fr = self._ts.load(i)
        if self._dn is not None and i in self._dn:
            return dataclasses.replace(fr, dn=self._dn[i])
        dn = reexposed_dn(self._ts, i, self._opts, self._seeds[i], frame=fr, rgb_fallback=self._rgb_fallback,
                          no_radiance=self.no_radiance)
        if self._dn is not None:
            self._dn[i] = dn
        return dataclasses.replace(fr, dn=dn)
