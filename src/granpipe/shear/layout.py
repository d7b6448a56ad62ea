"""Where the shear study's files live, its parameter points, cross-key checks and the
config subset of each rule (used by workflow/rules/shear.smk; docs/architecture.md).

A point is one packing fraction of the base section, named ``phi=0.82``, or of a
variant (``shear.variants``: named overrides of the physics and the preparation, with a
φ grid of their own), named ``<variant>/phi=0.82``. Paths are relative to
``results/<scale>/shear/``: ``runs/<point>/batch_<b>.nc``, ``fits/<point>.nc``,
``fits/summary.csv``, ``figures/fig<k>_<name>.png``.

    >>> point_name(0.82)
    'phi=0.82'
    >>> point_name(0.82, "wide")
    'wide/phi=0.82'
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from ..errors import ConfigError

__all__ = ["check", "FIGURES", "point_name", "wildcards_point", "split_point", "variants",
           "phis", "points", "n_replicas", "batches", "run_file", "fits_file", "physics_for",
           "preparation_for", "runs_params", "fits_params", "summary_params", "figures_params",
           "run_files", "trajectory_params", "movie_point", "movie_params", "movie_input",
           "movie_file"]  # fmt: skip

FIGURES = ("fig1_lambda_vs_phi", "fig2_event_triggered", "fig3_contrast", "fig4_chaos_map",
           "fig5_jamming", "fig6_prediction", "fig7_variants")  # fmt: skip


def point_name(phi: float | str, variant: str = "") -> str:
    """``phi=<φ>``, or ``<variant>/phi=<φ>`` for a variant's point (``phi`` a wildcard's
    text or a number)."""
    name = f"phi={float(phi):g}"
    return f"{variant}/{name}" if variant else name


def wildcards_point(wildcards) -> str:
    """The point a workflow job's ``shear_group``/``shear_phi`` wildcards name."""
    return point_name(wildcards.shear_phi, wildcards.shear_group.rstrip("/"))


def split_point(point: str) -> tuple[str, float]:
    """(variant, φ) of a point name (variant ``""``: the base section)."""
    variant, _, name = point.rpartition("/")
    return variant, float(name.split("=", 1)[1])


def variants(cfg: Mapping) -> list[str]:
    """``""`` (the base section) and each variant's name, sorted."""
    return ["", *sorted(cfg.get("variants", {}))]


def _overrides(cfg: Mapping, variant: str, part: str) -> dict:
    if not variant:
        return {}
    if variant not in cfg.get("variants", {}):
        raise ConfigError(f"variant {variant!r} is not in 'shear.variants' = "
                          f"{sorted(cfg.get('variants', {}))}")  # fmt: skip
    return dict(cfg["variants"][variant].get(part, {}))


def phis(cfg: Mapping, variant: str = "") -> list[float]:
    """The φ grid of the base section or of a variant (its own, default the base's)."""
    p = {**cfg["physics"], **_overrides(cfg, variant, "physics")}["phi"]
    return sorted(float(x) for x in (p if isinstance(p, list | tuple) else [p]))


def points(cfg: Mapping, variant: str | None = None) -> list[str]:
    """Every point (``variant`` None), or those of the base (``""``) or one variant."""
    names = variants(cfg) if variant is None else [variant]
    return [point_name(x, v) for v in names for x in phis(cfg, v)]


def n_replicas(cfg: Mapping, point: str) -> int:
    """Replicas of a point: the variant's ``ensemble.n_replicas``, default the base's."""
    own = _overrides(cfg, split_point(point)[0], "ensemble")
    return int(own.get("n_replicas", cfg["ensemble"]["n_replicas"]))


