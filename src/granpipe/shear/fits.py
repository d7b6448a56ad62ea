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

import dataclasses
import math
import warnings
from collections.abc import Mapping

import numpy as np
import xarray as xr

from ..analysis.bootstrap import (
    BootstrapResult,
    FitResult,
    bootstrap_batches,
    bootstrap_replicas,
    first_crossing,
)
from ..analysis.ensemble import pooled_batch_mean
from ..analysis.events import align_on_many_events
from ..analysis.prediction import (
    bootstrap_auc,
    event_follows,
    locate,
    roc_curve,
    trailing_mean,
)
from ..analysis.regression import segmented_fit
from ..analysis.smoothing import moving_average, window_half_width
from .measures import JAMMING, rearrangement_events, stress_release_events

__all__ = ["event_samples", "event_times", "point_fits", "transitions", "TRANSITIONS"]


def _active(ds: xr.Dataset, events: Mapping, detector: str) -> np.ndarray:
    """(R, S) bool: the samples in which the detector fires (before the quiet spell is
    asked for): ``network`` — at least ``min_changes`` edges changed; ``energy`` and
    ``torque`` — the normal springs' energy, or the magnitude of their torque on the
    inner ring, fell by at least ``release_drop`` times its median over the record."""
    if detector == "network":
        return ds["network_changes"].values >= int(events["min_changes"])
    x = ds["jamming_energy"].values if detector == "energy" else -ds["jamming_torque"].values
    fall = np.concatenate([np.zeros((len(x), 1)), x[:, :-1] - x[:, 1:]], axis=1)
    return (fall > 0) & (fall >= float(events["release_drop"]) * np.median(x, 1, keepdims=True))


def event_samples(ds: xr.Dataset, events: Mapping, detector: str | None = None) -> list:
    """Per replica, the sample indices (K,) int64 of its events under ``detector``
    (default ``events["detector"]``): a burst of network changes
    (:func:`~granpipe.shear.measures.rearrangement_events`) or a stress release
    (:func:`~granpipe.shear.measures.stress_release_events`), after ``quiet_s``."""
    detector = events["detector"] if detector is None else detector
    quiet = round(float(events["quiet_s"]) / float(ds.attrs["sample_s"]))
    if detector == "network":
        return [rearrangement_events(c, int(events["min_changes"]), quiet)
                for c in ds["network_changes"].values]  # fmt: skip
    x = ds["jamming_energy"].values if detector == "energy" else -ds["jamming_torque"].values
    return [stress_release_events(y, float(events["release_drop"]), quiet) for y in x]


def event_times(ds: xr.Dataset, events: Mapping, detector: str | None = None) -> list:
    """Per replica, the times [s] of its events (:func:`event_samples`): the middle of
    the sample interval in which each starts."""
    dt = float(ds.attrs["sample_s"])
    t = ds["sample"].values - dt / 2.0
    return [t[k] for k in event_samples(ds, events, detector)]


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


def _per_sample(block_values: np.ndarray, per: int) -> np.ndarray:
    """(R, S) means of (R, S·per) block values over each sample's ``per`` blocks."""
    R, T = block_values.shape
    return block_values[:, : T // per * per].reshape(R, T // per, per).mean(axis=2)


def jamming_rows(ds: xr.Dataset, cfg) -> tuple[list[FitResult], dict[str, np.ndarray]]:
    """Each jamming measure (:data:`~granpipe.shear.measures.JAMMING`) averaged over each
    replica's samples, then over replicas; returns the rows and the per-replica means."""
    rows, per_replica = [], {}
    for key, (unit, long_name) in JAMMING.items():
        v = np.nanmean(ds[f"jamming_{key}"].values, axis=1)
        per_replica[key] = v
        rows.append(
            _over_replicas(
                key,
                v[np.isfinite(v)],
                unit,
                f"{long_name}: the mean over each replica's samples, then over replicas",
                cfg,
            )
        )
    return rows, per_replica


PREDICTORS = {  # name: what scores a moment (the finite-time exponent of the "when")
    "lambda_all": "the whole tangent vector's growth rate (the finite-time maximal exponent)",
    "lambda": "λ(t) over disks with two contacts",
    "speed": "V(t), the disks' global speed (baseline)",
}


def when_prediction(ds: xr.Dataset, events: Mapping, idx: list, cfg) -> tuple[list, dict]:
    """Does the recent finite-time exponent say *when* an event follows?

    At each sample k where the detector has been quiet for ``quiet_s`` (an event could
    start next) and the horizon lies inside the record, the score is the predictor's
    mean over the ``predict_window_s`` ending at k and the label whether an event starts
    within the ``predict_horizon_s`` after k. Rows ``when_auc_<predictor>``: the area
    under the ROC curve pooled over replicas, bootstrap over replicas (0.5: no
    prediction); ``when_moments`` and ``when_positives`` count the moments. Curves: the
    ROC curves on a grid of false-positive rates and the histograms of the exponent's
    scores before events and elsewhere.
    """
    dt = float(ds.attrs["sample_s"])
    w = max(1, round(float(cfg["predict_window_s"]) / dt))
    h = max(1, round(float(cfg["predict_horizon_s"]) / dt))
    quiet = round(float(events["quiet_s"]) / dt)
    active = _active(ds, events, events["detector"])
    R, S = active.shape
    per = round(dt / float(ds.attrs["block_s"]))
    series = {"lambda_all": ds["lyapunov_all"].values,
              "lambda": _per_sample(ds["local_lyapunov"].values, per)[:, :S],
              "speed": _per_sample(ds["global_speed"].values, per)[:, :S]}  # fmt: skip
    c = np.concatenate([np.zeros((R, 1)), np.cumsum(active, axis=1)], axis=1)
    k = np.arange(S)
    lo = np.maximum(k + 1 - quiet, 0)
    candidate = ((c[:, k + 1] - c[:, lo]) == 0) & (k >= max(w, quiet) - 1) & (k + h < S)
    labels = [event_follows(S, e, h)[candidate[r]] for r, e in enumerate(idx)]
    n_pos = int(sum(y.sum() for y in labels))
    rows, curves = [], {}
    fpr_grid = np.linspace(0.0, 1.0, 101)
    for name, what in PREDICTORS.items():
        score = trailing_mean(series[name], w)
        scores = [score[r][candidate[r]] for r in range(R)]
        value, boot = bootstrap_auc(
            scores,
            labels,
            **_boot_kw({**cfg, "bootstrap_resamples": max(int(cfg["bootstrap_resamples"]), 1)}),
        )
        res = FitResult(f"when_auc_{name}", value, math.nan, "1", n=n_pos,
                        method=f"area under the ROC curve of {what} over the "
                        f"{w * dt:g} s before each quiet moment predicting an event within "
                        f"{h * dt:g} s, pooled over replicas (0.5: no prediction)")  # fmt: skip
        if int(cfg["bootstrap_resamples"]) > 0 and R > 1:
            res = res.with_ci(boot)
        rows.append(res)
        fpr, tpr = roc_curve(np.concatenate(scores), np.concatenate(labels))
        curves[f"when_roc_{name}"] = (
            np.interp(fpr_grid, fpr, tpr) if np.isfinite(fpr).all() else np.full(101, np.nan)
        )
    pooled = np.concatenate([trailing_mean(series["lambda_all"], w)[r][candidate[r]]
                             for r in range(R)])  # fmt: skip
    y = np.concatenate(labels)
    finite = np.isfinite(pooled)
    edges = (np.quantile(pooled[finite], np.linspace(0, 1, 41)) if finite.sum() > 1
             else np.linspace(-1, 1, 41))  # fmt: skip
    edges = np.unique(edges) if np.unique(edges).size > 1 else np.linspace(-1, 1, 41)
    curves["when_hist_before"] = np.histogram(pooled[y & finite], edges, density=True)[0]
    curves["when_hist_elsewhere"] = np.histogram(pooled[~y & finite], edges, density=True)[0]
    curves["when_hist_edges"] = edges
    rows.append(FitResult("when_moments", float(sum(len(x) for x in labels)), math.nan, "1",
                          n=R, method="quiet moments scored (all replicas)"))  # fmt: skip
    rows.append(FitResult("when_positives", float(n_pos), math.nan, "1", n=R,
                          method="of them, moments followed by an event within the "
                          "horizon"))  # fmt: skip
    return rows, {**curves, "fpr": fpr_grid}


def where_prediction(ds: xr.Dataset, idx: list, cfg) -> list[FitResult]:
    """Does the Lyapunov vector say *where* an event happens?

    For each event at sample e, the disks that rearrange are those with a changed
    neighbour edge in it (between samples e − 1 and e); the score of a disk is its |δu_i|
    at the sample ``where_lead_s`` before e (whole samples, at least one: the interval's
    start, before any of its edges changed), baseline its speed |v_i| then. Per event the
    precision at the event's own size
    (:func:`~granpipe.analysis.prediction.precision_at_size`; a random choice gives the
    set's share) and the area under the ROC curve over the disks;
    the mean over each replica's events, then over replicas, bootstrap over replicas.
    """
    lead = max(1, round(float(cfg["where_lead_s"]) / float(ds.attrs["sample_s"])))
    du, v, ch = (ds[k].values for k in ("disk_du", "disk_speed", "disk_changes"))
    per_rep = {k: [] for k in ("precision_du", "precision_speed", "precision_random",
                               "auc_du", "auc_speed", "event_size")}  # fmt: skip
    n_ev = 0
    for r, events in enumerate(idx):
        got = {k: [] for k in per_rep}
        for e in events[events >= lead]:
            one = locate({"du": du[r, e - lead], "speed": v[r, e - lead]}, ch[r, e] > 0)
            for k, x in (one or {}).items():
                got[k].append(x)
        n_ev += len(got["event_size"])
        for k, x in got.items():
            if x:
                per_rep[k].append(np.nanmean(x))
    what = {"precision_du": "fraction of the rearranging disks among those with the largest "
                            "|δu_i|, as many as rearrange",
            "precision_speed": "the same with the largest speeds |v_i| (baseline)",
            "precision_random": "the rearranging disks' share of all disks (a random "
                                "choice's expected precision)",
            "auc_du": "area under the ROC curve of |δu_i| over the disks, the rearranging "
                      "ones positive",
            "auc_speed": "the same of |v_i| (baseline)",
            "event_size": "disks that rearrange per event"}  # fmt: skip
    rows = []
    for k, x in per_rep.items():
        res = _over_replicas(f"where_{k}", np.asarray(x), "1", f"{what[k]}, "
                             f"at the sample {lead * float(ds.attrs['sample_s']):g} s before "
                             "the event's; mean over each replica's events, then over "
                             "replicas", cfg)  # fmt: skip
        rows.append(dataclasses.replace(res, n=n_ev))
    return rows


def detector_comparison(ds: xr.Dataset, events: Mapping, idx: list, cfg) -> list[FitResult]:
    """Both detectors side by side: the rate of stress releases (the springs' energy
    falling by ``release_drop`` of its median) and the fraction of them within one sample
    of a burst of network changes of the default detector."""
    dt = float(ds.attrs["sample_s"])
    R, S = ds["network_changes"].shape
    record = S * dt
    net = event_samples(ds, events, "network")
    rel = event_samples(ds, events, "energy")
    n_rel = sum(len(e) for e in rel)
    near = [np.isin(e, np.concatenate([n - 1, n, n + 1])) for e, n in zip(rel, net, strict=True)]
    coincident = float(np.concatenate(near).mean()) if n_rel else math.nan
    return [
        FitResult("release_event_rate", n_rel / (R * record), math.nan, "1/s", n=n_rel,
                  method="stress releases (the normal springs' energy falling by at least "
                  f"{float(events['release_drop']):g} of its median) per replica and second"),
        FitResult("release_network_coincidence", coincident, math.nan, "1", n=n_rel,
                  method="fraction of the stress releases within one sample of a burst of "
                  "network changes"),
    ]  # fmt: skip


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
    idx = event_samples(ds, params["events"])
    t_event = ds["sample"].values - float(ds.attrs["sample_s"]) / 2.0
    events = [t_event[k] for k in idx]
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
    jam_rows, jam = jamming_rows(ds, cfg)
    res += jam_rows
    when_rows, when = when_prediction(ds, params["events"], idx, cfg)
    res += when_rows + where_prediction(ds, idx, cfg)
    res += detector_comparison(ds, params["events"], idx, cfg)
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
            **{f"{k}_replica_mean": ("replica", jam[k], {"units": JAMMING[k][0],
               "long_name": f"{JAMMING[k][1]}, per replica"}) for k in JAMMING},
            **{f"when_roc_{k}": ("fpr", when[f"when_roc_{k}"], {"units": "1", "long_name":
               f"true-positive rate of {PREDICTORS[k]} predicting an event"})
               for k in PREDICTORS},
            "when_hist_before": ("score_bin", when["when_hist_before"], {"units": "t0",
                                 "long_name": "density of the exponent's scores before events"}),
            "when_hist_elsewhere": ("score_bin", when["when_hist_elsewhere"], {"units": "t0",
                                    "long_name": "... at the other quiet moments"}),
            "when_hist_edges": ("score_edge", when["when_hist_edges"], {"units": "1/t0",
                                "long_name": "edges of the score bins"}),
        },
        coords={"tau": ("tau", tau, {"units": "s", "long_name": label}),
                "tau_sample": ("tau_sample", tau_s, {"units": "s", "long_name": label}),
                "fpr": ("fpr", when["fpr"], {"units": "1", "long_name": "false-positive rate"}),
                "replica": ds["replica"]},
    )  # fmt: skip
    return res, curves


