"""Figures of the shear study (docs/shear.md, "Figures"): data in, Figure out.

* :func:`fig1_lambda_vs_phi` — ⟨λ⟩ (over disks with two contacts) and the maximal
  exponent (the whole tangent vector) against φ with their intervals, and the
  rearrangement rate (Ref. [20]'s chaotic-to-non-chaotic transition).
* :func:`fig2_event_triggered` — λ̄ averaged over the events, each replica aligned on its
  own, against t − t_event, one curve per φ (and the whole tangent vector's rate), with
  the count of events.
* :func:`fig3_contrast` — the drum paper's contrast: the shear cell's event-triggered λ̄
  beside the drum's λ̄ aligned on each pile's own onset of sustained flow, same law, same
  analysis (the drum's fits file, when the scale runs the drum), with what decides
  Ref. [20]'s claims written on it: φ* against φ_J, and the when-prediction's area.
* :func:`fig4_chaos_map` — where the chaos lives: the disks coloured by |δu_i| beside the
  same disks coloured by speed (the drum paper's Fig. 2 style), one replica.
* :func:`fig5_jamming` — is the transition the cell's jamming point: the maximal
  exponent, the contact number z, the pressure on the outer ring and the bulk |ψ6|
  against φ on one axis, with φ* and φ_J marked.
* :func:`fig6_prediction` — does the Lyapunov vector predict rearrangements: the ROC
  curves of "an event follows" from the finite-time exponent, their areas beside the
  baselines', and where: the precision of |δu_i| beside the speed's and a random choice's.
* :func:`fig7_variants` — what moves φ*: φ* and φ_J of each variant of the cell.

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

__all__ = ["fig1_lambda_vs_phi", "fig2_event_triggered", "fig3_contrast", "fig4_chaos_map",
           "fig5_jamming", "fig6_prediction", "fig7_variants"]  # fmt: skip


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


def _interval(row) -> str:
    """``0.883 [0.881, 0.885]`` of a FitResult, ``—`` when it has no value."""
    if row is None or not np.isfinite(row.value):
        return "—"
    ci = f" [{row.ci_low:.3f}, {row.ci_high:.3f}]" if np.isfinite(row.ci_low) else ""
    return f"{row.value:.3f}{ci}"


def fig3_contrast(shear: xr.Dataset, drum: xr.Dataset | None, transitions: list) -> plt.Figure:
    """The shear cell's λ̄ (over S, solid; the whole vector's rate, dashed) aligned on its
    rearrangements beside the drum's aligned on each pile's flow onset, and what decides
    Ref. [20]'s claims: φ* against φ_J, and how well λ_max before a moment predicts an
    event (the area under the ROC curve at this φ)."""
    fig, a = plt.subplots(figsize=(6.5, 4.4))
    lead, top = _v(shear, "lead_time"), _v(shear, "lambda_peak_time")
    crossing = f"lead {lead:.2f} s" if np.isfinite(lead) else "never > 0"
    a.plot(shear["tau"], shear["aligned_lambda_bar"], color="tab:purple",
           label=f"shear cell ({shear.attrs['point']}), aligned on rearrangements: "
           f"{crossing}, largest at {top:+.2f} s")  # fmt: skip
    a.plot(shear["tau_sample"], shear["aligned_lambda_all_bar"], color="tab:purple", ls="--",
           lw=0.9, label="shear cell, the whole tangent vector's rate λ_max")  # fmt: skip
    if drum is not None and "aligned_lambda_bar_onset" in drum:
        lag = _v(drum, "onset_lag_aligned")
        a.plot(drum["tau_onset"], drum["aligned_lambda_bar_onset"], color="tab:blue",
               label=f"drum, aligned on each pile's flow onset: crosses zero at "
               f"{lag:+.2f} s")  # fmt: skip
    a.axhline(0.0, color="0.5", lw=0.8)
    a.axvline(0.0, color="k", lw=0.8, ls=":")
    a.set(xlabel="time after the event [s]", ylabel="λ̄ [1/t0]",
          title="does λ lead the event (shear) or lag it (drum)?")  # fmt: skip
    a.legend(fontsize=7, loc="upper left")
    rows = {r.quantity: r for r in transitions}
    auc = (_v(shear, "when_auc_lambda_all"), _v(shear, "when_auc_lambda_all_ci_low"),
           _v(shear, "when_auc_lambda_all_ci_high"))  # fmt: skip
    a.text(0.99, 0.02, f"λ_max changes sign at φ* = {_interval(rows.get('phi_lambda_all_zero'))}\n"
           f"z = 4 at φ_J = {_interval(rows.get('phi_J_z_frictionless'))}; pressure leaves 0 "
           f"at {_interval(rows.get('phi_J_pressure'))}\n"
           f"when, at {shear.attrs['point']}: AUC of λ_max {auc[0]:.2f} [{auc[1]:.2f}, "
           f"{auc[2]:.2f}] (0.5: none)", transform=a.transAxes, ha="right", va="bottom",
           fontsize=7)  # fmt: skip
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


def _rows(fits: dict[str, xr.Dataset], q: str):
    """φ, value, and the interval's error bars of row ``q`` over the points."""
    phi = np.array([float(ds.attrs["phi"]) for ds in fits.values()])
    m = np.array([_v(ds, q) for ds in fits.values()])
    lo = np.array([_v(ds, f"{q}_ci_low") for ds in fits.values()])
    hi = np.array([_v(ds, f"{q}_ci_high") for ds in fits.values()])
    return phi, m, np.nan_to_num(np.abs(np.vstack([m - lo, hi - m])))


