"""``granpipe drum <stage>``: the drum study's stages from the command line.

The workflow (``workflow/rules/drum.smk``) calls these with ``--params``, the exact
config subset each rule depends on (a partial ``drum`` section; missing keys take
their schema defaults). ``granpipe drum replica`` runs one replica by hand.
"""

from __future__ import annotations

import os

import click

from ..cli import (
    INDEX,
    THREADS,
    movie_command,
    params_option,
    trajectory_command,
    trajectory_options,
)
from ..config import validate_params

__all__ = ["cli"]


def _threads(threads: int) -> int:
    """Set numba's thread count for the replicas of a batch run side by side."""
    import numba

    threads = max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS))
    numba.set_num_threads(threads)
    return threads


def _later_params(params: dict, fits: bool = False) -> dict:
    """``--params`` of the ensemble (or fits) stage, checked: the point, the config hash
    of its run files and ``ensemble`` (and ``fits`` and the row label)."""
    refs = {"ensemble": "/properties/ensemble"}
    extra = {"point": {"type": "string"}, "runs_config_hash": {"type": "string"}}
    if fits:
        refs["fits"] = "/properties/fits"
        extra["label"] = {"type": "string"}
    return validate_params(params, "drum", refs, extra, fill=False)


@click.group("drum")
def cli():
    """Rotating drum (Maghsoodi & Luijten 2016): λ(t) and V(t) at avalanche onset and decay."""


@cli.command("init")
@params_option
@click.option("--batch", type=INDEX, required=True, help="Batch index b (replicas b*size...).")
@click.option(
    "--out", type=click.Path(dir_okay=False), required=True, help="init/<point>/batch_<b>.nc"
)
@click.option("--threads", type=THREADS, default=1, show_default=True)
def init_cmd(params, batch, out, threads):
    """Random placement and start-up (fall, or settling) of the replicas of one batch."""
    from .stages import init_stage

    init_stage(params, batch, out, threads=_threads(threads))


@cli.command("runs")
@params_option
@click.option("--batch", type=INDEX, required=True)
@click.option("--init", "init_path", type=click.Path(exists=True, dir_okay=False), required=True)
@click.option(
    "--out", type=click.Path(dir_okay=False), required=True, help="runs/<point>/batch_<b>.nc"
)
@click.option("--threads", type=THREADS, default=1, show_default=True)
def runs_cmd(params, batch, init_path, out, threads):
    """The protocol (onset window, continuous avalanche, decay window) for one batch."""
    from .stages import runs_stage

    runs_stage(params, batch, init_path, out, threads=_threads(threads))


@cli.command("ensemble")
@params_option
@click.option("--out", type=click.Path(dir_okay=False), required=True)
@click.argument("runs", nargs=-1, required=True, type=click.Path(exists=True, dir_okay=False))
def ensemble_cmd(params, out, runs):
    """Streaming reduction of run files to means, standard errors and counts."""
    from .stages import ensemble_stage

    ensemble_stage(_later_params(params), runs, out)


@cli.command("fits")
@params_option
@click.option(
    "--ensemble", "ensemble_path", type=click.Path(exists=True, dir_okay=False), required=True
)
@click.option("--out", type=click.Path(dir_okay=False), required=True, help="fits/<point>.nc")
@click.argument("runs", nargs=-1, required=True, type=click.Path(exists=True, dir_okay=False))
def fits_cmd(params, ensemble_path, out, runs):
    """Onset time, sign-change times and lags of one point, with fit errors and CIs."""
    from .stages import fits_stage

    fits_stage(_later_params(params, fits=True), ensemble_path, runs, out)


@cli.command("summary")
@click.option("--out", type=click.Path(dir_okay=False), required=True, help="summary.csv")
@click.argument("fits", nargs=-1, required=True, type=click.Path(exists=True, dir_okay=False))
def summary_cmd(out, fits):
    """Gather the fitted numbers of every point into summary.csv."""
    from .stages import summary_stage

    summary_stage(fits, out)


@cli.command("figures")
@params_option
@click.option(
    "--ensemble", "ensembles", type=click.Path(exists=True, dir_okay=False), multiple=True,
    required=True, help="One per point, in the order of the params' points.",
)  # fmt: skip
@click.option(
    "--fits", "fits", type=click.Path(exists=True, dir_okay=False), multiple=True,
    required=True, help="One per point, in the same order.",
)  # fmt: skip
@click.option(
    "--snapshot",
    type=click.Path(exists=True, dir_okay=False),
    required=True,
    help="A run file of the reference point whose first replica holds snapshots.",
)
@click.option("--outdir", type=click.Path(file_okay=False), required=True)
def figures_cmd(params, ensembles, fits, snapshot, outdir):
    """Figs. 2-5 (reference point) and 6-8 (across points), PNG and PDF."""
    from .stages import figures_stage

    point = {
        "type": "object",
        "required": ["name", "period_s", "startup", "friction", "label", "runs_config_hash"],
    }
    params = validate_params(
        params, "drum", {"figures": "/properties/figures"},
        {"points": {"type": "array", "minItems": 1, "items": point}}, fill=False,
    )  # fmt: skip
    figures_stage(params, ensembles, fits, snapshot, outdir)


