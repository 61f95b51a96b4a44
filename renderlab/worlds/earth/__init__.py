"""earth world (see config.py for its scenario sections)."""
