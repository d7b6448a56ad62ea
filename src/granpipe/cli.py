"""The ``granpipe`` command: ``granpipe <study> <stage> [options]``.

Each study package owns a ``cli.py`` with a :class:`click.Group` named after the
study, one command per stage (init, runs, ensemble, fits, figures) and extras
(e.g. ``granpipe drum replica``). Study groups are imported only when invoked, so
``granpipe --help`` stays fast and does not compile kernels.
"""

from __future__ import annotations

import importlib
import importlib.util
import json
import math
import sys

import click

from . import __version__
from .config import STUDIES
from .errors import GranpipeError

__all__ = [
    "main",
    "cli",
    "params_option",
    "parse_params",
    "INDEX",
    "THREADS",
    "POSITIVE",
    "NON_NEGATIVE",
    "trajectory_options",
    "trajectory_command",
    "movie_command",
]


def parse_params(text: str) -> dict:
    """Parse the ``--params`` JSON text a rule passes (the rule's config subset); NaN and
    infinities are refused (JSON has none; Python's reader would take them)."""

    def refuse(constant):
        raise click.BadParameter(f"{constant} is not a number a config may hold",
                                 param_hint="--params")  # fmt: skip

    try:
        value = json.loads(text, parse_constant=refuse)
    except json.JSONDecodeError as exc:
        raise click.BadParameter(f"not valid JSON: {exc}", param_hint="--params") from None
    except RecursionError:
        raise click.BadParameter("nested too deeply", param_hint="--params") from None
    if not isinstance(value, dict):
        raise click.BadParameter("must be a JSON object", param_hint="--params")
    return value


INDEX = click.IntRange(0, 2**63 - 1)
"""A batch, replica, part or seed index: 0 or more, a 64-bit integer."""

THREADS = click.IntRange(1, 4096)
"""Threads of a job: at least one."""


class FiniteRange(click.FloatRange):
    """A ``click.FloatRange`` that also refuses NaN and infinities (a range's bounds let
    them through: ``nan > 0`` is false, and ``inf`` has no upper bound)."""

    def convert(self, value, param, ctx):
        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{number} is not a finite number", param, ctx)
        return number


POSITIVE = FiniteRange(0, min_open=True)
"""A finite number > 0 (Γ, a tap period)."""

NON_NEGATIVE = FiniteRange(0)
"""A finite number >= 0 (a tap amplitude)."""


params_option = click.option(
    "--params",
    "params",
    required=True,
    callback=lambda ctx, param, value: parse_params(value),
    help="JSON object: the config subset this stage depends on (rules pass it).",
)
"""Shared ``--params JSON`` option for stage commands."""


TRAJECTORY_FORMATS = ("extxyz", "vtu", "mp4", "gif")
"""The formats of ``granpipe <study> trajectory`` (:data:`granpipe.trajectory.FORMATS`;
spelled out here so that ``granpipe --help`` imports no array library)."""


def trajectory_options(fn):
    """The options of ``granpipe <study> trajectory``: replica, window, frame interval,
    format and output path."""
    opts = [
        click.option("--replica", type=INDEX, required=True, help="replica index"),
        click.option("--start", type=FiniteRange(), required=True,
                     help="window start [s of the study's record clock]"),
        click.option("--end", type=FiniteRange(), required=True, help="window end [s]"),
        click.option("--every", type=POSITIVE, required=True,
                     help="frame interval [s], rounded to whole steps"),
        click.option("--format", "fmt", type=click.Choice(TRAJECTORY_FORMATS), required=True,
                     help="extxyz (one file, OVITO), vtu (a .pvd index and .vtu frames, "
                     "ParaView), or a movie: mp4 (GIF without ffmpeg) or gif"),
        click.option("--out", type=click.Path(dir_okay=False), required=True,
                     help="the .xyz file, the .pvd index (frames in <stem>_frames/) or the "
                     "movie"),
        click.option("--fps", type=POSITIVE, default=10.0, show_default=True,
                     help="a movie's frames per second"),
    ]  # fmt: skip
    for opt in reversed(opts):
        fn = opt(fn)
    return params_option(fn)


