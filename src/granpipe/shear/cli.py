"""``granpipe shear <stage>``: the shear study's stages (docs/shear.md).

Each command takes ``--params JSON`` (the exact config subset its rule depends on, stored
as the output's ``config_subset``; :mod:`granpipe.shear.layout`) and paths; the functions
behind them live in :mod:`granpipe.shear.stages`.
"""

from __future__ import annotations

import click

from ..cli import INDEX, movie_command, params_option, trajectory_command, trajectory_options
from ..config import validate_params

__all__ = ["cli"]

_SECTIONS = ("physics", "preparation", "protocol", "fits")
_HASHES = {"type": "object", "minProperties": 1, "additionalProperties": {"type": "string"}}
_EXTRA = {
    "point": {"type": "string", "pattern": "^([A-Za-z][A-Za-z0-9_]*/)?phi=[0-9.e+-]+$"},
    "events": {"type": "object"},
    "batch_size": {"$ref": "#/x-study/properties/ensemble/properties/batch_size"},
    "n_replicas": {"$ref": "#/x-study/properties/ensemble/properties/n_replicas"},
    "runs_config_hash": {"type": "string"},
    "points": _HASHES,
    "bootstrap_resamples": {"$ref": "#/x-study/properties/fits/properties/bootstrap_resamples"},
    "confidence": {"$ref": "#/x-study/properties/fits/properties/confidence"},
    "seed": {"$ref": "#/x-study/properties/fits/properties/seed"},
    "dpi": {"$ref": "#/x-study/properties/figures/properties/dpi"},
    "contrast_phi": {"$ref": "#/x-study/properties/figures/properties/contrast_phi"},
    "movie": {"$ref": "#/x-study/properties/movie"},
}


def _checked(params: dict, *keys: str) -> dict:
    """``--params`` checked against the shear schema (``keys`` required, defaults filled)."""
    refs = {k: f"/properties/{k}" for k in _SECTIONS if k in keys}
    checked = validate_params(params, "shear", refs, {k: v for k, v in _EXTRA.items() if k in keys})
    if "events" in keys:  # a subset of the events section: each key checked against it
        validate_params(
            params["events"],
            "shear",
            {k: f"/properties/events/properties/{k}" for k in params["events"]},
        )
    return checked


@click.group("shear")
def cli():
    """Sheared annular cell (the drum paper's Ref. [20]): runs, fits, summary, figures."""


@cli.command("runs")
@params_option
@click.option("--batch", type=INDEX, required=True)
@click.option("--out", type=click.Path(dir_okay=False), required=True)
def runs_cmd(params, batch, out):
    """One batch of replicas of one φ (params: point, physics, preparation, protocol)."""
    from .stages import runs_stage

    keys = ("point", "physics", "preparation", "protocol", "events", "batch_size")
    runs_stage(_checked(params, *keys), batch, out)


@cli.command("fits")
@params_option
@click.option("--out", type=click.Path(dir_okay=False), required=True)
@click.argument("run_files", nargs=-1, required=True, type=click.Path(exists=True))
def fits_cmd(params, out, run_files):
    """A point's λ average, events, lead time and correlations from its run files."""
    from .stages import fits_stage

    keys = ("point", "runs_config_hash", "n_replicas", "events", "fits")
    fits_stage(_checked(params, *keys), run_files, out)


@cli.command("summary")
@params_option
@click.option("--out", type=click.Path(dir_okay=False), required=True)
@click.argument("fits_files", nargs=-1, required=True, type=click.Path(exists=True))
def summary_cmd(params, out, fits_files):
    """summary.csv: every point's rows and the zero crossing of ⟨λ⟩ in φ."""
    from .stages import summary_stage

    summary_stage(_checked(params, "points", "bootstrap_resamples", "confidence", "seed"),
                  fits_files, out)  # fmt: skip


@cli.command("figures")
@params_option
@click.option("--out-dir", type=click.Path(file_okay=False), required=True)
@click.option("--drum-fits", type=click.Path(exists=True, dir_okay=False), default=None,
              help="the drum's reference fits file, for the contrast figure")  # fmt: skip
@click.argument("fits_files", nargs=-1, required=True, type=click.Path(exists=True))
def figures_cmd(params, out_dir, drum_fits, fits_files):
    """Figs. 1-4, PNG and PDF."""
    from .stages import figures_stage

    keys = ("points", "bootstrap_resamples", "confidence", "seed", "dpi", "contrast_phi")
    figures_stage(_checked(params, *keys), fits_files, out_dir, drum_fits)


@cli.command("trajectory")
@trajectory_options
def trajectory_cmd(params, replica, start, end, every, fmt, out, fps):
    """One replica replayed over a window, every frame written for OVITO or ParaView
    (params: the runs' subset and n_replicas, granpipe.shear.layout.trajectory_params)."""
    from .trajectory import trajectory

    keys = ("point", "physics", "preparation", "protocol", "events", "n_replicas")
    trajectory_command(trajectory, _checked(params, *keys), replica, start, end, every, fmt,
                       out, fps)  # fmt: skip


@cli.command("movie")
@params_option
@click.option("--out", type=click.Path(dir_okay=False), required=True)
@click.argument("run_file", type=click.Path(exists=True, dir_okay=False))
def movie_cmd(params, out, run_file):
    """The report's movie: one replica around an event (params: the replay's subset, the
    runs' hash, events and movie; granpipe.shear.layout.movie_params)."""
    from .trajectory import movie_stage

    keys = ("point", "physics", "preparation", "protocol", "events", "n_replicas",
            "runs_config_hash", "movie")  # fmt: skip
    movie_command(movie_stage, _checked(params, *keys), run_file, out)
