"""What Ref. [20] measured, at one φ (:func:`point_fits`) and across φ
(:func:`phi_crossing`); definitions and tests: docs/shear.md, "Analysis".

``lambda_mean`` (time average of λ per replica, then over replicas), ``lambda_all_mean``
(the same of the whole tangent vector's growth rate, rattlers included: the maximal
exponent; docs/shear.md, "Two readings of λ"), ``event_rate``,
``event_lag`` (the first lasting upward zero crossing of λ̄, Eq. 2, of λ aligned on each
replica's own events, minus the event: the drum's aligned onset lag, by the same
functions) and ``lead_time`` = −``event_lag``, ``lambda_peak_time`` (where that λ̄ is
largest), ``lambda_excess_before``/``_after`` (λ's excess just before and after the
events over its level far from them), ``correlation_*`` (C(|δu|, |v|) over each
replica's samples, all, near events or elsewhere, then over replicas); across φ,
``phi_lambda_zero`` and ``phi_lambda_all_zero``. Intervals: bootstrap over replicas
(with all their events).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import xarray as xr

from ..analysis.bootstrap import FitResult, bootstrap_batches, bootstrap_replicas, first_crossing
from ..analysis.ensemble import pooled_batch_mean
from ..analysis.events import align_on_many_events
from ..analysis.smoothing import moving_average, window_half_width
from .measures import rearrangement_events

__all__ = ["event_times", "point_fits", "phi_crossing"]


def event_times(ds: xr.Dataset, events: Mapping) -> list[np.ndarray]:
    """Per replica, the times [s] of its rearrangement events: the middle of the sample
    interval in which a burst of at least ``min_changes`` edges starts after ``quiet_s``."""
    dt = float(ds.attrs["sample_s"])
    quiet = round(float(events["quiet_s"]) / dt)
    t = ds["sample"].values - dt / 2.0
    ch = ds["network_changes"].values
    return [t[rearrangement_events(c, int(events["min_changes"]), quiet)] for c in ch]


def _boot_kw(cfg):
    return dict(n_resamples=int(cfg["bootstrap_resamples"]), level=float(cfg["confidence"]),
                seed=int(cfg["seed"]))  # fmt: skip


def _over_replicas(name, values, unit, method, cfg) -> FitResult:
    """Mean over replicas of one value each, its standard error and bootstrap interval."""
    n = len(values)
    if n == 0:
        return FitResult(name, math.nan, math.nan, unit, n=0, method=method)
    sem = float(np.std(values, ddof=1) / math.sqrt(n)) if n > 1 else math.nan
    res = FitResult(name, float(np.mean(values)), sem, unit, n=n, method=method)
    if int(cfg["bootstrap_resamples"]) > 0 and n > 1:
        res = res.with_ci(bootstrap_replicas(np.asarray(values)[:, None], lambda m: m[:, 0],
                                             **_boot_kw(cfg)))  # fmt: skip
    return res


def _event_triggered(t, values, events, cfg, step, stem, of):
    """``values`` (R, T) at times ``t`` [s] (step ``step``) of each replica aligned on each
    of its own ``events``, pooled per replica: the rows ``event_lag``, ``lead_time`` (for
    another quantity than λ, ``stem="lambda_all"``: ``<stem>_event_lag``,
    ``<stem>_lead_time``), ``<stem>_peak_time``, ``<stem>_excess_before``/``_after``, with
    bootstrap intervals over replicas (``of`` names the quantity in their methods);
    returns ``(rows, tau, aligned mean, its moving average λ̄, events per τ)``."""
    tau, M, C = align_on_many_events(t, values, events, float(cfg["aligned_before_s"]),
                                     float(cfg["aligned_after_s"]))  # fmt: skip
    n_ev = sum(len(e) for e in events)
    q = window_half_width(float(cfg["moving_average_s"]), step)
    hold = round(float(cfg["crossing_hold_s"]) / step)
    mean, _, count = pooled_batch_mean(M, C)
    keep = count >= float(cfg["aligned_min_fraction"]) * max(n_ev, 1)
    search = (tau[keep][0], tau[keep][-1]) if keep.any() else (np.nan, np.nan)

    def bar(m):
        return moving_average(np.where(keep, m, np.nan), q)

    w = float(cfg["moving_average_s"])
    before, after, outer = (tau >= -w) & (tau < 0), (tau >= 0) & (tau < w), np.abs(tau) >= 2 * w

    def lag_and_peak(m):  # (..., 4): λ̄'s lasting upward zero crossing, its maximum, and the
        lb = bar(m)  # mean excess over the outer window just before and just after the event
        has = np.isfinite(lb).any(-1)
        top = np.nanargmax(np.where(np.isfinite(lb), lb, -np.inf), axis=-1)
        peak = np.where(has, tau[top], np.nan)
        base = np.nanmean(m[..., outer], -1)
        ex = [np.nanmean(m[..., x], -1) - base for x in (before, after)]
        return np.stack([first_crossing(tau, lb, search, +1, hold), peak, *ex], -1)

    pre = "" if stem == "lambda" else f"{stem}_"
    lag0, peak0, ex_before, ex_after = lag_and_peak(mean)
    lag_res = FitResult(f"{pre}event_lag", float(lag0), math.nan, "s", n=n_ev,
                        method=f"first lasting upward zero crossing of the moving average "
                        f"(Eq. 2) of {of} averaged over the events, each replica aligned on "
                        "each of its own, minus the event")  # fmt: skip
    peak = FitResult(f"{stem}_peak_time", float(peak0), math.nan, "s", n=n_ev,
                     method=f"time of the largest moving average of {of} averaged over the "
                     "events, minus the event (negative: largest before the events)")  # fmt: skip
    excess = [FitResult(f"{stem}_excess_{k}", float(v), math.nan, "1/t0", n=n_ev,
                        method=f"mean of {of} averaged over the events within {w:g} s {k} "
                        f"them, minus its mean {2 * w:g} s or more away from them")
              for k, v in (("before", ex_before), ("after", ex_after))]  # fmt: skip
    units = np.flatnonzero(C.max(axis=1) > 0)
    if int(cfg["bootstrap_resamples"]) > 0 and units.size > 1:
        boot = bootstrap_batches(M[units], C[units], lag_and_peak, **_boot_kw(cfg))
        lag_res, peak = lag_res.with_ci(boot, 0), peak.with_ci(boot, 1)
        excess = [x.with_ci(boot, k) for k, x in enumerate(excess, start=2)]
    lead = FitResult(f"{pre}lead_time", -lag_res.value, math.nan, "s", ci_low=-lag_res.ci_high,
                     ci_high=-lag_res.ci_low, ci_level=lag_res.ci_level, n=n_ev,
                     n_resamples=lag_res.n_resamples, method=f"−{pre}event_lag: how long "
                     f"before the events the moving average of {of} turns positive")  # fmt: skip
    return [lag_res, lead, peak, *excess], tau, mean, bar(mean), count


def point_fits(ds: xr.Dataset, params: Mapping) -> tuple[list[FitResult], xr.Dataset]:
    """The point's fitted numbers and curves from its runs (``ds``: batches concatenated
    along ``replica``); ``params`` is the fits rule's subset."""
    cfg = params["fits"]
    lam = ds["local_lyapunov"].values
    R = lam.shape[0]
    per_replica = np.nanmean(lam, axis=1)
    res = [_over_replicas("lambda_mean", per_replica, "1/t0", "time average of λ(t) over the "
                          "record, mean over replicas", cfg)]  # fmt: skip
    per_replica_all = ds["lyapunov_all"].values.mean(axis=1)
    res.append(_over_replicas("lambda_all_mean", per_replica_all, "1/t0", "growth rate of "
                              "the whole tangent vector (all mobile disks, rattlers included) "
                              "over the record, mean over replicas", cfg))  # fmt: skip
    events = event_times(ds, params["events"])
    n_ev = sum(len(e) for e in events)
    record = float(ds["time"].values[-1] + ds.attrs["block_s"] / 2)
    res.append(FitResult("event_rate", n_ev / (R * record), math.nan, "1/s", n=n_ev,
                         method="rearrangement events per replica and second"))  # fmt: skip
    before, after = float(cfg["aligned_before_s"]), float(cfg["aligned_after_s"])
    t = ds["time"].values
    block = float(ds.attrs["block_s"])
    rows, tau, mean, lbar, count = _event_triggered(t, lam, events, cfg, block, "lambda", "λ")
    res += rows
    _, Mv, Cv = align_on_many_events(t, ds["global_speed"].values, events, before, after)
    mean_v, _, _ = pooled_batch_mean(Mv, Cv)
    # the same of the whole tangent vector's rate, at the samples' resolution
    ts = ds["sample"].values - float(ds.attrs["sample_s"]) / 2.0
    rows, tau_s, mean_all, lbar_all, count_all = _event_triggered(
        ts, ds["lyapunov_all"].values, events, cfg, float(ds.attrs["sample_s"]), "lambda_all",
        "the whole tangent vector's rate",
    )  # fmt: skip
    res += rows
    corr = ds["speed_lyapunov_correlation"].values
    near = np.zeros(corr.shape, dtype=bool)
    s = ds["sample"].values
    window = float(cfg["correlation_window_s"])
    for r, ev in enumerate(events):
        if len(ev):
            near[r] = (np.abs(s[:, None] - ev[None, :]) <= window).any(axis=1)
    for name, m in (("all", np.ones_like(near)), ("events", near), ("quiet", ~near)):
        with np.errstate(invalid="ignore", divide="ignore"):  # a replica without such samples
            v = np.nansum(np.where(m, corr, np.nan), 1) / (m & np.isfinite(corr)).sum(1)
        res.append(_over_replicas(f"correlation_{name}", v[np.isfinite(v)], "1", "C(|δu|, |v|) "
                                  f"averaged over each replica's {name} samples, then over "
                                  "replicas", cfg))  # fmt: skip
    label = "time after each event"
    curves = xr.Dataset(
        {
            "lambda_replica_mean": ("replica", per_replica, {"units": "1/t0", "long_name":
                                    "time average of λ per replica"}),
            "lambda_all_replica_mean": ("replica", per_replica_all, {"units": "1/t0",
                                        "long_name": "growth rate of the whole tangent vector "
                                        "per replica"}),
            "aligned_lambda": ("tau", mean, {"units": "1/t0", "long_name": "λ averaged over "
                               "the events, each replica aligned on its own"}),
            "aligned_lambda_bar": ("tau", lbar,
                                   {"units": "1/t0", "long_name": "moving average (Eq. 2) of "
                                    "the aligned λ, where enough events contribute"}),
            "aligned_speed": ("tau", mean_v, {"units": "d_s/t0", "long_name": "V averaged over "
                              "the events"}),
            "aligned_count": ("tau", count, {"units": "1", "long_name": "events contributing"}),
            "aligned_lambda_all": ("tau_sample", mean_all, {"units": "1/t0", "long_name":
                                   "the whole tangent vector's rate averaged over the events"}),
            "aligned_lambda_all_bar": ("tau_sample", lbar_all, {"units": "1/t0", "long_name":
                                       "its moving average (Eq. 2)"}),
            "aligned_count_sample": ("tau_sample", count_all, {"units": "1", "long_name":
                                     "events contributing"}),
            "snapshot_positions": (("disk", "xy"), ds["snapshot_positions"].values[0],
                                   ds["snapshot_positions"].attrs),
            "snapshot_du": ("disk", ds["snapshot_du"].values[0], ds["snapshot_du"].attrs),
            "snapshot_speed": ("disk", ds["snapshot_speed"].values[0],
                               ds["snapshot_speed"].attrs),
            "diameter": ("disk", ds["diameter"].values, ds["diameter"].attrs),
        },
        coords={"tau": ("tau", tau, {"units": "s", "long_name": label}),
                "tau_sample": ("tau_sample", tau_s, {"units": "s", "long_name": label}),
                "replica": ds["replica"]},
    )  # fmt: skip
    return res, curves


