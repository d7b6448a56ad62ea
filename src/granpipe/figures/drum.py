"""Figures of the drum study (Maghsoodi & Luijten 2016, Figs. 2-5): data in, Figure out.

* :func:`fig2_snapshot` — disks coloured by speed, before the onset and during the
  avalanche (one replica).
* :func:`fig3_onset` — ensemble-mean λ(t) (points), λ̄ (Eq. 2), low-pass, the linear fit
  of the sign change, and V(t) on a second axis, onset window.
* :func:`fig4_decay` — the same for the decay window (drum stopped at t = 5 s).
* :func:`fig5_lambda_vs_speed` — λ̄ against V for onset and decay, arrows along time.
* :func:`fig6_startup` — V(t) and λ̄(t) of each start-up (paper, settled) side by side.
* :func:`fig7_lag_vs_rotation` — onset and decay lags, with their CIs, against the
  drum's angular speed Ω (beyond the paper).
* :func:`fig8_friction` — V(t) and λ̄(t) of each friction law.
* :func:`fig9_aligned` — V and λ̄ averaged over replicas aligned on each pile's own onset
  of sustained flow (and stop of flow), against t − t_flow and against the tilt.

Inputs are the datasets the pipeline writes: the ensemble file (``reduce_runs``), the
fits file (fitted numbers plus the curves of ``drum_fits``) and a run file holding a
snapshot. :func:`save` writes ``fig<k>_<name>.png`` and ``.pdf`` atomically.
"""

from __future__ import annotations

from collections.abc import Mapping

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

from ..analysis.smoothing import moving_average  # noqa: E402
from . import disk_map  # noqa: E402

__all__ = [
    "fig2_snapshot",
    "fig3_onset",
    "fig4_decay",
    "fig5_lambda_vs_speed",
    "fig6_startup",
    "fig7_lag_vs_rotation",
    "fig8_friction",
    "fig9_aligned",
]

LAMBDA_COLOR = "tab:blue"
LAMBDA_BAR_COLOR = "#6baed6"
FIT_COLOR = "tab:orange"
SPEED_COLOR = "tab:red"


def _value(fits: xr.Dataset, name: str) -> float:
    return float(fits[name].values) if name in fits else np.nan


def _ci_text(fits: xr.Dataset, name: str) -> str:
    v = _value(fits, name)
    if not np.isfinite(v):
        return "n/a"
    e = _value(fits, f"{name}_fit_error")
    lo, hi = _value(fits, f"{name}_ci_low"), _value(fits, f"{name}_ci_high")
    txt = f"{v:.2f} ± {e:.2f} s" if np.isfinite(e) else f"{v:.2f} s"
    if np.isfinite(lo) and np.isfinite(hi):
        txt += f" [{lo:.2f}, {hi:.2f}]"
    return txt