TRANSITIONS = {  # name: (unit, method)
    "phi_lambda_zero": (
        "1",
        "first zero crossing in φ of the replica mean of the time "
        "average of λ (over disks with two contacts), linear between points",
    ),
    "phi_lambda_all_zero": (
        "1",
        "φ*: first zero crossing in φ of the replica mean of the "
        "maximal exponent (the whole tangent vector's growth rate, "
        "rattlers included), linear between points",
    ),
    "phi_J_z_frictionless": (
        "1",
        "φ_J: where the mean contact number of the non-rattlers "
        "(fewer than 3 contacts removed) first reaches 4, the "
        "frictionless isostatic value, linear between points",
    ),
    "phi_J_z_frictional": (
        "1",
        "φ_J: where the mean contact number of the non-rattlers "
        "(fewer than 2 contacts removed) first reaches 3, the frictional "
        "isostatic value, linear between points",
    ),
    "phi_J_pressure": (
        "1",
        "φ_J: the break of a two-segment linear fit of the logarithm of "
        "the pressure on the outer ring against φ (where it leaves zero)",
    ),
    "phi_J_overlap": (
        "1",
        "φ_J: the break of a two-segment linear fit of the logarithm of the mean overlap against φ",
    ),
    "hexatic_at_phi_star": ("1", "bulk |ψ6| at φ*, linear between points"),
    "phi_star_minus_phi_J_z": ("1", "φ* − φ_J(z, frictionless reading)"),
    "phi_star_minus_phi_J_pressure": ("1", "φ* − φ_J(pressure)"),
}
"""The rows :func:`transitions` gives across φ."""

