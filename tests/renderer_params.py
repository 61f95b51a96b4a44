"""Every registered renderer as a pytest parameter (test helper, not part of renderlab); Cycles skipped when the
bpy package is not installed."""

from __future__ import annotations

import pytest

from renderlab import plugins


def _renderer_params():
    out = []
    for name in plugins.renderers.names():
        marks = []
        if name == "cycles":
            try:
                import importlib.util

                have = importlib.util.find_spec("bpy") is not None
            except (ImportError, ValueError):
                have = False
            marks = [] if have else [pytest.mark.skip(reason="cycles needs the bpy package")]
        out.append(pytest.param(name, marks=marks))
    return out


RENDERERS = _renderer_params()
