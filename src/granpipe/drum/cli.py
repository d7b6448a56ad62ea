"""``granpipe drum <stage>``: the drum study's stages from the command line.

The workflow (``workflow/rules/drum.smk``) calls these with ``--params``, the exact
config subset each rule depends on (a partial ``drum`` section; missing keys take
their schema defaults). ``granpipe drum replica`` runs one replica by hand.
"""

from __future__ import annotations

import os

import click

from ..cli import params_option

__all__ = ["cli"]


def _threads(threads: int) -> int:
    """Set numba's thread count for the replicas of a batch run side by side."""
    import numba

    threads = max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS))
    numba.set_num_threads(threads)
    return threads


@click.group("drum")
def cli():
    """Rotating drum (Maghsoodi & Luijten 2016): λ(t) and V(t) at avalanche onset and decay."""


@cli.command("init")
@params_option
@click.option("--batch", type=int, required=True, help="Batch index b (replicas b*size...).")
@click.option(
    "--out", type=click.Path(dir_okay=False), required=True, help="init/<point>/batch_<b>.nc"
)
@click.option("--threads", type=int, default=1, show_default=True)
def init_cmd(params, batch, out, threads):
    """Random placement and settling of the replicas of one batch."""
    from .stages import init_stage

    init_stage(params, batch, out, threads=_threads(threads))


@cli.command("runs")
@params_option
@click.option("--batch", type=int, required=True)
@click.option("--init", "init_path", type=click.Path(exists=True, dir_okay=False), required=True)
@click.option(
    "--out", type=click.Path(dir_okay=False), required=True, help="runs/<point>/batch_<b>.nc"
)
@click.option("--threads", type=int, default=1, show_default=True)
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

    ensemble_stage(params, runs, out)


@cli.command("fits")
@params_option
@click.option(
    "--ensemble", "ensemble_path", type=click.Path(exists=True, dir_okay=False), required=True
)
@click.option("--out", type=click.Path(dir_okay=False), required=True)
@click.option("--summary", type=click.Path(dir_okay=False), required=True)
@click.argument("runs", nargs=-1, required=True, type=click.Path(exists=True, dir_okay=False))
def fits_cmd(params, ensemble_path, out, summary, runs):
    """Onset time, sign-change times and lags with fit errors and bootstrap CIs."""
    from .stages import fits_stage

    fits_stage(params, ensemble_path, runs, out, summary)


@cli.command("figures")
@params_option
@click.option(
    "--ensemble", "ensemble_path", type=click.Path(exists=True, dir_okay=False), required=True
)
@click.option("--fits", "fits_path", type=click.Path(exists=True, dir_okay=False), required=True)
@click.option(
    "--snapshot",
    type=click.Path(exists=True, dir_okay=False),
    required=True,
    help="A run file whose first replica holds snapshots.",
)
@click.option("--outdir", type=click.Path(file_okay=False), required=True)
def figures_cmd(params, ensemble_path, fits_path, snapshot, outdir):
    """Figs. 2-5 (PNG and PDF)."""
    from .stages import figures_stage

    figures_stage(params, ensemble_path, fits_path, snapshot, outdir)


@cli.command("replica")
@click.option(
    "--seed",
    "replica",
    type=int,
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
    "--tiny", is_flag=True, help="A tiny drum (40 wall disks, 46 disks) with short windows."
)
def replica_cmd(replica, out, configfile, tiny):
    """Run one replica (placement, settling, protocol) outside the workflow."""
    from ..config import load
    from ..io import write_dataset
    from .protocol import run_replica
    from .settings import filled, seed_physics, tiny_section

    if configfile is None and os.path.exists("config/config.yaml"):
        configfile = "config/config.yaml"
    section = load(configfile)["drum"] if configfile else {}
    sec = filled(section)
    if tiny:
        sec = tiny_section(sec)
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
