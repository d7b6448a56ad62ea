"""The shear study's stages, file to file (docs/architecture.md, "Stages"): runs (one batch
of one φ: preparation and record), fits (a point's numbers from its batches: no ensemble
stage, the event-triggered averages need every replica's record), summary, figures. Each
input is checked against what the stage derives from its own ``--params`` (study, stage,
point, config hash); a point's batches must hold each replica 0 … n−1 once.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from ..io import RunFileError, check_run_files, expect_input, read_dataset, write_dataset
from .layout import split_point, variants
from .measures import JAMMING

__all__ = ["runs_stage", "fits_stage", "summary_stage", "figures_stage"]


# what the fits read of a run file, and the summary and figures of a fits file (a file an
# earlier granpipe wrote may lack some: refused naming the rule to force)
RUN_VARIABLES = ("local_lyapunov", "global_speed", "network_changes",
                 "speed_lyapunov_correlation", "lyapunov_all", "snapshot_positions",
                 "snapshot_du", "snapshot_speed", "diameter", "disk_du", "disk_speed",
                 "disk_changes", *(f"jamming_{k}" for k in JAMMING))  # fmt: skip
FITS_VARIABLES = ("lambda_replica_mean", "lambda_all_replica_mean", "aligned_lambda_bar",
                  "aligned_count", "aligned_lambda_all_bar", "tau_sample", "event_lag",
                  "snapshot_du", "when_roc_lambda_all",
                  *(f"{k}_replica_mean" for k in JAMMING))  # fmt: skip


def _log(msg):
    print(f"[shear {time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def runs_stage(params: Mapping, batch: int, out) -> Path:
    """One batch of replicas of the point ``params["point"]``."""
    from ..seeds import batch_replicas
    from .protocol import run_batch

    t0 = time.time()
    reps = list(batch_replicas(batch, int(params["batch_size"])))
    _log(f"{params['point']} batch {batch}: replicas {reps}")
    ds, seeds = run_batch(params, reps, _log)
    path = write_dataset(ds, out, config_subset=params, seeds=seeds, study="shear",
                         stage="runs", point=params["point"], batch=int(batch),
                         wall_time_s=time.time() - t0)  # fmt: skip
    _log(f"wrote {path} ({time.time() - t0:.1f} s)")
    return path


def fits_stage(params: Mapping, run_files: Sequence, out) -> Path:
    """The point's fits (:func:`granpipe.shear.fits.point_fits`) from its run files."""
    from ..analysis.summary import results_dataset
    from .fits import point_fits

    point, n = params["point"], int(params["n_replicas"])
    labels = check_run_files(run_files, study="shear", point=point,
                             config_hash=params["runs_config_hash"],
                             variables=RUN_VARIABLES)  # fmt: skip
    have = sorted(r for lab in labels for r in lab["replicas"])
    if have[:n] != list(range(n)):
        raise RunFileError(f"the run files of {point} hold replicas {have}, not 0 .. {n - 1}")
    parts = [read_dataset(p) for p in run_files]
    ds = (
        xr.concat(
            parts, dim="replica", data_vars="minimal", coords="minimal", combine_attrs="override"
        )
        .sortby("replica")
        .isel(replica=slice(0, n))
    )
    results, curves = point_fits(ds, params)
    fits = xr.merge([results_dataset(results), curves])
    fits.attrs["quantities"] = " ".join(r.quantity for r in results)
    path = write_dataset(fits, out, config_subset=params, study="shear", stage="fits",
                         point=point, phi=split_point(point)[1])  # fmt: skip
    _log(f"wrote {path}")
    return path


def _fits_files(params: Mapping, paths: Sequence) -> dict[str, xr.Dataset]:
    """Each point's fits file, once, computed from the subset ``params["points"]`` names."""
    want, seen = params["points"], {}
    groups = {split_point(pt)[0] for pt in want} - {""}
    for p in paths:
        ds = read_dataset(p)
        point = str(ds.attrs.get("point"))
        if point not in want:
            raise RunFileError(f"{p} holds the fits of {point}, not a point of this config")
        folder = Path(p).parent.name  # a variant's points sit in a folder of its name
        named = f"{folder}/{Path(p).stem}" if folder in groups else Path(p).stem
        if named != point:
            raise RunFileError(f"{p} holds the fits of {point}, not of {named}")
        if point in seen:
            raise RunFileError(f"point {point} appears twice")
        expect_input(ds, p, study="shear", stage="fits", point=point, config_hash=want[point],
                     variables=FITS_VARIABLES)  # fmt: skip
        seen[point] = ds
    missing = [pt for pt in want if pt not in seen]
    if missing:
        raise RunFileError(f"no fits file of the point(s) {', '.join(missing)}")
    return {pt: seen[pt] for pt in sorted(seen, key=split_point)}


