"""Drum fits: batches → ensemble → fitted times (docs/drum.md, "Analysis").

The generic pieces live in :mod:`granpipe.analysis` (streaming reduction,
moving average and low-pass, windowed fits, bootstrap); this module wires them
to the drum's run files and the paper's definitions (Maghsoodi & Luijten 2016,
Sec. III):

* onset time t_on = vertex of a quadratic fit of the ensemble-mean V(t) on
  1–4 s after t = 0, accepted only as a minimum (positive curvature, vertex
  inside the window; otherwise NaN with a note);
* sign-change times = zeros of linear fits of the ensemble-mean λ(t) on 10–20 s
  (onset window) and 7–9 s (decay window);
* lags = onset sign change − t_on, and decay sign change − t_stop (the drum is
  stopped at t_stop = 5 s of the decay window, which starts the decay by
  definition);
* λ̄ (Eq. 2, 0.5 s moving average) and the FFT low-pass (lowest 0.008 % of the
  per-step frequencies: f ≤ 8e-5 · 1/(2Δt) = 1 Hz) and their zero crossings
  as cross-checks; the start-up decay of V right after t = 0.

Every fitted time has a fit error (delta method) and a percentile bootstrap
interval over replicas (``bootstrap_unit: replica``) or over batch means
(``batch``, paper scale). The *automatic* windows keep the widths of the
configured ones, because our timing need not match the paper's: the onset window
is centred on the smallest smoothed V within ``vertex_search_s`` (the minimum that
follows the start-up decay), the sign-change windows on the first zero crossing of
λ̄ after the V minimum (onset) or the stop (decay) that lasts ``crossing_hold_s``.
Every bootstrap resample re-centres its own windows, so the interval includes the
window choice.
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import xarray as xr

from ..analysis.bootstrap import (
    FitResult,
    argmin_time,
    bootstrap_batches,
    bootstrap_replicas,
    first_crossing,
    vertex_times,
    zero_crossing_times,
)
from ..analysis.ensemble import EnsembleAccumulator
from ..analysis.smoothing import (
    lowpass_fft,
    moving_average,
    paper_lowpass_cutoff,
    window_half_width,
)

__all__ = [
    "WINDOWS",
    "SERIES",
    "PAPER_VALUES",
    "valid_replicas",
    "reduce_runs",
    "Units",
    "load_units",
    "smoothed_series",
    "drum_fits",
    "vertex_time",
    "zero_crossing_time",
    "lag",
    "minimum_times",
    "sign_change_times",
    "MINIMUM_REASONS",
    "SIGN_CHANGE_REASONS",
    "PileRecords",
    "load_pile",
    "pile_fits",
    "WHERE",
    "where_flow_starts",
]

WINDOWS = ("onset", "decay")
SERIES = ("lambda", "speed")
PAPER_VALUES = {
    "onset_time": 2.628,
    "onset_sign_change_time": 14.5,
    "onset_lag": 14.5 - 2.628,
    "decay_sign_change_time": 8.13,
    "decay_lag": 8.13 - 5.0,
    "onset_lambda_bar_zero_time": 14.5,
    "decay_lambda_bar_zero_time": 8.13,
    "onset_lowpass_zero_time": 14.5,
    "decay_lowpass_zero_time": 8.13,
    "onset_lag_lambda_bar": 14.5 - 2.628,
    "decay_lag_lambda_bar": 8.13 - 5.0,
}
"""The paper's numbers (Sec. III; seconds after the start of each recording)."""

_SCALARS = ("settle_time", "continuous_time", "decay_start", "wall_time")


def valid_replicas(ds: xr.Dataset, exclude_flagged: bool = True) -> np.ndarray:
    """(replica,) bool: replicas that settled and reached a continuous avalanche."""
    ok = np.ones(ds.sizes["replica"], dtype=bool)
    if exclude_flagged:
        for flag in ("settled", "continuous"):
            if flag in ds:
                ok &= ds[flag].values.astype(bool)
    return ok


def reduce_runs(paths: Sequence[str | os.PathLike], exclude_flagged: bool = True) -> xr.Dataset:
    """Ensemble mean, standard error and count of λ(t) and V(t), onset and decay.

    Streams over the run files (one open at a time, one
    :class:`~granpipe.analysis.ensemble.EnsembleAccumulator` per series), so peak
    memory is one batch plus the time axes, whatever the number of batches.

    Returns
    -------
    xarray.Dataset with, for w in (onset, decay) and s in (lambda, speed),
    ``{s}_{w}_mean``, ``{s}_{w}_sem`` (units of the series) and ``{s}_{w}_count``
    on dims ``time_{w}`` [t0] with coordinates ``seconds_{w}`` [s]; per-replica
    scalars summarised as ``{name}_mean`` / ``{name}_max`` (settle_time,
    continuous_time, decay_start, wall_time) and counts ``n_replicas``,
    ``n_excluded``, ``n_unsettled``, ``n_not_continuous`` (attrs).
    """
    paths = [os.fspath(p) for p in paths]
    if not paths:
        raise ValueError("no run files to reduce")
    accs = {(s, w): EnsembleAccumulator() for s in SERIES for w in WINDOWS}
    attrs: dict = {}
    coords: dict = {}
    longest = {w: -1 for w in WINDOWS}
    sums = {k: 0.0 for k in _SCALARS}
    maxs = {k: -np.inf for k in _SCALARS}
    counts = {k: 0 for k in _SCALARS}
    n_total = n_used = n_unsettled = n_notcont = 0
    run_attrs: dict = {}
    for path in paths:
        with xr.open_dataset(path, engine="netcdf4") as ds:
            ok = valid_replicas(ds, exclude_flagged)
            n_total += int(ds.sizes["replica"])
            n_used += int(ok.sum())
            n_unsettled += int((ds["settled"].values == 0).sum())
            n_notcont += int((ds["continuous"].values == 0).sum())
            if not run_attrs:
                run_attrs = {
                    k: ds.attrs[k] for k in ("dt", "dt_s", "t0_s", "block_steps", "stop_time_s")
                }
            for w in WINDOWS:
                tdim = f"time_{w}"
                if ds.sizes[tdim] > longest[w]:
                    longest[w] = ds.sizes[tdim]
                    for c in (tdim, f"seconds_{w}"):
                        coords[c] = ds[c].load().copy()
                for s in SERIES:
                    name = f"{s}_{w}"
                    da = ds[name].load()
                    attrs[name] = dict(da.attrs)
                    if ok.any():
                        accs[(s, w)].add(da.isel(replica=np.flatnonzero(ok)), time_dim=tdim)
            for k in _SCALARS:
                if k in ds and ok.any():
                    v = ds[k].values[ok]
                    v = v[np.isfinite(v)]
                    sums[k] += float(v.sum())
                    counts[k] += len(v)
                    if len(v):
                        maxs[k] = max(maxs[k], float(v.max()))
    out = xr.Dataset(coords={k: v for k, v in coords.items()})
    for (s, w), acc in accs.items():
        name = f"{s}_{w}"
        acc._grow(longest[w])
        a = attrs[name]
        lname = a.get("long_name", name)
        tdim = f"time_{w}"
        out[f"{name}_mean"] = (
            tdim,
            acc.mean,
            {"units": a["units"], "long_name": f"ensemble mean of {lname}"},
        )
        out[f"{name}_sem"] = (
            tdim,
            acc.sem,
            {"units": a["units"], "long_name": f"standard error of the ensemble mean of {lname}"},
        )
        out[f"{name}_count"] = (
            tdim,
            acc.count,
            {"units": "1", "long_name": f"replicas contributing to {lname}"},
        )
    labels = {
        "settle_time": "time to settle",
        "continuous_time": "time from t = 0 to a continuous avalanche",
        "decay_start": "start of the decay window after t = 0",
        "wall_time": "wall-clock cost of one replica",
    }
    for k in _SCALARS:
        mean = sums[k] / counts[k] if counts[k] else np.nan
        out[f"{k}_mean"] = ((), mean, {"units": "s", "long_name": f"mean {labels[k]}"})
        out[f"{k}_max"] = (
            (),
            maxs[k] if counts[k] else np.nan,
            {"units": "s", "long_name": f"largest {labels[k]}"},
        )
    out.attrs.update(run_attrs)
    out.attrs.update(
        n_replicas=n_used,
        n_replicas_run=n_total,
        n_excluded=n_total - n_used,
        n_unsettled=n_unsettled,
        n_not_continuous=n_notcont,
        n_batches=len(paths),
        exclude_flagged=int(bool(exclude_flagged)),
    )
    return out


@dataclass
class Units:
    """Bootstrap units of one window: per-replica series or per-batch means.

    ``speed`` and ``lambda_`` are (n_units, T); ``counts`` is (n_units, T) for
    batch means, ``None`` for replicas.
    """

    speed: np.ndarray
    lambda_: np.ndarray
    counts: np.ndarray | None
    n_replicas: int


