"""Where the shear study's files live, its parameter points, cross-key checks and the
config subset of each rule (used by workflow/rules/shear.smk; docs/architecture.md).

A point is one packing fraction, named ``phi=0.82``. Paths are relative to
``results/<scale>/shear/``: ``runs/<point>/batch_<b>.nc``, ``fits/<point>.nc``,
``fits/summary.csv``, ``figures/fig<k>_<name>.png``.

    >>> point_name(0.82)
    'phi=0.82'
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from ..errors import ConfigError

__all__ = ["check", "FIGURES", "point_name", "phis", "points", "batches", "run_file",
           "fits_file", "physics_for", "runs_params", "fits_params", "summary_params",
           "figures_params", "run_files"]  # fmt: skip

FIGURES = ("fig1_lambda_vs_phi", "fig2_event_triggered", "fig3_contrast", "fig4_chaos_map")


def point_name(phi: float | str) -> str:
    """``phi=<φ>`` (a wildcard's text or a number)."""
    return f"phi={float(phi):g}"


def phis(cfg: Mapping) -> list[float]:
    p = cfg["physics"]["phi"]
    return sorted(float(x) for x in (p if isinstance(p, list | tuple) else [p]))


def points(cfg: Mapping) -> list[str]:
    return [point_name(x) for x in phis(cfg)]


def batches(cfg: Mapping) -> list[str]:
    e = cfg["ensemble"]
    return [f"{b:04d}" for b in range(-(-int(e["n_replicas"]) // int(e["batch_size"])))]


def run_file(point: str, batch: str) -> str:
    return f"runs/{point}/batch_{batch}.nc"


def fits_file(point: str) -> str:
    return f"fits/{point}.nc"


def physics_for(cfg: Mapping, point: str) -> dict:
    """The physics section at one point (``phi`` one number, as its name says)."""
    phi = float(point.split("=", 1)[1])
    if phi not in phis(cfg):
        raise ConfigError(f"point {point!r} is not in 'shear.physics.phi' = {phis(cfg)}")
    return {**cfg["physics"], "phi": phi}


BYTES_PER_DISK = 4096
"""A generous bound on a job's memory per disk (engine state, neighbour list, Delaunay)."""


def check(cfg: Mapping) -> None:
    """Cross-key checks before any job (ConfigError names the key): every point's disks fit
    the placement rings and the annulus is wider than two disks; the sample holds whole
    blocks; the aligned window lies inside the record; the contrast figure's φ is a point;
    the plan is not too large."""
    import numpy as np

    from ..config import check_memory, check_plan
    from .model import ShearCell, n_disks
    from .preparation import placement

    ph, pr, fits = cfg["physics"], cfg["protocol"], cfg["fits"]
    if int(ph["n_outer"]) <= int(ph["n_inner"]):
        raise ConfigError("config key 'shear.physics.n_outer' must exceed 'n_inner' (the outer "
                          "ring encloses the inner)")  # fmt: skip
    n_phi = len(ph["phi"]) if isinstance(ph["phi"], list | tuple) else 1
    e = cfg["ensemble"]  # the plan and each job's memory, counted before anything is built
    jobs = n_phi * -(-int(e["n_replicas"]) // int(e["batch_size"]))
    check_plan("shear.ensemble.n_replicas", jobs, "raise 'shear.ensemble.batch_size' or list "
               "fewer phi")  # fmt: skip
    disks = n_disks({**ph, "phi": max(phis(cfg))}) + int(ph["n_inner"]) + int(ph["n_outer"])
    check_memory("shear.physics.n_outer", ph["n_outer"], BYTES_PER_DISK * disks)
    blocks = float(pr["record_s"]) / float(pr["block_s"])
    check_memory(
        "shear.protocol.record_s", pr["record_s"], 16.0 * blocks * (2 + int(e["batch_size"]))
    )
    prep = cfg["preparation"]
    for point in points(cfg):
        cell = ShearCell.from_physics(physics_for(cfg, point))
        if cell.r_out - cell.r_in < 2.0 * float(ph["d_large"]):
            raise ConfigError("config key 'shear.physics.n_outer': the annulus is narrower "
                              "than two large disks")  # fmt: skip
        try:
            placement(cell, float(prep["start_scale"]), float(prep["gap"]),
                      np.random.default_rng(0))  # fmt: skip
        except RuntimeError as exc:
            raise ConfigError(
                f"config key 'shear.preparation.start_scale' at {point}: {exc}"
            ) from None
    contrast = cfg["figures"]["contrast_phi"]
    if contrast is not None and float(contrast) not in phis(cfg):
        raise ConfigError(f"config key 'shear.figures.contrast_phi' = {contrast} is not one of "
                          f"'shear.physics.phi' = {phis(cfg)}")  # fmt: skip
    if float(pr["sample_s"]) < float(pr["block_s"]):
        raise ConfigError("config key 'shear.protocol.sample_s' is shorter than 'block_s'")
    span = float(fits["aligned_before_s"]) + float(fits["aligned_after_s"])
    if span >= float(pr["record_s"]) or math.isclose(span, 0.0):
        raise ConfigError("config keys 'shear.fits.aligned_before_s' + 'aligned_after_s' must "
                          "be > 0 and shorter than 'shear.protocol.record_s'")  # fmt: skip


def runs_params(cfg: Mapping, point: str) -> dict:
    """A batch's subset: the point's physics, the preparation, the protocol, the edge
    cutoff (the network is compared in the run) and the batch size."""
    return {"point": point, "physics": physics_for(cfg, point),
            "preparation": cfg["preparation"], "protocol": cfg["protocol"],
            "events": {"edge_cutoff": cfg["events"]["edge_cutoff"]},
            "batch_size": cfg["ensemble"]["batch_size"]}  # fmt: skip


def fits_params(cfg: Mapping, point: str) -> dict:
    """A point's fits: the detector's thresholds, the analysis, and the hash of the run
    files it reads."""
    from ..io import config_hash

    ev = cfg["events"]
    return {"point": point, "runs_config_hash": config_hash(runs_params(cfg, point)),
            "n_replicas": cfg["ensemble"]["n_replicas"],
            "events": {"min_changes": ev["min_changes"], "quiet_s": ev["quiet_s"]},
            "fits": cfg["fits"]}  # fmt: skip


def summary_params(cfg: Mapping) -> dict:
    """The summary (and the zero crossing of ⟨λ⟩ in φ): each point's fits hash."""
    from ..io import config_hash

    f = cfg["fits"]
    return {"points": {p: config_hash(fits_params(cfg, p)) for p in points(cfg)},
            "bootstrap_resamples": f["bootstrap_resamples"], "confidence": f["confidence"],
            "seed": f["seed"]}  # fmt: skip


def figures_params(cfg: Mapping) -> dict:
    return {**summary_params(cfg), "dpi": cfg["figures"]["dpi"],
            "contrast_phi": cfg["figures"]["contrast_phi"]}  # fmt: skip


def run_files(cfg: Mapping) -> list[str]:
    """Every simulation output of the section (what ``granpipe status`` counts)."""
    return [run_file(p, b) for p in points(cfg) for b in batches(cfg)]
