"""Figures of the box study (Fortini & Huang 2015, Figs. 1, 3, 4, 5): data in, Figure out.

* :func:`fig1_snapshots` — disks coloured by local order (hexagonal, square, disordered).
* :func:`fig3_phase_diagram` — thresholds in Γ against N_l (bouncing by s_b, detachment,
  convection by s_c), both starts, K_m = Γ² on the right axis; the grid points behind.
* :func:`fig4_granular_temperature` — T_g* against K_m (log–log), one colour per N_l,
  segmented fits and their breakpoints (dashed) with intervals (shaded).
* :func:`fig5_slip_probability` — p_s against 1/K_m (log), Arrhenius fits per region,
  points without slips as upper bounds.
* :func:`fig6_walls` — (ours) the thresholds in Γ against the walls: against the side
  walls' Coulomb coefficient μ_w (one panel per N_l) when the grid has several, else
  against N_l; one line style per drive of the side walls and wall torque, the paper's
  thresholds as lines.
* :func:`fig7_onset_record` — (ours) the convection onset against the record it is
  measured over, by Eq. (B2) and by the roll criterion, and the roll score against Γ.

Figures 3–5 draw one wall setting (the stage picks Table I's μ_w = 0.6 with the whole box
shaken when the grid has it); crystal points whose crystal broke before measurement are
drawn as crosses and are not part of any fit.

Inputs are pandas tables built from the fits files (:func:`granpipe.box.stages.load_fits`)
and snapshots (positions + order codes). :func:`save` writes PNG and PDF atomically.
"""

from __future__ import annotations

import re
import textwrap

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.collections import EllipseCollection  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from ..analysis.regression import zero_count_upper_bound  # noqa: E402

__all__ = [
    "ORDER_COLORS",
    "fig1_snapshots",
    "fig3_phase_diagram",
    "fig4_granular_temperature",
    "fig5_slip_probability",
    "fig6_walls",
    "fig7_onset_record",
    "onset_records",
    "segmented_curve",
]

#: Fig. 1 colours: disordered, hexagonal (green), square (red).
ORDER_COLORS = {0: "#9e9ecb", 1: "#2ca02c", 2: "#d62728"}
INIT_MARKERS = {"random": "^", "crystal": "o"}
CRITERION_COLORS = {
    "bouncing": "tab:green",
    "detachment": "tab:olive",
    "convection": "tab:blue",
    "rolls": "tab:purple",
}


def _reading(fig, reading: str | None):
    """The record and the fit readings a figure shows, as a small title over it, wrapped
    to the figure's width (a wider title would squeeze the panels)."""
    if reading:
        width = max(40, int(fig.get_figwidth() * 18))  # characters of 7 pt per inch
        fig.suptitle(textwrap.fill(reading, width), fontsize=7, color="0.3")


def _nl_colors(n_ls):
    cmap = plt.get_cmap("viridis")
    n_ls = sorted(set(int(n) for n in n_ls))
    return {n: cmap(i / max(len(n_ls) - 1, 1) * 0.85) for i, n in enumerate(n_ls)}