def load_units(
    paths: Sequence[str | os.PathLike],
    unit: str = "replica",
    exclude_flagged: bool = True,
) -> dict[str, Units]:
    """Per-replica records (``unit="replica"``) or batch means (``"batch"``) of each window.

    Memory: (replicas or batches) × time × 2 series per window, read one file at a
    time; for 70,000 replicas use ``"batch"`` (one row per file).
    """
    if unit not in ("replica", "batch"):
        raise ValueError("unit must be 'replica' or 'batch'")
    rows: dict = {(s, w): [] for s in SERIES for w in WINDOWS}
    counts: dict = {w: [] for w in WINDOWS}
    n_rep = 0
    lengths = {w: 0 for w in WINDOWS}
    for path in paths:
        with xr.open_dataset(path, engine="netcdf4") as ds:
            ok = np.flatnonzero(valid_replicas(ds, exclude_flagged))
            n_rep += len(ok)
            for w in WINDOWS:
                lengths[w] = max(lengths[w], ds.sizes[f"time_{w}"])
                for s in SERIES:
                    x = ds[f"{s}_{w}"].transpose("replica", f"time_{w}").values[ok]
                    if unit == "replica":
                        rows[(s, w)].extend(list(x))
                    elif len(ok):
                        fin = np.isfinite(x)
                        c = fin.sum(axis=0)
                        with np.errstate(invalid="ignore"):
                            m = np.where(fin, x, 0.0).sum(axis=0) / c
                        rows[(s, w)].append(np.where(c > 0, m, np.nan))
                        if s == SERIES[0]:
                            counts[w].append(c)

    def stack(seq, n, fill):
        out = np.full((len(seq), n), fill, dtype=np.float64)
        for i, r in enumerate(seq):
            out[i, : len(r)] = r
        return out

    result = {}
    for w in WINDOWS:
        n = lengths[w]
        result[w] = Units(
            speed=stack(rows[("speed", w)], n, np.nan),
            lambda_=stack(rows[("lambda", w)], n, np.nan),
            counts=stack(counts[w], n, 0.0) if unit == "batch" else None,
            n_replicas=n_rep,
        )
    return result


def smoothed_series(ens: xr.Dataset, fits_cfg: Mapping) -> xr.Dataset:
    """λ̄ (Eq. 2) and the FFT low-pass of the ensemble-mean λ, for both windows.

    The moving-average width is ``fits.moving_average_s`` (0.5 s: q = 62 at 4 ms);
    the low-pass keeps f ≤ ``lowpass_fraction`` · f_Nyquist of the per-step
    sampling Δt (``paper_lowpass_cutoff``: 1 Hz for the paper), applied to the
    block means (the fraction of *their* bins would keep only the mean).
    """
    block_s = float(ens.attrs["dt_s"]) * int(ens.attrs["block_steps"])
    q = window_half_width(float(fits_cfg["moving_average_s"]), block_s)
    cutoff = paper_lowpass_cutoff(float(fits_cfg["lowpass_fraction"]), float(ens.attrs["dt_s"]))
    out = xr.Dataset(coords={c: ens[c] for c in ens.coords})
    for w in WINDOWS:
        y = ens[f"lambda_{w}_mean"].values
        units = ens[f"lambda_{w}_mean"].attrs["units"]
        out[f"lambda_bar_{w}"] = (
            f"time_{w}",
            moving_average(y, q),
            {
                "units": units,
                "long_name": f"moving average of the ensemble-mean λ, width "
                f"{(2 * q + 1) * block_s:g} s (Eq. 2), {w} window",
            },
        )
        good = np.isfinite(y)
        lp = np.full_like(y, np.nan)
        if good.sum() > 2:
            # The low-pass needs a finite record: filter the finite stretch.
            i0, i1 = np.flatnonzero(good)[[0, -1]]
            seg = y[i0 : i1 + 1]
            if np.all(np.isfinite(seg)):
                lp[i0 : i1 + 1] = lowpass_fft(seg, cutoff=cutoff, dt=block_s)
        out[f"lambda_lowpass_{w}"] = (
            f"time_{w}",
            lp,
            {
                "units": units,
                "long_name": f"FFT low-pass (f <= {cutoff:g} Hz) of the ensemble-mean λ, "
                f"{w} window",
            },
        )
    out.attrs.update(moving_average_q=q, lowpass_cutoff_hz=cutoff, block_s=block_s)
    return out


def _fit_curve(t, res: FitResult, deg: int) -> np.ndarray:
    """The fitted polynomial on its window (NaN elsewhere), for the figures."""
    y = np.full_like(t, np.nan)
    if res.coefficients is None or res.window is None or not np.isfinite(res.value):
        return y
    lo, hi = res.window
    inside = (t >= lo) & (t <= hi)
    u = t[inside] - res.t_ref
    c = np.asarray(res.coefficients)
    y[inside] = sum(c[k] * u**k for k in range(deg + 1))
    return y


def _boot(units: Units, statistic, cfg):
    """Joint bootstrap of (V, λ) over replicas or batch means (granpipe.analysis.bootstrap)."""
    kw = dict(
        n_resamples=int(cfg["bootstrap_resamples"]),
        level=float(cfg["confidence"]),
        seed=int(cfg["seed"]),
    )
    if units.counts is None:
        return bootstrap_replicas([units.speed, units.lambda_], statistic, **kw)
    return bootstrap_batches([units.speed, units.lambda_], units.counts, statistic, **kw)


def _onset_window(t, mV, q, cfg, auto: bool):
    """The vertex-fit window of the onset: the configured one, or (auto) one of the same
    width centred on the minimum of the smoothed V within ``fits.vertex_search_s``
    (vectorised over resamples: ``mV`` (..., T) gives (lo, hi) arrays)."""
    lo, hi = (float(x) for x in cfg["onset_vertex_window_s"])
    if not auto:
        return lo, hi
    centre = argmin_time(t, mV, tuple(cfg["vertex_search_s"]), q)
    hw = 0.5 * (hi - lo)
    return np.maximum(float(t[0]), centre - hw), centre + hw


def _auto_zero_window(t, ml, search, half_width, direction, q, hold):
    """Automatic window of a sign-change fit, vectorised over series ``ml`` (..., T).

    Centred on the first zero crossing of λ̄ (Eq. 2, q-point half-width) within
    ``search`` (each bound a float or an array (...,)) after which λ̄ keeps its new sign
    for ``hold`` samples: with tens of replicas noise makes λ̄ cross zero many times, but
    rarely for long. NaN bounds where there is no such crossing.
    """
    lo = np.asarray(search[0], dtype=np.float64)
    hi = np.asarray(search[1], dtype=np.float64)
    if lo.ndim:
        lo = lo[..., np.newaxis]
    c = first_crossing(t, moving_average(ml, q), (lo, hi), direction, hold)
    return c - half_width, c + half_width


def _onset_analysis(t, ens, units, cfg, q, *, auto, suffix):
    """Onset time (a V minimum), its curvature, the sign change and the lag of the onset
    window, with a joint bootstrap in which every resample applies the same rules: its
    own windows (auto mode), and a vertex that counts only as a minimum inside its window.
    """
    mV = ens["speed_onset_mean"].values
    mL, sL = ens["lambda_onset_mean"].values, ens["lambda_onset_sem"].values
    sV = ens["speed_onset_sem"].values
    if not cfg.get("weighted", False):
        sV = sL = None  # ordinary least squares, errors from the residuals
    n = int(ens.attrs["n_replicas"])
    zcfg = tuple(cfg["onset_zero_window_s"])
    half_width = 0.5 * (zcfg[1] - zcfg[0])
    vwin = _onset_window(t, mV, q, cfg, auto)
    vmin = float(argmin_time(t, mV, tuple(cfg["vertex_search_s"]), q))
    search = (vmin if np.isfinite(vmin) else float(t[0]), float(t[-1]))
    change = vertex_time(t, mV, vwin, sV, quantity=f"onset_time{suffix}", n=n,
                         require_minimum=True)  # fmt: skip
    if auto:
        change = dataclasses.replace(change, method=change.method + " (auto window)")
    curv = _curvature(change, suffix, n)
    hold = _hold_samples(ens, cfg)
    zwin = _auto_zero_window(t, mL, search, half_width, +1, q, hold) if auto else zcfg
    sign = _sign_change(t, mL, zwin, sL, f"onset_sign_change_time{suffix}", n, auto, +1)
    lag_ = lag(sign, change, quantity=f"onset_lag{suffix}")
    v_ref, z_ref = change.t_ref, sign.t_ref

    def statistic(mv, ml):
        lo, hi = _onset_window(t, mv, q, cfg, auto)
        v, _, c2, _, _, _ = minimum_times(t, mv, (lo, hi), sV, t_ref=v_ref)
        if auto:
            start = argmin_time(t, mv, tuple(cfg["vertex_search_s"]), q)
            start = np.where(np.isfinite(start), start, float(t[0]))
            win = _auto_zero_window(t, ml, (start, float(t[-1])), half_width, +1, q, hold)
        else:
            win = zcfg
        z, _, _, _ = sign_change_times(t, ml, win, sL, direction=+1, t_ref=z_ref)
        return np.stack([v, c2, z, z - v], axis=-1)

    out = {"change": change, "curvature": curv, "sign": sign, "lag": lag_}
    if int(cfg["bootstrap_resamples"]) > 0:
        boot = _boot(units, statistic, cfg)
        for col, key in enumerate(("change", "curvature", "sign", "lag")):
            out[key] = out[key].with_ci(boot, col)
        valid = 1.0 - boot.n_failed[0] / boot.n_resamples
        out["valid"] = FitResult(
            f"onset_valid_fraction{suffix}", float(valid), math.nan, "1",
            n=boot.n_resamples,
            method="fraction of bootstrap resamples whose vertex is a minimum inside its window",
        )  # fmt: skip
    return out


