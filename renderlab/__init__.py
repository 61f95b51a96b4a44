"""renderlab: an optical-navigation lab.

``renderlab.Renderer`` is the warm frame API (pose in, image and truth out, in memory;
:mod:`renderlab.pipeline.frame_api`, ``docs/quickstart.md``); ``renderlab.camera_pose`` reads a pose in any
supported convention (:mod:`renderlab.pipeline.poses`). Both are imported on first use, so ``import renderlab``
(and ``renderlab --help``) stay instant.
"""
__version__ = "0.1.0"

_LAZY = {"Renderer": ("renderlab.pipeline.frame_api", "Renderer"),
         "Frame": ("renderlab.pipeline.frame_api", "Frame"),
         "camera_pose": ("renderlab.pipeline.poses", "camera_pose")}

__all__ = ["Renderer", "Frame", "camera_pose", "__version__"]


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        return getattr(importlib.import_module(module), attr)
    raise AttributeError(f"module 'renderlab' has no attribute {name!r}")
