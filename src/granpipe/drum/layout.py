"""Where the drum study's files live, relative to ``results/<scale>/drum/``.

One folder per parameter point (:func:`granpipe.drum.settings.points`), named after
its size, drum period and start-up, e.g. ``N=736,period=900s,startup=paper``. Replicas
come in fixed batches of ``ensemble.batch_size`` (:func:`granpipe.seeds.batch_replicas`),
so a larger ``n_replicas`` only appends batches, and a new period or start-up only adds
its own point. The workflow (``workflow/rules/drum.smk``) and ``granpipe status`` list
files through these functions, and the config subsets each rule depends on are built
here too (:func:`rule_params`).
"""

from __future__ import annotations

from collections.abc import Mapping

from .settings import PHYSICS_KEYS, filled, point_label, points

__all__ = [
    "POINT_PATTERN",
    "STARTUPS",
    "point_of",
    "point_name",
    "point_names",
    "point_sections",
    "rule_params",
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
    "COMPARISON_FIGURES",
    "figure_files",
]

FIGURES = {
    2: "snapshot",
    3: "onset",
    4: "decay",
    5: "lambda_vs_speed",
}
"""Figure number -> name for the reference point: ``figures/fig<k>_<name>.{png,pdf}``."""

COMPARISON_FIGURES = {
    6: "startup",
    7: "lag_vs_rotation",
}
"""Figures across points: V and λ̄ of each start-up; the lags against the drum's Ω."""


POINT_PATTERN = "N={drum_n},period={drum_period}s,startup={drum_startup}"
"""A point's folder name as Snakemake wildcards (:func:`point_name` fills them)."""

STARTUPS = ("paper", "settled")


def point_of(wildcards) -> str:
    """The point name of a job's wildcards ``drum_n``, ``drum_period``, ``drum_startup``."""
    return POINT_PATTERN.format(
        drum_n=wildcards.drum_n, drum_period=wildcards.drum_period,
        drum_startup=wildcards.drum_startup,
    )  # fmt: skip


def point_name(point: Mapping) -> str:
    """Folder name of a parameter point, e.g. ``N=736,period=900s,startup=paper``."""
    sec = filled(point)
    ph = sec["physics"]
    n = int(ph["n_small"]) + int(ph["n_large"])
    period = ph["period_s"]
    if isinstance(period, list):
        raise ValueError("point_name needs one point's section (settings.points)")
    return f"N={n},period={float(period):.4g}s,startup={sec['protocol']['startup']}"


def point_sections(section: Mapping) -> dict[str, dict]:
    """``{point name: point section}`` in the order of :func:`settings.points`."""
    return {point_name(p): p for p in points(section)}


def point_names(section: Mapping) -> list[str]:
    return list(point_sections(section))


def rule_params(section: Mapping) -> dict[str, dict]:
    """The config subset each drum rule depends on (its ``params:``), per point.

    Returns ``{"sim": {point: ...}, "ensemble": ..., "fits": ..., "figures": ...,
    "summary": ...}``: a simulation depends on its point's physics, settle (settled
    start-up only), protocol and batch size; the ensemble on ``exclude_flagged``; the
    fits on that and ``fits`` (and its point's label, for the row names); the figures on
    ``figures`` and the list of points (name, period, start-up, label; the reference first:
    a list, because the JSON of the params has sorted keys). Editing the physics of one
    point, or adding a point, changes no other point's subsets.
    """
    sec = filled(section)
    sim, fits, table = {}, {}, []
    ensemble = {"ensemble": {"exclude_flagged": sec["ensemble"]["exclude_flagged"]}}
    for name, p in point_sections(sec).items():
        keys = [k for k in PHYSICS_KEYS if k != "settle" or p["protocol"]["startup"] == "settled"]
        sim[name] = {
            **{k: p[k] for k in keys},
            "ensemble": {"batch_size": p["ensemble"]["batch_size"]},
        }
        fits[name] = {**ensemble, "fits": sec["fits"], "label": point_label(p, sec)}
        table.append({
            "name": name,
            "period_s": p["physics"]["period_s"],
            "startup": p["protocol"]["startup"],
            "label": fits[name]["label"],
        })  # fmt: skip
    return {
        "sim": sim,
        "ensemble": ensemble,
        "fits": fits,
        "figures": {"figures": sec["figures"], "points": table},
    }


def n_batches(section: Mapping) -> int:
    ens = filled(section)["ensemble"]
    return -(-int(ens["n_replicas"]) // int(ens["batch_size"]))


def batch_ids(section: Mapping) -> list[str]:
    """Batch labels ``0000``, ``0001``, ... covering ``ensemble.n_replicas``."""
    return [f"{b:04d}" for b in range(n_batches(section))]


def init_file(point: Mapping, batch: str | int) -> str:
    return f"init/{point_name(point)}/batch_{int(batch):04d}.nc"


def run_file(point: Mapping, batch: str | int) -> str:
    return f"runs/{point_name(point)}/batch_{int(batch):04d}.nc"


def _files(section: Mapping, kind: str, point: str | None) -> list[str]:
    sections = point_sections(section)
    names = list(sections) if point is None else [point]
    return [f"{kind}/{p}/batch_{b}.nc" for p in names for b in batch_ids(sections[p])]


def init_files(section: Mapping, point: str | None = None) -> list[str]:
    """Init files relative to ``results/<scale>/drum/`` (of one point, or of all)."""
    return _files(section, "init", point)


def run_files(section: Mapping, point: str | None = None) -> list[str]:
    """Run files relative to ``results/<scale>/drum/`` (of one point, or of all; used by
    ``granpipe status``)."""
    return _files(section, "runs", point)


def ensemble_file(point: Mapping | str) -> str:
    name = point if isinstance(point, str) else point_name(point)
    return f"ensemble/{name}.nc"


def fits_file(point: Mapping | str) -> str:
    name = point if isinstance(point, str) else point_name(point)
    return f"fits/{name}.nc"


def summary_file() -> str:
    return "fits/summary.csv"


def figure_files(exts=("png", "pdf")) -> list[str]:
    figs = {**FIGURES, **COMPARISON_FIGURES}
    return [f"figures/fig{k}_{name}.{ext}" for k, name in figs.items() for ext in exts]