def _window_plot(ens, fits, window: str, ax=None, mode: str = "config"):
    """λ points, λ̄, low-pass, fit segment(s) and V on a twin axis, for one window."""
    if ax is None:
        fig, ax = plt.subplots(figsize=(7.0, 4.8), layout="constrained")
    else:
        fig = ax.figure
    t = ens[f"seconds_{window}"].values
    lam = ens[f"lambda_{window}_mean"]
    ax.plot(t, lam.values, ".", ms=1.5, color=LAMBDA_COLOR, alpha=0.35, label="λ(t), ensemble mean")
    ax.plot(
        t,
        fits[f"lambda_bar_{window}"].values,
        "--",
        color=LAMBDA_BAR_COLOR,
        lw=1.8,
        label="λ̄(t), moving average (Eq. 2)",
    )
    ax.plot(
        t,
        fits[f"lambda_lowpass_{window}"].values,
        "-",
        color="k",
        lw=0.8,
        alpha=0.6,
        label="FFT low-pass",
    )
    for label, style in (("config", "-"), ("auto", ":")):
        name = f"fit_lambda_{window}_{label}"
        if name in fits and np.isfinite(fits[name].values).any():
            ax.plot(
                t,
                fits[name].values,
                style,
                color=FIT_COLOR,
                lw=3 if label == "config" else 2,
                label=f"linear fit ({label} window)",
            )
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xlabel("t [s]")
    ax.set_ylabel(f"λ [{lam.attrs.get('units', '')}]", color=LAMBDA_COLOR)
    # λ block means are noisy: scale the axis to the smoothed curve, not the outliers.
    lb = fits[f"lambda_bar_{window}"].values
    if np.isfinite(lb).any():
        lo, hi = np.nanmin(lb), np.nanmax(lb)
        pad = 1.5 * max(hi - lo, 1e-12)
        ax.set_ylim(min(lo - pad, -0.1 * pad), max(hi + pad, 0.1 * pad))
    ax2 = ax.twinx()
    V = ens[f"speed_{window}_mean"]
    ax2.plot(t, V.values, "-.", color=SPEED_COLOR, lw=1.4, label="V(t)")
    if window == "onset":
        for label, style in (("config", "-"), ("auto", ":")):
            name = f"fit_speed_onset_{label}"
            if name in fits and np.isfinite(fits[name].values).any():
                ax2.plot(t, fits[name].values, style, color="darkred", lw=2.5, alpha=0.7,
                         label=f"quadratic fit of V ({label} window)")  # fmt: skip
    ax2.set_ylabel(f"V [{V.attrs.get('units', '')}]", color=SPEED_COLOR)
    # the change of V is a few tens of per cent over rigid rotation: zoom on it
    finite = V.values[np.isfinite(V.values)]
    if finite.size:
        lo, hi = np.percentile(finite, [1.0, 99.0])
        ax2.set_ylim(max(0.0, lo - 0.3 * (hi - lo)), hi + 0.3 * (hi - lo))
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    fig.legend(h1 + h2, l1 + l2, fontsize=7, loc="outside lower center", ncol=3, frameon=False)
    ax.set_xlim(t[0], t[-1])
    return fig, ax, ax2


def fig3_onset(ens: xr.Dataset, fits: xr.Dataset) -> plt.Figure:
    """Fig. 3: chaotic behaviour at avalanche onset (paper: onset 2.628 s, sign change 14.5 s)."""
    fig, ax, _ = _window_plot(ens, fits, "onset")
    t_on = _value(fits, "onset_time")
    t_auto = _value(fits, "onset_time_auto")
    t_sc = _value(fits, "onset_sign_change_time")
    for x, ls in ((t_on, ":"), (t_auto, ":"), (t_sc, "--")):
        if np.isfinite(x):
            ax.axvline(x, color="0.3", ls=ls, lw=0.8)
    n = int(ens.attrs.get("n_replicas", 0))
    refused = "" if np.isfinite(t_on) else " (no minimum in the paper's window)"
    ax.set_title(
        f"Avalanche onset ({n} replicas): onset {_ci_text(fits, 'onset_time')}{refused}, "
        f"automatic {_ci_text(fits, 'onset_time_auto')};\n"
        f"sign change {_ci_text(fits, 'onset_sign_change_time')}, "
        f"lag (automatic onset) {_ci_text(fits, 'onset_lag_auto')}",
        fontsize=8,
    )
    return fig


def fig4_decay(ens: xr.Dataset, fits: xr.Dataset) -> plt.Figure:
    """Fig. 4: dynamics at avalanche decay (drum stopped at 5 s; paper: sign change 8.13 s)."""
    fig, ax, _ = _window_plot(ens, fits, "decay")
    stop = float(ens.attrs.get("stop_time_s", np.nan))
    if np.isfinite(stop):
        ax.axvline(stop, color="0.3", ls=":", lw=0.8)
    t_sc = _value(fits, "decay_sign_change_time")
    if np.isfinite(t_sc):
        ax.axvline(t_sc, color="0.3", ls="--", lw=0.8)
    n = int(ens.attrs.get("n_replicas", 0))
    ax.set_title(
        f"Avalanche decay ({n} replicas): drum stopped at {stop:.2f} s, "
        f"sign change {_ci_text(fits, 'decay_sign_change_time')}",
        fontsize=8,
    )
    return fig


