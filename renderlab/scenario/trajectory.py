"""Scenario section ``[trajectory]`` for camera-path trajectories: generated (``line``, ``orbit``) or read from the
user's files (``table``, ``ccsds``, ``spice``); the world-specific kinds live with their worlds (``ev5_descent``,
``leo``, ``separation``). Light: pydantic only (and the pure-Python epoch parser)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from renderlab.contracts.config_types import Finite, Positive, Vec3
from renderlab.contracts.config_types import Strict as _Strict

class TrajectoryConfig(_Strict):
    """Camera path. ``line``: from ``start_m`` to ``end_m``; ``orbit``: around ``target_m`` at
    ``range_m`` and ``elevation_deg`` from ``azimuth_start_deg`` to ``azimuth_end_deg``.
    The camera always looks at ``target_m`` with ``up`` toward the top of the image."""

    kind: Literal["line", "orbit"] = Field("orbit", description="line: from start_m to end_m; orbit: around "
                                           "target_m at range_m and elevation_deg")
    frames: Annotated[int, Field(gt=0, le=100000)] = Field(1, description="Number of frames")
    dt_s: Positive = Field(1.0, description="Time between frames [s]")
    target_m: Vec3 = Field([0.0, 0.0, 0.0], description="Point the camera looks at, render frame [m]")
    up: Vec3 = Field([0.0, 0.0, 1.0], description="Direction toward the top of the image, render frame")
    start_m: Vec3 | None = Field(None, description="line: first camera position, render frame (required) [m]")
    end_m: Vec3 | None = Field(None, description="line: last camera position (default: start_m) [m]")
    range_m: Positive = Field(10.0, description="orbit: distance from target_m [m]")
    elevation_deg: Annotated[float, Field(gt=-90, lt=90, allow_inf_nan=False)] = Field(
        30.0, description="orbit: elevation of the camera above target_m (height range_m·sin(elevation)) [deg]")
    azimuth_start_deg: Finite = Field(-90.0, description="orbit: azimuth of the first frame, from +x toward +y "
                                      "[deg]")
    azimuth_end_deg: Finite = Field(-90.0, description="orbit: azimuth of the last frame [deg]")

    @model_validator(mode="after")
    def _line_fields(self):
        if self.kind == "line" and self.start_m is None:
            raise ValueError("trajectory kind 'line' needs 'start_m'")
        return self


#: trajectory kinds read from the user's files (every lab world takes them, each in its own frame: the docstring of
#: SourceTrajectoryConfig, docs/scenario_keys.md)
SOURCE_KINDS = ("table", "ccsds", "spice")
_COMMON = {"kind", "frames", "dt_s", "start_s", "times_s", "epoch_utc", "frame", "attitude", "target_m", "up",
           "camera_mount_quat_xyzw", "interpolation"}
_OWN = {"table": {"file", "quaternion_order", "quaternion_direction"},
        "ccsds": {"oem", "aem", "observer", "center", "camera_frame"},
        "spice": {"kernels", "observer", "center", "camera_frame", "aberration"}}
_NEEDS = {"table": ("file",), "ccsds": ("oem",), "spice": ("kernels", "observer", "center", "frame", "epoch_utc")}
_NEEDS_ATTITUDE = {"table": ("quaternion_order", "quaternion_direction"), "ccsds": ("aem",), "spice": ("camera_frame",)}


class SourceTrajectoryConfig(_Strict):
    """Camera path read from the user's files (:mod:`renderlab.trajectory_io`); paths relative to the scenario. Every
    world takes it, each in its own frame (named by ``frame``, the OEM's REF_FRAME or the SPICE frame): analytic —
    the scene frame; ev5 — ``EV5_FIXED``, the asteroid's body-fixed frame, with ``[sun] direction`` at time 0 turning
    with the spin; earth — ``GCRF`` or ``ITRF`` about the geocentre, epochs required, nadir pointing when the files
    give no attitude; microsat — the chaser's ``LVLH``, the camera relative to the target, whose tumble
    ``[world.tumble]`` sets (:mod:`renderlab.worlds.ev5.file_trajectory`, :mod:`renderlab.worlds.earth.file_trajectory`,
    :mod:`renderlab.worlds.microsat.file_trajectory`).

    ``table``: ``file`` (CSV or Parquet: ``time_s`` or ``epoch``, ``x_m y_m z_m``, ``qx qy qz qw``) with the
    declared ``quaternion_order`` (``xyzw``/``wxyz``) and ``quaternion_direction``
    (``cam_to_frame``/``frame_to_cam``); ``ccsds``: ``oem`` (positions) and ``aem`` (attitude), KVN;
    ``spice``: ``kernels`` with ``observer``, ``center``, ``frame`` and ``camera_frame`` as SPICE spells them, and
    ``aberration`` (``NONE``, ``LT``, ``LT+S``); without a leapseconds kernel among the kernels one is written from
    astropy's leap-second table.

    Without the attitude keys (``aem``, ``camera_frame``, the table's quaternion keys) the files give positions
    only and the world's default pointing applies (Earth: nadir); worlds without one refuse the scenario.

    Frame k is taken at ``start_s + k·dt_s`` (or ``times_s[k]``): seconds after ``epoch_utc`` (default: the
    source's first epoch; required for ``spice``), or on the table's own ``time_s`` axis. ``attitude =
    "look_at"`` ignores the file's attitude and points the camera at ``target_m`` with ``up`` up;
    ``camera_mount_quat_xyzw`` (``R_att_from_cam``) mounts the camera in the attitude file's frame.
    Positions interpolate by ``interpolation`` (cubic/linear), attitude by SLERP.
    """

    kind: Literal["table", "ccsds", "spice"] = Field(description="table: CSV/Parquet file; ccsds: OEM (+ AEM) "
                                                     "KVN files; spice: SPICE kernels")
    frames: Annotated[int, Field(gt=0, le=100000)] = Field(1, description="Number of frames")
    dt_s: Positive = Field(1.0, description="Time between frames [s]")
    start_s: Finite = Field(0.0, description="Time of frame 0 after epoch_utc (or on the table's time_s axis) [s]")
    times_s: Annotated[list[Finite], Field(min_length=1, max_length=100000)] | None = Field(
        None, description="Explicit frame times, strictly increasing; replaces frames/dt_s/start_s [s]")
    epoch_utc: str | None = Field(None, description="ISO UTC epoch of time 0 (default: the source's first epoch; "
                                  "required for spice)")
    frame: Annotated[str, Field(min_length=1)] | None = Field(None, description="Reference frame of the positions "
                                                              "as the source names it (spice: required); ev5: "
                                                              "EV5_FIXED, earth: GCRF or ITRF, microsat: LVLH")
    file: str | None = Field(None, description="table: CSV or Parquet with time_s or epoch, x_m y_m z_m, qx qy qz "
                             "qw; relative to the scenario file")
    quaternion_order: Literal["xyzw", "wxyz"] | None = Field(None, description="table: component order of the "
                                                             "file's quaternions (without the quaternion keys: "
                                                             "the world's default pointing, Earth: nadir)")
    quaternion_direction: Literal["cam_to_frame", "frame_to_cam"] | None = Field(
        None, description="table: the rotation the file's quaternions describe")
    oem: str | None = Field(None, description="ccsds: OEM file (positions), KVN, relative to the scenario file")
    aem: str | None = Field(None, description="ccsds: AEM file (attitude), KVN, relative to the scenario file "
                            "(without it: the world's default pointing, Earth: nadir)")
    kernels: Annotated[list[Annotated[str, Field(min_length=1)]], Field(min_length=1)] | None = Field(
        None, description="spice: kernel files (or meta-kernels), relative to the scenario file")
    observer: str | None = Field(None, description="ccsds/spice: the camera's body as the source spells it "
                                 "(OEM OBJECT_NAME, checked; SPICE observer)")
    center: str | None = Field(None, description="ccsds/spice: origin of frame (OEM CENTER_NAME, checked; SPICE "
                               "center)")
    camera_frame: str | None = Field(None, description="ccsds: the AEM's camera-side frame (checked); spice: the "
                                     "camera's SPICE frame (attitude = file; without it: the world's default pointing, Earth: nadir)")
    attitude: Literal["file", "look_at"] = Field("file", description="file: the source's attitude; look_at: "
                                                 "ignore it and point the camera at target_m with up up")
    target_m: Vec3 = Field([0.0, 0.0, 0.0], description="look_at: point the camera looks at [m]")
    up: Vec3 = Field([0.0, 0.0, 1.0], description="look_at: direction toward the top of the image")
    camera_mount_quat_xyzw: Annotated[list[Finite], Field(min_length=4, max_length=4)] | None = Field(
        None, description="Unit quaternion R_att_from_cam mounting the camera in the attitude file's frame")
    interpolation: Literal["cubic", "linear"] = Field("cubic", description="Interpolation of the positions "
                                                      "(attitude: SLERP); not for spice")
    aberration: Literal["NONE", "LT", "LT+S"] = Field(
        "NONE", description="spice: SPICE aberration correction of the positions (and of sun.source = \"spice\"): "
        "NONE geometric; LT the centre where the camera sees it, one light time earlier; LT+S also stellar "
        "aberration (renderlab.trajectory_io.spice)")

    @field_validator("epoch_utc", mode="before")
    @classmethod
    def _epoch(cls, v):
        """ISO UTC text (or an unquoted TOML date-time) → checked ISO text."""
        from renderlab.trajectory_io.timescales import utc_text

        return utc_text(v)

    @model_validator(mode="after")
    def _kind_fields(self):
        k = self.kind  # keys given with a value other than the default (a dumped scenario reloads as it was)
        given = {n for n in self.model_fields_set if getattr(self, n) != type(self).model_fields[n].default}
        extra = sorted(given - _COMMON - _OWN[k])
        if extra:
            raise ValueError(f"kind '{k}' does not use '{extra[0]}'")
        missing = [n for n in _NEEDS[k] if getattr(self, n) is None]
        if missing:
            raise ValueError(f"kind '{k}' needs '{missing[0]}'")
        att = [n for n in _NEEDS_ATTITUDE[k] if getattr(self, n) is not None]
        if self.attitude == "file" and att and len(att) < len(_NEEDS_ATTITUDE[k]):
            gap = next(n for n in _NEEDS_ATTITUDE[k] if n not in att)
            raise ValueError(f"kind '{k}' needs '{gap}' with '{att[0]}'")
        if self.attitude == "file" and given & {"target_m", "up"}:
            raise ValueError("target_m and up are for attitude = \"look_at\"")
        if k == "spice" and "interpolation" in given:
            raise ValueError("kind 'spice' does not use 'interpolation' (SPICE interpolates its kernels)")
        if self.times_s is not None:
            if given & {"frames", "dt_s", "start_s"}:
                raise ValueError("give either times_s or frames/dt_s/start_s")
            if any(b <= a for a, b in zip(self.times_s, self.times_s[1:])):
                raise ValueError("times_s must increase strictly")
        q = self.camera_mount_quat_xyzw
        if q is not None and self.attitude == "file" and not att:
            raise ValueError("camera_mount_quat_xyzw mounts the camera in the attitude file's frame; this "
                             f"trajectory has no attitude ({' / '.join(_NEEDS_ATTITUDE[k])})")
        if q is not None and abs(sum(v * v for v in q) ** 0.5 - 1.0) > 1e-6:
            raise ValueError("camera_mount_quat_xyzw must be a unit quaternion")
        return self

    def reads_attitude(self) -> bool:
        """Whether the camera attitude comes from the files (``attitude = "file"`` and the kind's attitude keys
        given: ``aem``, ``camera_frame`` or the table's quaternion keys). Without them the files give positions
        only and the world's default pointing applies (Earth: nadir); a world without one refuses the scenario
        (:meth:`missing_attitude`)."""
        return self.attitude == "file" and all(getattr(self, n) is not None for n in _NEEDS_ATTITUDE[self.kind])

    def missing_attitude(self) -> str:
        """The message for a world that needs the attitude from the files and did not get it."""
        keys = " and ".join(f"'{n}'" for n in _NEEDS_ATTITUDE[self.kind])
        return f"kind '{self.kind}' needs {keys} (or attitude = \"look_at\")"

    def frame_times(self) -> list[float]:
        """Time of every frame on the trajectory's axis (``times_s``, else ``start_s + k·dt_s``)."""
        if self.times_s is not None:
            return [float(t) for t in self.times_s]
        return [self.start_s + k * self.dt_s for k in range(self.frames)]
