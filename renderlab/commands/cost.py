"""The request checks and the cost model: what a request is and what it will cost, before anything runs.

Request checks: path arguments (:func:`check_path`), the scenario file (:func:`check_input_file`: a regular file
of sane size, never a FIFO or a folder), ``--set`` keys (:func:`check_overrides`) and :func:`load_checked`, the
scenario loader behind them (input nested too deeply or too large is refused, not a traceback).

Cost model:

Every key of a scenario has its own limit, but keys multiply: ``render.spp = 65536`` is valid and so is a
256 × 192 camera, yet together they need 51 GB of sub-pixel offsets; an EV5 ``world.facet_m = 0.3`` asks for
21 M global facets; ``world.site.cell_m = 0.001`` for 4 G site cells. :func:`estimate` turns a validated
scenario (and the frame and run counts of the command) into pixels × spp × frames × runs, EV5 global facets
and site cells, the peak memory of one run and the disk the outputs take; :func:`check` refuses a request past
:data:`LIMITS` (or past the free disk space) with the estimate in the one-line message. ``--allow-large``
(``render``, ``campaign``, ``crosscheck``, ``visibility``) lifts the limits: the user asks for it explicitly.

The numbers are estimates (upper-side, from the data the code allocates per frame and per site cell), meant
to tell a typo from a real job, not to predict the run to the byte.

Light: standard library only (no numpy), so a refused request costs milliseconds.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import stat
from dataclasses import dataclass
from pathlib import Path

from renderlab.errors import UserError

GIB = 1024 ** 3
MAX_SCENARIO_BYTES = 16 * 1024 * 1024
MAX_SET_DEPTH = 32
_KEY_PART = re.compile(r"^(?:[A-Za-z_][A-Za-z0-9_-]{0,63}|[0-9]{1,9})$")

#: default limits, lifted by ``--allow-large``
LIMITS = {
    "samples": 1e11,  # pixels × spp × frames × runs (≈ 500 runs of the shipped EV5 descent)
    "memory_bytes": 8 * GIB,  # peak of one run (one worker process)
    "disk_bytes": 200 * GIB,  # everything the request writes
    "facets": 8e6,  # EV5 global facets (icosphere level 9 = 5.2 M; the shipped scene has 1.3 M)
    "site_cells": 64e6,  # EV5 site grid points (the shipped scene has 10.2 M)
    "visibility_images": 2e7,  # images × inclinations × FOVs of ``renderlab visibility``
}
MAX_VISIBILITY_STEPS = 1_000_000  # images per orbit track (24 h at 30 s is 2 880)

#: bytes per pixel and frame in memory besides the sub-pixel offsets (AOVs, accumulators, sensor, EXR buffers)
BYTES_PER_PIXEL = 256
BYTES_PER_SAMPLE = 16  # the (spp, pixels, 2) float64 sub-pixel offsets of a frame
BYTES_PER_FACET = 200  # vertices, faces, per-vertex albedo and the renderer's BVH
BYTES_PER_SITE_CELL = 300  # heights, albedo, normals, the site mesh (2 triangles) and its BVH
DISK_PER_PIXEL = 40  # one frame on disk: float EXR channels, DN PNG, preview
DISK_PER_SITE_CELL = 16


@dataclass(frozen=True)
class Estimate:
    """The cost of a request (see the module docstring)."""

    pixels: int
    spp: int
    frames: int
    runs: int
    facets: int
    site_cells: int
    memory_bytes: int
    disk_bytes: int

    @property
    def samples(self) -> int:
        """pixels × spp × frames × runs."""
        return self.pixels * self.spp * self.frames * self.runs

    def describe(self) -> str:
        """One line: the factors and the totals."""
        parts = [f"{self.pixels} px × {self.spp} spp × {self.frames} frames × {self.runs} runs = "
                 f"{self.samples:.3g} samples"]
        if self.facets or self.site_cells:
            parts.append(f"{self.facets:.3g} global facets, {self.site_cells:.3g} site cells")
        parts.append(f"~{_size(self.memory_bytes)} memory per run, ~{_size(self.disk_bytes)} on disk")
        return "; ".join(parts)


def _size(n: float) -> str:
    for unit, scale in (("TiB", 1024 ** 4), ("GiB", GIB), ("MiB", 1024 ** 2), ("KiB", 1024)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{int(n)} B"


def frame_count(scenario) -> int:
    """Frames the scenario's trajectory asks for (EV5 ``altitudes_m`` or a camera path's ``times_s`` when given,
    else ``frames``)."""
    traj = scenario.trajectory
    for key in ("altitudes_m", "times_s"):
        listed = getattr(traj, key, None)
        if listed is not None:
            return len(listed)
    return int(getattr(traj, "frames", 1))


def ev5_facets(world) -> int:
    """Global facets of the procedural EV5 body (``world.facet_m`` → icosphere level), 0 for a shape file."""
    if getattr(world, "shape_file", None):
        return 0
    a, b, c = (float(v) / 2 for v in world.size_m)
    radius = (a * b * c) ** (1 / 3)
    for level in range(0, 16):
        area = 4 * math.pi * radius ** 2 / (20 * 4 ** level)
        if math.sqrt(4 * area / math.sqrt(3)) <= world.facet_m:
            return 20 * 4 ** level
    return 20 * 4 ** 16


def ev5_site_cells(world) -> int:
    """Grid points of the EV5 landing site: (extent_m / cell_m + 1)²."""
    n = round(world.site.extent_m / world.site.cell_m) + 1
    return int(n) ** 2


def estimate(scenario, *, frames: int | None = None, runs: int = 1, renders: int = 1) -> Estimate:
    """The cost of rendering ``scenario`` (``frames`` caps the trajectory's, as ``--frames`` does) ``runs`` times;
    ``renders`` renders per run (``crosscheck``: 2, Mitsuba and Cycles)."""
    n_frames = frame_count(scenario)
    if frames is not None:
        n_frames = min(n_frames, int(frames))
    pixels = int(scenario.camera.width) * int(scenario.camera.height)
    spp = 1 if scenario.render.pixel_filter == "center" else int(scenario.render.spp)
    world = scenario.world
    facets = cells = 0
    extra_mem = extra_disk = 0
    if world.kind == "ev5":
        facets, cells = ev5_facets(world), ev5_site_cells(world)
        extra_mem = facets * BYTES_PER_FACET + cells * BYTES_PER_SITE_CELL
        extra_disk = cells * DISK_PER_SITE_CELL
    elif world.kind == "earth":  # ground texture: oversampled and antialiased per pixel, 8 B per texel
        extra_mem = int(pixels * world.texture_oversample ** 2 * world.antialias ** 2 * 8)
    memory = pixels * (spp * BYTES_PER_SAMPLE + BYTES_PER_PIXEL) + extra_mem
    disk = runs * renders * (n_frames * pixels * DISK_PER_PIXEL + extra_disk)
    return Estimate(pixels, spp * renders, n_frames, int(runs), facets, cells, int(memory), int(disk))


def _free_bytes(out: Path) -> int | None:
    """Free bytes on the file system that would hold ``out`` (its nearest existing ancestor)."""
    p = Path(os.path.abspath(out))
    while not p.exists() and p != p.parent:
        p = p.parent
    try:
        return shutil.disk_usage(p).free
    except OSError:
        return None


def check(est: Estimate, *, out: Path | None = None, allow_large: bool = False, what: str = "request") -> Estimate:
    """Refuse ``est`` past :data:`LIMITS` or the free space at ``out`` (unless ``allow_large``).

    Raises
    ------
    UserError
        Naming the limit passed and the whole estimate; ``--allow-large`` lifts the limits.
    """
    if est.frames < 1:
        raise UserError(f"{what}: the trajectory has no frames (an empty altitudes_m list?)")
    if allow_large:
        return est
    over = []
    if est.samples > LIMITS["samples"]:
        over.append(f"{est.samples:.3g} samples > {LIMITS['samples']:.3g}")
    if est.memory_bytes > LIMITS["memory_bytes"]:
        over.append(f"~{_size(est.memory_bytes)} memory per run > {_size(LIMITS['memory_bytes'])}")
    if est.disk_bytes > LIMITS["disk_bytes"]:
        over.append(f"~{_size(est.disk_bytes)} on disk > {_size(LIMITS['disk_bytes'])}")
    if est.facets > LIMITS["facets"]:
        over.append(f"{est.facets:.3g} global facets > {LIMITS['facets']:.3g} (world.facet_m)")
    if est.site_cells > LIMITS["site_cells"]:
        over.append(f"{est.site_cells:.3g} site cells > {LIMITS['site_cells']:.3g} (world.site.extent_m / cell_m)")
    free = _free_bytes(out) if out is not None else None
    if free is not None and est.disk_bytes > free:
        over.append(f"~{_size(est.disk_bytes)} on disk > {_size(free)} free at {out}")
    if over:
        raise UserError(f"{what} is too large: {'; '.join(over)} (estimate: {est.describe()}); "
                        "pass --allow-large to run it anyway")
    return est


def check_scenario(scenario, *, frames: int | None = None, runs: int = 1, renders: int = 1, out=None,
                   allow_large: bool = False, what: str = "scenario") -> Estimate:
    """:func:`estimate` then :func:`check` (what the commands call before anything runs)."""
    est = estimate(scenario, frames=frames, runs=runs, renders=renders)
    return check(est, out=None if out is None else Path(out), allow_large=allow_large, what=what)


def check_visibility(hours: float, cadence_s: float, n_inclinations: int, n_fovs: int, *,
                     allow_large: bool = False) -> int:
    """Images per orbit track of ``renderlab visibility``; refuse a sweep past the limits.

    Raises
    ------
    UserError
        Non-finite or non-positive ``hours``/``cadence_s``, or a sweep past :data:`MAX_VISIBILITY_STEPS` /
        ``LIMITS["visibility_images"]`` without ``allow_large``.
    """
    for flag, v in (("--hours", hours), ("--cadence-s", cadence_s)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise UserError(f"{flag} must be a finite positive number, got {v}")
    steps = math.ceil(hours * 3600.0 / cadence_s)
    total = steps * n_inclinations * n_fovs
    if not allow_large and (steps > MAX_VISIBILITY_STEPS or total > LIMITS["visibility_images"]):
        raise UserError(f"visibility sweep is too large: {steps:.3g} images per track (limit "
                        f"{MAX_VISIBILITY_STEPS:.3g}) × {n_inclinations} inclinations × {n_fovs} FOVs = {total:.3g} "
                        f"(limit {LIMITS['visibility_images']:.3g}); shorten --hours, raise --cadence-s or pass "
                        "--allow-large")
    return steps


# ----------------------------------------------------------------------------------------- request checks
def check_path(text, flag: str) -> Path:
    """A path argument: non-empty, no NUL, at most 4095 bytes and components of at most 255 bytes."""
    if not isinstance(text, str) or not text.strip():
        raise UserError(f"{flag} must not be empty")
    if "\0" in text:
        raise UserError(f"{flag} contains a NUL character")
    try:
        raw = os.fsencode(text)
    except UnicodeError:
        raise UserError(f"{flag}: the path cannot be encoded for this file system") from None
    if len(raw) > 4095:
        raise UserError(f"{flag}: the path is longer than 4095 bytes")
    for part in raw.split(b"/"):
        if len(part) > 255:
            raise UserError(f"{flag}: path component {os.fsdecode(part[:24])!r}… is longer than 255 bytes")
    return Path(text)


def check_input_file(path, what: str = "scenario") -> Path:
    """A file to read: exists, is a regular file (not a folder, FIFO or device), at most 16 MiB."""
    p = check_path(str(path), what)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise UserError(f"{what} file not found: {path}") from None
    except OSError as exc:
        raise UserError(f"cannot read {what} file {path}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(st.st_mode):
        raise UserError(f"{what} {path} is a folder, not a file")
    if not stat.S_ISREG(st.st_mode):
        raise UserError(f"{what} {path} is not a regular file (a FIFO, socket or device)")
    if st.st_size > MAX_SCENARIO_BYTES:
        raise UserError(f"{what} file {path} is {st.st_size} bytes (more than {MAX_SCENARIO_BYTES}); not a scenario")
    return p


def check_overrides(overrides: list[str]) -> None:
    """``--set`` keys: dotted plain names (letters, digits, ``_``, ``-``) and list indices, at most 32 deep."""
    for text in overrides:
        if "\0" in text:
            raise UserError("--set contains a NUL character")
        key = text.split("=", 1)[0].strip()
        parts = key.split(".")
        if len(parts) > MAX_SET_DEPTH:
            raise UserError(f"--set {key[:60]}…: more than {MAX_SET_DEPTH} levels of keys")
        for part in parts:
            if part and not _KEY_PART.match(part):
                raise UserError(f"--set {key[:80]}: {part[:40]!r} is not a key name (letters, digits, _ and -, "
                                "at most 64) or a list index")


MAX_KEY_PARTS = 64


def toml_key_parts(text: str) -> int:
    """The most dotted parts of any key (``a.b.c = ...``, ``[a.b.c]``) in TOML ``text``, by a linear scan:
    tomllib takes quadratic time on very long dotted keys (100 000 parts: minutes), so they are refused first."""
    most, quote, pos, n = 0, "", 0, len(text)
    while pos < n:
        end = text.find("\n", pos)
        end = n if end < 0 else end
        line = text[pos:end]
        pos = end + 1
        if quote:  # inside a multi-line string: look for its end only
            if quote in line:
                quote = ""
            continue
        parts, q, i, in_key = 1, "", 0, True
        while i < len(line):
            c = line[i]
            if q:
                if c == "\\" and q == '"':
                    i += 1
                elif c == q:
                    q = ""
            elif line.startswith(('"""', "'''"), i):
                if line.count(line[i:i + 3]) % 2:
                    quote = line[i:i + 3]
                break
            elif c in "\"'":
                q = c
            elif c == "#":
                break
            elif c in "=]{,":  # a key ends; one starts again inside an inline table (or an array item)
                most, parts, in_key = max(most, parts), 1, c in "{,"
            elif c == "." and in_key:
                parts += 1
            i += 1
        most = max(most, parts)
    return most


def load_checked(path, overrides: list[str] | None = None):
    """:func:`renderlab.scenario.load_scenario` behind the request checks: the file, the ``--set`` keys, and
    refusals instead of tracebacks for input nested too deeply or too large to hold."""
    from renderlab.scenario import load_scenario

    p = check_input_file(path)
    check_overrides(list(overrides or []))
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        text = ""  # load_scenario names it: not a text file
    except OSError as exc:
        raise UserError(f"cannot read scenario file {path}: {exc.strerror or exc}") from None
    for where, t in [(p.name, text), *(("--set", o.partition("=")[2]) for o in overrides or [])]:
        if toml_key_parts(t) > MAX_KEY_PARTS:
            raise UserError(f"{where}: a key with more than {MAX_KEY_PARTS} dotted parts (nested too deeply)")
    try:
        return load_scenario(p, list(overrides or []))
    except RecursionError:
        raise UserError(f"{p.name}: scenario (or a --set value) is nested too deeply") from None
    except MemoryError:
        raise UserError(f"{p.name}: scenario (or a --set value) is too large to hold in memory") from None
    except ValueError as err:  # tomllib: an integer of more than 4300 digits, and the like
        raise UserError(f"{p.name}: not a valid scenario ({' '.join(str(err).split())[:200]})") from None