def fig1_snapshots(panels: list[dict], lx: float = 20.0):
    """Snapshots coloured by local order (Fig. 1).

    Parameters
    ----------
    panels : list of dict
        Each with ``title`` (str), ``positions`` (N, 2) [σ], ``order`` (N,) int codes
        (0 disordered, 1 hexagonal, 2 square), optional ``z_plate`` [σ].
    lx : float [σ]
        Box width (side walls drawn at 0 and lx).
    """
    n = len(panels)
    height = max(float(np.max(p["positions"][:, 1])) for p in panels) + 1.0
    fig, axes = plt.subplots(
        1, n, figsize=(2.3 * n + 0.6, 0.8 + 2.3 * height / lx), layout="constrained",
        squeeze=False,
    )  # fmt: skip
    for ax, p in zip(axes[0], panels, strict=True):
        pos = np.asarray(p["positions"], dtype=float)
        order = np.asarray(p["order"], dtype=int)
        zb = float(p.get("z_plate", min(0.0, pos[:, 1].min() - 0.5)))
        colors = [ORDER_COLORS.get(int(o), "grey") for o in order]
        ax.add_collection(
            EllipseCollection(
                np.ones(len(pos)), np.ones(len(pos)), np.zeros(len(pos)), units="xy",
                offsets=pos, offset_transform=ax.transData, facecolors=colors,
                edgecolors="k", linewidths=0.15,
            )
        )  # fmt: skip
        ax.plot([0, 0], [zb, height], "k-", lw=1)
        ax.plot([lx, lx], [zb, height], "k-", lw=1)
        ax.plot([0, lx], [zb, zb], "k-", lw=2)
        ax.set_xlim(-0.5, lx + 0.5)
        ax.set_ylim(zb - 0.5, height)
        ax.set_aspect("equal")
        ax.set_xticks([0, lx / 2, lx])
        ax.set_title(p["title"], fontsize=8)
        frac = np.bincount(order, minlength=3) / max(len(order), 1)
        ax.set_xlabel(f"hex {frac[1]:.2f}, sq {frac[2]:.2f}, dis {frac[0]:.2f}", fontsize=7)
    axes[0][0].set_ylabel("z / σ")
    handles = [
        Line2D([], [], marker="o", ls="", mfc=ORDER_COLORS[k], mec="k", label=lab)
        for k, lab in ((1, "hexagonal"), (2, "square"), (0, "disordered"))
    ]
    fig.legend(handles=handles, loc="outside lower center", ncol=3, fontsize=8)
    return fig


def _beyond_grid(ax, x, lo, hi, status, marker, color, fill, *, ms, step):
    """Thresholds outside the grid: the marker at the grid end (``lo`` for above, ``hi``
    for below) with an arrow of length ``step`` beyond it."""
    for xi, l_, h_, st in zip(x, lo, hi, status, strict=True):
        edge, d = (l_, step) if st == "above_grid" else (h_, -step)
        if st in ("above_grid", "below_grid") and np.isfinite(edge):
            ax.plot([xi], [edge], marker, color=color, fillstyle=fill, ms=ms, zorder=3)
            ax.annotate("", (xi, edge + d), (xi, edge),
                        arrowprops={"arrowstyle": "->", "color": color})  # fmt: skip


