"""Measures of the column study: ensemble statistics of the runs (docs/column.md).

* :func:`t_interval` — mean and Student-t interval of the mean.
* :func:`relaxation_ensemble` — relaxation batches → per-tap mean, spread, standard
  error, count, and the stick band of the column.
* :func:`return_period` — the period of the tap-to-tap return map (Theorem 1).
* :func:`chaos_map` — chaos points → the (a, T) map of largest Lyapunov exponents with
  t-intervals, the chaotic/regular flags and the return-map periods.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
import xarray as xr
from scipy import stats

from ..io import config_from_attrs
from .model import ColumnParams, physics

__all__ = [
    "t_interval",
    "relaxation_ensemble",
    "stick_band_densities",
    "return_period",
    "UNDECIDED_MARGIN",
    "chaos_map",
]


def t_interval(x, confidence: float = 0.95):
    """Mean and Student-t interval of the mean of the finite values of x; (mean, lo, hi, n)."""
    x = np.asarray(x, dtype=np.float64)
    x = x[np.isfinite(x)]
    n = x.size
    if n == 0:
        return np.nan, np.nan, np.nan, 0
    m = float(x.mean())
    if n < 2:
        return m, np.nan, np.nan, n
    half = stats.t.ppf(0.5 + confidence / 2, n - 1) * x.std(ddof=1) / math.sqrt(n)
    return m, m - half, m + half, n


def relaxation_ensemble(batches: Iterable[xr.Dataset]):
    """Mean, standard deviation (spread), standard error and count per tap over replicas.

    Streams: each batch is merged into running moments (:class:`granpipe.analysis.
    ensemble.EnsembleAccumulator`) and dropped, so ``batches`` may be a generator that
    reads one file at a time. Only the per-replica density curves, (replica, tap), are
    kept, for the relaxation fit's per-replica statistics.
    """
    from ..analysis.ensemble import EnsembleAccumulator

    acc = {name: EnsembleAccumulator() for name in ("density", "height")}
    rows, attrs, taps, phys = [], None, None, None
    for b in batches:
        for name, a in acc.items():
            a.add(b[name], time_dim="tap")
        rows.append(b["density"].transpose("replica", "tap"))
        if attrs is None:
            attrs, taps = dict(b.attrs), b["tap"]
        phys = phys or config_from_attrs(b).get("physics")
    if attrs is None:
        raise ValueError("relaxation ensemble: no batch given")
    out = {}
    for name, unit in (("density", "mass/length"), ("height", "length")):
        a = acc[name]
        out[f"{name}_mean"] = ("tap", a.mean, {"units": unit, "long_name": f"ensemble mean {name}"})
        out[f"{name}_std"] = (
            "tap",
            a.std,
            {"units": unit, "long_name": f"replica spread (standard deviation) of {name}"},
        )
        out[f"{name}_sem"] = (
            "tap",
            a.sem,
            {"units": unit, "long_name": f"standard error of the mean {name}"},
        )
    out["count"] = ("tap", acc["density"].count, {"units": "1", "long_name": "replicas"})
    res = xr.Dataset(out, coords={"tap": taps}, attrs=attrs)
    res["density_replicas"] = xr.concat(rows, dim="replica")
    if phys:
        res.attrs.update(stick_band_densities(physics(phys)))
    return res


def stick_band_densities(p: ColumnParams) -> dict:
    """Linear densities of the equilibrium column and of the stick-band limits.

    A column at rest has every contact stuck with force F_j = (weight above) inside
    [K(1−e)c_j, K(1+e)c_j], so c_j ∈ [c_eq/(1+e), c_eq/(1−e)]: the rest height, and hence
    the density a tapped column can settle to, is confined to this band.
    """
    sc = p.mass_ratio * p.N * (p.N + 1) / 2  # Σ c_eq
    H = 2 * p.N * p.r
    return {
        "density_equilibrium": p.N * p.m / (H - sc),
        "density_band_low": p.N * p.m / (H - sc / (1 + p.e)),
        "density_band_high": p.N * p.m / (H - sc / (1 - p.e)),
    }


UNDECIDED_MARGIN = 100.0
"""A period p > 1 is undecided when a shorter lag comes within this factor of the tolerance."""


def return_period(x, modes, max_period: int, tolerance: float):
    """Smallest period p ≤ ``max_period`` of a sequence of states x_0 … x_(L−1).

    p is a period if ||x_(k+p) − x_k|| < ``tolerance`` and the contact modes of x_(k+p)
    and x_k agree for every pair inside the window (k = 0 … L − 1 − p; with
    L ≥ 2 ``max_period`` every phase of a p-cycle is compared at least once). The norm is
    the Euclidean one of the rows of ``x`` (the caller scales them: y/r, v/(ω_c r), the
    norm of :func:`granpipe.column.discrete.tangent_scales`). A NaN state makes every
    lag that touches it fail.

    A slow oscillating approach to a fixed point (multiplier μ near −1) closes the lag-2
    distance (∝ |1 − μ²|) long before the lag-1 one (∝ |1 − μ|) and would pass for
    period 2. So a period p > 1 counts only if every shorter lag stays above
    :data:`UNDECIDED_MARGIN` × ``tolerance``; otherwise the result is −2 (undecided: still
    converging, or too close to the bifurcation that created the p-cycle).

    Parameters
    ----------
    x : (L, n) float64, scaled states
    modes : (L, N) int or None, contact modes (None: not compared)
    max_period : int ≥ 1, with L ≥ 2 max_period
    tolerance : float > 0

    Returns
    -------
    period : int, the smallest period; 0 if none up to ``max_period``; −2 if undecided
    distance : (max_period,) float64, the largest distance over the window per lag p
    """
    x = np.asarray(x, dtype=np.float64)
    L = x.shape[0]
    if max_period < 1 or L < 2 * max_period:
        raise ValueError(f"need max_period >= 1 and at least 2 max_period states, got {L}")
    dist = np.full(max_period, np.nan)
    period = 0
    for lag in range(1, max_period + 1):
        dd = np.sqrt(np.sum((x[lag:] - x[:-lag]) ** 2, axis=1))
        dist[lag - 1] = np.max(dd)  # NaN if any state is NaN
        same = True if modes is None else bool(np.all(modes[lag:] == modes[:-lag]))
        if period == 0 and same and dist[lag - 1] < tolerance:
            period = lag
    if period > 1 and not np.all(dist[: period - 1] >= UNDECIDED_MARGIN * tolerance):
        period = -2
    return period, dist


def chaos_map(points: Iterable[xr.Dataset], confidence: float = 0.95):
    """Reduce per-point datasets to the (a, T) map: mean exponents with t-intervals.

    ``chaotic`` is 1 where the lower end of the interval of λ (per tap, with saltation) is
    above zero, 0 where the upper end is below zero, and −1 (undecided) otherwise.

    Return-map periods (:func:`lyapunov_point`): ``period_counts`` (a, T, period) counts
    the replicas per detected period (period 0: none up to the maximum; broken columns
    and undecided replicas are left out, the latter counted in ``period_undecided``),
    ``period_mode`` is the most common detected period (the smallest on a tie; 0 if no
    replica has one), ``period_fraction`` the fraction of the unbroken replicas with a
    detected period, ``period_max`` the largest detected one, ``rest_fraction`` the mean
    fraction of return-window states at rest.
    """
    pts = list(points)
    A = np.array(sorted({float(ds.attrs["a"]) for ds in pts}))
    T = np.array(sorted({float(ds.attrs["T"]) for ds in pts}))
    shape = (A.size, T.size)
    p_max = max(int(ds.attrs.get("return_max_period", 0)) for ds in pts)
    counts = np.zeros((*shape, p_max + 1), dtype=np.int64)
    p_mode = np.zeros(shape, dtype=np.int64)
    p_top = np.zeros(shape, dtype=np.int64)
    p_frac = np.full(shape, np.nan)
    undecided = np.zeros(shape, dtype=np.int64)
    rest = np.full(shape, np.nan)
    fields = {
        k: np.full(shape, np.nan)
        for k in (
            "lambda_mean",
            "lambda_low",
            "lambda_high",
            "twin_mean",
            "twin_low",
            "twin_high",
            "plain_mean",
            "plain_low",
            "plain_high",
            "lambda_time",
        )
    }
    n = np.zeros(shape, dtype=np.int64)
    failed = np.zeros(shape, dtype=np.int64)
    chaotic = np.full(shape, -1, dtype=np.int64)
    for ds in pts:
        i = int(np.searchsorted(A, float(ds.attrs["a"])))
        j = int(np.searchsorted(T, float(ds.attrs["T"])))
        m, lo, hi, nn = t_interval(ds["lambda_tap"].values, confidence)
        fields["lambda_mean"][i, j], fields["lambda_low"][i, j], fields["lambda_high"][i, j] = (
            m,
            lo,
            hi,
        )
        fields["lambda_time"][i, j] = m / T[j]
        n[i, j] = nn
        failed[i, j] = int(ds["failed"].sum())
        for key, var in (("twin", "lambda_twin"), ("plain", "lambda_plain")):
            m2, lo2, hi2, _ = t_interval(ds[var].values, confidence)
            fields[f"{key}_mean"][i, j], fields[f"{key}_low"][i, j], fields[f"{key}_high"][i, j] = (
                m2,
                lo2,
                hi2,
            )
        if np.isfinite(lo) and lo > 0:
            chaotic[i, j] = 1
        elif np.isfinite(hi) and hi < 0:
            chaotic[i, j] = 0
        if "return_period" in ds:
            per = ds["return_period"].values
            undecided[i, j] = int(np.sum(per == -2))
            n_ok = int(np.sum(per != -1))
            per = per[per >= 0]
            counts[i, j] = np.bincount(per, minlength=p_max + 1)[: p_max + 1]
            if n_ok:
                p_frac[i, j] = float(np.sum(per > 0)) / n_ok
                rest[i, j] = float(np.nanmean(ds["rest_fraction"].values))
            if np.any(per > 0):
                p_mode[i, j] = int(np.argmax(counts[i, j, 1:])) + 1
                p_top[i, j] = int(per.max())
    names = {
        "lambda_mean": ("1/tap", "mean largest Lyapunov exponent (tangent with saltation)"),
        "lambda_low": ("1/tap", f"lower end of the {confidence:.0%} t-interval"),
        "lambda_high": ("1/tap", f"upper end of the {confidence:.0%} t-interval"),
        "lambda_time": ("1/time", "mean largest Lyapunov exponent per unit time"),
        "twin_mean": ("1/tap", "mean exponent from twin trajectories"),
        "twin_low": ("1/tap", "twin estimate, lower end of the interval"),
        "twin_high": ("1/tap", "twin estimate, upper end of the interval"),
        "plain_mean": ("1/tap", "mean exponent from the variational equations without saltation"),
        "plain_low": ("1/tap", "plain variational estimate, lower end"),
        "plain_high": ("1/tap", "plain variational estimate, upper end"),
    }
    data = {
        k: (("a", "T"), v, {"units": names[k][0], "long_name": names[k][1]})
        for k, v in fields.items()
    }
    data["n"] = (("a", "T"), n, {"units": "1", "long_name": "replicas with a finite estimate"})
    data["failed"] = (
        ("a", "T"),
        failed,
        {"units": "1", "long_name": "replicas whose column broke"},
    )
    data["chaotic"] = (
        ("a", "T"),
        chaotic,
        {"units": "1", "long_name": "1 chaotic, 0 regular, -1 undecided (interval contains 0)"},
    )
    data["period_counts"] = (
        ("a", "T", "period"),
        counts,
        {"units": "1", "long_name": "replicas per detected return-map period (0: none)"},
    )
    data["period_mode"] = (
        ("a", "T"),
        p_mode,
        {"units": "taps", "long_name": "most common detected return-map period (0: none)"},
    )
    data["period_max"] = (
        ("a", "T"),
        p_top,
        {"units": "taps", "long_name": "largest detected return-map period (0: none)"},
    )
    data["period_fraction"] = (
        ("a", "T"),
        p_frac,
        {"units": "1", "long_name": "fraction of replicas with a detected return-map period"},
    )
    data["period_undecided"] = (
        ("a", "T"),
        undecided,
        {"units": "1", "long_name": "replicas whose return-map period is undecided"},
    )
    data["rest_fraction"] = (
        ("a", "T"),
        rest,
        {"units": "1", "long_name": "mean fraction of return-window states at rest"},
    )
    attrs = {"confidence": confidence, "return_max_period": p_max}
    for key in ("return_taps", "return_tolerance"):
        vals = {ds.attrs[key] for ds in pts if key in ds.attrs}
        if len(vals) == 1:
            attrs[key] = vals.pop()
    return xr.Dataset(
        data,
        coords={
            "a": ("a", A, {"units": "length", "long_name": "tap amplitude a"}),
            "T": ("T", T, {"units": "time", "long_name": "tap period T"}),
            "period": (
                "period",
                np.arange(p_max + 1),
                {"units": "taps", "long_name": "detected return-map period (0: none)"},
            ),
        },
        attrs=attrs,
    )
