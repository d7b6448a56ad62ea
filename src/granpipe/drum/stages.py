"""The drum study's stages, as library functions the CLI (and so the workflow) calls.

init → runs → ensemble → fits → summary, figures (docs/architecture.md, "Stages").
The simulation stages take one parameter point's config subset (``params``, a
partial ``drum`` section; missing keys take their schema defaults); the later stages
take the subsets :func:`granpipe.drum.layout.rule_params` builds. Each reads its
inputs, checks that they belong together, and writes its outputs atomically with
that subset as provenance.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..errors import GranpipeError, RunFileError
from ..io import check_run_files, config_hash, expect_input, read_dataset, write_dataset
from .layout import ENSEMBLE_KEYS, load

__all__ = [
    "init_stage",
    "runs_stage",
    "ensemble_stage",
    "fits_stage",
    "summary_stage",
    "figures_stage",
    "restamp_stage",
]

STUDY = "drum"


def _log(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def _point(sec) -> str:
    from .layout import point_name

    return point_name(sec)


def _section(params: Mapping):
    """The drum section of a later stage's ``--params`` (without the point, the run
    files' config hash and the row label: :func:`granpipe.drum.layout.rule_params`)."""
    section_keys = set(params) - {"point", "runs_config_hash", "label"}
    return load({k: params[k] for k in section_keys})


def init_stage(params: Mapping, batch: int, out: str | os.PathLike, threads: int = 1) -> Path:
    """Place every replica of ``batch`` and run its start-up; write the init file."""
    from .protocol import init_batch

    sec = load(params)  # filled once, handed down frozen
    ds = init_batch(sec, int(batch), threads=threads, log=_log)
    seeds = [int(s) for s in ds["seed"].values]
    path = write_dataset(
        ds, out, config_subset=params, seeds=seeds, study=STUDY, stage="init",
        batch=int(batch), point=_point(sec),
    )  # fmt: skip
    _log(f"wrote {path}")
    return path


def runs_stage(
    params: Mapping, batch: int, init: str | os.PathLike, out: str | os.PathLike, threads: int = 1
) -> Path:
    """Run the protocol for every replica of ``batch`` from its init file."""
    from .protocol import run_batch

    sec = load(params)  # filled once, handed down frozen
    (info,) = check_run_files(
        [init], study=STUDY, stage="init", point=_point(sec), config_hash=config_hash(params)
    )
    if info["batch"] is not None and int(info["batch"]) != int(batch):
        raise RunFileError(f"{init} holds batch {info['batch']}, not batch {batch}")
    init_ds = read_dataset(init)
    ds = run_batch(sec, int(batch), init_ds, threads=threads, log=_log)
    seeds = [int(s) for s in ds["seed"].values]
    path = write_dataset(
        ds, out, config_subset=params, seeds=seeds, study=STUDY, stage="runs",
        batch=int(batch), point=_point(sec),
    )  # fmt: skip
    _log(f"wrote {path}")
    return path


def ensemble_stage(params: Mapping, runs: Sequence[str | os.PathLike], out) -> Path:
    """Stream the run files of one point into ensemble means, standard errors and counts."""
    from .fits import reduce_runs

    sec = _section(params)
    t0 = time.perf_counter()
    point, runs_hash = params["point"], params["runs_config_hash"]
    check_run_files(runs, study=STUDY, point=point, config_hash=runs_hash)
    ds = reduce_runs(runs, exclude_flagged=sec["ensemble"]["exclude_flagged"])
    _log(
        f"reduced {ds.attrs['n_batches']} batch(es): {ds.attrs['n_replicas']} replicas used, "
        f"{ds.attrs['n_excluded']} excluded, in {time.perf_counter() - t0:.1f} s"
    )
    path = write_dataset(
        ds, out, config_subset=params, study=STUDY, stage="ensemble", point=point,
        runs_config_hash=runs_hash,
    )  # fmt: skip
    _log(f"wrote {path}")
    return path


