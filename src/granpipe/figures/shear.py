"""Figures of the shear study (docs/shear.md, "Figures"): data in, Figure out.

* :func:`fig1_lambda_vs_phi` — ⟨λ⟩ (over disks with two contacts) and the maximal
  exponent (the whole tangent vector) against φ with their intervals, and the
  rearrangement rate (Ref. [20]'s chaotic-to-non-chaotic transition).
* :func:`fig2_event_triggered` — λ̄ averaged over the events, each replica aligned on its
  own, against t − t_event, one curve per φ (and the whole tangent vector's rate), with
  the count of events.
* :func:`fig3_contrast` — the drum paper's contrast: the shear cell's event-triggered λ̄
  beside the drum's λ̄ aligned on each pile's own onset of sustained flow, same law, same
  analysis (the drum's fits file, when the scale runs the drum).
* :func:`fig4_chaos_map` — where the chaos lives: the disks coloured by |δu_i| beside the
  same disks coloured by speed (the drum paper's Fig. 2 style), one replica.

Inputs are the fits files (``granpipe.shear.fits``); the stage writes PNG and PDF through
:func:`granpipe.figures.save_figure`.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

from . import disk_map  # noqa: E402

__all__ = ["fig1_lambda_vs_phi", "fig2_event_triggered", "fig3_contrast", "fig4_chaos_map"]


def _v(ds, name):
    return float(ds[name].values) if name in ds else np.nan


def fig1_lambda_vs_phi(fits: dict[str, xr.Dataset]) -> plt.Figure:
    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.6))
    phi = np.array([float(ds.attrs["phi"]) for ds in fits.values()])
    for q, label in (("lambda_mean", "λ(t) over disks with ≥ 2 contacts (drum paper)"),
                     ("lambda_all_mean", "whole tangent vector (rattlers included)")):  # fmt: skip
        m = np.array([_v(ds, q) for ds in fits.values()])
        lo = np.array([_v(ds, f"{q}_ci_low") for ds in fits.values()])
        hi = np.array([_v(ds, f"{q}_ci_high") for ds in fits.values()])
        err = np.nan_to_num(np.vstack([m - lo, hi - m]))
        a.errorbar(phi, m, yerr=err, fmt="o-", capsize=3, label=label)
    a.axhline(0.0, color="0.5", lw=0.8)
    a.legend(fontsize=7)
    a.set(xlabel="packing fraction φ", ylabel="⟨λ⟩ [1/t0]", title="time-averaged λ")
    rate = [_v(ds, "event_rate") for ds in fits.values()]
    b.plot(phi, rate, "s-", color="tab:green")
    b.set(xlabel="packing fraction φ", ylabel="events per replica and s",
          title="rearrangements")  # fmt: skip
    fig.tight_layout()
    return fig


def _minus_far(tau, y):
    """``y(tau)`` minus its mean where ``|tau|`` is at least half the window's reach."""
    return y - np.nanmean(np.where(np.abs(tau) >= 0.5 * np.abs(tau).max(), y, np.nan))


def fig2_event_triggered(fits: dict[str, xr.Dataset], min_events: int = 100) -> plt.Figure:
    """λ̄ aligned on the events minus its level far from them (|τ| ≥ half the window), per
    φ with at least ``min_events`` events (dashed: the same of the whole tangent vector's
    rate), and the events behind each τ."""
    fig, (a, b) = plt.subplots(2, 1, figsize=(6, 6), sharex=True,
                               gridspec_kw={"height_ratios": [3, 1]})  # fmt: skip
    for point, ds in fits.items():
        tau, lb = ds["tau"].values, ds["aligned_lambda_bar"].values
        if int(ds["event_lag"].attrs.get("n", 0)) < min_events:
            continue
        lead, top = _v(ds, "lead_time"), _v(ds, "lambda_peak_time")
        txt = f"{point}: " + (f"lead {lead:.2f} s, " if np.isfinite(lead) else "never > 0, ")
        (line,) = a.plot(tau, _minus_far(tau, lb), label=txt + f"largest at {top:+.2f} s")
        ts = ds["tau_sample"].values
        a.plot(ts, _minus_far(ts, ds["aligned_lambda_all_bar"].values), ls="--", lw=0.9,
               color=line.get_color())  # fmt: skip
        b.plot(tau, ds["aligned_count"], color=line.get_color())
    a.axhline(0.0, color="0.5", lw=0.8)
    a.axvline(0.0, color="k", lw=0.8, ls=":")
    a.set(ylabel="λ̄ − its level far from events [1/t0]",
          title=f"λ̄ aligned on each rearrangement (φ with ≥ {min_events} events)\n"
          "solid: over disks with ≥ 2 contacts; dashed: whole tangent vector")  # fmt: skip
    a.legend(fontsize=7)
    b.set(xlabel="t − t_event [s]", ylabel="events")
    fig.tight_layout()
    return fig


def fig3_contrast(shear: xr.Dataset, drum: xr.Dataset | None) -> plt.Figure:
    fig, a = plt.subplots(figsize=(6.5, 4))
    lead, top = _v(shear, "lead_time"), _v(shear, "lambda_peak_time")
    crossing = f"lead {lead:.2f} s" if np.isfinite(lead) else "never > 0"
    a.plot(shear["tau"], shear["aligned_lambda_bar"], color="tab:purple",
           label=f"shear cell ({shear.attrs['point']}), aligned on rearrangements: "
           f"{crossing}, largest at {top:+.2f} s")  # fmt: skip
    if drum is not None and "aligned_lambda_bar_onset" in drum:
        lag = _v(drum, "onset_lag_aligned")
        a.plot(drum["tau_onset"], drum["aligned_lambda_bar_onset"], color="tab:blue",
               label=f"drum, aligned on each pile's flow onset: crosses zero at "
               f"{lag:+.2f} s")  # fmt: skip
    a.axhline(0.0, color="0.5", lw=0.8)
    a.axvline(0.0, color="k", lw=0.8, ls=":")
    a.set(xlabel="time after the event [s]", ylabel="λ̄ [1/t0]",
          title="does λ lead the event (shear) or lag it (drum)?")  # fmt: skip
    a.legend(fontsize=7)
    fig.tight_layout()
    return fig


def fig4_chaos_map(fits: xr.Dataset) -> plt.Figure:
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.6), layout="constrained")
    xy = fits["snapshot_positions"].values
    d = fits["diameter"].values
    disk_map(axes[0], xy, d, fits["snapshot_du"].values, cmap="magma", vmax=1.0,
             label="|δu_i| / largest")  # fmt: skip
    disk_map(axes[1], xy, d, fits["snapshot_speed"].values, label="|v_i| [d_s/t0]")
    axes[0].set_title("the Lyapunov vector", fontsize=9)
    axes[1].set_title("speed", fontsize=9)
    fig.suptitle(f"where the chaos lives ({fits.attrs['point']}, one replica)")
    return fig