def _hold_samples(ens, cfg) -> int:
    """``fits.crossing_hold_s`` in stored blocks."""
    block_s = float(ens.attrs["dt_s"]) * int(ens.attrs["block_steps"])
    return int(round(float(cfg["crossing_hold_s"]) / block_s))


def _sign_change(t, mL, window, sL, quantity, n, auto, direction) -> FitResult:
    """Zero of a linear fit of λ on ``window``, accepted only as a sign change the right
    way inside the window (NaN with a note otherwise; :func:`sign_change_times`)."""
    lo, hi = (float(x) for x in window)
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return FitResult(quantity, math.nan, math.nan, "s", n=n, method="linear fit, zero",
                         note="λ̄ has no lasting zero crossing the right way after the "
                         "change of state: no window for the sign change")  # fmt: skip
    res = zero_crossing_time(t, mL, (lo, hi), sL, quantity=quantity, n=n)
    _, _, reason, _ = sign_change_times(t, mL, (lo, hi), sL, direction=direction,
                                        t_ref=res.t_ref)  # fmt: skip
    if int(reason):
        res = dataclasses.replace(res, value=math.nan, fit_error=math.nan,
                                  note=SIGN_CHANGE_REASONS[int(reason)])  # fmt: skip
    if auto:
        res = dataclasses.replace(res, method=res.method + " (auto window)")
    return res


def _curvature(change: FitResult, suffix: str, n: int) -> FitResult:
    """The fitted curvature c₂ of the onset parabola [(d_s/t0)/s²] with its fit error."""
    c2 = err = math.nan
    if change.coefficients is not None:
        c2 = float(np.asarray(change.coefficients)[2])
        err = float(np.sqrt(np.asarray(change.covariance)[2, 2]))
    return FitResult(
        f"onset_curvature{suffix}", c2, err, "(d_s/t0)/s^2", n=n, window=change.window,
        method="curvature c2 of the quadratic fit of V (a minimum needs c2 > 0)",
    )  # fmt: skip


def _decay_analysis(t, ens, units, cfg, q, stop, *, auto, suffix):
    """Sign change and lag of the decay window (the decay starts at the stop, exactly)."""
    mL, sL = ens["lambda_decay_mean"].values, ens["lambda_decay_sem"].values
    if not cfg.get("weighted", False):
        sL = None
    n = int(ens.attrs["n_replicas"])
    zcfg = tuple(cfg["decay_zero_window_s"])
    half_width = 0.5 * (zcfg[1] - zcfg[0])
    search = (stop, float(t[-1]))
    hold = _hold_samples(ens, cfg)
    zwin = _auto_zero_window(t, mL, search, half_width, -1, q, hold) if auto else zcfg
    sign = _sign_change(t, mL, zwin, sL, f"decay_sign_change_time{suffix}", n, auto, -1)
    lag_ = lag(sign, stop, quantity=f"decay_lag{suffix}")
    z_ref = sign.t_ref

    def statistic(mv, ml):
        win = _auto_zero_window(t, ml, search, half_width, -1, q, hold) if auto else zcfg
        z, _, _, _ = sign_change_times(t, ml, win, sL, direction=-1, t_ref=z_ref)
        return np.stack([z, z - stop], axis=-1)

    out = {"sign": sign, "lag": lag_}
    if np.isfinite(sign.value) and int(cfg["bootstrap_resamples"]) > 0:
        boot = _boot(units, statistic, cfg)
        out["sign"] = sign.with_ci(boot, 0)
        out["lag"] = lag_.with_ci(boot, 1)
    return out


def _startup_excess(t, ens, units, cfg, q) -> list[FitResult]:
    """How far V still decays after t = 0: mean V over ``fits.startup_window_s`` minus
    mean V over a window of the same width centred on the V minimum, with its bootstrap
    standard error, and that difference in standard errors."""
    mV = ens["speed_onset_mean"].values
    lo, hi = (float(x) for x in cfg["startup_window_s"])
    hw = 0.5 * (hi - lo)
    search = tuple(cfg["vertex_search_s"])
    n = int(ens.attrs["n_replicas"])

    def excess(mv):
        mv = np.atleast_2d(mv)
        c = argmin_time(t, mv, search, q)[:, None]
        early = np.where((t >= lo) & (t <= hi), mv, np.nan)
        near = np.where(np.abs(t - c) <= hw, mv, np.nan)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return np.nanmean(early, axis=-1) - np.nanmean(near, axis=-1)

    value = float(excess(mV)[0])
    se = lo_ci = hi_ci = math.nan
    n_res = 0
    if int(cfg["bootstrap_resamples"]) > 1:
        boot = _boot(units, lambda mv, ml: excess(mv), cfg)
        se, lo_ci, hi_ci = float(boot.std[0]), float(boot.ci_low[0]), float(boot.ci_high[0])
        n_res = boot.n_resamples
    method = (
        f"mean V on [{lo:g}, {hi:g}] s minus mean V within {hw:g} s of the V minimum; "
        "error: bootstrap standard deviation"
    )
    return [
        FitResult("onset_startup_excess", value, se, "d_s/t0", ci_low=lo_ci, ci_high=hi_ci,
                  ci_level=float(cfg["confidence"]), n=n, n_resamples=n_res, method=method),
        FitResult("onset_startup_excess_sigma", value / se if se > 0 else math.nan, math.nan,
                  "1", n=n, method="onset_startup_excess in units of its standard error"),
    ]  # fmt: skip


