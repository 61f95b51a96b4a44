"""Dynamics: camera paths, orbits, spin, relative motion, attitude."""
