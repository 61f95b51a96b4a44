"""microsat world: a Chibis-M-like microsatellite separating from a chaser (see config.py, model.py, plan.py)."""

from .plan import MicrosatPlan, SeparationTruth, make_plan, separation_truth

__all__ = ["MicrosatPlan", "SeparationTruth", "make_plan", "separation_truth"]