@cli.command("restamp")
@click.option(
    "--configfile", type=click.Path(exists=True, dir_okay=False), required=True,
    help="The config whose points the files are to serve.",
)  # fmt: skip
@click.argument("files", nargs=-1, required=True, type=click.Path(exists=True, dir_okay=False))
def restamp_cmd(configfile, files):
    """Reuse init and run files (e.g. of a renamed point) under this config's point names.

    Each file whose physics subset is that of a point of the config is written, data
    untouched, to that point's folder (results/<scale>/drum/<init|runs>/<point>/) with
    the point's name and config hash; a file whose physics no point has is refused.
    """
    from ..config import load
    from .stages import restamp_stage

    cfg = load(configfile)
    if "drum" not in cfg:
        raise click.BadParameter(f"{configfile} has no drum section", param_hint="--configfile")
    restamp_stage(cfg["drum"], files, os.path.join(cfg["results"], cfg["scale"], "drum"))


@cli.command("replica")
@click.option(
    "--seed",
    "replica",
    type=INDEX,
    required=True,
    help="Replica index S: its stream is replica_rng('drum', physics, S), the same "
    "as replica S of the workflow.",
)
@click.option("--out", type=click.Path(dir_okay=False), required=True)
@click.option(
    "--configfile",
    type=click.Path(exists=True, dir_okay=False),
    default=None,
    help="Config whose drum section to use (default: config/config.yaml if present, "
    "else the schema defaults).",
)
@click.option(
    "--point", default=None, help="Parameter point (folder name); default: the reference point."
)
@click.option(
    "--tiny", is_flag=True, help="A tiny drum (40 wall disks, 46 disks) with short windows."
)
def replica_cmd(replica, out, configfile, point, tiny):
    """Run one replica (placement, start-up, protocol) outside the workflow."""
    from ..config import load
    from ..errors import ConfigError
    from ..io import write_dataset
    from .layout import filled, point_sections, seed_physics
    from .protocol import run_replica, tiny_section

    folder = os.path.dirname(os.path.abspath(out))
    if not (os.path.isdir(folder) and os.access(folder, os.W_OK)):
        raise click.BadParameter(f"cannot write into {folder}", param_hint="--out")
    if configfile is None and os.path.exists("config/config.yaml"):
        configfile = "config/config.yaml"
    section = load(configfile)["drum"] if configfile else {}
    sec = filled(section)
    if tiny:
        sec = tiny_section(sec)
    sections = point_sections(sec)
    if point is not None and point not in sections:
        raise ConfigError(f"--point {point!r} is not a point of this config: {list(sections)}")
    sec = sections[point] if point is not None else next(iter(sections.values()))
    ds = run_replica(sec, replica, log=lambda m: click.echo(m, err=True))
    write_dataset(
        ds,
        out,
        config_subset=seed_physics(sec),
        seeds=[int(ds["seed"].values[0])],
        study="drum",
        stage="replica",
    )
    click.echo(f"wrote {out}", err=True)


@cli.command("trajectory")
@trajectory_options
@click.option("--part", type=click.Choice(["onset", "decay"]), default="onset",
              show_default=True, help="the recorded window whose t = 0 --start and --end "
              "count from")  # fmt: skip
def trajectory_cmd(params, replica, start, end, every, fmt, out, fps, part):
    """One replica replayed over a window of its onset or decay window, every frame
    written for OVITO or ParaView (params: the point's simulation subset and
    ensemble.n_replicas, granpipe.drum.layout.trajectory_params)."""
    import functools

    from .layout import load
    from .trajectory import trajectory

    replay = functools.partial(trajectory, part=part)
    trajectory_command(replay, load(params), replica, start, end, every, fmt, out, fps)


@cli.command("movie")
@params_option
@click.option("--part", type=click.Choice(["onset", "decay"]), required=True,
              help="the recorded window the movie shows")  # fmt: skip
@click.option("--out", type=click.Path(dir_okay=False), required=True)
@click.argument("run_file", type=click.Path(exists=True, dir_okay=False))
def movie_cmd(params, part, out, run_file):
    """The report's movie of one window: one replica around its pile's flow onset or stop
    (params: the replay's subset, fits and movie; granpipe.drum.layout.movie_params)."""
    from .layout import load
    from .trajectory import movie_stage

    movie_command(movie_stage, load(params), part, run_file, out)