def drum_fits(
    ens: xr.Dataset,
    units: Mapping[str, Units],
    fits_cfg: Mapping,
    label: str = "",
    pile: PileRecords | None = None,
) -> tuple[list[FitResult], xr.Dataset]:
    """All fitted times of the drum study, with fit errors and bootstrap intervals.

    Parameters
    ----------
    ens : Dataset from :func:`reduce_runs` (its ``seconds_*`` coordinates are the
        fit abscissae, in seconds after the start of each recording).
    units : from :func:`load_units` (the same replicas as ``ens``).
    fits_cfg : the ``drum.fits`` section (filled).
    label : str
        Appended to every quantity name (a point's label, e.g. ``"[period=450s]"``).
    pile : from :func:`load_pile` (the same run files), optional
        Adds the pile's events and the averages aligned on each replica's own events
        (:func:`pile_fits`) beside the paper-style rows.

    Returns
    -------
    results : list of FitResult, named ``onset_time`` (NaN, with a ``note``, unless the
        vertex is a minimum inside its window), ``onset_curvature``,
        ``onset_valid_fraction``, ``onset_sign_change_time``, ``onset_lag``,
        ``decay_sign_change_time``, ``decay_lag``, the same with suffix ``_auto``
        (automatic windows), the zero crossings of λ̄ and of the low-pass
        (``{w}_lambda_bar_zero_time``, ``{w}_lowpass_zero_time``) and the start-up decay
        (``onset_startup_excess``, ``onset_startup_excess_sigma``).
    curves : Dataset of λ̄, low-pass and the fitted segments (NaN off-window),
        on the ensemble's time axes, for the figures.

    Notes
    -----
    Central values and fit errors come from the ensemble mean (ordinary least
    squares with residual-based errors, or weighted by 1/SEM² with
    ``fits.weighted``), so they do not depend on the bootstrap unit; intervals from
    the joint percentile bootstrap of V and λ (the lag's interval from the
    per-resample difference, keeping the correlation of the two fits). A resample
    whose vertex is not a minimum inside its window gives no onset (nor lag); the
    fraction of resamples that did is ``onset_valid_fraction``.
    """
    cfg = dict(fits_cfg)
    curves = smoothed_series(ens, cfg)
    q = int(curves.attrs["moving_average_q"])
    stop = float(ens.attrs["stop_time_s"])
    t_on = ens["seconds_onset"].values
    t_de = ens["seconds_decay"].values
    results: list[FitResult] = []
    modes = [("", False)] + ([("_auto", True)] if cfg["auto_windows"] else [])
    for suffix, auto in modes:
        on = _onset_analysis(t_on, ens, units["onset"], cfg, q, auto=auto, suffix=suffix)
        de = _decay_analysis(t_de, ens, units["decay"], cfg, q, stop, auto=auto, suffix=suffix)
        results += [on[k] for k in ("change", "curvature", "valid", "sign", "lag") if k in on]
        results += [de["sign"], de["lag"]]
        name = "auto" if auto else "config"
        for cname, tt, res, deg, ref in (
            (f"fit_speed_onset_{name}", t_on, on["change"], 2, "speed_onset_mean"),
            (f"fit_lambda_onset_{name}", t_on, on["sign"], 1, "lambda_onset_mean"),
            (f"fit_lambda_decay_{name}", t_de, de["sign"], 1, "lambda_decay_mean"),
        ):
            kind = "quadratic fit of V" if deg == 2 else "linear fit of λ"
            curves[cname] = (
                ens[ref].dims[0],
                _fit_curve(tt, res, deg),
                {"units": ens[ref].attrs["units"], "long_name": f"{kind}, {name} window"},
            )
    auto = next((r for r in results if r.quantity == "onset_time_auto"), None)
    if auto is None:  # no automatic windows: the automatic onset for the lag rows only
        auto = _onset_analysis(t_on, ens, units["onset"], {**cfg, "bootstrap_resamples": 0},
                               q, auto=True, suffix="_auto")["change"]  # fmt: skip
    results.extend(_crossings(ens, curves, units, q, stop, cfg, auto))
    results.extend(_startup_excess(t_on, ens, units["onset"], cfg, q))
    if label:
        results = [dataclasses.replace(r, quantity=r.quantity + label) for r in results]
    if pile is not None:
        more, pcurves = pile_fits(pile, ens, cfg, label)
        results += more
        curves = curves.merge(pcurves)
    return results, curves


def _crossings(ens, curves, units, q, stop, cfg, onset_auto) -> list[FitResult]:
    """Zero crossings of λ̄ (with a bootstrap interval) and of the low-pass (value only):
    the first after which the curve keeps its new sign for ``fits.crossing_hold_s``; and
    the lags they give, λ̄'s crossing minus the automatic onset time (onset) or the stop
    (decay), bootstrapped jointly with the onset. The crossings are searched after the V
    minimum (onset) or the stop (decay); for the onset also after the start-up window
    alone (``onset_lambda_bar_first_zero_time``, and its lag), so that a λ̄ that turns
    positive *before* the avalanche (the drum with static friction) is measured too."""
    out = []
    hold = _hold_samples(ens, cfg)
    search_v = tuple(cfg["vertex_search_s"])
    first_from = float(cfg["startup_window_s"][1])
    for w, direction in (("onset", +1), ("decay", -1)):
        t = ens[f"seconds_{w}"].values
        if w == "onset":
            vmin = float(argmin_time(t, ens["speed_onset_mean"].values, search_v, q))
            search = (vmin if np.isfinite(vmin) else 0.0, float(t[-1]))
        else:
            search = (stop, float(t[-1]))
        u = units[w]
        n = u.n_replicas

        def stat(mv, ml, t=t, w=w, search=search, direction=direction):
            if w == "onset":
                lo, hi = _onset_window(t, mv, q, cfg, True)
                v, _, _, _, _, _ = minimum_times(t, mv, (lo, hi), None, t_ref=onset_auto.t_ref)
                start = argmin_time(t, mv, search_v, q)
                rng = (np.where(np.isfinite(start), start, 0.0)[:, None], float(t[-1]))
            else:
                v, rng = np.full(mv.shape[0], stop), search
            lb = moving_average(ml, q)
            c = first_crossing(t, lb, rng, direction, hold)
            cols = [c, c - v]
            if w == "onset":  # also the first crossing after the start-up, wherever it is
                c0 = first_crossing(t, lb, (first_from, float(t[-1])), direction, hold)
                cols += [c0, c0 - v]
            return np.stack(cols, axis=-1)

        value = float(first_crossing(t, curves[f"lambda_bar_{w}"].values, search, direction, hold))
        change = onset_auto.value if w == "onset" else stop
        boot = _boot(u, stat, cfg)
        held = f"that lasts {cfg['crossing_hold_s']:g} s"
        out.append(
            FitResult(f"{w}_lambda_bar_zero_time", value, np.nan, "s", n=n,
                      method=f"first zero crossing of the moving average (Eq. 2) {held}",
                      ).with_ci(boot, 0)
        )  # fmt: skip
        what = "the automatic onset time" if w == "onset" else "the stop of the drum"
        out.append(
            FitResult(f"{w}_lag_lambda_bar", value - change, np.nan, "s", n=n,
                      method=f"zero crossing of the moving average minus {what}",
                      ).with_ci(boot, 1)
        )  # fmt: skip
        if w == "onset":
            first = float(first_crossing(t, curves["lambda_bar_onset"].values,
                                         (first_from, float(t[-1])), direction, hold))  # fmt: skip
            out.append(
                FitResult("onset_lambda_bar_first_zero_time", first, np.nan, "s", n=n,
                          method=f"first zero crossing of the moving average after the "
                          f"start-up window ({first_from:g} s) {held}, before or after the "
                          "onset").with_ci(boot, 2)
            )  # fmt: skip
            out.append(
                FitResult("onset_lag_lambda_bar_first", first - change, np.nan, "s", n=n,
                          method="that crossing minus the automatic onset time (negative: "
                          "λ̄ turns positive before the avalanche starts)").with_ci(boot, 3)
            )  # fmt: skip
        lp = curves[f"lambda_lowpass_{w}"].values
        lp_zero = float(first_crossing(t, lp, search, direction, hold))
        out.append(
            FitResult(f"{w}_lowpass_zero_time", lp_zero, np.nan, "s", n=n,
                      method=f"first zero crossing of the FFT low-pass {held}")
        )  # fmt: skip
    return out


# ----------------------------------- onset, sign changes and lags (Sec. III)
MINIMUM_REASONS = {
    0: "",
    1: "too few points in the window for a quadratic fit",
    2: "the fitted parabola has no positive curvature: its vertex is a maximum",
    3: "the vertex lies outside the fit window",
}
"""Codes of :func:`minimum_times`: why a vertex was not accepted as a minimum."""


def minimum_times(t, Y, window, sigma=None, *, t_ref=None, error_scale="auto"):
    """Vertices of quadratic fits accepted only as minima inside their windows.

    A vertex is a minimum of V only if the curvature c₂ > 0 and it lies within the fit
    window [t_lo, t_hi]; otherwise its value is NaN and ``reason`` says why
    (:data:`MINIMUM_REASONS`).

    Returns
    -------
    value, fit_error : (...,) [time]
    curvature, curvature_error : (...,) [Y/time²], the fitted c₂ and its standard error
    reason : (...,) int
    extras : dict as :func:`vertex_times`
    """
    value, err, ex = vertex_times(t, Y, window, sigma, t_ref=t_ref, error_scale=error_scale)
    c2 = ex["coef"][..., 2]
    with np.errstate(invalid="ignore"):
        c2_err = np.sqrt(ex["cov"][..., 2, 2])
    lo = np.asarray(window[0], dtype=np.float64)
    hi = np.asarray(window[1], dtype=np.float64)
    reason = np.where(
        ~np.isfinite(c2),
        1,
        np.where(c2 <= 0, 2, np.where((value < lo) | (value > hi) | ~np.isfinite(value), 3, 0)),
    )
    value = np.where(reason == 0, value, np.nan)
    err = np.where(reason == 0, err, np.nan)
    return value, err, c2, c2_err, reason, ex


SIGN_CHANGE_REASONS = {
    0: "",
    1: "too few points in the window for a linear fit",
    2: "the fitted line changes sign the other way",
    3: "the zero of the fitted line lies outside the fit window",
}
"""Codes of :func:`sign_change_times`: why a zero was not accepted as the sign change."""