def fig3_phase_diagram(points: pd.DataFrame, thresholds: pd.DataFrame, reading: str | None = None):
    """Dynamical phase diagram (Fig. 3): thresholds in Γ against N_l, K_m on the right.

    Parameters
    ----------
    points : DataFrame
        Columns N_l, Gamma, init, bouncing, detached, convection (flags per grid point).
    thresholds : DataFrame
        Columns init, N_l, criterion, Gamma, Gamma_low, Gamma_high, status.
    reading : str, optional
        The record and the criteria behind it, drawn over the figure.
    """
    fig, ax = plt.subplots(figsize=(8.0, 4.6), layout="constrained")
    _reading(fig, reading)
    offsets = {"random": -0.6, "crystal": 0.6}
    # grid points: phase found at each (N_l, Γ)
    for init, g in points.groupby("init"):
        x = g["N_l"].to_numpy(float) + 1.6 * offsets.get(init, 0.0)
        phase = np.where(g["convection"] > 0, 2, np.where(g["bouncing"] > 0, 1, 0))
        for code, face in ((0, "none"), (1, "0.6"), (2, "k")):
            m = phase == code
            ax.scatter(x[m], g["Gamma"].to_numpy()[m], s=9, marker="s", facecolors=face,
                       edgecolors="0.5", linewidths=0.5, zorder=1)  # fmt: skip
    for (init, crit), g in thresholds.groupby(["init", "criterion"]):
        g = g.sort_values("N_l")
        x = g["N_l"].to_numpy(float) + offsets.get(init, 0.0)
        y = g["Gamma"].to_numpy(float)
        lo = g["Gamma_low"].to_numpy(float)
        hi = g["Gamma_high"].to_numpy(float)
        color = CRITERION_COLORS.get(crit, "k")
        fill = "full" if init == "random" else "none"
        ok = np.isfinite(y)
        ax.errorbar(
            x[ok], y[ok], yerr=[y[ok] - lo[ok], hi[ok] - y[ok]], fmt=INIT_MARKERS.get(init, "o"),
            color=color, fillstyle=fill, ms=7, capsize=3, lw=1, ls="-" if ok.sum() > 1 else "",
            label=f"{crit}, {init}", zorder=3,
        )  # fmt: skip
        _beyond_grid(ax, x, lo, hi, g["status"], INIT_MARKERS.get(init, "o"), color, fill,
                     ms=7, step=0.2)  # fmt: skip
    ax.axhline(1.0, color="0.7", lw=0.8, ls=":")
    n_ls = points["N_l"].to_numpy(float)
    ax.set_xlim(n_ls.min() - 5.0, n_ls.max() + 5.0)
    g_all = points["Gamma"].to_numpy(float)
    ax.set_ylim(max(0.0, g_all.min() - 0.35), g_all.max() + 0.35)
    ax.set_xlabel(r"$N_l\,\sigma$")
    ax.set_ylabel(r"$\Gamma$")
    sec = ax.secondary_yaxis(
        "right", functions=(lambda g: np.square(g), lambda k: np.sqrt(np.clip(k, 0, None)))
    )
    sec.set_ylabel(r"$K_m = \Gamma^2$")
    fig.legend(fontsize=7, loc="outside right upper", title="thresholds (arrows: beyond the\n"
               "grid); squares: grid points\n(open comoving, grey bouncing,\nblack convective)",
               title_fontsize=7)  # fmt: skip
    return fig


def segmented_curve(x_log: np.ndarray, intercept: float, slopes, breakpoints_log):
    """y = a + b x + Σ c_k (x − ψ_k)₊ from intercept, per-segment slopes and breakpoints."""
    slopes = np.asarray(slopes, dtype=float)
    psi = np.asarray(breakpoints_log, dtype=float)
    y = intercept + slopes[0] * x_log
    for k, p in enumerate(psi):
        y = y + (slopes[k + 1] - slopes[k]) * np.clip(x_log - p, 0, None)
    return y


def _fitted(temperature, init, n_l):
    """A group's rows of the temperature fit that hold a value (none where it was refused)."""
    t = temperature
    return t[(t["init"] == init) & (t["N_l"] == n_l) & np.isfinite(t["value"])]


