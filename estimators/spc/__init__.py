"""SPC-style landmark measurement (Gaskell's stereophotoclinometry as flown for navigation), faithful to
the approximations the Retina paper blames for its bias: image resampled into the maplet frame,
grid-point shading with an approximate (horizon-march) shadow test, shadowed points thrown away,
correlation and quadric peak interpolation in the maplet frame. See :mod:`.method`; what it shares with Retina
(projection, correlation, peak finders, final output phase) is :mod:`estimators.landmarks`.

References
----------
R. W. Gaskell et al., "Characterizing and navigating small bodies with imaging data", Meteoritics & Planetary
Science 43(6), 2008, pp. 1049–1061, doi:10.1111/j.1945-5100.2008.tb00692.x.

C. A. Wright et al., "Relative Terrain Imaging Navigation (RETINA) Tool for the Asteroid Redirect Robotic Mission
(ARRM)", NASA Goddard Space Flight Center, 2016 (the comparison SPC is held to; a technical report, no DOI).
"""

from estimators.spc.method import SpcOptions, extract_in_maplet, measure_frame, measure_landmark, predict_maplet

__all__ = ["SpcOptions", "extract_in_maplet", "measure_frame", "measure_landmark", "predict_maplet"]