def sign_change_times(t, Y, window, sigma=None, *, direction=0, t_ref=None, error_scale="auto"):
    """Zeros of linear fits accepted only as sign changes inside their windows.

    The zero counts only if the fitted slope has the sign ``direction`` (+1 rising, −1
    falling, 0 either) and the zero lies within the fit window; otherwise the value is
    NaN and ``reason`` says why (:data:`SIGN_CHANGE_REASONS`). An extrapolated zero
    says where a straight line would cross, not where λ did.

    Returns
    -------
    value, fit_error : (...,) [time]; reason : (...,) int; extras : dict as
    :func:`zero_crossing_times`
    """
    value, err, ex = zero_crossing_times(t, Y, window, sigma, t_ref=t_ref, error_scale=error_scale)
    c1 = ex["coef"][..., 1]
    lo = np.asarray(window[0], dtype=np.float64)
    hi = np.asarray(window[1], dtype=np.float64)
    wrong = (np.sign(c1) != direction) if direction else np.zeros(np.shape(c1), dtype=bool)
    with np.errstate(invalid="ignore"):
        outside = (value < lo) | (value > hi) | ~np.isfinite(value)
    reason = np.where(~np.isfinite(c1), 1, np.where(wrong, 2, np.where(outside, 3, 0)))
    value = np.where(reason == 0, value, np.nan)
    err = np.where(reason == 0, err, np.nan)
    return value, err, reason, ex


def _resolve_window(kind, t, Y, window, half_width, search, smooth_q, direction):
    """(lo, hi) arrays (or floats) of the fit window; ``window="auto"`` centres it."""
    if isinstance(window, str):
        if window != "auto":
            raise ValueError("window must be (t_lo, t_hi) or 'auto'")
        if half_width is None:
            raise ValueError("window='auto' needs half_width")
        if kind == "vertex":
            centre = argmin_time(t, Y, search, smooth_q)
        else:
            Ys = moving_average(Y, smooth_q) if smooth_q else Y
            centre = first_crossing(t, Ys, search, direction)
        return centre - half_width, centre + half_width, centre
    lo, hi = float(window[0]), float(window[1])
    if not hi > lo:
        raise ValueError(f"empty fit window {window}")
    return lo, hi, None


def _scalar_fit(
    kind,
    t,
    y,
    window,
    sigma,
    *,
    half_width,
    search,
    smooth_q,
    direction,
    quantity,
    unit,
    error_scale,
    n,
    require_minimum=False,
):
    y = np.asarray(y, dtype=np.float64)
    if y.ndim != 1:
        raise ValueError("y must be (time,); use vertex_times/zero_crossing_times for batches")
    lo, hi, _ = _resolve_window(kind, t, y, window, half_width, search, smooth_q, direction)
    if not (np.isfinite(lo) and np.isfinite(hi)):
        what = "no minimum in the search range" if kind == "vertex" else "no zero crossing"
        return FitResult(quantity, math.nan, math.nan, unit, n=n, method=f"{kind}: no window",
                         note=f"{what}: no window to fit")  # fmt: skip
    t_ref = 0.5 * (float(lo) + float(hi))
    note = ""
    if kind == "vertex" and require_minimum:
        value, err, _, _, reason, ex = minimum_times(
            t, y, (lo, hi), sigma, t_ref=t_ref, error_scale=error_scale
        )
        note = MINIMUM_REASONS[int(reason)]
    else:
        fn = vertex_times if kind == "vertex" else zero_crossing_times
        value, err, ex = fn(t, y, (lo, hi), sigma, t_ref=t_ref, error_scale=error_scale)
    return FitResult(
        quantity=quantity,
        value=float(value),
        fit_error=float(err),
        unit=unit,
        n=n,
        window=(float(lo), float(hi)),
        t_ref=ex["t_ref"],
        coefficients=ex["coef"],
        covariance=ex["cov"],
        chi2_red=float(ex["chi2_red"]),
        method=("quadratic fit, vertex" if kind == "vertex" else "linear fit, zero crossing")
        + (" (auto window)" if isinstance(window, str) else ""),
        note=note,
    )


def vertex_time(
    t: np.ndarray,
    y: np.ndarray,
    window=(1.0, 4.0),
    sigma: np.ndarray | None = None,
    *,
    half_width: float | None = None,
    search: tuple[float, float] | None = None,
    smooth_q: int = 0,
    quantity: str = "onset_time",
    unit: str = "s",
    error_scale: str = "auto",
    n: int | None = None,
    require_minimum: bool = False,
) -> FitResult:
    """Avalanche onset: vertex of a quadratic fit to V(t) (drum paper, Sec. III).

    Parameters
    ----------
    t : (T,) float [unit]
    y : (T,) float, the ensemble-mean global speed V(t) [d_s/t0]
    window : (t_lo, t_hi) or "auto"
        Fit window (the paper: 1 s < t < 4 s). ``"auto"``: centred on the minimum
        of y (after a (2·smooth_q+1)-point moving average) within ``search``,
        of half-width ``half_width``.
    sigma : (T,) float, optional
        SEM of y; weights 1/σ² (see :func:`granpipe.analysis.bootstrap.polyfit_window` for
        ``error_scale``).
    n : int, optional
        Replicas behind y, stored in the result.
    require_minimum : bool
        Accept the vertex only as a minimum inside the window (:func:`minimum_times`);
        otherwise the value is NaN and ``note`` says why.
    """
    return _scalar_fit(
        "vertex",
        t,
        y,
        window,
        sigma,
        half_width=half_width,
        search=search,
        smooth_q=smooth_q,
        direction=0,
        quantity=quantity,
        unit=unit,
        error_scale=error_scale,
        n=n,
        require_minimum=require_minimum,
    )


def zero_crossing_time(
    t: np.ndarray,
    y: np.ndarray,
    window=(10.0, 20.0),
    sigma: np.ndarray | None = None,
    *,
    half_width: float | None = None,
    search: tuple[float, float] | None = None,
    smooth_q: int = 0,
    direction: int = 0,
    quantity: str = "sign_change_time",
    unit: str = "s",
    error_scale: str = "auto",
    n: int | None = None,
) -> FitResult:
    """Sign change of λ: zero of a linear fit to λ(t) (drum paper, Sec. III).

    Parameters
    ----------
    y : (T,) float, the ensemble-mean local Lyapunov exponent λ(t) [1/t0]
    window : (t_lo, t_hi) or "auto"
        The paper: 10–20 s (onset), 7–9 s (decay). ``"auto"``: centred on the
        first zero crossing (``direction``: +1 upward, −1 downward, 0 either) of
        λ̄, the (2·smooth_q+1)-point moving average of Eq. (2), within ``search``.
    Other parameters as :func:`vertex_time`.
    """
    return _scalar_fit(
        "zero",
        t,
        y,
        window,
        sigma,
        half_width=half_width,
        search=search,
        smooth_q=smooth_q,
        direction=direction,
        quantity=quantity,
        unit=unit,
        error_scale=error_scale,
        n=n,
    )


def lag(sign_change: FitResult, change_of_state: FitResult | float, quantity: str = "lag"):
    """Lag = sign-change time − change-of-state time (drum paper, Sec. III).

    ``change_of_state`` is the onset :class:`FitResult`, or a number for a state
    change imposed exactly (the decay starts at 5 s: error 0). The fit errors
    are combined in quadrature, which ignores their correlation (both fits use
    the same replicas); :func:`avalanche_lag` gives a joint bootstrap interval.
    """
    if isinstance(change_of_state, FitResult):
        v0, e0 = change_of_state.value, change_of_state.fit_error
    else:
        v0, e0 = float(change_of_state), 0.0
    return FitResult(
        quantity=quantity,
        value=sign_change.value - v0,
        fit_error=math.hypot(sign_change.fit_error, e0),
        unit=sign_change.unit,
        n=sign_change.n,
        method="sign change minus change of state",
    )


# ------------------------- the pile's events, and averages aligned on each pile's own
@dataclass
class PileRecords:
    """What the fits take from the run files about the pile (docs/drum.md, "The pile's
    state and events"): per replica the event times and tilts, and the records aligned on
    each replica's own sustained-flow onset (onset) and flow stop (decay) as bootstrap
    units (rows of replicas, or batch means with ``counts``).

    Attributes
    ----------
    events : dict of (R,) arrays over every kept replica: ``startup_end``,
        ``first_burst``, ``flow_onset`` [s after t = 0], ``flow_stop`` [s after the start
        of the decay window], ``tilt_t0``, ``startup_end_tilt``, ``first_burst_tilt``,
        ``flow_onset_tilt`` [degree], ``replica`` (index), and (run files that record it)
        ``correlation_onset``/``correlation_decay``, each replica's mean C(|δu|, |v|)
    tau : {"onset", "decay"} (L,) [s], block centre minus the event time
    aligned : {"onset", "decay"} -> (speed, lambda, tilt), each (units, L)
    counts : {"onset", "decay"} -> (units, L) replicas per batch (batch units) or None
    tilt_mean : {"onset", "decay"} -> (T,) [degree], ensemble-mean tilt at the stored
        blocks' centres (plain, not aligned)
    n_replicas : int, replicas kept (flagged ones left out as in the ensemble)
    """

    events: dict
    tau: dict
    aligned: dict
    counts: dict
    tilt_mean: dict
    n_replicas: int


