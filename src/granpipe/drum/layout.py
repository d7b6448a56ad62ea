"""Where the drum study's files live, relative to ``results/<scale>/drum/``.

One parameter point (the paper's drum), named after its size and period, e.g.
``N=736,period=900s``. Replicas come in fixed batches of ``ensemble.batch_size``
(:func:`granpipe.seeds.batch_replicas`), so a larger ``n_replicas`` only appends
batches. The workflow (``workflow/rules/drum.smk``) and ``granpipe status`` list
files through these functions.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from .settings import filled

__all__ = [
    "point_name",
    "batch_ids",
    "n_batches",
    "init_file",
    "run_file",
    "run_files",
    "init_files",
    "ensemble_file",
    "fits_file",
    "summary_file",
    "FIGURES",
    "figure_files",
]

FIGURES = {
    2: "snapshot",
    3: "onset",
    4: "decay",
    5: "lambda_vs_speed",
}
"""Figure number -> name: ``figures/fig<k>_<name>.{png,pdf}``."""


def point_name(section: Mapping) -> str:
    """Name of the parameter point, e.g. ``N=736,period=900s``."""
    ph = filled(section)["physics"]
    n = int(ph["n_small"]) + int(ph["n_large"])
    period_s = 2.0 * math.pi / float(ph["omega"]) * float(ph["t0_s"])
    return f"N={n},period={period_s:.4g}s"


def n_batches(section: Mapping) -> int:
    ens = filled(section)["ensemble"]
    return -(-int(ens["n_replicas"]) // int(ens["batch_size"]))


def batch_ids(section: Mapping) -> list[str]:
    """Batch labels ``0000``, ``0001``, ... covering ``ensemble.n_replicas``."""
    return [f"{b:04d}" for b in range(n_batches(section))]


def init_file(section: Mapping, batch: str | int) -> str:
    return f"init/{point_name(section)}/batch_{int(batch):04d}.nc"


def run_file(section: Mapping, batch: str | int) -> str:
    return f"runs/{point_name(section)}/batch_{int(batch):04d}.nc"


def init_files(section: Mapping) -> list[str]:
    """Init files relative to ``results/<scale>/drum/``."""
    point = point_name(section)
    return [f"init/{point}/batch_{b}.nc" for b in batch_ids(section)]


def run_files(section: Mapping) -> list[str]:
    """Run files relative to ``results/<scale>/drum/`` (used by ``granpipe status``)."""
    point = point_name(section)
    return [f"runs/{point}/batch_{b}.nc" for b in batch_ids(section)]


def ensemble_file(section: Mapping) -> str:
    return f"ensemble/{point_name(section)}.nc"


def fits_file(section: Mapping) -> str:
    return f"fits/{point_name(section)}.nc"


def summary_file() -> str:
    return "fits/summary.csv"


def figure_files(exts=("png", "pdf")) -> list[str]:
    return [f"figures/fig{k}_{name}.{ext}" for k, name in FIGURES.items() for ext in exts]