def fits_stage(
    params: Mapping,
    ensemble: str | os.PathLike,
    runs: Sequence[str | os.PathLike],
    out: str | os.PathLike,
) -> Path:
    """Fit onset time, sign changes and lags of one point; write ``fits/<point>.nc``.

    ``params["label"]`` (from :func:`granpipe.drum.layout.rule_params`) is appended to
    every quantity name; the point's summary rows are stored in the file
    (:func:`summary_stage` gathers them).
    """
    from ..analysis.summary import results_dataset
    from .fits import PAPER_VALUES, drum_fits, load_pile, load_units

    label = str(params.get("label", ""))
    sec = _section(params)
    fcfg = sec["fits"]
    point, runs_hash = params["point"], params["runs_config_hash"]
    check_run_files(runs, study=STUDY, point=point, config_hash=runs_hash)
    ens = read_dataset(ensemble)
    expect_input(
        ens, ensemble, study=STUDY, stage="ensemble", point=point,
        config_hash=config_hash({k: params[k] for k in ENSEMBLE_KEYS}),
    )  # fmt: skip
    units = load_units(runs, fcfg["bootstrap_unit"], sec["ensemble"]["exclude_flagged"])
    n_units = units["onset"].speed.shape[0]
    _log(
        f"bootstrap over {n_units} {fcfg['bootstrap_unit']}(s) "
        f"({units['onset'].n_replicas} replicas), {fcfg['bootstrap_resamples']} resamples"
    )
    pile = load_pile(runs, fcfg, fcfg["bootstrap_unit"], sec["ensemble"]["exclude_flagged"])
    results, curves = drum_fits(ens, units, fcfg, label=label, pile=pile)
    for r in results:
        ci = f"[{r.ci_low:.3f}, {r.ci_high:.3f}]" if np.isfinite(r.ci_low) else ""
        paper = PAPER_VALUES.get(r.quantity.removesuffix("_auto")) if not label else None
        _log(
            f"{r.quantity:40s} = {r.value:9.4g} ± {r.fit_error:.3g} {r.unit} {ci}"
            + (f"  (paper {paper:.3f})" if paper is not None else "")
            + (f"  -- {r.note}" if r.note else "")
        )
    ds = results_dataset(results).merge(curves)
    ds.attrs.update(curves.attrs)
    ds.attrs.update(
        {k: ens.attrs[k] for k in ("n_replicas", "stop_time_s", "dt_s", "block_steps")},
        bootstrap_unit=fcfg["bootstrap_unit"],
        n_bootstrap_units=n_units,
        label=label,
        quantities=" ".join(r.quantity for r in results),
    )
    path = write_dataset(
        ds, out, config_subset=params, study=STUDY, stage="fits", point=point,
        runs_config_hash=runs_hash,
    )  # fmt: skip
    _log(f"wrote {path}")
    return path


def summary_stage(fits: Sequence[str | os.PathLike], summary: str | os.PathLike) -> Path:
    """Gather the rows of every point's fits file into ``summary.csv`` (the paper's
    numbers next to the reference point's rows, whose label is empty)."""
    from ..analysis.summary import results_rows, write_summary
    from .fits import PAPER_VALUES

    rows, points = [], {}
    for path in fits:
        ds = read_dataset(path)
        expect_input(ds, path, study=STUDY, stage="fits")
        point = str(ds.attrs.get("point"))
        if Path(path).stem != point:  # fits/<point>.nc (layout.fits_file)
            raise RunFileError(
                f"{path} holds the fits of point {point}, not of {Path(path).stem}: a file "
                "copied over another point's; remove it and rerun"
            )
        if point in points:
            raise RunFileError(f"point {point} appears twice: in {points[point]} and in {path}")
        points[point] = path
        if ds.attrs.get("label", ""):
            rows += results_rows(ds, STUDY)
        else:  # the reference point: the paper's numbers beside its rows
            rows += results_rows(ds, STUDY, lambda q: PAPER_VALUES.get(q.removesuffix("_auto")))
    path = write_summary(rows, summary, merge=False)
    _log(f"wrote {len(rows)} rows to {path}")
    return path