def _event_args(cfg: Mapping, block_s: float) -> dict:
    n = max(1, int(round(float(cfg["flow_block_s"]) / block_s)))
    coarse = n * block_s
    return dict(
        block=n,
        startup_excess=float(cfg["startup_end_excess"]),
        startup_hold=max(1, int(round(float(cfg["startup_end_hold_s"]) / coarse))),
        burst_excess=float(cfg["burst_excess"]),
        flow_excess=float(cfg["flow_excess"]),
        flow_hold=max(1, int(round(float(cfg["flow_hold_s"]) / coarse))),
    )


def _interp_rows(x_new, x, Y) -> np.ndarray:
    """Row-wise linear interpolation of (R, S) samples at ``x`` onto ``x_new`` (NaN rows
    stay NaN; NaN past a row's last finite sample)."""
    out = np.full((Y.shape[0], len(x_new)), np.nan)
    for i, y in enumerate(Y):
        ok = np.isfinite(y)
        if ok.sum() >= 2:
            xs = x[ok]
            out[i] = np.where(x_new <= xs[-1], np.interp(x_new, xs, y[ok]), np.nan)
    return out


WHERE = ("precision_du", "precision_speed", "precision_random", "auc_du", "auc_speed",
         "event_size")  # fmt: skip
"""The ``where_<key>`` rows of :func:`where_flow_starts` (docs/drum.md, "Where the
avalanche starts")."""


def where_flow_starts(pile_seconds, flow_onset, du, speed, *, block_s: float, lead_s: float,
                      flow_speed: float, members: str = "speed") -> dict:  # fmt: skip
    """Per replica: does |δu_i| before its pile's onset say which disks start to flow?

    The onset sample is the pile sample at the end of the onset's first coarse block
    (``flow_onset + block_s``, the pile flows then; the first sample after half a sample
    before it, as the samples and blocks need not share the last bits). The disks that start
    to flow are those with |v_i| above ``flow_speed`` there (``members="speed"``) or
    whose speed rose by more than ``flow_speed`` since the scoring sample (``"rise"``).
    Each disk is scored by its |δu_i| ``lead_s`` before the onset sample (whole pile
    samples, at least one; baseline: its |v_i| then), and the event is scored by
    :func:`granpipe.analysis.prediction.locate`.

    Parameters
    ----------
    pile_seconds : (S,) [s], the pile's samples after t = 0
    flow_onset : (R,) [s], each replica's onset of sustained flow (NaN: none)
    du : (R, S, N) [1], |δu_i| over its largest; speed : (R, S, N) [d_s/t0], |v_i|
    block_s : [s], the coarse block of the flow onset (``fits.flow_block_s``)
    lead_s : [s]; flow_speed : [d_s/t0]

    Returns
    -------
    ``{key: (R,) float for key in WHERE}`` and ``"onset_sample"`` (R,) int (−1 where
    none); NaN where a replica has no onset, its onset sample is not ``lead_s`` after
    the window's start, or no disk starts to flow.
    """
    from ..analysis.prediction import locate

    tp = np.asarray(pile_seconds, dtype=np.float64)
    dt = float(np.median(np.diff(tp))) if len(tp) > 1 else math.inf
    lead = max(1, int(round(float(lead_s) / dt))) if np.isfinite(dt) else 1
    R = len(flow_onset)
    out = {k: np.full(R, np.nan) for k in WHERE}
    out["onset_sample"] = np.full(R, -1, np.int64)
    for r, t in enumerate(np.asarray(flow_onset, dtype=np.float64)):
        if not np.isfinite(t):
            continue
        e = int(np.searchsorted(tp, t + float(block_s) - 0.5 * dt))  # the nearest at or after
        if e >= len(tp) or e < lead:
            continue
        v_e, v_s = (np.asarray(speed[r, k], dtype=np.float64) for k in (e, e - lead))
        flows = (v_e - v_s if members == "rise" else v_e) > float(flow_speed)
        got = locate({"du": du[r, e - lead], "speed": v_s}, flows & np.isfinite(v_e))
        out["onset_sample"][r] = e
        for k, x in (got or {}).items():
            out[k][r] = x
    return out


def load_pile(
    paths: Sequence[str | os.PathLike],
    fits_cfg: Mapping,
    unit: str = "replica",
    exclude_flagged: bool = True,
) -> PileRecords | None:
    """The pile's events and the aligned records of the run files (None if the run files
    hold no pile samples). Memory: (replicas or batches) × aligned length × 3 per window.
    """
    from ..analysis.ensemble import batch_moments
    from ..analysis.events import align_on_events
    from .measures import onset_events, stop_events

    cfg = dict(fits_cfg)
    before, after = float(cfg["aligned_before_s"]), float(cfg["aligned_after_s"])
    ev_rows: dict = {}
    rows: dict = {(w, k): [] for w in WINDOWS for k in range(3)}
    cnts: dict = {w: [] for w in WINDOWS}
    tau: dict = {}
    tilt_sum: dict = {}
    tilt_n: dict = {}
    n_rep = 0
    for path in paths:
        with xr.open_dataset(path, engine="netcdf4") as ds:
            if "tilt_onset" not in ds:
                return None
            ok = np.flatnonzero(valid_replicas(ds, exclude_flagged))
            n_rep += len(ok)
            block_s = float(ds.attrs["dt_s"]) * int(ds.attrs["block_steps"])
            args = _event_args(cfg, block_s)
            stop_time = float(ds.attrs["stop_time_s"])
            out = {"replica": ds["replica"].values[ok]}
            for w in WINDOWS:
                corr = ds.get(f"speed_lyapunov_correlation_{w}")
                if corr is not None:  # each replica's mean over the window's samples
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN row
                        out[f"correlation_{w}"] = np.nanmean(corr.values[ok], axis=1)
                t = ds[f"seconds_{w}"].values
                tp = ds[f"seconds_pile_{w}"].values
                V = ds[f"speed_{w}"].transpose("replica", f"time_{w}").values[ok]
                L = ds[f"lambda_{w}"].transpose("replica", f"time_{w}").values[ok]
                rig = ds[f"rigid_speed_{w}"].values[ok]
                tilt_p = ds[f"tilt_{w}"].values[ok]
                tilt = _interp_rows(t, tp, tilt_p)
                if w == "onset":
                    ev = onset_events(t, V, tp, rig, **args)
                    event = ev["flow_onset"]
                    out.update(ev)
                    out["tilt_t0"] = tilt_p[:, 0]
                    out["where_recorded"] = np.full(len(ok), "disk_du_onset" in ds)
                    if "disk_du_onset" in ds:
                        wh = where_flow_starts(
                            tp, event, ds["disk_du_onset"].values[ok],
                            ds["disk_speed_onset"].values[ok],
                            block_s=args["block"] * block_s, lead_s=float(cfg["where_lead_s"]),
                            flow_speed=float(cfg["where_flow_speed"]),
                            members=cfg["where_members"],
                        )  # fmt: skip
                    else:
                        wh = {k: np.full(len(ok), np.nan) for k in WHERE}
                        wh["onset_sample"] = np.full(len(ok), -1, np.int64)
                    out.update({f"where_{k}": x for k, x in wh.items()})
                    for k in ("startup_end", "first_burst", "flow_onset"):
                        out[f"{k}_tilt"] = np.array([
                            np.interp(e, tp, y) if np.isfinite(e) else np.nan
                            for e, y in zip(ev[k], tilt_p, strict=True)
                        ])  # fmt: skip
                else:
                    event = stop_events(t, V, tp, rig, block=args["block"], stop_time=stop_time,
                                        stop_fraction=float(cfg["stop_fraction"]),
                                        hold=args["flow_hold"])  # fmt: skip
                    out["flow_stop"] = event
                # the event placed at the centre of its first block: tau = centre - event
                centre = event + 0.5 * block_s
                for k, Y in enumerate((V, L, tilt)):
                    tau_w, Z = align_on_events(t, Y, centre, before, after)
                    if unit == "replica":
                        rows[(w, k)].extend(list(Z))
                    elif len(ok):
                        c, m, _ = batch_moments(Z)
                        rows[(w, k)].append(m)
                        if k == 0:
                            cnts[w].append(c.astype(np.float64))
                tau[w] = tau_w
                fin = np.isfinite(tilt)
                s = np.where(fin, tilt, 0.0).sum(0)
                n = fin.sum(0)
                if w in tilt_sum and len(tilt_sum[w]) != len(s):
                    m_ = max(len(s), len(tilt_sum[w]))
                    s, n = np.pad(s, (0, m_ - len(s))), np.pad(n, (0, m_ - len(n)))
                    tilt_sum[w] = np.pad(tilt_sum[w], (0, m_ - len(tilt_sum[w])))
                    tilt_n[w] = np.pad(tilt_n[w], (0, m_ - len(tilt_n[w])))
                tilt_sum[w] = tilt_sum.get(w, 0.0) + s
                tilt_n[w] = tilt_n.get(w, 0) + n
            for k, v in out.items():
                ev_rows.setdefault(k, []).append(np.asarray(v))
    if not ev_rows:
        return None
    events = {k: np.concatenate(v) for k, v in ev_rows.items()}
    aligned = {w: tuple(np.array(rows[(w, k)], dtype=np.float64) for k in range(3))
               for w in WINDOWS}  # fmt: skip
    counts = {w: (np.array(cnts[w]) if unit == "batch" else None) for w in WINDOWS}
    with np.errstate(invalid="ignore", divide="ignore"):
        tilt_mean = {w: np.where(tilt_n[w] > 0, tilt_sum[w] / tilt_n[w], np.nan) for w in WINDOWS}
    return PileRecords(events, tau, aligned, counts, tilt_mean, n_rep)


