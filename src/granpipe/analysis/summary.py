"""``summary.csv``: one row per fitted quantity, next to the paper's number (docs/architecture.md).

Columns, in this order::

    study, quantity, value, unit, fit_error, ci_low, ci_high, n, paper_value

Empty cells where a column does not apply (no CI, no paper value). ``n`` is an
integer (replicas, periods or grid points behind the value, as the study
documents). Numbers are written with 10 significant digits.

Every row is built by :func:`summary_row`: the studies' fits call it directly or through
the ``to_row`` / ``summary_row(s)`` methods of the fitted results (``FitResult``,
``SegmentedFit``, ``ArrheniusFit``, the box's ``Threshold``), and :func:`results_rows`
reads rows back from a fits file the same way.

Several fits rules may add rows to the same file; :func:`write_summary` with
``merge=True`` reads the existing file, replaces rows with the same
(study, quantity) and writes the result atomically (temporary file + rename).
Atomic rename protects readers from partial files, not two writers from each
other: rules writing the same summary must not run concurrently (or should
each write their own file and a final rule concatenate them).
"""

from __future__ import annotations

import io
import math
import os
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from ..io import write_text

__all__ = [
    "COLUMNS",
    "summary_row",
    "summary_frame",
    "read_summary",
    "write_summary",
    "results_dataset",
    "results_rows",
]

COLUMNS = [
    "study",
    "quantity",
    "value",
    "unit",
    "fit_error",
    "ci_low",
    "ci_high",
    "n",
    "paper_value",
]
_FLOAT = ["value", "fit_error", "ci_low", "ci_high", "paper_value"]


def _num(x) -> float:
    if x is None:
        return math.nan
    try:
        return float(x)
    except (TypeError, ValueError):
        raise ValueError(f"not a number: {x!r}") from None


def summary_row(
    study: str,
    quantity: str,
    value: float,
    unit: str = "",
    fit_error: float | None = None,
    ci_low: float | None = None,
    ci_high: float | None = None,
    n: int | None = None,
    paper_value: float | None = None,
) -> dict:
    """One row as a dict with exactly :data:`COLUMNS` (``None`` → empty cell)."""
    if not study or not quantity:
        raise ValueError("study and quantity are required")
    if n is not None and not (isinstance(n, float) and math.isnan(n)):
        n = int(n)
    else:
        n = None
    return {
        "study": str(study),
        "quantity": str(quantity),
        "value": _num(value),
        "unit": "" if unit is None else str(unit),
        "fit_error": _num(fit_error),
        "ci_low": _num(ci_low),
        "ci_high": _num(ci_high),
        "n": n,
        "paper_value": _num(paper_value),
    }


def summary_frame(rows: Iterable[Mapping]) -> pd.DataFrame:
    """A DataFrame with :data:`COLUMNS` from rows (dicts, e.g. ``FitResult.to_row``).

    Missing keys become empty; unknown keys raise ``ValueError``.
    """
    clean = []
    for r in rows:
        extra = set(r) - set(COLUMNS)
        if extra:
            raise ValueError(f"unknown summary columns: {sorted(extra)}")
        clean.append(summary_row(**{k: r.get(k) for k in COLUMNS if k in r}))
    df = pd.DataFrame(clean, columns=COLUMNS)
    for c in _FLOAT:
        df[c] = df[c].astype("float64")
    df["n"] = df["n"].astype("Int64")
    df["unit"] = df["unit"].fillna("")
    return df


def read_summary(path: str | os.PathLike) -> pd.DataFrame:
    """Read a ``summary.csv`` back (empty cells → NaN / <NA>)."""
    df = pd.read_csv(
        path,
        dtype={"study": str, "quantity": str, "unit": str},
        keep_default_na=False,
        na_values={c: [""] for c in [*_FLOAT, "n"]},
    )
    missing = [c for c in COLUMNS if c not in df.columns]
    if missing:
        raise ValueError(f"{path}: missing columns {missing}")
    df = df[COLUMNS]
    for c in _FLOAT:
        df[c] = df[c].astype("float64")
    df["n"] = df["n"].astype("Int64")
    return df