def _split_broken(g: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(points used by the fits, crystal points left out because their crystal broke),
    by the points table's ``fitted`` column."""
    used = g["fitted"].astype(bool)
    return g[used], g[~used]


def _finish_panel(ax, init: str, inits: list, points: pd.DataFrame, xlabel: str, ylabel: str):
    """A panel of Figs. 4 and 5: logarithmic p_s or T_g* axis, labels, the start's title
    ((a) or (b)), its legend and the note on crystals broken before measurement."""
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(f"({'ab'[inits.index(init)]}) {init} start", fontsize=9)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    _broken_note(ax, points[points["init"] == init])


def _broken_note(ax, points: pd.DataFrame) -> None:
    if not points["fitted"].astype(bool).all():
        ax.text(0.98, 0.02, "×: crystal broken before measurement\n(not fitted)",
                transform=ax.transAxes, ha="right", va="bottom", fontsize=7)  # fmt: skip


def _panels(inits):
    fig, axes = plt.subplots(1, len(inits), figsize=(4.2 * len(inits), 3.8),
                             layout="constrained", squeeze=False)  # fmt: skip
    return fig, dict(zip(inits, axes[0], strict=True))


def fig4_granular_temperature(
    points: pd.DataFrame, temperature: pd.DataFrame, fit_n_l: int, reading: str | None = None
):
    """T_g* against K_m (Fig. 4): (a) random, (b) crystal.

    Parameters
    ----------
    points : DataFrame with N_l, init, K_m, T_g, T_g_sem
    temperature : DataFrame with init, N_l, name (``breakpoint``, ``slope_<region>``,
        ``intercept``), index, value, ci_low, ci_high
    fit_n_l : int
        Linear density whose breakpoints are drawn as dashed lines.
    reading : str, optional
        The record and the points fitted, drawn over the figure.
    """
    inits = [i for i in ("random", "crystal") if i in set(points["init"])]
    fig, axes = _panels(inits)
    _reading(fig, reading)
    colors = _nl_colors(points["N_l"])
    for init, ax in axes.items():
        for n_l, g in points[points["init"] == init].groupby("N_l"):
            g, broken = _split_broken(g.sort_values("K_m"))
            ok = g["T_g"] > 0
            ax.errorbar(g["K_m"][ok], g["T_g"][ok], yerr=g["T_g_sem"][ok].fillna(0), fmt="o",
                        ms=4, color=colors[int(n_l)], label=f"$N_l$ = {int(n_l)}")  # fmt: skip
            ax.plot(broken["K_m"], broken["T_g"], "x", ms=5, color=colors[int(n_l)])
            t = _fitted(temperature, init, n_l)
            if t.empty or not ok.any():
                continue
            bps = t[t["name"] == "breakpoint"].sort_values("index")
            slopes = t[t["name"].str.startswith("slope_")].sort_values("index")
            a = float(t[t["name"] == "intercept"]["value"].iloc[0])
            x = np.linspace(np.log(g["K_m"][ok].min()), np.log(g["K_m"][ok].max()), 200)
            y = segmented_curve(x, a, slopes["value"], np.log(bps["value"]))
            ax.plot(np.exp(x), np.exp(y), "-", color=colors[int(n_l)], lw=1)
            if int(n_l) == int(fit_n_l):
                names = [s.removeprefix("slope_") for s in slopes["name"]]
                for b in bps.itertuples():
                    ax.axvline(b.value, color="k", ls="--", lw=0.9)
                    if np.isfinite(b.ci_low) and np.isfinite(b.ci_high):
                        ax.axvspan(b.ci_low, b.ci_high, color="0.85", zorder=0)
                edges = [g["K_m"][ok].min(), *bps["value"], g["K_m"][ok].max()]
                for name, lo, hi in zip(names, edges[:-1], edges[1:], strict=True):
                    ax.text(np.sqrt(lo * hi), 0.04, name, transform=ax.get_xaxis_transform(),
                            ha="center", fontsize=9)  # fmt: skip
        ax.set_xscale("log")
        _finish_panel(ax, init, inits, points, r"$K_m$", r"$T_g^* = T_g/(mg\sigma)$")
    return fig


def fig5_slip_probability(
    points: pd.DataFrame, slips: pd.DataFrame, temperature: pd.DataFrame, fit_n_l: int,
    bound_cl: float = 0.95, reading: str | None = None,
):  # fmt: skip
    """p_s against 1/K_m (Fig. 5) with Arrhenius fits per region for ``fit_n_l``.

    Points without slips are drawn as downward triangles at the exact binomial upper
    bound (``bound_cl``) on p_s; ``reading`` (the record and the fit's readings) is drawn
    over the figure.
    """
    inits = [i for i in ("random", "crystal") if i in set(points["init"])]
    fig, axes = _panels(inits)
    _reading(fig, reading)
    colors = _nl_colors(points["N_l"])
    for init, ax in axes.items():
        for n_l, g in points[points["init"] == init].groupby("N_l"):
            g, broken = _split_broken(g[g["n_trials"] > 0].sort_values("K_m"))
            ax.plot(1.0 / broken["K_m"], broken["p_s"].where(broken["p_s"] > 0), "x", ms=5,
                    color=colors[int(n_l)])  # fmt: skip
            if g.empty:
                continue
            x = 1.0 / g["K_m"].to_numpy()
            p = g["p_s"].to_numpy()
            c = colors[int(n_l)]
            pos = p > 0
            ax.errorbar(x[pos], p[pos], yerr=g["p_s_sem"].to_numpy()[pos], fmt="o", ms=4,
                        color=c, label=f"$N_l$ = {int(n_l)}")  # fmt: skip
            up = zero_count_upper_bound(g["n_trials"].to_numpy()[~pos], bound_cl)
            ax.plot(x[~pos], up, "v", ms=5, mfc="none", color=c)
            if int(n_l) != int(fit_n_l):
                continue
            s = slips[(slips["init"] == init) & (slips["N_l"] == n_l)]
            t = _fitted(temperature, init, n_l)
            bps = np.sort(t[t["name"] == "breakpoint"]["value"].to_numpy())
            bend = s[s["name"] == "K_m_bend"]["value"].to_numpy()  # A2/B at the slip bend
            if len(bps) == 2 and bend.size and np.isfinite(bend[0]):
                bps = np.array([bps[0], bend[0]])
            regions = [
                r.removeprefix("slope_")
                for r in t[t["name"].str.startswith("slope_")].sort_values("index")["name"]
            ]
            for b in bps:
                ax.axvline(1.0 / b, color="k", ls="--", lw=0.9)
            edges = np.concatenate([[0.0], bps, [np.inf]])
            kall = g["K_m"].to_numpy()[pos]  # each line over the points it fits (p_s > 0)
            labels = [f"Arrhenius fits, $N_l$ = {int(n_l)}:"]
            # random: one curve over the whole range (as the paper); crystal: per region
            draw = ["all"] if (init == "random" or not regions) else regions
            for r_i, region in enumerate(draw):
                eb = s[s["name"] == f"E_b_{region}"]
                la = s[s["name"] == f"log_A_{region}"]
                if eb.empty or not np.isfinite(eb["value"].iloc[0]):
                    continue
                lo, hi = (0.0, np.inf) if region == "all" else (edges[r_i], edges[r_i + 1])
                kk = kall[(kall > lo) & (kall <= hi)]
                if kk.size == 0:
                    continue
                xx = np.linspace(1 / kk.max(), 1 / kk.min(), 50)
                e, se = float(eb["value"].iloc[0]), float(eb["se"].iloc[0])
                log_a = float(la["value"].iloc[0])
                ax.plot(xx, np.exp(log_a - e * xx), "-", color=c, lw=1.2)
                labels.append(f"{region}: $E_b$ = {e:.3g} ± {se:.2g}")
            ax.text(0.03, 0.03, "\n".join(labels), transform=ax.transAxes, ha="left",
                    va="bottom", fontsize=7, bbox={"fc": "white", "ec": "0.7"})  # fmt: skip
        _finish_panel(ax, init, inits, points, r"$1/K_m$", r"slip probability $p_s$")
    return fig


WALL_STYLES = {
    ("shaken", "lever"): "-",
    ("shaken", "none"): "--",
    ("still", "lever"): ":",
    ("still", "none"): "-.",
}
"""Line style of each (side walls' drive, wall torque) in Fig. 6."""


def fig6_walls(thresholds: pd.DataFrame, paper: dict | None = None):
    """Thresholds in Γ against the walls (ours): against the side walls' Coulomb
    coefficient μ_w, one panel per N_l, when the grid has more than one μ_w; against N_l,
    one panel per μ_w, otherwise. One line per criterion, start and wall setting (line
    style: the side walls' drive and torque, :data:`WALL_STYLES`).

    Parameters
    ----------
    thresholds : DataFrame
        Columns init, N_l, mu_w, side_walls, wall_torque, criterion, Gamma, Gamma_low,
        Gamma_high, status (rows of :func:`granpipe.box.fits.thresholds_table`).
    paper : dict, optional
        Lines to draw: label -> Γ (e.g. the paper's bouncing and random-start convection).

    A threshold below (above) the grid is drawn at the grid's first (last) Γ with an
    arrow; error bars are the bracketing grid points.
    """
    against_mu = thresholds["mu_w"].nunique() > 1
    x_col, panel_col = ("mu_w", "N_l") if against_mu else ("N_l", "mu_w")
    panels = sorted(set(thresholds[panel_col]))
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels) + 2.2, 3.8),
                             layout="constrained", squeeze=False, sharey=True)  # fmt: skip
    span = float(np.ptp(thresholds[x_col].to_numpy(float))) or 1.0
    order = [(i, c) for c in CRITERION_COLORS for i in ("random", "crystal")]
    for ax, value in zip(axes[0], panels, strict=True):
        sel = thresholds[thresholds[panel_col] == value]
        for (init, crit, side, torque), g in sel.groupby(
            ["init", "criterion", "side_walls", "wall_torque"]
        ):
            g = g.sort_values(x_col)
            k = order.index((init, crit)) if (init, crit) in order else 0
            x = g[x_col].to_numpy(float) + span * 0.006 * (k - len(order) / 2)
            y = g["Gamma"].to_numpy(float)
            lo, hi = g["Gamma_low"].to_numpy(float), g["Gamma_high"].to_numpy(float)
            color = CRITERION_COLORS.get(crit, "k")
            fill = "full" if init == "random" else "none"
            mk = INIT_MARKERS.get(init, "o")
            ok = np.isfinite(y)
            ax.errorbar(x[ok], y[ok], yerr=[y[ok] - lo[ok], hi[ok] - y[ok]], fmt=mk,
                        ls=WALL_STYLES.get((side, torque), "-"), color=color, fillstyle=fill,
                        ms=6, capsize=3, lw=1,
                        label=f"{crit}, {init}, {side} walls, torque {torque}")  # fmt: skip
            _beyond_grid(ax, x, lo, hi, g["status"], mk, color, fill, ms=6, step=0.15)
        for label, line in (paper or {}).items():
            ax.axhline(line, color="0.5", lw=0.8, ls=":")
            ax.text(1.0, line, label, transform=ax.get_yaxis_transform(), ha="right",
                    va="bottom", fontsize=6, color="0.35")  # fmt: skip
        if against_mu:
            ax.set_xlabel(r"side-wall friction $\mu_w$")
            ax.set_title(f"$N_l$ = {int(value)}", fontsize=9)
        else:
            ax.set_xlabel(r"$N_l\sigma$ (layers)")
            ax.set_title(f"$\\mu_w$ = {value:g}", fontsize=9)
    axes[0][0].set_ylabel(r"threshold $\Gamma$")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=6, loc="outside right upper",
               title="thresholds (arrows:\nbeyond the grid)", title_fontsize=7)  # fmt: skip
    return fig


