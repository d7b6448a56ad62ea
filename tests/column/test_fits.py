"""Column summary rows that stay when their input is missing: the scan over the width
w_σ of the smooth sign gives a row per model, top and configured width, empty where the
convergence run has no value, and the note names those rows."""

import math

import numpy as np
import xarray as xr

from granpipe.column import fits
from granpipe.column.protocol import SIGMA_SCAN_MODELS, TOP_TREATMENTS


def _conv(widths):
    scan = np.arange(len(SIGMA_SCAN_MODELS) * len(TOP_TREATMENTS) * len(widths), dtype=float)
    da = (("scan_model", "top", "sigma_width"), scan.reshape(-1, len(TOP_TREATMENTS), len(widths)))
    return xr.Dataset(
        {"sigma_scan_relative_displacements": da},
        coords={"scan_model": list(SIGMA_SCAN_MODELS), "top": list(TOP_TREATMENTS),
                "sigma_width": widths},
        attrs={"sigma_scan_refinement": 2},
    )  # fmt: skip


def _names(widths):
    return {
        f"continuum_relative_displacements[model={m},top={t},sigma_width={w:g}]"
        for m in SIGMA_SCAN_MODELS
        for t in TOP_TREATMENTS
        for w in widths
    }


def test_every_configured_sigma_scan_row_is_present_and_the_note_names_the_empty_ones():
    configured = [0.01, 0.001]
    for conv, run in ((_conv([0.01]), [0.01]), (xr.Dataset(), [])):
        rows = {r["quantity"]: r["value"] for r in fits.sigma_scan_rows(conv, configured)}
        assert set(rows) == _names(configured)
        empty = _names(configured) - _names(run)
        assert all(math.isnan(rows[q]) for q in empty)
        assert all(math.isfinite(rows[q]) for q in _names(run))
        note = "\n".join(fits.sigma_scan_note(conv, configured))
        assert all(q in note for q in empty) and not any(q in note for q in _names(run))
