"""Preview figures of a truth set: the sensor images of every frame and the truth AOVs of one. Images are resampled
to the panel with matplotlib's anti-aliased filter after colour mapping (``interpolation="antialiased"``,
``interpolation_stage="rgba"``): a 1024² frame in a 300-pixel panel keeps its texture instead of nearest-neighbour
moiré, and a categorical map (body ids) is never averaged into a wrong category's colour."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.contracts.result_folder import save_figure

#: imshow keywords of every image panel (module docstring)
SMOOTH = {"interpolation": "antialiased", "interpolation_stage": "rgba"}


def _normal_rgb(n: np.ndarray) -> np.ndarray:
    rgb = 0.5 * (np.nan_to_num(n, nan=0.0) + 1.0)
    rgb[np.isnan(n).any(axis=-1)] = 0.0
    return np.clip(rgb, 0, 1)


def truthset_preview(ts, out_png: Path, *, frame: int = 0, residual: np.ndarray | None = None,
                     title: str = "") -> Path:
    """Write a PNG: top row the DN images of up to 4 frames, bottom row range, normals, ids and an
    optional residual map of ``frame``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n_top = min(4, len(ts))
    fig, axes = plt.subplots(2, 4, figsize=(13, 6.2), constrained_layout=True)
    for k in range(4):
        ax = axes[0, k]
        if k < n_top:
            f = ts.load(k)
            bits = int(f.meta.get("sensor", {}).get("bits", 10))
            ax.imshow(f.dn, cmap="gray", vmin=0, vmax=2**bits - 1, **SMOOTH)
            ax.set_title(f"frame {k}: sensor DN ({bits}-bit)", fontsize=9)
        ax.axis("off")
    f = ts.load(frame)
    im = axes[1, 0].imshow(np.where(f.id >= 0, f.range, np.nan), cmap="viridis", **SMOOTH)
    fig.colorbar(im, ax=axes[1, 0], shrink=0.8, label="range (m)")
    axes[1, 0].set_title(f"frame {frame}: range AOV", fontsize=9)
    axes[1, 1].imshow(_normal_rgb(f.normal), **SMOOTH)
    axes[1, 1].set_title("shading normal AOV (render frame)", fontsize=9)
    im = axes[1, 2].imshow(np.where(f.id >= 0, f.id, np.nan), cmap="tab10", **SMOOTH)
    axes[1, 2].set_title("body id AOV", fontsize=9)
    if residual is not None:
        lim = max(1e-6, float(np.nanpercentile(np.abs(residual), 99.5)))
        im = axes[1, 3].imshow(residual, cmap="coolwarm", vmin=-lim, vmax=lim, **SMOOTH)
        fig.colorbar(im, ax=axes[1, 3], shrink=0.8, label="relative error")
        axes[1, 3].set_title("Lambert radiance − A·E·cos i/π (relative)", fontsize=9)
    for ax in axes[1]:
        ax.axis("off")
    if title:
        fig.suptitle(title, fontsize=11)
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, out_png.with_suffix(""))  # the lab's one figure writer (100-dpi palette PNG)
    return out_png.with_suffix(".png")