def figures_stage(
    params: Mapping,
    ensembles: Sequence[str | os.PathLike],
    fits: Sequence[str | os.PathLike],
    snapshot: str | os.PathLike,
    outdir: str | os.PathLike,
) -> list[Path]:
    """Figs. 2-5 and 9 of the reference point and the comparison figures 6-8 (PNG and PDF).

    ``ensembles`` and ``fits`` hold one file per point, in the order of
    ``params["points"]`` (a list of ``{"name", "period_s", "startup", "friction", "label"}``, the
    first the reference point).
    """
    from ..figures import drum as figs
    from ..figures import save_figure
    from .fits import PAPER_VALUES
    from .layout import COMPARISON_FIGURES, FIGURES

    sec = load({"figures": params["figures"]})
    dpi = int(sec["figures"]["dpi"])
    points = list(params["points"])
    if len(points) != len(ensembles) or len(points) != len(fits):
        raise RunFileError(
            f"figures need one ensemble and one fits file per point ({len(points)} points): "
            f"got {len(ensembles)} ensemble and {len(fits)} fits file(s)"
        )
    table = {}
    for meta, e, f in zip(points, ensembles, fits, strict=True):
        name, runs_hash = meta["name"], meta["runs_config_hash"]
        ens, fit = read_dataset(e), read_dataset(f)
        for ds, path, stage in ((ens, e, "ensemble"), (fit, f, "fits")):
            expect_input(ds, path, study=STUDY, stage=stage, point=name,
                         runs_config_hash=runs_hash)  # fmt: skip
        table[name] = {**meta, "ensemble": ens, "fits": fit}
    ref = table[next(iter(table))]
    ens, fit = ref["ensemble"], ref["fits"]
    run = read_dataset(snapshot)
    expect_input(
        run, snapshot, study=STUDY, stage="runs", point=points[0]["name"],
        config_hash=points[0]["runs_config_hash"], batch=sec["figures"]["snapshot_batch"],
    )  # fmt: skip
    outdir = Path(outdir)
    makers = {
        2: lambda: figs.fig2_snapshot(run),
        3: lambda: figs.fig3_onset(ens, fit),
        4: lambda: figs.fig4_decay(ens, fit),
        5: lambda: figs.fig5_lambda_vs_speed(ens, fit),
        6: lambda: figs.fig6_startup(table),
        7: lambda: figs.fig7_lag_vs_rotation(table, PAPER_VALUES),
        8: lambda: figs.fig8_friction(table),
        9: lambda: figs.fig9_aligned(ens, fit),
    }
    paths = []
    for k, name in {**FIGURES, **COMPARISON_FIGURES}.items():
        paths += save_figure(makers[k](), outdir / f"fig{k}_{name}", dpi=dpi)
    _log(f"wrote {len(paths)} figure files to {outdir}")
    return paths


def restamp_stage(
    section: Mapping, files: Sequence[str | os.PathLike], results: str | os.PathLike
) -> list[Path]:
    """Reuse init and run files under the point names of a config: each file whose
    physics subset is that of a point of ``section`` (its stored config filled with this
    version's defaults, against the point's simulation subset of
    :func:`granpipe.drum.layout.rule_params`) is written, data untouched, to that point's
    folder under ``results`` (``results/<scale>/drum``) with the point's name and config
    hash, so that the stages accept it. A file whose physics no point has, or whose
    target exists, is refused naming both.
    """
    from ..io import config_from_attrs
    from .layout import init_file, point_sections, rule_params, run_file, trajectory_keys

    sim = rule_params(section)["sim"]
    points = point_sections(section)
    targets = []
    for f in files:
        ds = read_dataset(f)
        stage = ds.attrs.get("stage")
        if ds.attrs.get("study") != STUDY or stage not in ("init", "runs"):
            raise RunFileError(f"{f} is not a drum init or runs file")
        try:
            stored = load(config_from_attrs(ds))
        except GranpipeError as exc:
            raise RunFileError(f"{f}: its stored config is not a drum config here: {exc}") from None
        have = {
            **trajectory_keys(stored),
            "ensemble": {"batch_size": stored["ensemble"]["batch_size"]},
        }
        name = next((n for n, want in sim.items() if want == have), None)
        if name is None:
            raise RunFileError(
                f"{f} holds physics (point {ds.attrs.get('point')!r}) that no point of this "
                f"config has (points: {', '.join(sim)}): it cannot be reused here"
            )
        where = init_file if stage == "init" else run_file
        target = Path(results) / where(points[name], int(ds.attrs["batch"]))
        if target.exists():
            raise RunFileError(f"{f} would be written to {target}, which exists: remove it first")
        targets.append((ds, f, name, target))
    written = []
    for ds, f, name, target in targets:
        seeds = [int(s) for s in str(ds.attrs["seeds"]).split()]
        write_dataset(
            ds, target, config_subset=sim[name], seeds=seeds, study=STUDY,
            stage=ds.attrs["stage"], batch=int(ds.attrs["batch"]), point=name,
            restamped_from=f"{f} ({ds.attrs.get('point')}, config hash "
            f"{str(ds.attrs.get('config_hash'))[:12]})",
        )  # fmt: skip
        _log(f"{f} -> {target}")
        written.append(target)
    return written