TABLE_KEYS = ("lambda", "lambda_all", "z_frictionless", "z_frictional", "pressure", "overlap",
              "hexatic")  # fmt: skip
"""The per-replica means :func:`transitions` reads at each point."""


def _break(phis, y):
    """(B,) the break in φ of a two-segment linear fit of ln y (B, P); NaN if undefined."""
    out = np.full(y.shape[0], np.nan)
    for b, yb in enumerate(y):
        ok = np.isfinite(yb) & (yb > 0)
        if ok.sum() >= 5:
            fit = segmented_fit(phis[ok], np.log(yb[ok]), 1, ci_method="wald")
            out[b] = fit.breakpoints[0]
    return out


def _transition_values(phis, m) -> np.ndarray:
    """(B, len(TRANSITIONS)) from the means ``m[key]`` (B, P) over the points."""
    star = first_crossing(phis, m["lambda_all"], None, 0)
    z = first_crossing(phis, m["z_frictionless"] - 4.0, None, +1)
    pressure = _break(phis, m["pressure"])
    hexatic = np.array([np.interp(s, phis, h) if np.isfinite(s) else np.nan
                        for s, h in zip(star, m["hexatic"], strict=True)])  # fmt: skip
    cols = [first_crossing(phis, m["lambda"], None, 0), star, z,
            first_crossing(phis, m["z_frictional"] - 3.0, None, +1), pressure,
            _break(phis, m["overlap"]), hexatic, star - z, star - pressure]  # fmt: skip
    return np.stack(cols, axis=-1)


