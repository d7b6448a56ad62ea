"""The drum study's stages, as library functions the CLI (and so the workflow) calls.

init → runs → ensemble → fits → figures (DESIGN.md, "Stages and what each writes").
Each function takes the config subset its rule passes (``params``, a partial
``drum`` section; missing keys take their schema defaults), reads its inputs,
and writes its outputs atomically with that subset as provenance.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..io import read_dataset, write_dataset
from .settings import filled

__all__ = [
    "init_stage",
    "runs_stage",
    "ensemble_stage",
    "fits_stage",
    "figures_stage",
]

STUDY = "drum"


def _log(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def init_stage(params: Mapping, batch: int, out: str | os.PathLike, threads: int = 1) -> Path:
    """Place and settle every replica of ``batch``; write ``init/<point>/batch_<b>.nc``."""
    from .protocol import settle_batch

    sec = filled(params)
    ds = settle_batch(sec, int(batch), threads=threads, log=_log)
    seeds = [int(s) for s in ds["seed"].values]
    path = write_dataset(
        ds, out, config_subset=params, seeds=seeds, study=STUDY, stage="init", batch=int(batch)
    )
    _log(f"wrote {path}")
    return path


def runs_stage(
    params: Mapping, batch: int, init: str | os.PathLike, out: str | os.PathLike, threads: int = 1
) -> Path:
    """Run the protocol for every replica of ``batch`` from its settled state."""
    from .protocol import run_batch

    sec = filled(params)
    init_ds = read_dataset(init)
    ds = run_batch(sec, int(batch), init_ds, threads=threads, log=_log)
    seeds = [int(s) for s in ds["seed"].values]
    path = write_dataset(
        ds, out, config_subset=params, seeds=seeds, study=STUDY, stage="runs", batch=int(batch)
    )
    _log(f"wrote {path}")
    return path


def ensemble_stage(params: Mapping, runs: Sequence[str | os.PathLike], out) -> Path:
    """Stream the run files into ensemble means, standard errors and counts."""
    from .fitting import reduce_runs

    sec = filled(params)
    t0 = time.perf_counter()
    ds = reduce_runs(runs, exclude_flagged=sec["ensemble"]["exclude_flagged"])
    _log(
        f"reduced {ds.attrs['n_batches']} batch(es): {ds.attrs['n_replicas']} replicas used, "
        f"{ds.attrs['n_excluded']} excluded, in {time.perf_counter() - t0:.1f} s"
    )
    path = write_dataset(ds, out, config_subset=params, study=STUDY, stage="ensemble")
    _log(f"wrote {path}")
    return path


def fits_stage(
    params: Mapping,
    ensemble: str | os.PathLike,
    runs: Sequence[str | os.PathLike],
    out: str | os.PathLike,
    summary: str | os.PathLike,
) -> Path:
    """Fit onset time, sign changes and lags; write ``fits/<point>.nc`` and summary rows."""
    from ..analysis.summary import results_dataset, write_summary
    from .fitting import PAPER_VALUES, drum_fits, load_units

    sec = filled(params)
    fcfg = sec["fits"]
    ens = read_dataset(ensemble)
    units = load_units(runs, fcfg["bootstrap_unit"], sec["ensemble"]["exclude_flagged"])
    n_units = units["onset"].speed.shape[0]
    _log(
        f"bootstrap over {n_units} {fcfg['bootstrap_unit']}(s) "
        f"({units['onset'].n_replicas} replicas), {fcfg['bootstrap_resamples']} resamples"
    )
    results, curves = drum_fits(ens, units, fcfg)
    for r in results:
        ci = f"[{r.ci_low:.3f}, {r.ci_high:.3f}]" if np.isfinite(r.ci_low) else ""
        paper = PAPER_VALUES.get(r.quantity.removesuffix("_auto"))
        _log(
            f"{r.quantity:32s} = {r.value:8.3f} ± {r.fit_error:.3f} {r.unit} {ci}"
            + (f"  (paper {paper:.3f})" if paper is not None else "")
        )
    ds = results_dataset(results).merge(curves)
    ds.attrs.update(curves.attrs)
    ds.attrs.update(
        {k: ens.attrs[k] for k in ("n_replicas", "stop_time_s", "dt_s", "block_steps")},
        bootstrap_unit=fcfg["bootstrap_unit"],
        n_bootstrap_units=n_units,
    )
    path = write_dataset(ds, out, config_subset=params, study=STUDY, stage="fits")
    rows = [r.to_row(STUDY, PAPER_VALUES.get(r.quantity.removesuffix("_auto"))) for r in results]
    write_summary(rows, summary, merge=True)
    _log(f"wrote {path} and {len(rows)} rows of {summary}")
    return path


def figures_stage(
    params: Mapping,
    ensemble: str | os.PathLike,
    fits: str | os.PathLike,
    snapshot: str | os.PathLike,
    outdir: str | os.PathLike,
) -> list[Path]:
    """Figs. 2-5 as PNG and PDF in ``outdir``."""
    from ..figures import drum as figs
    from .layout import FIGURES

    sec = filled(params)
    dpi = int(sec["figures"]["dpi"])
    ens = read_dataset(ensemble)
    fit = read_dataset(fits)
    run = read_dataset(snapshot)
    outdir = Path(outdir)
    makers = {
        2: lambda: figs.fig2_snapshot(run),
        3: lambda: figs.fig3_onset(ens, fit),
        4: lambda: figs.fig4_decay(ens, fit),
        5: lambda: figs.fig5_lambda_vs_speed(ens, fit),
    }
    paths = []
    for k, name in FIGURES.items():
        paths += figs.save(makers[k](), outdir / f"fig{k}_{name}", dpi=dpi)
    _log(f"wrote {len(paths)} figure files to {outdir}")
    return paths
