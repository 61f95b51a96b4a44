"""Geometry of a Chibis-M-like microsatellite as flat-faceted triangle meshes (body frame, metres).

Body frame = principal axes of the inertia tensor, origin at the centre of mass (the bus centre).
Parts: a box bus, two thin solar panels along ±y, ``n_antennas`` thin square rods leaving the bus
corners, and a small bright sphere ("knob") on every antenna tip. The knobs are the reference
features of Ivanov et al. (§3, Fig. 3: "the tips of the antennas"): in the flight video (Figs 10-11)
the long antennas are the brightest, thinnest details and their tips appear as isolated bright
points after thresholding; a small high-albedo knob reproduces that (a bright, compact blob whose
centroid is the tip) without relying on sub-pixel-wide rods being resolved by the renderer. The
knob centre is the truth position of each feature.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Part:
    """One rigid mesh part: ``vertices`` (V, 3) m in the body frame, ``faces`` (F, 3) counter-clockwise
    seen from outside."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    albedo: float


def _outward(V: np.ndarray, F: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Flip faces of a convex piece whose normal points toward ``centre``."""
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    n = np.cross(b - a, c - a)
    inward = np.einsum("ij,ij->i", n, (a + b + c) / 3 - centre) < 0
    F = F.copy()
    F[inward] = F[inward][:, [0, 2, 1]]
    return F


def box_mesh(centre, half, R=np.eye(3)) -> tuple[np.ndarray, np.ndarray]:
    """A box (12 triangles) with half-extents ``half`` along the columns of ``R``."""
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    V = np.asarray(centre, float) + (signs * np.asarray(half, float)) @ np.asarray(R, float).T
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    F = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    return V, _outward(V, F, np.asarray(centre, float))


def rod_mesh(p0, p1, width: float) -> tuple[np.ndarray, np.ndarray]:
    """A square-section rod from ``p0`` to ``p1``."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    axis = (p1 - p0) / np.linalg.norm(p1 - p0)
    helper = np.array([1.0, 0, 0]) if abs(axis[0]) < 0.9 else np.array([0, 1.0, 0])
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    R = np.column_stack([axis, u, v])
    return box_mesh((p0 + p1) / 2, [np.linalg.norm(p1 - p0) / 2, width / 2, width / 2], R)


def icosphere(centre, radius: float, subdivisions: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """A geodesic sphere (20·4^subdivisions triangles) inscribed in the sphere of ``radius``."""
    t = (1 + 5**0.5) / 2
    V = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
         [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    F = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
         [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11],
         [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    V = [np.array(v, float) / np.linalg.norm(v) for v in V]
    for _ in range(subdivisions):
        cache, newF = {}, []

        def mid(i, j):
            key = (min(i, j), max(i, j))
            if key not in cache:
                m = V[i] + V[j]
                V.append(m / np.linalg.norm(m))
                cache[key] = len(V) - 1
            return cache[key]

        for a, b, c in F:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            newF += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        F = newF
    Vc = np.asarray(centre, float) + radius * np.array(V)
    return Vc, _outward(Vc, np.array(F), np.asarray(centre, float))


def merge(pieces) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate (V, F) pieces into one mesh."""
    Vs, Fs, off = [], [], 0
    for V, F in pieces:
        Vs.append(V)
        Fs.append(F + off)
        off += len(V)
    return np.vstack(Vs), np.vstack(Fs)


def antenna_geometry(world, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Antenna roots on the bus and tip (knob centre) positions, each (n_antennas, 3).

    Antennas leave alternate top/bottom bus corners, pointing outward and tilted toward ±z, with a
    seeded jitter of up to ``antenna_jitter_deg`` on the direction, so the tips are not coplanar.
    """
    hx, hy, hz = np.asarray(world.bus_size_m) / 2
    n = world.n_antennas
    roots, tips = [], []
    for k in range(n):
        az = 2 * np.pi * (k + 0.5) / n
        zsign = 1.0 if k % 2 == 0 else -1.0
        root = np.array([hx * np.sign(np.cos(az)) * min(1, abs(np.cos(az)) * 1.5),
                         hy * np.sign(np.sin(az)) * min(1, abs(np.sin(az)) * 1.5), zsign * hz])
        d = np.array([np.cos(az), np.sin(az), zsign * (0.35 + 0.35 * (k % 3) / 2)])
        d /= np.linalg.norm(d)
        jit = np.radians(world.antenna_jitter_deg) * rng.uniform(-1, 1, 3)
        d = d + np.cross(jit, d)
        d /= np.linalg.norm(d)
        roots.append(root)
        tips.append(root + d * world.antenna_length_m)
    return np.array(roots), np.array(tips)


def box_parts(world) -> list[tuple[np.ndarray, np.ndarray]]:
    """(centre, half-extent) of the axis-aligned boxes, body frame: the bus, then the two solar panels along ±y."""
    hx, hy, hz = np.asarray(world.bus_size_m) / 2
    pw, pl = world.panel_size_m
    return [(np.zeros(3), np.array([hx, hy, hz])),
            *((np.array([0.0, s * (hy + 0.01 + pl / 2), 0.0]), np.array([pw / 2, pl / 2, 0.004])) for s in (-1, 1))]


def build_parts(world) -> tuple[list[Part], np.ndarray]:
    """Mesh parts of the satellite and the true feature positions (knob centres, (n, 3), body frame)."""
    rng = np.random.default_rng(world.seed)
    boxes = box_parts(world)
    bus = box_mesh(*boxes[0])
    panels = merge([box_mesh(*b) for b in boxes[1:]])
    roots, tips = antenna_geometry(world, rng)
    r = world.knob_radius_m
    rods = merge([rod_mesh(a, b - (b - a) / np.linalg.norm(b - a) * 0.5 * r, world.antenna_width_m)
                  for a, b in zip(roots, tips)])
    parts = [Part("bus", *bus, world.albedo_bus), Part("panels", *panels, world.albedo_panel),
             Part("antennas", *rods, world.albedo_antenna)]
    for k, tip in enumerate(tips):
        parts.append(Part(f"knob{k}", *icosphere(tip, r, 2), world.albedo_knob))
    return parts, tips


#: body id of each part kind; knob k has KNOB_ID0 + k
PART_IDS = {"bus": 0, "panels": 1, "antennas": 2}
KNOB_ID0 = 10
