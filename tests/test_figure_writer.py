"""The lab's one figure writer (:func:`renderlab.contracts.result_folder.save_figure`): a 100-dpi palette PNG that
decodes (OpenCV, an independent decoder) to matplotlib's own anti-aliased drawing within a few levels, carries no
text, time or size chunk, and is the same bytes for the same figure; SVG only inside ``with_svg``; nothing under
``tables_only``. Every report module saves through it (no other ``savefig`` to a file in the package)."""

from __future__ import annotations

import ast
import struct
from pathlib import Path

import numpy as np

from renderlab.contracts.result_folder import (
    FIGURE_DPI,
    figure_png,
    save_figure,
    tables_only,
    with_svg,
)
from renderlab.report import style

PACKAGE = Path(__file__).resolve().parents[1] / "renderlab"


def _figure():
    plt = style.plt()
    fig, ax = plt.subplots(figsize=(4.0, 3.0))
    x = np.linspace(0, 10, 400)
    for k, colour in enumerate(style.OKABE_ITO[:4]):
        ax.plot(x, np.sin(x + k), color=colour, label=f"line {k}")
    ax.imshow(np.outer(np.linspace(0, 1, 64), np.ones(64)), extent=(0, 2, -1, 0), cmap="viridis", aspect="auto")
    ax.set(xlabel="time (s)", ylabel="value (m)")
    ax.legend()
    return fig


def _chunks(png: bytes) -> list[bytes]:
    out, k = [], 8
    while k < len(png):
        n, kind = struct.unpack(">I4s", png[k:k + 8])
        out.append(kind)
        k += 12 + n
    return out


def test_palette_png_decodes_to_matplotlibs_drawing_and_repeats_byte_for_byte(tmp_path):
    import cv2
    from PIL import Image

    fig = _figure()
    fig.set_dpi(FIGURE_DPI)
    fig.canvas.draw()
    drawn = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(float)  # Agg's RGB at the writer's dpi
    png = figure_png(fig)
    again = figure_png(_figure())
    assert png == again, "the same figure gives the same bytes"
    assert _chunks(png) in (
        [b"IHDR", b"PLTE", b"IDAT", b"IEND"], [b"IHDR", b"PLTE", b"IDAT", b"IDAT", b"IEND"]), _chunks(png)
    (tmp_path / "f.png").write_bytes(png)
    with Image.open(tmp_path / "f.png") as im:
        assert im.mode == "P" and len(im.getpalette()) // 3 <= 256 and im.size == (400, 300)
    decoded = cv2.imread(str(tmp_path / "f.png"), cv2.IMREAD_COLOR)[..., ::-1].astype(float)
    assert decoded.shape == drawn.shape
    diff = np.abs(decoded - drawn)
    assert diff.mean() < 1.0 and np.quantile(diff, 0.999) < 24, (diff.mean(), np.quantile(diff, 0.999))
    assert len(png) < 0.6 * len(_rgba_png(fig)), "the palette PNG is smaller than matplotlib's RGBA PNG"
    style.plt().close("all")


def _rgba_png(fig) -> bytes:
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=FIGURE_DPI)
    return buf.getvalue()


def test_svg_on_demand_and_nothing_under_tables_only(tmp_path):
    assert save_figure(_figure(), tmp_path / "a") == ["a.png", None]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png"]
    with with_svg():
        assert save_figure(_figure(), tmp_path / "b") == ["b.png", "b.svg"]
    svg = (tmp_path / "b.svg").read_text()
    assert svg.lstrip().startswith("<?xml") and "<dc:date>" not in svg
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()
    with tables_only():
        assert style.save(_figure(), tmp_path / "c") == ["c.png", None]
    assert not (tmp_path / "c.png").exists()
    assert not style.plt().get_fignums(), "every figure closed"


def test_no_other_figure_writer_in_the_package():
    """Only the writer itself calls ``savefig``: every report, study and command goes through it."""
    calls = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "savefig":
                calls.append(path.relative_to(PACKAGE).as_posix())
    assert sorted(set(calls)) == ["contracts/result_folder.py"], calls