def transitions(phis, tables: list[Mapping], cfg: Mapping, suffix: str = "") -> list:
    """Ref. [20]'s transition and the cell's jamming point across φ (:data:`TRANSITIONS`),
    each with a percentile bootstrap that resamples every point's replicas at once, so
    that differences such as φ* − φ_J keep their correlation.

    Parameters
    ----------
    phis : (P,) increasing
    tables : P mappings of :data:`TABLE_KEYS` to (R_p,) per-replica means at each point
    cfg : ``bootstrap_resamples``, ``confidence``, ``seed``
    suffix : appended to each row's quantity (a variant's ``[name]``)

    A crossing is empty (NaN) where the quantity keeps its sign over the grid; a break
    needs five points with a positive mean.
    """
    phis = np.asarray(phis, dtype=np.float64)
    full = {k: np.array([[np.nanmean(t[k]) for t in tables]]) for k in TABLE_KEYS}
    values = _transition_values(phis, full)[0]
    n = int(cfg["bootstrap_resamples"])
    boot = None
    if n > 0 and len(phis) > 1 and all(len(t["lambda_all"]) > 1 for t in tables):
        rng = np.random.default_rng(int(cfg["seed"]))
        draws = [rng.integers(0, len(t["lambda_all"]), (n, len(t["lambda_all"])))
                 for t in tables]  # fmt: skip
        m = {k: np.stack([np.nanmean(np.asarray(t[k])[d], axis=1)
                          for t, d in zip(tables, draws, strict=True)], axis=1)
             for k in TABLE_KEYS}  # fmt: skip
        samples = _transition_values(phis, m)
        a = (1.0 - float(cfg["confidence"])) / 2.0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            lo, hi = np.nanquantile(samples, a, 0), np.nanquantile(samples, 1 - a, 0)
        boot = BootstrapResult(samples, lo, hi, float(cfg["confidence"]), n, len(phis),
                               np.isnan(samples).sum(0), int(cfg["seed"]))  # fmt: skip
    rows = []
    for c, (name, (unit, method)) in enumerate(TRANSITIONS.items()):
        res = FitResult(f"{name}{suffix}", float(values[c]), math.nan, unit, n=len(phis),
                        method=method)  # fmt: skip
        if boot is not None and np.isfinite(values[c]):
            res = res.with_ci(boot, c)
            res = dataclasses.replace(res, n=len(phis))
        rows.append(res)
    return rows