def write_summary(
    rows: pd.DataFrame | Iterable[Mapping],
    path: str | os.PathLike,
    *,
    merge: bool = True,
) -> Path:
    """Write rows to ``summary.csv`` atomically.

    Parameters
    ----------
    rows : DataFrame with :data:`COLUMNS`, or iterable of row dicts
    merge : bool
        If the file exists, keep its rows except those with the same
        (study, quantity) as a new row (replaced). Rows are sorted by study,
        then quantity. ``merge=False`` overwrites the file.
    """
    df = rows if isinstance(rows, pd.DataFrame) else summary_frame(rows)
    df = summary_frame(df.to_dict("records"))
    if df.duplicated(["study", "quantity"]).any():
        raise ValueError("duplicate (study, quantity) rows")
    path = Path(path)
    if merge and path.exists():
        old = read_summary(path)
        keys = set(zip(df["study"], df["quantity"], strict=True))
        keep = [(s, q) not in keys for s, q in zip(old["study"], old["quantity"], strict=True)]
        df = pd.concat([old[keep], df], ignore_index=True) if any(keep) else df
    df = df.sort_values(["study", "quantity"], kind="stable").reset_index(drop=True)
    buf = io.StringIO()
    df.to_csv(buf, index=False, na_rep="", float_format="%.10g")
    return write_text(buf.getvalue(), path)


def results_dataset(results: Iterable) -> xr.Dataset:
    """FitResults → an xarray Dataset for ``fits/*.nc`` (one scalar per number).

    For a result with quantity ``q`` the variables are ``q``, ``q_fit_error``,
    ``q_ci_low``, ``q_ci_high`` (its unit) and attributes on ``q``: ``n``,
    ``ci_level``, ``n_resamples``, ``method``, and the fit window. Every variable
    carries ``units`` and ``long_name`` (as :func:`granpipe.io.write_dataset` requires).
    """
    ds = xr.Dataset()
    for r in results:
        q, unit = r.quantity, r.unit or "1"
        name = q.replace("_", " ")
        attrs = {"units": unit, "long_name": name, "method": r.method}
        if r.n is not None:
            attrs["n"] = int(r.n)
        if np.isfinite(r.ci_level):
            attrs["ci_level"] = float(r.ci_level)
            attrs["n_resamples"] = int(r.n_resamples)
            attrs["n_failed_resamples"] = int(r.n_failed)
        if r.window is not None:
            attrs["window"] = np.asarray(r.window, dtype=np.float64)
        if getattr(r, "note", ""):
            attrs["note"] = r.note
        ds[q] = ((), float(r.value), attrs)
        ds[f"{q}_fit_error"] = (
            (),
            float(r.fit_error),
            {"units": unit, "long_name": f"fit error of {name}"},
        )
        ds[f"{q}_ci_low"] = (
            (),
            float(r.ci_low),
            {"units": unit, "long_name": f"lower CI bound of {name}"},
        )
        ds[f"{q}_ci_high"] = (
            (),
            float(r.ci_high),
            {"units": unit, "long_name": f"upper CI bound of {name}"},
        )
    return ds


def results_rows(
    ds: xr.Dataset, study: str, paper_value: Callable[[str], float | None] | None = None
) -> list[dict]:
    """The summary rows of a fits file written from :func:`results_dataset` (the inverse).

    The quantities are those named, in order, by the file's ``quantities`` attribute;
    ``paper_value(quantity)`` gives the paper's number for a row (``None``: none).
    """
    names = str(ds.attrs.get("quantities", "")).split()
    if not names:
        raise ValueError("the fits file lists no quantities (attribute 'quantities')")
    rows = []
    for q in names:
        if q not in ds:
            raise ValueError(f"the fits file lists {q} but does not hold it")
        var = ds[q]
        n = var.attrs.get("n")
        rows.append(
            summary_row(
                study, q, float(var.values), var.attrs.get("units", ""),
                fit_error=float(ds[f"{q}_fit_error"].values),
                ci_low=float(ds[f"{q}_ci_low"].values),
                ci_high=float(ds[f"{q}_ci_high"].values),
                n=None if n is None else int(n),
                paper_value=None if paper_value is None else paper_value(q),
            )
        )  # fmt: skip
    return rows
