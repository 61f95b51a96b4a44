"""renderlab in Basilisk (AVS Lab, https://avslab.github.io/basilisk/): the lab's renderer as Basilisk's camera.

* :mod:`renderlab.basilisk.frames` — Basilisk's MRPs, Euler parameters, DCMs and camera conventions turned into the
  lab's :class:`~renderlab.dynamics.camera_paths.CameraPose` and :class:`~renderlab.geometry.camera.CameraModel`
  (numpy only);
* :mod:`renderlab.basilisk.camera` — ``RenderlabCamera``, a Basilisk Python ``SysModel`` that renders each camera
  step through :meth:`renderlab.Renderer.frame` from the spacecraft and planet state messages and writes a
  ``CameraImageMsg`` (an 8-bit PNG in memory) and a ``CameraConfigMsg``.

Basilisk itself (``bsk``, ``bsk-opnav``: the ``basilisk`` extra) is imported only when a module is first used;
``examples/basilisk_mars_opnav.py`` is a closed loop (Mars orbit → renderlab camera → ``houghCircles`` →
``pixelLineConverter`` → ``relativeODuKF``), and ``docs/extending.md`` ("Use renderlab as Basilisk's camera") the
walk-through.
"""