_RECORD_CRITERION = re.compile(r"^(convection|rolls)(?:_(\d+)periods)?$")


def onset_records(thresholds: pd.DataFrame, full_record: int) -> pd.DataFrame:
    """The convection onsets of :func:`fig7_onset_record` as a table: the rows of the
    criteria ``convection`` / ``rolls`` (the whole record, ``full_record`` periods) and
    ``convection_<n>periods`` / ``rolls_<n>periods`` (its first n periods), with columns
    ``reading`` (``convection`` = Eq. (B2), ``rolls``) and ``record`` [periods]."""
    rows = []
    for _, r in thresholds.iterrows():
        m = _RECORD_CRITERION.match(str(r["criterion"]))
        if m:
            n = int(m.group(2)) if m.group(2) else int(full_record)
            rows.append({**r.to_dict(), "reading": m.group(1), "record": n})
    out = pd.DataFrame(rows, columns=[*thresholds.columns, "reading", "record"])
    # the whole record also named by its length: keep one row per (group, reading, record)
    keys = ["init", "N_l", "reading", "record"]
    return out.drop_duplicates(keys, keep="last").sort_values(keys, kind="stable")


def fig7_onset_record(
    points: pd.DataFrame, thresholds: pd.DataFrame, paper_gamma: float | None = None,
    reading: str | None = None,
):  # fmt: skip
    """(ours) How long the convection onset looked: the onset in Γ against the record it
    is measured over (top: Eq. (B2)'s s_c and the roll criterion, one line per N_l and
    start), and the roll criterion against Γ over the whole record (bottom: the smaller of
    the score over its threshold and the centre's rise over its threshold, rolls at 1,
    dotted; :func:`granpipe.box.fits.roll_levels`).

    Parameters
    ----------
    points : DataFrame with N_l, Gamma, init, roll_level, measured_periods
    thresholds : DataFrame, rows of :func:`granpipe.box.fits.thresholds_table`
    paper_gamma : float, optional, the paper's random-start onset (√3.3 = 1.82)
    reading : str, optional, drawn over the figure

    A threshold beyond the grid is drawn at the grid's end with an arrow; error bars are
    the bracketing grid points.
    """
    full = int(points["measured_periods"].min())
    table = onset_records(thresholds, full)
    inits = [i for i in ("random", "crystal") if i in set(points["init"])]
    fig, axes = plt.subplots(2, len(inits), figsize=(4.4 * len(inits) + 2.0, 6.6),
                             layout="constrained", squeeze=False)  # fmt: skip
    _reading(fig, reading)
    colors = _nl_colors(points["N_l"])
    styles = {"convection": ("-", "s"), "rolls": ("--", "D")}
    for j, init in enumerate(inits):
        top, bottom = axes[0][j], axes[1][j]
        for (n_l, rd), g in table[table["init"] == init].groupby(["N_l", "reading"]):
            ls, mk = styles[rd]
            x = g["record"].to_numpy(float) * (1.0 + 0.04 * (rd == "rolls"))
            y, lo, hi = (g[c].to_numpy(float) for c in ("Gamma", "Gamma_low", "Gamma_high"))
            ok = np.isfinite(y)
            label = f"N_l = {int(n_l)}, " + ("Eq. (B2)" if rd == "convection" else "rolls")
            top.errorbar(x[ok], y[ok], yerr=[y[ok] - lo[ok], hi[ok] - y[ok]], fmt=mk, ls=ls,
                         color=colors[int(n_l)], ms=5, capsize=3, lw=1, label=label)  # fmt: skip
            _beyond_grid(top, x, lo, hi, g["status"], mk, colors[int(n_l)], "full", ms=5,
                         step=0.15)  # fmt: skip
        if paper_gamma is not None and init == "random":
            top.axhline(paper_gamma, color="0.4", lw=0.8, ls=":", label="paper (K_m ≈ 3.3)")
        top.set_xscale("log")
        top.set_xlabel("record [measured periods]")
        top.set_ylabel(r"convection onset $\Gamma$")
        top.set_title(f"{init} start", fontsize=9)
        top.legend(fontsize=6)
        for n_l, g in points[points["init"] == init].groupby("N_l"):
            g = g.sort_values("Gamma")
            bottom.plot(g["Gamma"], g["roll_level"], "o-", ms=3, lw=1,
                        color=colors[int(n_l)], label=f"N_l = {int(n_l)}")  # fmt: skip
        bottom.axhline(1.0, color="0.4", lw=0.8, ls=":")
        bottom.set_xlabel(r"$\Gamma$")
        bottom.set_ylabel(f"roll criterion over {full} periods")
        bottom.legend(fontsize=6)
    return fig