def _variant(fits: Mapping[str, xr.Dataset], variant: str) -> dict[str, xr.Dataset]:
    """The fits of one variant's points (``""``: the base section's), in φ order."""
    return {pt: ds for pt, ds in fits.items() if split_point(pt)[0] == variant}


def _transitions(params: Mapping, fits: Mapping[str, xr.Dataset], variant: str) -> list:
    """The rows of :func:`granpipe.shear.fits.transitions` of one variant."""
    from .fits import TABLE_KEYS, transitions

    own = _variant(fits, variant)
    phis = [split_point(pt)[1] for pt in own]
    tables = [{k: ds[f"{k}_replica_mean"].values for k in TABLE_KEYS} for ds in own.values()]
    return transitions(phis, tables, params, f"[{variant}]" if variant else "")


def summary_stage(params: Mapping, fits_files: Sequence, out) -> Path:
    """summary.csv: each point's rows (quantity ``<name>[<point>]``) and, per variant
    (the base section's without a suffix, a variant's with ``[<variant>]``), the
    transition and the jamming point across φ (:data:`granpipe.shear.fits.TRANSITIONS`)."""
    from ..analysis.summary import results_rows, write_summary

    fits = _fits_files(params, fits_files)
    rows = []
    for point, ds in fits.items():
        for row in results_rows(ds, "shear"):
            rows.append({**row, "quantity": f"{row['quantity']}[{point}]"})
    for variant in variants(params):
        rows += [r.to_row("shear") for r in _transitions(params, fits, variant)]
    path = write_summary(rows, out, merge=False)
    _log(f"wrote {len(rows)} rows to {path}")
    return path


def figures_stage(params: Mapping, fits_files: Sequence, out_dir, drum_fits=None) -> list:
    """Figs. 1-7 (PNG and PDF) of the base section's points, and of every variant's
    transition (Fig. 7); the contrast figure takes the drum's reference fits file when the
    scale runs the drum (``drum_fits``), else shows the shear cell alone."""
    from ..figures import save_figure
    from ..figures import shear as F

    every = _fits_files(params, fits_files)
    fits = _variant(every, "")
    drum = None
    if drum_fits is not None:
        drum = read_dataset(drum_fits)
        expect_input(drum, drum_fits, study="drum", stage="fits")
    phi = params["contrast_phi"]
    if phi is None:  # the largest φ with a lead time
        have = [pt for pt, ds in fits.items() if np.isfinite(float(ds["event_lag"]))]
        phi = split_point((have or list(fits))[-1])[1]
    chosen = fits.get(f"phi={float(phi):g}")
    if chosen is None:
        raise RunFileError(f"figures.contrast_phi = {phi} is not a point of this config")
    trans = {v: _transitions(params, every, v) for v in variants(params)}
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    dpi = int(params["dpi"])
    figures = {"fig1_lambda_vs_phi": lambda: F.fig1_lambda_vs_phi(fits),
               "fig2_event_triggered": lambda: F.fig2_event_triggered(fits),
               "fig3_contrast": lambda: F.fig3_contrast(chosen, drum, trans[""]),
               "fig4_chaos_map": lambda: F.fig4_chaos_map(chosen),
               "fig5_jamming": lambda: F.fig5_jamming(fits, trans[""]),
               "fig6_prediction": lambda: F.fig6_prediction(fits),
               "fig7_variants": lambda: F.fig7_variants(trans)}  # fmt: skip
    paths = []
    for name, draw in figures.items():
        paths += save_figure(draw(), out_dir / name, dpi)
    _log(f"wrote {len(paths)} figure files to {out_dir}")
    return paths