def _arrows(ax, x, y, color, n_arrows=6):
    good = np.flatnonzero(np.isfinite(x) & np.isfinite(y))
    if len(good) < 4:
        return
    idx = good[np.linspace(0, len(good) - 2, n_arrows + 2).astype(int)[1:-1]]
    step = max(1, len(good) // 100)
    for i in idx:
        j = min(i + step, good[-1])
        ax.annotate(
            "",
            xy=(x[j], y[j]),
            xytext=(x[i], y[i]),
            arrowprops=dict(arrowstyle="-|>", color=color, lw=1.2, mutation_scale=14),
        )


def fig5_lambda_vs_speed(ens: xr.Dataset, fits: xr.Dataset) -> plt.Figure:
    """Fig. 5: λ̄ against V(t), onset (red) and decay (blue); arrows show time's direction.

    V is smoothed with the same moving average as λ̄ so both curves have one resolution.
    """
    q = int(fits.attrs.get("moving_average_q", 0))
    fig, ax = plt.subplots(figsize=(5.5, 4.2), layout="constrained")
    for w, color in (("onset", "tab:red"), ("decay", "tab:blue")):
        V = moving_average(ens[f"speed_{w}_mean"].values, q)
        lb = fits[f"lambda_bar_{w}"].values
        ax.plot(V, lb, "-", color=color, lw=1.5, label=w)
        _arrows(ax, V, lb, color)
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xlabel(f"V [{ens['speed_onset_mean'].attrs.get('units', '')}]")
    ax.set_ylabel(f"λ̄ [{ens['lambda_onset_mean'].attrs.get('units', '')}]")
    ax.legend(title="avalanche", fontsize=8)
    return fig


_POINT_KEYS = ("period_s", "startup", "friction", "gamma_t")
"""The keys that make a parameter point (``granpipe.drum.layout.POINT_KEYS``)."""


def _same(points: dict, key: str) -> dict:
    """The points that share the reference point's value of every point key but ``key``."""
    items = list(points.items())
    ref = items[0][1]
    others = [k for k in _POINT_KEYS if k != key]
    return {n: p for n, p in items if all(p.get(k) == ref.get(k) for k in others)}


def _compare(points: dict, key: str, colors: dict, title: str) -> plt.Figure:
    """V(t) and λ̄(t) of the onset and decay windows of the points that differ from the
    reference point in ``key`` only (one curve per value of ``key``)."""
    chosen = _same(points, key)
    fig, axes = plt.subplots(2, 2, figsize=(10.0, 6.4), layout="constrained", sharex="col")
    for p in chosen.values():
        ens, fit, lab = p["ensemble"], p["fits"], p["label"]
        q = int(fit.attrs.get("moving_average_q", 0))
        n = int(ens.attrs.get("n_replicas", 0))
        c = colors.get(p[key], None)
        for j, w in enumerate(("onset", "decay")):
            t = ens[f"seconds_{w}"].values
            V = moving_average(ens[f"speed_{w}_mean"].values, max(1, q // 5))
            axes[0, j].plot(t, V, "-", color=c, lw=1.2, label=f"{p[key]} ({n} replicas)")
            axes[1, j].plot(t, fit[f"lambda_bar_{w}"].values, "-", color=c, lw=1.5)
            if w == "onset":
                t_on = _value(fit, f"onset_time_auto{lab}")
                if np.isfinite(t_on):
                    axes[0, 0].axvline(t_on, color=c, ls=":", lw=1.0)
    for j, w in enumerate(("onset", "decay")):
        axes[0, j].set_ylabel("V [d_s/t0]")
        axes[0, j].set_ylim(bottom=0)
        axes[1, j].set_ylabel("λ̄ [1/t0]")
        axes[1, j].axhline(0.0, color="0.5", lw=0.6)
        axes[1, j].set_xlabel(f"t [s], {w} window")
    axes[0, 0].legend(title=title, fontsize=8)
    axes[0, 0].set_title("onset window (dotted: automatic onset time)", fontsize=9)
    axes[0, 1].set_title("decay window (drum stopped at 5 s)", fontsize=9)
    return fig


def fig6_startup(points: dict) -> plt.Figure:
    """V(t) and λ̄(t) of the onset and decay windows for each start-up at the reference
    period and friction law: the paper's (disks fall in the turning drum) and the
    settled pile.

    ``points``: ``{name: {"period_s", "startup", "friction", "label", "ensemble",
    "fits"}}``, the reference point first (:func:`granpipe.drum.stages.figures_stage`).
    """
    return _compare(points, "startup", {"paper": "tab:red", "settled": "tab:gray"}, "start-up")


def fig8_friction(points: dict) -> plt.Figure:
    """V(t) and λ̄(t) of the onset and decay windows for each friction law at the
    reference period and start-up: the paper's Eq. (1) (viscous) and static friction
    (docs/drum.md, "Static friction"). Arguments as :func:`fig6_startup`."""
    return _compare(points, "friction", {"viscous": "tab:red", "static": "tab:green"},
                    "friction")  # fmt: skip


def fig7_lag_vs_rotation(
    points: dict, paper: Mapping[str, float], undetermined_width: float = 20.0
) -> plt.Figure:
    """Onset and decay lags (sign change of λ minus change of avalanche state) against the
    drum's angular speed Ω, with their bootstrap intervals; the paper's lags at 900 s
    (``paper["onset_lag"]``, ``paper["decay_lag"]`` [s]).

    A lag whose interval is wider than ``undetermined_width`` [s], or that has no value
    (no minimum, no lasting sign change), is not a measurement: it is marked at the
    bottom of the axis as undetermined instead of stretching the axis.
    """
    chosen = _same(points, "period_s")
    fig, ax = plt.subplots(figsize=(6.4, 4.6), layout="constrained")
    y_lo, y_hi = -5.0, 30.0
    for kind, color, dx in (("onset_lag", "tab:red", 0.98), ("decay_lag", "tab:blue", 1.02)):
        for suffix, mfc in (("_auto", color), ("", "white")):
            window = "automatic windows" if suffix else "paper's windows"
            label = f"{kind.split('_')[0]}, {window}"
            for p in chosen.values():
                name = f"{kind}{suffix}{p['label']}"
                om = 2.0 * np.pi / float(p["period_s"]) * dx * (1.0 if suffix else 1.03)
                v = _value(p["fits"], name)
                lo, hi = _value(p["fits"], f"{name}_ci_low"), _value(p["fits"], f"{name}_ci_high")
                if not (np.isfinite(v) and np.isfinite(lo) and np.isfinite(hi)) or (
                    hi - lo > undetermined_width
                ):
                    ax.plot([om], [y_lo + 1.0], "x", color=color, ms=7)
                    continue
                ax.errorbar([om], [v], yerr=[[v - lo], [hi - v]], fmt="o", color=color,
                            mfc=mfc, capsize=3, label=label)  # fmt: skip
                label = None
        ax.plot([2.0 * np.pi / 900.0], [paper[kind]], "*", color=color, ms=12, mec="k",
                label=f"{kind.split('_')[0]}, paper (900 s)")  # fmt: skip
    ax.plot([], [], "x", color="0.3", label="undetermined (no value, or CI > "
            f"{undetermined_width:g} s)")  # fmt: skip
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xscale("log")
    ax.set_ylim(y_lo, y_hi)
    ax.set_xlabel("Ω [rad/s]")
    ax.set_ylabel("lag [s]")
    ax.set_title("lag of the λ sign change behind the avalanche state (95 % CIs)", fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    return fig


def fig2_snapshot(run: xr.Dataset) -> plt.Figure:
    """Fig. 2-style snapshots of one replica, disks coloured by speed (blue slow, red fast);
    beyond the paper, a second row with the same disks coloured by their part of the
    Lyapunov vector |δu_i| (where the chaos lives), when the run file holds it.

    Parameters
    ----------
    run : a run file holding ``snapshot_position``/``snapshot_velocity``
        (snapshot, particle, xy), ``diameter`` (particle), ``wall_position``
        (snapshot, wall, xy), ``wall_diameter`` and optionally ``snapshot_du``.
    """
    snaps = list(run["snapshot"].values)
    du = run["snapshot_du"].values if "snapshot_du" in run else None
    rows = 2 if du is not None and np.isfinite(du).any() else 1
    fig, axes = plt.subplots(rows, len(snaps), figsize=(4.6 * len(snaps), 4.4 * rows),
                             layout="constrained", squeeze=False)  # fmt: skip
    d = run["diameter"].values
    dw = float(run["wall_diameter"].values)
    titles = run["snapshot"].attrs.get("descriptions", "").split(";")
    units = run["snapshot_velocity"].attrs.get("units", "")
    for k in range(len(snaps)):
        pos = run["snapshot_position"].values[k]
        vel = run["snapshot_velocity"].values[k]
        wall = run["wall_position"].values[k]
        label = f"({'abcdefgh'[k]}) " + (titles[k] if k < len(titles) and titles[k] else snaps[k])
        disk_map(axes[0, k], pos, d, np.hypot(vel[:, 0], vel[:, 1]), label=f"speed [{units}]",
                 walls=wall, wall_diameter=dw)  # fmt: skip
        axes[0, k].set_title(label, fontsize=8)
        if rows == 2:
            disk_map(axes[1, k], pos, d, du[k], cmap="magma", vmax=1.0, walls=wall,
                     wall_diameter=dw, label="|δu_i| / largest")  # fmt: skip
            axes[1, k].set_title(f"{label}: the Lyapunov vector", fontsize=8)
    return fig


def fig9_aligned(ens: xr.Dataset, fits: xr.Dataset) -> plt.Figure:
    """V and λ̄ averaged over the replicas aligned on each one's own onset of sustained
    flow (against t − t_flow, with the replicas contributing at each offset), against the
    pile's tilt, and for the decay aligned on each pile's own stop of flow; beside them,
    the paper-style ensemble means (plain, at fixed t), shifted by the mean t_flow.

    ``fits`` is a fits file with the pile's curves (:func:`granpipe.drum.fits.pile_fits`);
    without them the figure says that the run files hold no pile samples.
    """
    fig, axes = plt.subplots(2, 3, figsize=(13.0, 6.8), layout="constrained")
    if "aligned_speed_onset" not in fits:
        for ax in axes.flat:
            ax.set_axis_off()
        axes[0, 0].text(0.0, 0.5, "the run files hold no samples of the pile's state",
                        transform=axes[0, 0].transAxes)  # fmt: skip
        return fig
    q = int(fits.attrs.get("moving_average_q", 0))
    t_flow = _value(fits, "flow_onset_time")
    n_rep = int(ens.attrs.get("n_replicas", 0))
    label = fits.attrs.get("label", "")
    tau = fits["tau_onset"].values
    count = fits["aligned_count_onset"].values
    Va = moving_average(fits["aligned_speed_onset"].values, max(1, q // 5))
    lb = fits["aligned_lambda_bar_onset"].values
    tilt_a = fits["aligned_tilt_onset"].values
    t = ens["seconds_onset"].values
    Vp = moving_average(ens["speed_onset_mean"].values, max(1, q // 5))
    lbp = fits["lambda_bar_onset"].values
    tilt_p = fits["tilt_onset_mean"].values
    lag = _value(fits, f"onset_lag_aligned{label}")
    n_flow = int(np.isfinite(fits["replica_flow_onset"].values).sum())

    ax = axes[0, 0]
    ax.plot(tau, Va, color=SPEED_COLOR, lw=1.3, label=f"aligned on t_flow ({n_flow} replicas)")
    ax.plot(t - t_flow, Vp, color=SPEED_COLOR, lw=1.0, ls=":",
            label=f"ensemble at fixed t ({n_rep}), shifted by mean t_flow")  # fmt: skip
    ax.set_ylabel("V [d_s/t0]")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7, loc="upper left")
    ax.set_title(f"onset: mean t_flow = {_ci_text(fits, 'flow_onset_time')}", fontsize=9)
    twin = ax.twinx()
    twin.plot(tau, count, color="0.5", lw=0.8)
    twin.set_ylabel("replicas contributing", color="0.4")
    twin.set_ylim(0, max(1.0, float(np.nanmax(count))) * 3.0)
    ax = axes[1, 0]
    ax.plot(tau, lb, color=LAMBDA_BAR_COLOR, lw=1.6, label="λ̄, aligned")
    ax.plot(t - t_flow, lbp, color=LAMBDA_BAR_COLOR, lw=1.0, ls=":", label="λ̄, ensemble")
    if np.isfinite(lag):
        ax.axvline(lag, color=FIT_COLOR, lw=1.0, ls="--",
                   label=f"aligned lag {_ci_text(fits, f'onset_lag_aligned{label}')}")  # fmt: skip
    ax.axvline(0.0, color="k", lw=0.6)
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xlabel("t − t_flow [s] (each replica's own onset of sustained flow)")
    ax.set_ylabel("λ̄ [1/t0]")
    ax.legend(fontsize=7, loc="upper left")

    ax = axes[0, 1]
    ax.plot(tilt_a, Va, color=SPEED_COLOR, lw=1.3, label="aligned")
    ax.plot(tilt_p, Vp, color=SPEED_COLOR, lw=1.0, ls=":", label="ensemble at fixed t")
    tf = _value(fits, "flow_onset_tilt")
    if np.isfinite(tf):
        ax.axvline(tf, color="k", lw=0.6, label=f"mean flow tilt {tf:.1f}°")
    ax.set_ylabel("V [d_s/t0]")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7, loc="upper left")
    ax.set_title("against the tilt of the pile's surface", fontsize=9)
    ax = axes[1, 1]
    ax.plot(tilt_a, lb, color=LAMBDA_BAR_COLOR, lw=1.6, label="aligned")
    ax.plot(tilt_p, lbp, color=LAMBDA_BAR_COLOR, lw=1.0, ls=":", label="ensemble at fixed t")
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xlabel("tilt [degree] (mean over the replicas, aligned or at fixed t)")
    ax.set_ylabel("λ̄ [1/t0]")
    ax.legend(fontsize=7, loc="upper left")

    if "tau_decay" in fits:
        tau_d = fits["tau_decay"].values
        ax = axes[0, 2]
        ax.plot(tau_d, moving_average(fits["aligned_speed_decay"].values, max(1, q // 5)),
                color=SPEED_COLOR, lw=1.3)  # fmt: skip
        ax.set_ylabel("V [d_s/t0]")
        ax.set_ylim(bottom=0)
        ax.set_title(f"decay: flow stops {_ci_text(fits, 'decay_flow_stop_time')} after the "
                     "drum", fontsize=9)  # fmt: skip
        twin = ax.twinx()
        twin.plot(tau_d, fits["aligned_count_decay"].values, color="0.5", lw=0.8)
        twin.set_ylabel("replicas contributing", color="0.4")
        twin.set_ylim(0, max(1.0, float(np.nanmax(fits["aligned_count_decay"].values))) * 3.0)
        ax = axes[1, 2]
        ax.plot(tau_d, fits["aligned_lambda_bar_decay"].values, color=LAMBDA_BAR_COLOR, lw=1.6)
        lag_d = _value(fits, f"decay_lag_aligned{label}")
        if np.isfinite(lag_d):
            ax.axvline(
                lag_d,
                color=FIT_COLOR,
                lw=1.0,
                ls="--",
                label=f"aligned lag {_ci_text(fits, f'decay_lag_aligned{label}')}",
            )
            ax.legend(fontsize=7, loc="upper right")  # fmt: skip
        ax.axvline(0.0, color="k", lw=0.6)
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.set_xlabel("t − t_stop [s] (each replica's own stop of flow)")
        ax.set_ylabel("λ̄ [1/t0]")
    return fig
