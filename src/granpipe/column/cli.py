"""``granpipe column <stage>``: the column study's workflow stages (docs/architecture.md).

Each command takes ``--params JSON`` (the exact config subset its rule depends on) and
input/output paths; the functions behind the commands live in
:mod:`granpipe.column.stages`. Stage map (outputs under ``results/<scale>/column/``):

* runs:     ``trajectories`` (Fig. 1 columns), ``relaxation`` (one batch of replicas),
            ``chaos`` (one (a, T) point of the map: Lyapunov exponents and return-map
            periods), ``continuum`` (discrete vs L-W vs BSR),
            ``convergence`` (continuum solvers under refinement)
* ensemble: ``ensemble --kind relaxation|chaos`` (batches → means, spreads, intervals)
* fits:     ``fits`` (relaxation fit, chaos thresholds, return-map periods, continuum
            distances → summary.csv, fits netCDF and the Theorem 1 note)
* figures:  ``figures`` (fig1–fig6, PNG and PDF)

The column has no separate init stage: its start is the closed-form equilibrium (Eq. 27),
perturbed per replica inside the runs.
"""

from __future__ import annotations

import click

from ..cli import INDEX, NON_NEGATIVE, POSITIVE, params_option
from ..config import validate_params

_PHYSICS = "/$defs/physics"
_RELAX, _CHAOS = "/properties/relaxation/properties/", "/properties/chaos/properties/"
_CONT, _FIG1 = "/properties/continuum/properties/", "/properties/figure1/properties/"
_STEP = {"step_factor": "/properties/integrator/properties/step_factor"}
_STRING = {"type": "string"}
_HASHES = {"type": "object", "additionalProperties": True}


def _checked(params: dict, refs: dict, extra: dict | None = None) -> dict:
    """``--params`` of a stage, checked against the column schema (every key of ``refs``
    and ``extra`` required)."""
    return validate_params(params, "column", refs, extra)


def _continuum_refs(convergence: bool) -> dict:
    keys = ("sigma_width", "bsr_kernel_width")
    if not convergence:
        keys += ("n_taps", "lw_refinement", "bsr_refinement", "bsr_derived_refinement", "record_dt")
    refs = {"physics": _PHYSICS, **_STEP, **{k: _CONT + k for k in keys}}
    if convergence:
        refs["convergence"] = _CONT + "convergence"
    return refs


cli = click.Group(
    "column", help="Tapped column of particles (docs/column.md): stages of the study."
)


@cli.command("trajectories")
@params_option
@click.option("--set", "set_name", required=True, help="Name of the column in params['sets'].")
@click.option("--out", required=True, type=click.Path(dir_okay=False))
def trajectories_cmd(params, set_name, out):
    """Fig. 1: y_i(t) of one column over the configured taps from the equilibrium start."""
    from .stages import trajectories_stage

    refs = {"sets": _FIG1 + "sets", "n_taps": _FIG1 + "n_taps", "record_dt": _FIG1 + "record_dt"}
    trajectories_stage(_checked(params, {**refs, **_STEP}), set_name, out)


@cli.command("relaxation")
@params_option
@click.option("--batch", required=True, type=INDEX, help="Batch index (fixed replica range).")
@click.option("--out", required=True, type=click.Path(dir_okay=False))
def relaxation_cmd(params, batch, out):
    """Density relaxation: one batch of perturbed starts over many taps."""
    from .stages import relaxation_stage

    keys = ("n_taps", "batch_size", "perturbation")
    checked = _checked(params, {"physics": _PHYSICS, **_STEP, **{k: _RELAX + k for k in keys}})
    relaxation_stage(checked, batch, out)


