"""SPC-style landmark measurement (Gaskell's stereophotoclinometry as flown for navigation), faithful to
the approximations the Retina paper blames for its bias: image resampled into the maplet frame,
grid-point shading with an approximate (horizon-march) shadow test, shadowed points thrown away,
correlation and quadric peak interpolation in the maplet frame. See :mod:`.method`."""

from estimators.spc.method import SpcOptions, extract_in_maplet, measure_frame, measure_landmark, predict_maplet

__all__ = ["SpcOptions", "extract_in_maplet", "measure_frame", "measure_landmark", "predict_maplet"]
