"""Plots, previews and reports."""