def _mark(ax, row, color, label):
    """A vertical line at a transition row's value and a band over its interval."""
    if row is None or not np.isfinite(row.value):
        return
    ax.axvline(row.value, color=color, lw=1.0, label=label)
    if np.isfinite(row.ci_low) and np.isfinite(row.ci_high):
        ax.axvspan(row.ci_low, row.ci_high, color=color, alpha=0.12, lw=0)


def fig5_jamming(fits: dict[str, xr.Dataset], transitions: list) -> plt.Figure:
    """The maximal exponent, z (both readings), the pressure and overlap, and |ψ6| against
    φ; φ* (black) and φ_J by pressure (red) and by z = 4 (blue) with their intervals."""
    rows = {r.quantity: r for r in transitions}
    fig, axes = plt.subplots(4, 1, figsize=(6, 9), sharex=True)
    phi, m, err = _rows(fits, "lambda_all_mean")
    axes[0].errorbar(phi, m, yerr=err, fmt="o-", capsize=3, label="maximal exponent")
    axes[0].axhline(0.0, color="0.5", lw=0.8)
    axes[0].set_ylabel("λ_max [1/t0]")
    for q, iso, label in (("z_frictionless", 4.0, "z, rattlers < 3 contacts"),
                          ("z_frictional", 3.0, "z, rattlers < 2 contacts")):  # fmt: skip
        phi, m, err = _rows(fits, q)
        (line,) = axes[1].plot(phi, m, "o-", label=label)
        axes[1].errorbar(phi, m, yerr=err, fmt="none", capsize=3, color=line.get_color())
        axes[1].axhline(iso, color=line.get_color(), lw=0.8, ls=":")
    axes[1].set_ylabel("contacts per non-rattler z")
    phi, m, err = _rows(fits, "pressure")
    axes[2].errorbar(phi, m, yerr=err, fmt="o-", capsize=3, color="tab:red",
                     label="pressure on the outer ring")  # fmt: skip
    axes[2].set(yscale="log", ylabel="P [m_s g/d_s]")
    twin = axes[2].twinx()
    phi, m, _ = _rows(fits, "overlap")
    twin.plot(phi, m, "s--", color="tab:orange", ms=4, label="mean overlap")
    twin.set(yscale="log", ylabel="mean overlap [d_s]")
    phi, m, err = _rows(fits, "hexatic")
    axes[3].errorbar(phi, m, yerr=err, fmt="o-", capsize=3, color="tab:green")
    axes[3].set(ylabel="bulk |ψ6|", xlabel="packing fraction φ", ylim=(0, 1))
    for ax in axes:
        _mark(ax, rows.get("phi_lambda_all_zero"), "k", "φ* (λ_max = 0)")
        _mark(ax, rows.get("phi_J_pressure"), "tab:red", "φ_J (pressure)")
        _mark(ax, rows.get("phi_J_z_frictionless"), "tab:blue", "φ_J (z = 4)")
    axes[0].legend(fontsize=7)
    axes[1].legend(fontsize=7)
    axes[0].set_title("the transition against the cell's jamming point")
    fig.tight_layout()
    return fig


