"""``granpipe box <stage>``: the vibrated-box study's stages (docs/box.md).

Each command takes ``--params JSON`` (the exact config subset its rule depends on, stored
as the output's ``config_subset``) and input/output paths; progress goes to stderr. The
functions behind the commands live in :mod:`granpipe.box.stages`.
"""

from __future__ import annotations

import click

from ..cli import (
    INDEX,
    POSITIVE,
    movie_command,
    params_option,
    trajectory_command,
    trajectory_options,
)
from ..config import validate_params

__all__ = ["cli"]

_REFS = {
    "physics": "/properties/physics",
    "init": "/properties/init",
    "protocol": "/properties/protocol",
    "detection": "/properties/detection",
    "slips": "/properties/slips",
    "order": "/properties/order",
    "fits": "/properties/fits",
    "movie": "/properties/movie",
    "Lx": "/properties/physics/properties/Lx",
}
_HASHES = {"type": "object", "minProperties": 1, "additionalProperties": {"type": "string"}}
_EXTRA = {
    "mu_side_walls": {"$ref": "#/x-study/properties/grid/properties/mu_side_walls/items"},
    "part_periods": {
        "type": "array", "minItems": 2, "maxItems": 2, "items": {"type": "integer", "minimum": 0}
    },
    "point": {"type": "string"},
    "replicas": {"type": "integer", "minimum": 1},
    "runs_config_hashes": {"type": "array", "minItems": 1, "items": {"type": "string"}},
    "points": _HASHES,
    "states": _HASHES,
    "N_l": {"$ref": "#/x-study/properties/grid/properties/N_l/items"},
    "Gamma": {"$ref": "#/x-study/properties/grid/properties/Gamma/items"},
    "init_kind": {"enum": ["crystal", "random"]},
}  # fmt: skip


def _checked(params: dict, *keys: str) -> dict:
    """``--params`` of a stage, checked against the box schema (its ``keys`` required,
    defaults filled); the points' side-wall friction rides in ``physics``."""
    check = dict(params)
    physics = check.get("physics")
    if "physics" in keys and isinstance(physics, dict):
        check["physics"] = {k: v for k, v in physics.items() if k != "mu_side_walls"}
        if "mu_side_walls" in physics:
            check["mu_side_walls"] = physics["mu_side_walls"]
        keys = (*keys, "mu_side_walls")
    out = validate_params(
        check, "box", {k: v for k, v in _REFS.items() if k in keys},
        {k: v for k, v in _EXTRA.items() if k in keys},
    )  # fmt: skip
    if "mu_side_walls" in out:
        out["physics"]["mu_side_walls"] = out.pop("mu_side_walls")
    return out


@click.group("box")
def cli():
    """Vibrated box (Fortini & Huang 2015): init, runs, ensemble, fits, figures."""


@cli.command("init")
@params_option
@click.option(
    "--N-l", "n_l", type=click.IntRange(1), required=True, help="linear density N_l = N/Lx [1/σ]"
)
@click.option(
    "--init", "kind", type=click.Choice(["crystal", "random"]), required=True, help="start"
)
@click.option("--replica", type=INDEX, default=0, show_default=True)
@click.option("--out", type=click.Path(dir_okay=False), required=True)
def init_cmd(params, n_l, kind, replica, out):
    """Prepare a settled crystal or random initial state (params: physics, init)."""
    from .stages import init_stage

    init_stage(_checked(params, "physics", "init"), n_l, kind, replica, out)


@cli.command("runs")
@params_option
@click.option("--N-l", "n_l", type=click.IntRange(1), required=True)
@click.option("--Gamma", "gamma", type=POSITIVE, required=True, help="Γ = Aω²/g")
@click.option("--init", "kind", type=click.Choice(["crystal", "random"]), required=True)
@click.option("--replica", type=INDEX, default=0, show_default=True)
@click.option("--part", type=click.IntRange(0, 999), default=0, show_default=True)
@click.option("--init-file", type=click.Path(exists=True, dir_okay=False), required=True)
@click.option(
    "--previous",
    type=click.Path(exists=True, dir_okay=False),
    default=None,
    help="run file of the previous part (parts > 0)",
)
@click.option("--out", type=click.Path(dir_okay=False), required=True)
def runs_cmd(params, n_l, gamma, kind, replica, part, init_file, previous, out):
    """Run one part of a point (params: physics, init, protocol, part_periods)."""
    from .stages import runs_stage

    checked = _checked(params, "physics", "init", "protocol", "part_periods")
    if "measured_periods" not in params["protocol"]:  # a part's subset has none (layout)
        checked["protocol"].pop("measured_periods")
    runs_stage(checked, n_l, gamma, kind, replica, part, init_file, out, previous=previous)


@cli.command("ensemble")
@params_option
@click.option("--out", type=click.Path(dir_okay=False), required=True)
@click.argument("run_files", nargs=-1, required=True, type=click.Path(exists=True))
def ensemble_cmd(params, out, run_files):
    """Measures of one point from its run files (params: Lx, detection, slips, order)."""
    from .stages import ensemble_stage

    params = _checked(params, "Lx", "detection", "slips", "order", "point", "replicas",
                      "runs_config_hashes")  # fmt: skip
    ensemble_stage(params, run_files, out)


@cli.command("fits")
@params_option
@click.option("--out-dir", type=click.Path(file_okay=False), required=True)
@click.argument("ensemble_files", nargs=-1, required=True, type=click.Path(exists=True))
def fits_cmd(params, out_dir, ensemble_files):
    """Thresholds, T_g* regions, Arrhenius barriers, summary.csv (params: detection, fits)."""
    from .stages import fits_stage

    fits_stage(_checked(params, "detection", "fits", "points"), ensemble_files, out_dir)


@cli.command("figures")
@params_option
@click.option("--fits-dir", type=click.Path(exists=True, file_okay=False), required=True)
@click.option("--out-dir", type=click.Path(file_okay=False), required=True)
@click.option(
    "--init-file", "init_files", multiple=True, type=click.Path(exists=True), required=True
)
@click.argument("ensemble_files", nargs=-1, required=True, type=click.Path(exists=True))
def figures_cmd(params, fits_dir, out_dir, init_files, ensemble_files):
    """Figures 1, 3, 4, 5 and 6 (thresholds against μ_w), PNG and PDF (params: Lx, order, fits)."""
    from .stages import figures_stage

    params = _checked(params, "Lx", "order", "fits", "points", "states")
    figures_stage(params, fits_dir, init_files, ensemble_files, out_dir)


@cli.command("trajectory")
@trajectory_options
def trajectory_cmd(params, replica, start, end, every, fmt, out, fps):
    """One replica replayed over a window (times in t0 from the drive's start), every frame
    written for OVITO or ParaView (params: physics, init, protocol, N_l, Gamma, init_kind,
    replicas; granpipe.box.layout.trajectory_params)."""
    from .trajectory import trajectory

    keys = ("physics", "init", "protocol", "N_l", "Gamma", "init_kind", "replicas")
    trajectory_command(trajectory, _checked(params, *keys), replica, start, end, every, fmt,
                       out, fps)  # fmt: skip


@cli.command("movie")
@params_option
@click.option("--out", type=click.Path(dir_okay=False), required=True)
def movie_cmd(params, out):
    """The report's movie of one point: one replica over the last periods of its record
    (params: the replay's subset and movie; granpipe.box.layout.movie_params)."""
    from .trajectory import movie_stage

    keys = ("physics", "init", "protocol", "N_l", "Gamma", "init_kind", "replicas", "movie")
    movie_command(movie_stage, _checked(params, *keys), out)
