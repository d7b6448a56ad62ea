"""granpipe.figures: one module per study, and the one way figures are written."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["save_figure"]


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