def fig6_prediction(fits: dict[str, xr.Dataset]) -> plt.Figure:
    """When: the ROC curves of the finite-time maximal exponent per φ, and the areas of
    each predictor; where: the precision of |δu_i| at each event's size beside the
    speed's and a random choice's, and the areas over the disks."""
    fig, ((a, b), (c, d)) = plt.subplots(2, 2, figsize=(10, 7.5))
    for point, ds in fits.items():
        a.plot(ds["fpr"], ds["when_roc_lambda_all"], label=point)
    a.plot([0, 1], [0, 1], color="0.5", lw=0.8, ls=":")
    a.set(xlabel="false-positive rate", ylabel="true-positive rate",
          title="when: an event follows, from λ_max over the window before")  # fmt: skip
    a.legend(fontsize=7)
    for q, label in (("when_auc_lambda_all", "λ_max (whole vector)"),
                     ("when_auc_lambda", "λ over disks with ≥ 2 contacts"),
                     ("when_auc_speed", "V (baseline)")):  # fmt: skip
        phi, m, err = _rows(fits, q)
        b.errorbar(phi, m, yerr=err, fmt="o-", capsize=3, label=label)
    b.axhline(0.5, color="0.5", lw=0.8)
    b.set(xlabel="packing fraction φ", ylabel="area under the ROC curve", title="when")
    b.legend(fontsize=7)
    for q, label in (("where_precision_du", "|δu_i|"), ("where_precision_speed", "|v_i|"),
                     ("where_precision_random", "random")):  # fmt: skip
        phi, m, err = _rows(fits, q)
        c.errorbar(phi, m, yerr=err, fmt="o-", capsize=3, label=label)
    c.set(xlabel="packing fraction φ", ylabel="precision at the event's size",
          title="where: the disks that rearrange")  # fmt: skip
    c.legend(fontsize=7)
    for q, label in (("where_auc_du", "|δu_i|"), ("where_auc_speed", "|v_i|")):
        phi, m, err = _rows(fits, q)
        d.errorbar(phi, m, yerr=err, fmt="o-", capsize=3, label=label)
    d.axhline(0.5, color="0.5", lw=0.8)
    d.set(xlabel="packing fraction φ", ylabel="area under the ROC curve (disks)",
          title="where")  # fmt: skip
    d.legend(fontsize=7)
    fig.tight_layout()
    return fig


def fig7_variants(transitions: dict[str, list]) -> plt.Figure:
    """φ* and φ_J (pressure; z = 4) of each variant (``""`` the base cell), with their
    intervals, one row per variant."""
    names = list(transitions)
    fig, ax = plt.subplots(figsize=(6.5, 0.6 * len(names) + 1.6))
    marks = (("phi_lambda_all_zero", "k", "o", "φ* (λ_max = 0)"),
             ("phi_J_pressure", "tab:red", "s", "φ_J (pressure)"),
             ("phi_J_z_frictionless", "tab:blue", "^", "φ_J (z = 4)"))  # fmt: skip
    for k, (q, color, marker, label) in enumerate(marks):
        for y, name in enumerate(names):
            row = {r.quantity.split("[")[0]: r for r in transitions[name]}.get(q)
            if row is None or not np.isfinite(row.value):
                continue
            err = np.nan_to_num([[row.value - row.ci_low], [row.ci_high - row.value]])
            ax.errorbar(row.value, y + 0.15 * (k - 1), xerr=np.abs(err), fmt=marker,
                        color=color, capsize=3, label=label if y == 0 else None)  # fmt: skip
    ax.set_yticks(range(len(names)), [n or "base cell" for n in names])
    ax.set(xlabel="packing fraction φ", title="what moves the transition and the jamming point")
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    return fig
