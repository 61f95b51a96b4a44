"""renderlab-ncc-baseline: a plain NCC landmark method registered through the ``renderlab.landmark_methods``
entry point (see :mod:`renderlab_ncc_baseline.method`)."""

from renderlab_ncc_baseline.method import NccBaseline

__all__ = ["NccBaseline"]