def batches(cfg: Mapping, point: str) -> list[str]:
    """The batches of a point (fixed ranges of ``ensemble.batch_size`` replica indices)."""
    size = int(cfg["ensemble"]["batch_size"])
    return [f"{b:04d}" for b in range(-(-n_replicas(cfg, point) // size))]


def run_file(point: str, batch: str) -> str:
    return f"runs/{point}/batch_{batch}.nc"


def fits_file(point: str) -> str:
    return f"fits/{point}.nc"


def physics_for(cfg: Mapping, point: str) -> dict:
    """The physics section at one point (its variant's overrides, ``phi`` one number, as
    its name says)."""
    variant, phi = split_point(point)
    if phi not in phis(cfg, variant):
        key = f"shear.variants.{variant}.physics.phi" if variant else "shear.physics.phi"
        raise ConfigError(f"point {point!r} is not in '{key}' = {phis(cfg, variant)}")
    return {**cfg["physics"], **_overrides(cfg, variant, "physics"), "phi": phi}


def preparation_for(cfg: Mapping, point: str) -> dict:
    """The preparation section at one point (its variant's overrides)."""
    return {**cfg["preparation"], **_overrides(cfg, split_point(point)[0], "preparation")}


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

    pr, fits = cfg["protocol"], cfg["fits"]
    e = cfg["ensemble"]  # the plan and each job's memory, counted before anything is built
    size = int(e["batch_size"])
    jobs = sum(-(-n_replicas(cfg, p) // size) for p in points(cfg))
    check_plan("shear.ensemble.n_replicas", jobs, "raise 'shear.ensemble.batch_size' or list "
               "fewer phi")  # fmt: skip
    blocks = float(pr["record_s"]) / float(pr["block_s"])
    samples = float(pr["record_s"]) / float(pr["sample_s"])
    for point in points(cfg):
        variant = split_point(point)[0]
        key = f"shear.variants.{variant}." if variant else "shear."
        phys = physics_for(cfg, point)
        if int(phys["n_outer"]) <= int(phys["n_inner"]):
            raise ConfigError(f"config key '{key}physics.n_outer' must exceed 'n_inner' (the "
                              "outer ring encloses the inner)")  # fmt: skip
        n = n_disks(phys)
        disks = n + int(phys["n_inner"]) + int(phys["n_outer"])
        check_memory(f"{key}physics.n_outer", phys["n_outer"], BYTES_PER_DISK * disks)
        per_replica = 16.0 * blocks + 9.0 * samples * n  # block records, per-disk samples
        check_memory("shear.protocol.record_s", pr["record_s"],
                     per_replica * (2 + int(e["batch_size"])))  # fmt: skip
        cell = ShearCell.from_physics(phys)
        if cell.r_out - cell.r_in < 2.0 * float(phys["d_large"]):
            raise ConfigError(f"config key '{key}physics.n_outer' at {point}: the annulus is "
                              "narrower than two large disks")  # fmt: skip
        prep = preparation_for(cfg, point)
        try:
            placement(cell, float(prep["start_scale"]), float(prep["gap"]),
                      np.random.default_rng(0))  # fmt: skip
        except RuntimeError as exc:
            raise ConfigError(
                f"config key '{key}preparation.start_scale' at {point}: {exc}"
            ) from None
    if float(fits["where_lead_s"]) < float(pr["sample_s"]) * (1 - 1e-9):
        raise ConfigError("config key 'shear.fits.where_lead_s' is shorter than one sample "
                          "('shear.protocol.sample_s')")  # fmt: skip
    contrast = cfg["figures"]["contrast_phi"]
    if contrast is not None and float(contrast) not in phis(cfg):
        raise ConfigError(f"config key 'shear.figures.contrast_phi' = {contrast} is not one of "
                          f"'shear.physics.phi' = {phis(cfg)}")  # fmt: skip
    if float(pr["sample_s"]) < float(pr["block_s"]):
        raise ConfigError("config key 'shear.protocol.sample_s' is shorter than 'block_s'")
    mv = cfg["movie"]
    if mv["enabled"]:
        if mv["phi"] is not None and float(mv["phi"]) not in phis(cfg):
            raise ConfigError(f"config key 'shear.movie.phi' = {mv['phi']} is not one of "
                              f"'shear.physics.phi' = {phis(cfg)}")  # fmt: skip
        n = n_replicas(cfg, movie_point(cfg))
        if int(mv["replica"]) >= n:
            raise ConfigError(f"config key 'shear.movie.replica' = {mv['replica']} is outside "
                              f"the point's ensemble (replicas 0 .. {n - 1})")  # fmt: skip
        if float(mv["every_s"]) < float(cfg["physics"]["dt"]) * float(cfg["physics"]["t0_s"]):
            raise ConfigError("config key 'shear.movie.every_s' is below the time step")
    span = float(fits["aligned_before_s"]) + float(fits["aligned_after_s"])
    if span >= float(pr["record_s"]) or math.isclose(span, 0.0):
        raise ConfigError("config keys 'shear.fits.aligned_before_s' + 'aligned_after_s' must "
                          "be > 0 and shorter than 'shear.protocol.record_s'")  # fmt: skip


def runs_params(cfg: Mapping, point: str) -> dict:
    """A batch's subset: the point's physics, the preparation, the protocol, the edge
    cutoff (the network is compared in the run) and the batch size."""
    return {"point": point, "physics": physics_for(cfg, point),
            "preparation": preparation_for(cfg, point), "protocol": cfg["protocol"],
            "events": {"edge_cutoff": cfg["events"]["edge_cutoff"]},
            "batch_size": cfg["ensemble"]["batch_size"]}  # fmt: skip


def trajectory_params(cfg: Mapping, point: str) -> dict:
    """``granpipe shear trajectory``'s subset: the runs' (a replay is the run) and the
    point's replica count (the replicas it may replay)."""
    return {**runs_params(cfg, point), "n_replicas": n_replicas(cfg, point)}


def movie_point(cfg: Mapping) -> str:
    """The movie's point: ``movie.phi`` of the base cell, default the first φ listed (a φ
    added to the list leaves the movie as it is)."""
    phi = cfg["movie"]["phi"]
    if phi is None:
        listed = cfg["physics"]["phi"]
        phi = listed[0] if isinstance(listed, list | tuple) else listed
    return point_name(float(phi))


def movie_params(cfg: Mapping) -> dict:
    """``granpipe shear movie``'s subset: the replay's (:func:`trajectory_params`), the
    hash of the run files it reads for the events, the detector (all of ``events``) and
    the ``movie`` section."""
    from ..io import config_hash

    point = movie_point(cfg)
    return {**trajectory_params(cfg, point), "events": dict(cfg["events"]),
            "runs_config_hash": config_hash(runs_params(cfg, point)),
            "movie": dict(cfg["movie"])}  # fmt: skip


def movie_input(cfg: Mapping) -> str:
    """The run file the movie reads: the batch holding ``movie.replica``."""
    batch = int(cfg["movie"]["replica"]) // int(cfg["ensemble"]["batch_size"])
    return run_file(movie_point(cfg), f"{batch:04d}")


def movie_file(cfg: Mapping) -> str:
    return f"movie/{movie_point(cfg)}.{cfg['movie']['format']}"


def fits_params(cfg: Mapping, point: str) -> dict:
    """A point's fits: the detector's thresholds, the analysis, and the hash of the run
    files it reads."""
    from ..io import config_hash

    ev = cfg["events"]
    return {"point": point, "runs_config_hash": config_hash(runs_params(cfg, point)),
            "n_replicas": n_replicas(cfg, point),
            "events": {k: ev[k] for k in ("min_changes", "quiet_s", "detector",
                                          "release_drop")},
            "fits": cfg["fits"]}  # fmt: skip


def summary_params(cfg: Mapping) -> dict:
    """The summary (and the transitions across φ): each point's fits hash, the variants'
    names."""
    from ..io import config_hash

    f = cfg["fits"]
    return {"points": {p: config_hash(fits_params(cfg, p)) for p in points(cfg)},
            "variants": {v: {} for v in variants(cfg) if v},
            "bootstrap_resamples": f["bootstrap_resamples"], "confidence": f["confidence"],
            "seed": f["seed"]}  # fmt: skip


def figures_params(cfg: Mapping) -> dict:
    return {**summary_params(cfg), "dpi": cfg["figures"]["dpi"],
            "contrast_phi": cfg["figures"]["contrast_phi"]}  # fmt: skip


def run_files(cfg: Mapping) -> list[str]:
    """Every simulation output of the section (what ``granpipe status`` counts)."""
    return [run_file(p, b) for p in points(cfg) for b in batches(cfg, p)]