def phi_crossing(phis, replica_means, cfg: Mapping, name="phi_lambda_zero",
                 of="the time average of λ") -> FitResult:  # fmt: skip
    """φ where the replicas' mean of ``of`` first crosses zero (either way: Ref. [20] finds
    it chaotic below the crossing, not above; the direction is a result here), by linear
    interpolation between the grid points; bootstrap over each point's replicas.

    Parameters
    ----------
    phis : (P,) increasing; replica_means : P arrays (R_p,) [1/t0], each point's replicas
    name, of : the row's quantity and what its method names
    """
    phis = np.asarray(phis, dtype=np.float64)
    means = np.array([np.mean(m) for m in replica_means])
    value = float(first_crossing(phis, means, None, 0))
    res = FitResult(name, value, math.nan, "1", n=len(phis), method="first zero crossing in "
                    f"φ of the replica mean of {of}, linear between grid points")  # fmt: skip
    n = int(cfg["bootstrap_resamples"])
    if n > 0 and all(len(m) > 1 for m in replica_means):
        rng = np.random.default_rng(int(cfg["seed"]))
        boot = np.stack([[rng.choice(m, len(m)).mean() for m in replica_means] for _ in range(n)])
        x = first_crossing(phis, boot, None, 0)
        ok = np.isfinite(x)
        a = (1.0 - float(cfg["confidence"])) / 2.0
        if ok.any():
            lo, hi = np.quantile(x[ok], [a, 1.0 - a])
            res = FitResult(res.quantity, value, math.nan, "1", float(lo), float(hi),
                            float(cfg["confidence"]), n=len(phis), n_resamples=n,
                            n_failed=int((~ok).sum()), method=res.method)  # fmt: skip
    return res
