"""Figures of the column study: one function per figure, data in, Figure out.

fig1 trajectories (paper Fig. 1), fig2 continuum vs discrete (paper Fig. 2), and our
fig3 density relaxation, fig4 chaos map (Lyapunov exponents and return-map periods),
fig5 continuum convergence, fig6 Lyapunov estimates (saltation tangent vs twins vs plain
variational).
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402
from matplotlib.colors import TwoSlopeNorm  # noqa: E402

__all__ = [
    "fig1_trajectories",
    "fig2_continuum",
    "fig3_density_relaxation",
    "fig4_chaos_map",
    "fig5_continuum_convergence",
    "fig6_lyapunov_estimates",
]


def fig1_trajectories(runs: list[xr.Dataset], unit: str = "cm", time_unit: str = "s"):
    """y_1(t) … y_N(t) and the floor for each column (one panel per dataset)."""
    fig, axes = plt.subplots(1, len(runs), figsize=(6.0 * len(runs), 4.2), squeeze=False)
    for ax, ds in zip(axes[0], runs, strict=True):
        t = ds["time"].values
        ax.plot(t, ds["floor"].values, color="0.3", lw=1.0, ls="--", label="floor $y_0$")
        cmap = plt.get_cmap("viridis")
        n = ds.sizes["particle"]
        for i in range(n):
            ax.plot(t, ds["y"].values[:, i], lw=0.9, color=cmap(i / max(n - 1, 1)))
        ax.set_xlabel(f"t [{time_unit}]")
        ax.set_ylabel(f"$y_i$ [{unit}]")
        ax.set_title(
            f"N = {n}, T = {ds.attrs.get('T', np.nan):g} {time_unit}, "
            f"tap π/ω = {ds.attrs.get('tap_duration', np.nan):.3g} {time_unit}"
        )
        ax.legend(loc="upper right", fontsize=8)
    fig.suptitle("Fig. 1: particle trajectories of the tapped column (Eq. 19)")
    fig.tight_layout()
    return fig


def fig2_continuum(ds: xr.Dataset):
    """Discrete y_i(t) beside the continuum models with the hybrid and the free top.

    Chain units: heights in h = 2r, time in taps (t/T); the L-W solution surface is the
    hybrid run's displacement from rest.
    """
    fig, axes = plt.subplots(3, 3, figsize=(15, 12), sharex=True)
    T = float(ds.attrs["period"])
    t = ds["time"].values / T
    n = ds.sizes["particle"]
    cmap = plt.get_cmap("viridis")
    panels = [("y_discrete", "discrete (Eq. 24)", None)]
    for model, name in (
        ("longwave", "long-wave (derived)"),
        ("bsr", "BSR (Eq. 45 as printed)"),
        ("bsr_derived", "BSR (derived)"),
    ):
        for top in ("hybrid", "free"):
            panels.append((f"y_{model}_{top}", f"{name}, {top} top", f"{model}_{top}"))
    slots = [axes[0, 0], axes[0, 1], axes[0, 2], axes[1, 0], axes[1, 1], axes[2, 0], axes[2, 1]]
    for ax, (var, title, key) in zip(slots, panels, strict=True):
        for i in range(n):
            ax.plot(t, ds[var].values[:, i], lw=0.8, color=cmap(i / max(n - 1, 1)))
        ax.plot(t, ds["floor"].values, color="0.3", lw=0.8, ls="--")
        if key is not None:
            title += (
                f"\nRMS distance: positions {ds.attrs[f'rms_positions_{key}']:.3g} h,"
                f"\ndisplacements {ds.attrs[f'rms_displacements_{key}']:.3g} h "
                f"({ds.attrs[f'relative_displacements_{key}']:.2g} of the discrete)"
            )
        ax.set_title(title, fontsize=9)
        ax.set_ylabel("height / h")
    for ax in axes[2]:
        ax.set_xlabel("t / T (taps)")
    ax = axes[1, 2]
    y = ds["y_longwave_field"].values
    disp = y - y[0]
    lim = np.nanmax(np.abs(disp)) or 1.0
    im = ax.pcolormesh(
        t,
        ds["label"].values,
        disp.T,
        cmap="RdBu_r",
        norm=TwoSlopeNorm(0.0, -lim, lim),
        shading="auto",
    )
    fig.colorbar(im, ax=ax, label="y(z, t) − y(z, 0)  [h]")
    ax.set_ylabel("label z / h")
    ax.set_title("long-wave, hybrid top: solution surface (displacement from rest)", fontsize=9)
    ax = axes[2, 2]
    rho = ds["rho_bsr_derived"].values
    im = ax.pcolormesh(t, ds["height"].values, rho.T, cmap="viridis", shading="auto")
    fig.colorbar(im, ax=ax, label="linear density [m/h]")
    ax.set_ylabel("height z / h")
    ax.set_title("BSR (derived), hybrid top: density", fontsize=9)
    fig.suptitle(
        f"Fig. 2: continuum models beside the discrete column (N = {n}; tap "
        f"{ds.attrs['tap_duration'] / T:.2f} T, amplitude {ds.attrs['tap_amplitude']:.2f} h; "
        f"L-W at h/{ds.attrs['lw_refinement']}, BSR at h/{ds.attrs['bsr_refinement']}, "
        f"derived BSR at h/{ds.attrs['bsr_derived_refinement']})"
    )
    fig.tight_layout()
    return fig


def fig3_density_relaxation(ens: xr.Dataset, fit: dict | None = None, unit: str = "kg/m"):
    """Ensemble mean linear density against tap number, spread and standard error."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    tap = ens["tap"].values
    m = ens["density_mean"].values
    sd = ens["density_std"].values
    se = ens["density_sem"].values
    ax.fill_between(tap, m - sd, m + sd, color="C0", alpha=0.15, label="replica spread (±1 sd)")
    ax.fill_between(
        tap, m - 1.96 * se, m + 1.96 * se, color="C0", alpha=0.35, label="95% interval of the mean"
    )
    ax.plot(tap, m, color="C0", lw=1.2, label=f"mean over {int(ens['count'].max())} replicas")
    if fit is not None and np.isfinite(fit["relaxed_density"][0]):
        v, _, _, lo, hi, _ = fit["relaxed_density"]
        ax.axhline(
            v,
            color="C3",
            lw=1.0,
            ls="--",
            label=f"relaxed (second half): {v:.6g} [{lo:.6g}, {hi:.6g}]",
        )
    a = ens.attrs
    if "density_equilibrium" in a:
        ax.axhline(
            a["density_equilibrium"],
            color="0.2",
            lw=0.8,
            ls=":",
            label="equilibrium start (Eq. 27)",
        )
        for key, lab in (
            ("density_band_low", "stick-band limits (loosest / densest rest)"),
            ("density_band_high", None),
        ):
            ax.axhline(a[key], color="0.5", lw=0.8, ls="-.", label=lab)
    ax.set_xlabel("tap number n (sample at (n + 0.99) T)")
    ax.set_ylabel(f"mean linear density N m / H [{unit}]")
    ax.set_title("Density relaxation of the tapped column (generic set)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def _period_panel(ax, cmap_ds: xr.Dataset, length_unit: str, time_unit: str):
    """The most common return-map period per (a, T) cell; 'none' where no period ≤ p_max."""
    from matplotlib.colors import BoundaryNorm, ListedColormap

    A = cmap_ds["a"].values
    T = cmap_ds["T"].values
    p_max = int(cmap_ds.attrs.get("return_max_period", cmap_ds.sizes["period"] - 1))
    mode = cmap_ds["period_mode"].values.astype(float)
    frac = cmap_ds["period_fraction"].values
    counts = cmap_ds["period_counts"].values
    undecided = (
        cmap_ds["period_undecided"].values
        if "period_undecided" in cmap_ds
        else np.zeros(mode.shape, dtype=int)
    )
    # white: no replica with data, or every replica undecided
    field = np.where(np.isfinite(frac) & (counts.sum(axis=-1) > 0), mode, np.nan)
    # 0 (none) light grey, then one light colour per period 1 … p_max (black text stays legible)
    ramp = plt.get_cmap("YlGnBu")
    colours = ["0.85", *[ramp(0.15 + 0.6 * k / max(p_max - 1, 1)) for k in range(p_max)]]
    norm = BoundaryNorm(np.arange(-0.5, p_max + 1.5), len(colours))
    im = ax.pcolormesh(
        np.arange(T.size + 1),
        np.arange(A.size + 1),
        field,
        cmap=ListedColormap(colours),
        norm=norm,
        shading="flat",
    )
    ticks = [0, *(q for q in (1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64) if q <= p_max)]
    if ticks[-1] != p_max:
        ticks.append(p_max)
    cb = ax.figure.colorbar(im, ax=ax, ticks=ticks)
    cb.ax.set_yticklabels([f"none ≤ {p_max}", *map(str, ticks[1:])])
    cb.set_label("most common return-map period p [taps]")
    chaotic = cmap_ds["chaotic"].values
    for i in range(A.size):
        for j in range(T.size):
            und = int(undecided[i, j])
            n = int(counts[i, j].sum()) + und
            if n == 0:
                txt = "n/a"
            elif n == und:
                txt = f"undecided\n{und}/{n}"
            else:
                m = int(mode[i, j])
                txt = f"{f'p = {m}' if m else 'none'}\n{int(counts[i, j, m])}/{n}"
                txt += f" ({und}?)" if und else ""
            if chaotic[i, j] == 1:
                ax.add_patch(plt.Rectangle((j, i), 1, 1, fill=False, hatch="//", lw=0))
            ax.text(j + 0.5, i + 0.5, txt, ha="center", va="center", fontsize=7)
    ax.set_xticks(np.arange(T.size) + 0.5, [f"{x:g}" for x in T])
    ax.set_yticks(np.arange(A.size) + 0.5, [f"{x:g}" for x in A])
    ax.set_xlabel(f"tap period T [{time_unit}]")
    ax.set_ylabel(f"tap amplitude a [{length_unit}]")
    ax.set_title(
        f"return map x_k -> x_(k+1) at t = kT: period (replicas with it / all, '?' "
        f"undecided); tolerance {cmap_ds.attrs.get('return_tolerance', float('nan')):g}",
        fontsize=8,
    )


def fig4_chaos_map(cmap_ds: xr.Dataset, length_unit: str = "m", time_unit: str = "s"):
    """λ per tap and per unit time over (a, T), chaotic points (interval above 0) marked;
    and, when measured, the return-map period per point in the same layout."""
    A = cmap_ds["a"].values
    T = cmap_ds["T"].values
    lam = cmap_ds["lambda_mean"].values
    periods = "period_mode" in cmap_ds
    fig, axes = plt.subplots(1, 3 if periods else 2, figsize=(19.5 if periods else 13, 5))
    for ax, field, label in (
        (axes[0], lam, "λ [1/tap]"),
        (axes[1], cmap_ds["lambda_time"].values, f"λ/T [1/{time_unit}]"),
    ):
        lim = np.nanmax(np.abs(field)) if np.any(np.isfinite(field)) else 1.0
        norm = TwoSlopeNorm(0.0, -lim, lim) if np.nanmin(field) < 0 < np.nanmax(field) else None
        im = ax.pcolormesh(
            np.arange(T.size + 1),
            np.arange(A.size + 1),
            field,
            cmap="RdBu_r",
            norm=norm,
            shading="flat",
        )
        fig.colorbar(im, ax=ax, label=label)
        chaotic = cmap_ds["chaotic"].values
        for i in range(A.size):
            for j in range(T.size):
                txt = f"{field[i, j]:.2g}"
                if chaotic[i, j] == 1:
                    ax.add_patch(plt.Rectangle((j, i), 1, 1, fill=False, hatch="//", lw=0))
                    txt += "\nchaos"
                elif chaotic[i, j] == 0:
                    txt += "\nregular"
                else:
                    txt += "\n?"
                if cmap_ds["failed"].values[i, j]:
                    txt += f"\n{int(cmap_ds['failed'].values[i, j])} broke"
                ax.text(j + 0.5, i + 0.5, txt, ha="center", va="center", fontsize=7)
        ax.set_xticks(np.arange(T.size) + 0.5, [f"{x:g}" for x in T])
        ax.set_yticks(np.arange(A.size) + 0.5, [f"{x:g}" for x in A])
        ax.set_xlabel(f"tap period T [{time_unit}]")
        ax.set_ylabel(f"tap amplitude a [{length_unit}]")
    if periods:
        _period_panel(axes[2], cmap_ds, length_unit, time_unit)
    conf = cmap_ds.attrs.get("confidence", 0.95)
    fig.suptitle(
        f"Largest Lyapunov exponent of the tapped column (tangent with saltation); "
        f"hatched: {conf:.0%} t-interval above 0 (chaos), 'regular': below 0"
        + ("; right: period of the return map" if periods else "")
    )
    fig.tight_layout()
    return fig


def fig5_continuum_convergence(conv: xr.Dataset):
    """Per model and top: successive differences and distance to the discrete column
    against h/Δz (chain units), with slope guides of order 1 and 2."""
    scan = conv.get("sigma_scan_relative_displacements")
    fig, axes = plt.subplots(
        1, 3 if scan is not None else 2, figsize=(18 if scan is not None else 12, 4.5)
    )
    ax, ax2 = axes[0], axes[1]
    styles = {"hybrid": "-", "free": ":"}
    for i, model in enumerate(conv["model"].values):
        ks = conv["refinement"].values[i]
        ok = ks > 0
        for top in conv["top"].values:
            e = conv["error"].sel(model=model, top=top).values[ok]
            k = ks[ok][: e.size]
            m = np.isfinite(e)
            orders = conv.attrs[f"orders_{model}_{top}"]
            c = f"C{i}"
            ax.loglog(k[m], e[m], "o" + styles[top], color=c,
                      label=f"{model}, {top} top (orders {orders})")  # fmt: skip
            if m.any() and top == "hybrid":
                k0, e0 = k[m][0], e[m][0]
                for order, ls in ((1, ":"), (2, "--")):
                    ax.loglog(k[m], e0 * (k[m] / k0) ** (-order), ls, color="0.6", lw=0.7)
            rel = conv["relative_displacements"].sel(model=model, top=top).values[ok]
            ax2.semilogx(ks[ok], rel, "o" + styles[top], color=c, label=f"{model}, {top} top")
    for a in (ax, ax2):
        a.set_xscale("log", base=2)
        a.xaxis.set_major_formatter(plt.matplotlib.ticker.ScalarFormatter())
    ax.set_xlabel("h / Δz")
    ax.set_ylabel("max |y(h/k) − y(h/2k)|  [h]")
    ax.set_title("successive differences; guides: order 1, 2", fontsize=9)
    ax.legend(fontsize=7)
    ax2.set_xlabel("h / Δz")
    ax2.set_ylabel("RMS displacement distance / RMS discrete displacement")
    ax2.set_yscale("log")
    ax2.set_title("distance to the discrete column under refinement", fontsize=9)
    ax2.legend(fontsize=7)
    if scan is not None:
        ax3 = axes[2]
        w = scan["sigma_width"].values
        for i, model in enumerate(scan["scan_model"].values):
            for top in scan["top"].values:
                ax3.loglog(w, scan.sel(scan_model=model, top=top).values, "o" + styles[top],
                           color=f"C{i}", label=f"{model}, {top} top")  # fmt: skip
        ax3.set_xlabel("width w_σ of the smooth sign  [h sqrt(K/m)]")
        ax3.set_ylabel("RMS displacement distance / RMS discrete displacement")
        ax3.set_title(
            f"against w_σ (L-W, derived BSR at h/{conv.attrs['sigma_scan_refinement']});\n"
            "smooth_chain: the discrete chain with that smooth sign",
            fontsize=9,
        )
        ax3.legend(fontsize=7)
    fig.suptitle("Continuum models under refinement (Fig. 2 problem, chain units)")
    fig.tight_layout()
    return fig


def fig6_lyapunov_estimates(cmap_ds: xr.Dataset):
    """Twin and plain-variational estimates against the saltation tangent, with intervals."""
    fig, ax = plt.subplots(figsize=(6, 5.5))
    x = cmap_ds["lambda_mean"].values.ravel()
    xe = np.vstack(
        [x - cmap_ds["lambda_low"].values.ravel(), cmap_ds["lambda_high"].values.ravel() - x]
    )
    for key, label, c in (
        ("twin", "twin trajectories", "C0"),
        ("plain", "variational, no saltation", "C3"),
    ):
        y = cmap_ds[f"{key}_mean"].values.ravel()
        ye = np.vstack(
            [y - cmap_ds[f"{key}_low"].values.ravel(), cmap_ds[f"{key}_high"].values.ravel() - y]
        )
        ok = np.isfinite(x) & np.isfinite(y)
        ax.errorbar(
            x[ok],
            y[ok],
            xerr=np.abs(np.nan_to_num(xe[:, ok])),
            yerr=np.abs(np.nan_to_num(ye[:, ok])),
            fmt="o",
            ms=4,
            color=c,
            lw=0.7,
            label=label,
        )
    lo = np.nanmin(
        [
            np.nanmin(x),
            np.nanmin(cmap_ds["twin_mean"].values),
            np.nanmin(cmap_ds["plain_mean"].values),
        ]
    )
    hi = np.nanmax(
        [
            np.nanmax(x),
            np.nanmax(cmap_ds["twin_mean"].values),
            np.nanmax(cmap_ds["plain_mean"].values),
        ]
    )
    ax.plot([lo, hi], [lo, hi], color="0.4", lw=0.8)
    ax.axhline(0, color="0.8", lw=0.6)
    ax.axvline(0, color="0.8", lw=0.6)
    ax.set_xlabel("λ, tangent with saltation [1/tap]")
    ax.set_ylabel("λ, other estimate [1/tap]")
    ax.set_title("Saltation matters: twins follow the corrected tangent", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig
