"""granpipe.figures: one module per study, the one way figures are written, and the one
way disks are drawn."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

__all__ = ["save_figure", "disk_map"]


def save_figure(fig, stem: str | os.PathLike, dpi: int = 150) -> list[Path]:
    """Write ``<stem>.png`` (at ``dpi``) and ``<stem>.pdf`` atomically, close the figure.

    Returns the two paths. Every study's figures stage writes through this function.
    """
    import matplotlib.pyplot as plt

    from ..io import atomic_path

    stem = Path(stem)
    paths = []
    for ext in ("png", "pdf"):
        path = stem.with_name(f"{stem.name}.{ext}")
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format=ext, dpi=dpi, bbox_inches="tight")
        paths.append(path)
    plt.close(fig)
    return paths


def disk_map(ax, xy, diameters, values, *, cmap="jet", label="", vmax=None, walls=None,
             wall_diameter=None):  # fmt: skip
    """Draw disks (centres ``xy`` (N, 2), ``diameters`` (N,), data units) coloured by
    ``values`` (N,) on ``ax``, with a colour bar ``label`` clipped at ``vmax`` (default:
    the 99th percentile, so that a few fast rattlers do not set the scale alone), and the
    wall disks (``walls`` (n, 2)) in grey; equal aspect, no ticks. Returns the collection."""
    import matplotlib.pyplot as plt
    from matplotlib.collections import EllipseCollection

    d = np.asarray(diameters, dtype=float)
    v = np.asarray(values, dtype=float)
    top = vmax if vmax is not None else float(np.nanpercentile(v, 99.0))
    disks = EllipseCollection(d, d, np.zeros_like(d), units="xy", offsets=xy,
                              offset_transform=ax.transData, cmap=plt.get_cmap(cmap),
                              edgecolors="k", linewidths=0.2)  # fmt: skip
    disks.set_array(v)
    disks.set_clim(0.0, max(top, 1e-12))
    ax.add_collection(disks)
    extent = np.abs(np.asarray(xy)).max() + d.max()
    if walls is not None and len(walls):
        w = np.full(len(walls), float(wall_diameter))
        ax.add_collection(EllipseCollection(w, w, np.zeros_like(w), units="xy", offsets=walls,
                                            offset_transform=ax.transData, facecolors="0.6",
                                            edgecolors="0.3", linewidths=0.2))  # fmt: skip
        extent = np.abs(np.asarray(walls)).max() + float(wall_diameter)
    ax.set_xlim(-extent, extent)
    ax.set_ylim(-extent, extent)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    cb = ax.figure.colorbar(disks, ax=ax, shrink=0.7, extend="max")
    cb.set_label(label)
    return disks