def trajectory_command(replay, params, replica, start, end, every, fmt, out, fps) -> None:
    """Run a study's ``trajectory`` and write it; a refusal names its option."""
    from .trajectory import TrajectoryError, replay_to_file

    try:
        path, ds = replay_to_file(replay, params, replica, (start, end), every, fmt, out, fps)
    except TrajectoryError as exc:
        raise click.BadParameter(str(exc), param_hint=f"--{exc.option}") from None
    click.echo(f"wrote {path}: {ds.sizes['frame']} frames of {ds.sizes['disk']} disks",
               err=True)  # fmt: skip


def movie_command(stage, params, *args) -> None:
    """Run a study's ``movie_stage(params, *args)``; a refusal names its option."""
    from .trajectory import TrajectoryError

    try:
        path, frames = stage(params, *args)
    except TrajectoryError as exc:
        raise click.BadParameter(str(exc), param_hint=f"movie.{exc.option}") from None
    click.echo(f"wrote {path}: {frames} frames", err=True)


class StudyGroup(click.Group):
    """Top-level group that imports ``granpipe.<study>.cli`` on demand."""

    def _study_module(self, name):
        if name not in STUDIES:
            return None
        modname = f"granpipe.{name}.cli"
        if importlib.util.find_spec(modname) is None:
            return None
        return importlib.import_module(modname)

    def list_commands(self, ctx):
        names = set(super().list_commands(ctx))
        names.update(s for s in STUDIES if importlib.util.find_spec(f"granpipe.{s}.cli"))
        return sorted(names)

    def get_command(self, ctx, name):
        cmd = super().get_command(ctx, name)
        if cmd is not None:
            return cmd
        module = self._study_module(name)
        return getattr(module, "cli", None) if module else None


@click.group(cls=StudyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="granpipe")
def cli():
    """granpipe: rotating drum, tapped column and vibrated box studies.

    Run a stage with ``granpipe <study> <stage> --help`` for its options; the
    Snakemake workflow calls these commands with the config subset as --params.
    """


@cli.command("check-config")
@click.argument("path", type=click.Path(exists=True, dir_okay=False))
def check_config(path):
    """Validate a config file against the schemas and print the filled config."""
    import yaml

    from .config import load

    cfg = load(path)
    click.echo(yaml.safe_dump(cfg, sort_keys=False))


@cli.command("status")
@click.option(
    "--results", default="results", show_default=True, type=click.Path(file_okay=False),
    help="Results root.",
)  # fmt: skip
@click.option(
    "--configfile", default=None, type=click.Path(exists=True, dir_okay=False),
    help="Config whose expected batches to compare.",
)  # fmt: skip
def status(results, configfile):
    """Per study and scale: batches present and missing, latest fitted numbers."""
    from .status import report

    click.echo(report(results, configfile))


def main(argv=None):
    """Console-script entry point; turns granpipe errors and misused arguments into one
    clear line (exit 1, or click's 2 for a usage error)."""
    try:
        cli.main(args=argv, prog_name="granpipe", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        sys.exit(1)
    except click.ClickException as exc:  # a misused argument: one line naming it
        hint = " (see --help)" if isinstance(exc, click.UsageError) else ""
        click.echo(f"granpipe: error: {exc.format_message()}{hint}", err=True)
        sys.exit(exc.exit_code)
    except GranpipeError as exc:
        click.echo(f"granpipe: error: {exc}", err=True)
        sys.exit(1)
    except MemoryError as exc:  # sizes past what `granpipe check-config` lets through
        click.echo(
            f"granpipe: error: out of memory ({exc}); the sizes in --params are larger than "
            "this machine holds (`granpipe check-config` estimates them per job)",
            err=True,
        )
        sys.exit(1)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)


if __name__ == "__main__":  # pragma: no cover
    main()