@cli.command("chaos")
@params_option
@click.option("--a", "amplitude", required=True, type=NON_NEGATIVE, help="Tap amplitude a.")
@click.option("--T", "period", required=True, type=POSITIVE, help="Tap period T.")
@click.option("--out", required=True, type=click.Path(dir_okay=False))
def chaos_cmd(params, amplitude, period, out):
    """One point of the chaos map: largest Lyapunov exponents and return-map periods."""
    from .stages import chaos_stage

    keys = ("n_replicas", "transient_taps", "taps", "perturbation", "twin_epsilon", "plain",
            "return_max_period", "return_taps", "return_tolerance")  # fmt: skip
    refs = {"physics": _PHYSICS, **_STEP, **{k: _CHAOS + k for k in keys}}
    chaos_stage(_checked(params, refs), amplitude, period, out)


@cli.command("continuum")
@params_option
@click.option("--out", required=True, type=click.Path(dir_okay=False))
def continuum_cmd(params, out):
    """Fig. 2 data: discrete column, L-W and BSR solutions and their distances."""
    from .stages import continuum_stage

    continuum_stage(_checked(params, _continuum_refs(False)), out)


@cli.command("convergence")
@params_option
@click.option("--out", required=True, type=click.Path(dir_okay=False))
def convergence_cmd(params, out):
    """Both continuum solvers under grid refinement on the Fig. 2 problem."""
    from .stages import convergence_stage

    convergence_stage(_checked(params, _continuum_refs(True)), out)


@cli.command("ensemble")
@params_option
@click.option("--kind", required=True, type=click.Choice(["relaxation", "chaos"]))
@click.option("--out", required=True, type=click.Path(dir_okay=False))
@click.argument("inputs", nargs=-1, required=True, type=click.Path(exists=True))
def ensemble_cmd(params, kind, out, inputs):
    """Reduce run files: relaxation batches → per-tap statistics; chaos points → the map."""
    from .stages import ensemble_stage

    if kind == "relaxation":
        extra = {"kind": {"const": "relaxation"}, "runs_config_hash": _STRING}
        params = _checked(params, {}, extra)
    else:
        params = _checked(params, {"confidence": _CHAOS + "confidence"}, {"points": _HASHES})
    ensemble_stage(params, kind, out, inputs)


@cli.command("fits")
@params_option
@click.option("--relaxation", "relax_path", required=True, type=click.Path(exists=True))
@click.option("--chaos", "chaos_path", required=True, type=click.Path(exists=True))
@click.option("--continuum", "cont_path", required=True, type=click.Path(exists=True))
@click.option("--convergence", "conv_path", required=True, type=click.Path(exists=True))
@click.option("--out-csv", required=True, type=click.Path(dir_okay=False))
@click.option("--out-nc", required=True, type=click.Path(dir_okay=False))
@click.option("--out-note", required=True, type=click.Path(dir_okay=False))
def fits_cmd(params, relax_path, chaos_path, cont_path, conv_path, out_csv, out_nc, out_note):
    """Relaxation fit, chaos thresholds, continuum distances: summary.csv rows and a note."""
    from .stages import fits_stage

    refs = {"n_boot": _RELAX + "n_boot", "units": "/properties/units"}
    params = _checked(params, refs, {"inputs": _HASHES})
    fits_stage(params, relax_path, chaos_path, cont_path, conv_path, out_csv, out_nc, out_note)


@cli.command("figures")
@params_option
@click.option("--trajectories", "traj", required=True, multiple=True, type=click.Path(exists=True))
@click.option("--continuum", "cont_path", required=True, type=click.Path(exists=True))
@click.option("--relaxation", "relax_path", required=True, type=click.Path(exists=True))
@click.option("--chaos", "chaos_path", required=True, type=click.Path(exists=True))
@click.option("--convergence", "conv_path", required=True, type=click.Path(exists=True))
@click.option("--outdir", required=True, type=click.Path(file_okay=False))
def figures_cmd(params, traj, cont_path, relax_path, chaos_path, conv_path, outdir):
    """Figures 1–6 as PNG and PDF: fig<k>_<name>.{png,pdf}."""
    from .stages import figures_stage

    params = _checked(params, {"units": "/properties/units"}, {"inputs": _HASHES})
    figures_stage(params, traj, cont_path, relax_path, chaos_path, conv_path, outdir)