_EVENT_ROWS = (
    ("tilt_at_t0", "tilt_t0", "degree", "tilt of the pile's surface at t = 0"),
    ("startup_end_time", "startup_end", "s", "end of the start-up transient"),
    ("startup_end_tilt", "startup_end_tilt", "degree", "tilt at the end of the start-up"),
    ("first_burst_time", "first_burst", "s", "first burst after the start-up"),
    ("first_burst_tilt", "first_burst_tilt", "degree", "tilt at the first burst"),
    ("flow_onset_time", "flow_onset", "s", "onset of sustained flow"),
    ("flow_onset_tilt", "flow_onset_tilt", "degree", "tilt at the onset of sustained flow"),
    ("decay_flow_stop_time", "flow_stop", "s", "stop of the pile's flow after the drum's stop"),
)


def _event_results(pile: PileRecords, cfg: Mapping, stop: float) -> list[FitResult]:
    """Means over the replicas that have each event, with a bootstrap interval over
    replicas; the spread between replicas (standard deviation) of the flow onset's time
    and tilt; how many replicas reach sustained flow inside the onset window."""
    out = []
    ev = pile.events
    R = len(ev["flow_onset"])
    kw = dict(n_resamples=int(cfg["bootstrap_resamples"]), level=float(cfg["confidence"]),
              seed=int(cfg["seed"]))  # fmt: skip
    for quantity, key, unit, what in _EVENT_ROWS:
        x = np.asarray(ev[key], dtype=np.float64)
        if key == "flow_stop":
            x = x - stop
            what += " (time after the drum's stop)"
        has = np.isfinite(x)
        n = int(has.sum())
        value = float(np.mean(x[has])) if n else math.nan
        se = float(np.std(x[has], ddof=1) / math.sqrt(n)) if n > 1 else math.nan
        res = FitResult(quantity, value, se, unit, n=n,
                        method=f"mean over the {n} of {R} replicas with the event: {what}; "
                        "fit error: standard error of the mean")  # fmt: skip
        if n > 1 and int(cfg["bootstrap_resamples"]) > 0:
            sq = np.stack([x, x * x], axis=-1)[:, :, np.newaxis]  # (R, 2, 1)
            boot = bootstrap_replicas(
                [sq[:, 0], sq[:, 1]],
                lambda m1, m2: np.stack(
                    [m1[:, 0], np.sqrt(np.maximum(m2[:, 0] - m1[:, 0] ** 2, 0.0))], -1
                ),
                **kw,
            )
            res = res.with_ci(boot, 0)
            if key in ("flow_onset", "flow_onset_tilt"):
                sd = float(np.std(x[has], ddof=1))
                out.append(
                    FitResult(f"{quantity}_sd", sd, math.nan, unit, n=n,
                              method=f"standard deviation between replicas of the {what}",
                              ).with_ci(boot, 1)
                )  # fmt: skip
        out.append(res)
    n_flow = int(np.isfinite(ev["flow_onset"]).sum())
    note = ""
    if n_flow < 0.9 * R:
        note = (
            f"only {n_flow} of {R} replicas reach sustained flow inside the onset window: the "
            "aligned onset average sees the early ones only (lengthen "
            "drum.protocol.onset_window_s)"
        )
    what = f"inside the onset window ({n_flow} of {R}; the aligned onset rows leave out the rest)"
    out += [
        FitResult("flow_onset_reached", n_flow / R if R else math.nan, math.nan, "1", n=R,
                  method=f"fraction of the replicas that reach sustained flow {what}",
                  note=note),
        FitResult("flow_onset_left_out", float(R - n_flow), math.nan, "1", n=R,
                  method=f"replicas that do not reach sustained flow {what}", note=note),
    ]  # fmt: skip
    return out


_WHERE_ROWS = {
    "precision_du": "fraction of the disks that start to flow among those with the largest "
                    "|δu_i|, as many as start to flow",
    "precision_speed": "the same with the largest speeds |v_i| (baseline)",
    "precision_random": "the share of the mobile disks that start to flow (a random choice's "
                        "expected precision)",
    "auc_du": "area under the ROC curve of |δu_i| over the mobile disks, those that start to "
              "flow positive",
    "auc_speed": "the same of |v_i| (baseline)",
    "event_size": "mobile disks that start to flow at the onset",
}  # fmt: skip


def _where_rows(pile: PileRecords, cfg: Mapping) -> list[FitResult]:
    """The ``where_*`` rows (:data:`WHERE`): each replica's one onset scored by
    :func:`where_flow_starts`, the mean over the replicas that have it, its standard error
    and a joint percentile bootstrap over those replicas; NaN with a note where none
    has (no replica flows inside the onset window, or no per-disk record)."""
    ev = pile.events
    R = len(ev["flow_onset"])
    X = np.stack([np.asarray(ev[f"where_{k}"], dtype=np.float64) for k in WHERE], -1)
    has = np.isfinite(X[:, 0])
    n = int(has.sum())
    note = ""
    if not np.all(ev["where_recorded"]):
        note = ("the run files hold no per-disk record (drum.protocol.disk_record false) for "
                f"{int((~ev['where_recorded']).sum())} of {R} replicas")  # fmt: skip
    if n == 0:
        n_flow = int(np.isfinite(ev["flow_onset"]).sum())
        none = (f"no replica has an onset to score ({n_flow} of {R} reach sustained flow "
                "inside the onset window)")  # fmt: skip
        note = f"{note}; {none}" if note else none
    lead = float(cfg["where_lead_s"])
    who = (f"|v_i| above {cfg['where_flow_speed']:g} d_s/t0 at the onset sample"
           if cfg["where_members"] == "speed" else
           f"|v_i| risen by more than {cfg['where_flow_speed']:g} d_s/t0 since the scores' "
           "sample")  # fmt: skip
    boot = None
    if n > 1 and int(cfg["bootstrap_resamples"]) > 0:
        boot = bootstrap_replicas(X[has], lambda m: m, level=float(cfg["confidence"]),
                                  n_resamples=int(cfg["bootstrap_resamples"]),
                                  seed=int(cfg["seed"]))  # fmt: skip
    rows = []
    for j, k in enumerate(WHERE):
        x = X[has, j]
        value = float(np.nanmean(x)) if n else math.nan
        fin = np.isfinite(x)
        se = float(np.std(x[fin], ddof=1) / math.sqrt(fin.sum())) if fin.sum() > 1 else math.nan
        res = FitResult(f"where_{k}", value, se, "1", n=n, note=note,
                        method=f"{_WHERE_ROWS[k]} (those with {who}); scores "
                        f"{lead:g} s before the onset sample (the first pile sample after the "
                        "first coarse block of each replica's own onset of sustained flow); "
                        f"mean over the {n} of {R} replicas with an onset")  # fmt: skip
        rows.append(res.with_ci(boot, j) if boot is not None else res)
    return rows


