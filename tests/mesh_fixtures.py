"""Mesh files for the mesh-reader and renderer tests (test helper, not part of renderlab): a unit box with quad
faces written as plain OBJ/PLY (trimesh cannot export quads), and trimesh's own exporters."""

from __future__ import annotations

import numpy as np

BOX_V = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)], float)
BOX_QUADS = np.array([(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])


def write_quad_box(path, scale: float = 1.0, encoding: str = "ascii"):
    """A unit box with 6 quad faces (outward, counter-clockwise) as OBJ or PLY (ascii / binary_little_endian)."""
    V = BOX_V * scale
    if path.suffix == ".obj":
        path.write_text("".join(f"v {a!r} {b!r} {c!r}\n" for a, b, c in V)
                        + "".join("f " + " ".join(str(i + 1) for i in q) + "\n" for q in BOX_QUADS))
        return path
    head = (f"ply\nformat {encoding} 1.0\nelement vertex {len(V)}\nproperty float x\nproperty float y\n"
            f"property float z\nelement face {len(BOX_QUADS)}\nproperty list uchar int vertex_indices\nend_header\n")
    if encoding == "ascii":
        body = ("".join(f"{a!r} {b!r} {c!r}\n" for a, b, c in V)
                + "".join("4 " + " ".join(map(str, q)) + "\n" for q in BOX_QUADS)).encode()
    else:
        face = np.zeros(len(BOX_QUADS), [("n", "u1"), ("i", "<i4", (4,))])
        face["n"], face["i"] = 4, BOX_QUADS
        body = V.astype("<f4").tobytes() + face.tobytes()
    path.write_bytes(head.encode() + body)
    return path


def write_trimesh(path, mesh, **kw):
    """Export with trimesh's own writer for the file's extension."""
    mesh.export(str(path), file_type=path.suffix[1:], **kw)
    return path
