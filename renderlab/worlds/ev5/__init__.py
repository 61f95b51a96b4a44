"""ev5 world (see config.py for its scenario sections)."""