def _aligned_analysis(pile: PileRecords, w: str, cfg: Mapping, q: int, hold: int):
    """The aligned average of one window, its λ̄ and the lag from the event to λ̄'s first
    lasting zero crossing (upward at the onset, downward at the decay), with the aligned
    mean tilt there; bootstrap over the same units."""
    from ..analysis.ensemble import pooled_batch_mean, replica_mean_sem

    tau = pile.tau[w]
    Zv, Zl, Zt = pile.aligned[w]
    c = pile.counts[w]
    direction = +1 if w == "onset" else -1
    event = "flow_onset" if w == "onset" else "flow_stop"
    n_ev = int(np.isfinite(pile.events[event]).sum())
    name = "onset_lag_aligned" if w == "onset" else "decay_lag_aligned"
    if Zv.size == 0 or n_ev == 0:  # the rows stay, empty, saying why (docs/results.md)
        what = "reaches sustained flow inside the onset window" if w == "onset" else \
            "stops flowing inside the decay window"  # fmt: skip
        note = f"no replica {what}: nothing to align on"
        return [FitResult(name, math.nan, math.nan, "s", n=0, method="aligned lag", note=note),
                FitResult(f"{name}_tilt", math.nan, math.nan, "degree", n=0,
                          method="aligned mean tilt at that crossing", note=note)], {}  # fmt: skip
    if c is None:
        (mv, _, count), (ml, _, _), (mt, _, _) = (replica_mean_sem(Z) for Z in (Zv, Zl, Zt))
    else:
        (mv, _, count), (ml, _, _), (mt, _, _) = (pooled_batch_mean(Z, c) for Z in (Zv, Zl, Zt))
    count = np.asarray(count, dtype=np.float64)
    keep = count >= float(cfg["aligned_min_fraction"]) * n_ev
    valid = np.flatnonzero(keep)
    search = (float(tau[valid[0]]), float(tau[valid[-1]])) if len(valid) else (np.nan, np.nan)

    def bar(ml_):
        return moving_average(np.where(keep, ml_, np.nan), q)

    def at(mt_, x):
        """(b,) values of the (b, L) series ``mt_`` at the (b,) times ``x``."""
        x = np.atleast_1d(x)
        mt_ = np.atleast_2d(mt_)
        i = np.clip(np.searchsorted(tau, x) - 1, 0, len(tau) - 2)
        i = np.where(np.isfinite(x), i, 0)
        f = (x - tau[i]) / (tau[i + 1] - tau[i])
        rows = np.arange(mt_.shape[0])
        y = mt_[rows, i] * (1 - f) + mt_[rows, i + 1] * f
        return np.where(np.isfinite(x), y, np.nan)

    lb = bar(ml)
    lag_value = float(first_crossing(tau, lb, search, direction, hold))
    tilt_value = float(at(mt, np.array([lag_value]))[0])

    def stat(mv_, ml_, mt_):
        cr = first_crossing(tau, bar(ml_), search, direction, hold)
        return np.stack([cr, at(mt_, cr)], axis=-1)

    what = ("each replica's own onset of sustained flow" if w == "onset"
            else "each replica's own stop of flow after the drum's stop")  # fmt: skip
    held = f"that lasts {cfg['crossing_hold_s']:g} s"
    lag_res = FitResult(name, lag_value, math.nan, "s", n=n_ev,
                        method=f"first zero crossing {held} of λ̄ (Eq. 2) of λ averaged over the "
                        f"replicas aligned on {what}, minus that event (searched where at "
                        f"least {cfg['aligned_min_fraction']:g} of them contribute)")  # fmt: skip
    tilt_res = FitResult(
        f"{name}_tilt",
        tilt_value,
        math.nan,
        "degree",
        n=n_ev,
        method="aligned mean tilt of the pile's surface at that crossing",
    )
    if int(cfg["bootstrap_resamples"]) > 0 and n_ev > 1:
        kw = dict(n_resamples=int(cfg["bootstrap_resamples"]), level=float(cfg["confidence"]),
                  seed=int(cfg["seed"]))  # fmt: skip
        if c is None:
            boot = bootstrap_replicas([Zv, Zl, Zt], stat, **kw)
        else:
            boot = bootstrap_batches([Zv, Zl, Zt], c, stat, **kw)
        lag_res, tilt_res = lag_res.with_ci(boot, 0), tilt_res.with_ci(boot, 1)
    dim = f"tau_{w}"
    lab = "onset of sustained flow" if w == "onset" else "stop of flow"
    mv, ml, mt = (np.where(keep, m, np.nan) for m in (mv, ml, mt))
    curves = {
        f"aligned_speed_{w}": (dim, mv, {"units": "d_s/t0", "long_name": f"mean V aligned on "
                               f"each replica's {lab} (where enough replicas reach)"}),
        f"aligned_lambda_{w}": (dim, ml, {"units": "1/t0", "long_name": f"mean λ aligned on "
                                f"each replica's {lab}"}),
        f"aligned_lambda_bar_{w}": (dim, lb, {"units": "1/t0", "long_name": "moving average "
                                    f"(Eq. 2) of the aligned λ, where at least "
                                    f"{cfg['aligned_min_fraction']:g} of the replicas reach"}),
        f"aligned_tilt_{w}": (dim, mt, {"units": "degree", "long_name": f"mean tilt aligned on "
                              f"each replica's {lab}"}),
        f"aligned_count_{w}": (dim, count, {"units": "1", "long_name": "replicas contributing "
                               "to the aligned averages"}),
    }  # fmt: skip
    coords = {dim: (dim, tau, {"units": "s", "long_name": f"time after each replica's {lab}"})}
    return [lag_res, tilt_res], {"curves": curves, "coords": coords}


def pile_fits(pile: PileRecords, ens: xr.Dataset, fits_cfg: Mapping,
              label: str = "") -> tuple[list[FitResult], xr.Dataset]:  # fmt: skip
    """Rows and curves of the pile's events and of the averages aligned on each replica's
    own events (docs/drum.md, "Aligned on each pile's avalanche").

    Returns
    -------
    results : FitResults ``tilt_at_t0``, ``startup_end_time``/``_tilt``,
        ``first_burst_time``/``_tilt``, ``flow_onset_time``/``_tilt`` (and ``_sd``, the
        spread between replicas), ``flow_onset_reached`` (fraction of the replicas),
        ``decay_flow_stop_time`` (after the drum's stop), ``onset_lag_aligned`` and
        ``decay_lag_aligned`` [s] with the aligned tilt at λ̄'s crossing (``_tilt``),
        ``correlation_onset``/``correlation_decay`` (where the run files record them),
        ``where_precision_du``, ``_speed``, ``_random``, ``where_auc_du``, ``_speed``,
        ``where_event_size`` (:func:`where_flow_starts`; NaN with a note where no replica
        has an onset to score)
    curves : Dataset with the aligned averages on ``tau_onset``/``tau_decay`` [s], their
        counts, the ensemble-mean tilt on ``time_onset``/``time_decay`` and the
        per-replica event times on ``event_replica``
    """
    cfg = dict(fits_cfg)
    block_s = float(ens.attrs["dt_s"]) * int(ens.attrs["block_steps"])
    q = window_half_width(float(cfg["moving_average_s"]), block_s)
    hold = _hold_samples(ens, cfg)
    stop = float(ens.attrs["stop_time_s"])
    results = _event_results(pile, cfg, stop) + _where_rows(pile, cfg)
    for w in WINDOWS:
        c = pile.events.get(f"correlation_{w}", np.array([]))
        c = c[np.isfinite(c)]
        if c.size:
            sem = float(c.std(ddof=1) / math.sqrt(c.size)) if c.size > 1 else math.nan
            results.append(FitResult(f"correlation_{w}", float(c.mean()), sem, "1", n=c.size,
                                     method=f"C(|δu|, |v|) over the mobile disks, mean over "
                                     f"the pile's samples of the {w} window, then over "
                                     "replicas (where the chaos lives)"))  # fmt: skip
    out = xr.Dataset()
    for w in WINDOWS:
        res, extra = _aligned_analysis(pile, w, cfg, q, hold)
        results += res
        if extra:
            out = out.assign_coords(extra["coords"])
            for k, v in extra["curves"].items():
                out[k] = v
        tdim = f"time_{w}"
        tm = np.full(ens.sizes[tdim], np.nan)
        n = min(len(tm), len(pile.tilt_mean[w]))
        tm[:n] = pile.tilt_mean[w][:n]
        out[f"tilt_{w}_mean"] = (tdim, tm, {"units": "degree", "long_name": "ensemble-mean "
                                 f"tilt of the pile's surface, {w} window"})  # fmt: skip
    ev = pile.events
    out = out.assign_coords(
        event_replica=(
            "event_replica",
            np.asarray(ev["replica"], np.int64),
            {"units": "1", "long_name": "replica index"},
        )
    )
    for key, units, what in (
        ("startup_end", "s", "end of the start-up transient after t = 0"),
        ("first_burst", "s", "first burst after t = 0"),
        ("flow_onset", "s", "onset of sustained flow after t = 0"),
        ("flow_onset_tilt", "degree", "tilt at the onset of sustained flow"),
        ("flow_stop", "s", "stop of flow after the start of the decay window"),
    ):
        out[f"replica_{key}"] = (
            "event_replica",
            np.asarray(ev[key], np.float64),
            {"units": units, "long_name": f"each replica's {what}"},
        )
    if label:
        results = [dataclasses.replace(r, quantity=r.quantity + label) for r in results]
    return results, out
