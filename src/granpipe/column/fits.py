"""Column fits and the note: the relaxation fit, summary rows of every stage and their
reading against the paper.

:func:`relaxation_fit` fits the relaxation ensemble; then its rows, the chaos map's rows
(exponents, return-map periods, thresholds), the continuum comparison's rows
(docs/column.md, "What the comparison shows") and the plain-text note that reads them
against Theorem 1 and Fig. 2.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import xarray as xr

from ..analysis.summary import summary_row
from . import continuum as cont
from .measures import t_interval
from .model import ColumnParams
from .protocol import (
    CONTINUUM_MODELS,
    MODEL_NAMES,
    SIGMA_SCAN_MODELS,
    TOP_TREATMENTS,
)

__all__ = [
    "relaxation_fit",
    "summary_rows",
    "theorem1_note",
    "continuum_rows",
    "continuum_note",
]


def summary_rows(
    fit: Mapping, cmap: xr.Dataset, comp: xr.Dataset, conv: xr.Dataset, units, sigma_widths=()
):
    """Every summary row of the column and the chaos thresholds per period.

    ``fit``: :func:`relaxation_fit`; ``cmap``: the chaos map;
    ``comp``/``conv``: the continuum comparison and convergence runs; ``units``: the
    config's unit names; ``sigma_widths``: the config's scan widths (rows of
    :func:`sigma_scan_rows`). Returns (rows, thresholds (n_T,) [length]).
    """
    rows = []

    def row(q, v, unit, err=None, lo=None, hi=None, n=None):
        rows.append(summary_row("column", q, v, unit, err, lo, hi, n))

    for q, (v, unit, err, lo, hi, n) in fit.items():
        row(q, v, unit.replace("mass/length", f"kg/{units['length']}"), err, lo, hi, n)
    A, T = cmap["a"].values, cmap["T"].values
    for i, a in enumerate(A):
        for j, t in enumerate(T):
            row(
                f"lyapunov_per_tap[a={a:g},T={t:g}]",
                cmap["lambda_mean"].values[i, j],
                "1/tap",
                lo=cmap["lambda_low"].values[i, j],
                hi=cmap["lambda_high"].values[i, j],
                n=int(cmap["n"].values[i, j]),
            )
    if "period_mode" in cmap:
        decided = cmap["period_counts"].values.sum(axis=-1)
        n_per = decided + (cmap["period_undecided"].values if "period_undecided" in cmap else 0)
        for i, a in enumerate(A):
            for j, t in enumerate(T):
                # the most common period (0: none up to the maximum; -2: all undecided)
                row(
                    f"return_period[a={a:g},T={t:g}]",
                    int(cmap["period_mode"].values[i, j]) if decided[i, j] else -2,
                    "taps",
                    n=int(n_per[i, j]),
                )
                row(
                    f"return_periodic_fraction[a={a:g},T={t:g}]",
                    float(cmap["period_fraction"].values[i, j]),
                    "1",
                    n=int(n_per[i, j]),
                )
        for j, t in enumerate(T):
            row(
                f"return_period_longest[T={t:g}]",
                int(cmap["period_max"].values[:, j].max()),
                "taps",
                n=int(n_per[:, j].sum()),
            )
    thresholds = np.full(T.size, np.nan)
    for j, t in enumerate(T):
        idx = np.where(cmap["chaotic"].values[:, j] == 1)[0]
        if idx.size:
            thresholds[j] = A[idx[0]]
        row(f"chaos_onset_amplitude[T={t:g}]", thresholds[j], units["length"], n=T.size)
    diff_twin = (cmap["twin_mean"] - cmap["lambda_mean"]).values
    diff_plain = (cmap["plain_mean"] - cmap["lambda_mean"]).values
    row(
        "lyapunov_twin_minus_tangent_mean_abs",
        float(np.nanmean(np.abs(diff_twin))),
        "1/tap",
        n=int(np.isfinite(diff_twin).sum()),
    )
    row(
        "lyapunov_plain_minus_tangent_mean_abs",
        float(np.nanmean(np.abs(diff_plain))),
        "1/tap",
        n=int(np.isfinite(diff_plain).sum()),
    )
    row(
        "chaotic_fraction_of_map",
        float(np.mean(cmap["chaotic"].values == 1)),
        "1",
        n=int(cmap["chaotic"].size),
    )
    rows.extend(continuum_rows(comp, conv, units["fig2_length"], sigma_widths))
    return rows, thresholds


def _period_label(cmap, i, j):
    """The return-map period of one chaos point as the note prints it."""
    counts = cmap["period_counts"].values[i, j]
    und = int(cmap["period_undecided"].values[i, j]) if "period_undecided" in cmap else 0
    n = int(counts.sum()) + und
    if n == 0:
        return "n/a"
    if not counts.sum():
        return f"undecided ({und}/{n})"
    mode = int(cmap["period_mode"].values[i, j])
    label = f"{mode if mode else 'none'} ({int(counts[mode])}/{n})"
    return label + (f", {und} undecided" if und else "")


def _return_periods_reading(cmap, units):
    """Lines of the note on Theorem 1's periodic orbits, and the verdict on that claim.

    Per period T: the most common detected return-map period along the amplitudes up to
    the first chaotic one (a point counts as periodic when most of its replicas have a
    period). Returns (lines, verdict) with verdict "yes" (periods above 1 before chaos
    and growing with a), "in part" (a period above 1 before chaos at some T, not growing
    further; the longest period and those T added) or "no" (period 1 up to chaos
    everywhere).
    """

    A, T = cmap["a"].values, cmap["T"].values
    ch = cmap["chaotic"].values
    p_max = int(cmap.attrs.get("return_max_period", cmap.sizes.get("period", 1) - 1))
    window = cmap.attrs.get("return_taps", "?")
    tol = cmap.attrs.get("return_tolerance", float("nan"))
    mode = cmap["period_mode"].values
    frac = cmap["period_fraction"].values
    lines = [
        "",
        f"Return map (states at the end of each of the last {window} measured taps, "
        f"periods p <= {p_max}, scaled distance < {tol:g}; most common period over the "
        "replicas, '(k/n)' replicas with it, 'none': no period up to the maximum, "
        "'undecided': a shorter lag nearly repeats too, the orbit is still converging):",
    ]
    above_one, growing, aperiodic_regular, undecided = [], [], [], []
    for j, t in enumerate(T):
        first = np.where(ch[:, j] == 1)[0]
        stop = int(first[0]) if first.size else A.size
        seq = [_period_label(cmap, i, j) for i in range(A.size)]
        lines.append(
            f"- T = {t:g} {units['time']}: "
            + ", ".join(
                f"a = {a:g}: {lab}{' [chaos]' if ch[i, j] == 1 else ''}"
                for i, (a, lab) in enumerate(zip(A, seq, strict=True))
            )
        )
        before = [int(mode[i, j]) for i in range(stop) if frac[i, j] > 0.5]
        if any(q > 1 for q in before):
            above_one.append(t)
            q = [x for x in before if x > 0]
            if len(set(q)) > 2 and all(b >= a for a, b in zip(q[:-1], q[1:], strict=True)):
                growing.append(t)
        counts = cmap["period_counts"].values[:, j]
        aperiodic_regular += [
            (A[i], t) for i in range(A.size) if ch[i, j] == 0 and frac[i, j] == 0.0 and counts[i, 0]
        ]
        if "period_undecided" in cmap:
            undecided += [(A[i], t) for i in range(A.size) if cmap["period_undecided"].values[i, j]]
    longest = int(np.max(cmap["period_max"].values)) if cmap["period_max"].size else 0
    chaotic_periodic = int(np.sum((ch == 1) & (frac > 0)))
    if growing:
        verdict = "yes"
        txt = (
            "periods grow with a before chaos at T = "
            + ", ".join(f"{t:g}" for t in growing)
            + f"; the longest detected period is {longest} (searched up to {p_max})."
        )
    elif above_one:
        where = ", ".join(f"{t:g}" for t in above_one)
        verdict = f"in part (longest period {longest}, before chaos at T = {where} only)"
        txt = (
            "a period above 1 appears before chaos at T = "
            + ", ".join(f"{t:g}" for t in above_one)
            + f" only, and does not grow further: the longest detected period is {longest} "
            f"(searched up to {p_max}); elsewhere the return map has period 1 up to the "
            "first chaotic amplitude."
        )
    else:
        verdict = "no"
        txt = (
            "the return map has period 1 at every regular amplitude and no period up to "
            f"{p_max} from the first chaotic amplitude on: no periods growing with a."
        )
    lines.append(f"Periodic orbits: {txt}")
    if aperiodic_regular:
        lines.append(
            "Regular (negative exponent) but no period found at "
            + ", ".join(f"(a = {a:g}, T = {t:g})" for a, t in aperiodic_regular)
            + ": still converging in the window, or a period above the maximum."
        )
    if undecided:
        lines.append(
            "Undecided replicas (a shorter lag within 100 x the tolerance: still converging, "
            "or next to the bifurcation of the cycle) at "
            + ", ".join(f"(a = {a:g}, T = {t:g})" for a, t in undecided)
            + "."
        )
    if chaotic_periodic:
        lines.append(f"{chaotic_periodic} chaotic points have a replica with a period.")
    return lines, verdict


def theorem1_note(cmap, comp, conv, units, relax=None, sigma_widths=()):
    """Plain-text reading of the chaos map against Theorem 1, and the continuum distances."""
    A, T = cmap["a"].values, cmap["T"].values
    ch = cmap["chaotic"].values
    lines = ["# Column study: what the numbers say", ""]
    lines.append(
        "## Theorem 1 (periodic orbits of growing period, then chaos, as the tap amplitude "
        "a grows; chaos for small period T)"
    )
    lines.append("")
    per_T = []
    monotone = True
    for j, t in enumerate(T):
        idx = np.where(ch[:, j] == 1)[0]
        if idx.size:
            amin = A[idx[0]]
            if not np.all(ch[idx[0] :, j] == 1):
                monotone = False
            per_T.append(f"T = {t:g} {units['time']}: chaotic from a = {amin:g} {units['length']}")
        else:
            per_T.append(f"T = {t:g} {units['time']}: no chaotic amplitude in the grid")
            monotone = False
    regular = int(np.sum(ch == 0))
    chaotic = int(np.sum(ch == 1))
    undecided = int(np.sum(ch == -1))
    lines.append(
        f"Grid: {A.size} amplitudes x {T.size} periods; {chaotic} chaotic, {regular} "
        f"regular, {undecided} undecided points ({cmap.attrs.get('confidence', 0.95):.0%}"
        " t-interval of the ensemble mean of the largest exponent, tangent with saltation)."
    )
    lines.extend(f"- {s}" for s in per_T)
    top_chaotic = int(np.sum(ch[-1, :] == 1))
    bottom_regular = int(np.sum(ch[0, :] == 0))
    lines.append("")
    claim_a = "yes" if top_chaotic == T.size and bottom_regular > 0 else "no"
    if top_chaotic == T.size and bottom_regular > 0:
        verdict_a = (
            f"supports the amplitude part: the largest amplitude is chaotic at all {T.size} "
            f"periods, the smallest is regular at {bottom_regular} of them, and chaos, once "
            "reached, persists to the largest amplitude "
            + ("at every period." if monotone else "at some periods only.")
        )
    else:
        verdict_a = (
            f"does not cleanly support the amplitude part: the largest amplitude is "
            f"chaotic at {top_chaotic} of {T.size} periods, the smallest regular at "
            f"{bottom_regular}."
        )
    lines.append(f"Amplitude: the map {verdict_a}")
    lam_t = cmap["lambda_time"].values
    if T.size > 1:
        # amplitudes where a shorter period is chaotic and a longer one regular
        emerge = [
            A[i]
            for i in range(A.size)
            if any(ch[i, j] == 1 and np.any(ch[i, j + 1 :] == 0) for j in range(T.size - 1))
        ]
        # amplitudes chaotic at the shortest period whose exponent per unit time there
        # exceeds the one at the longest period
        faster = [
            A[i]
            for i in range(A.size)
            if ch[i, 0] == 1 and np.isfinite(lam_t[i, 0]) and lam_t[i, 0] > lam_t[i, -1]
        ]
        n_short = int(np.sum(ch[:, 0] == 1))
        parts = []
        if emerge:
            parts.append(
                "chaos appears as T shrinks at a = "
                + ", ".join(f"{a:g}" for a in emerge)
                + f" {units['length']} (a shorter period chaotic, a longer one regular)"
            )
        if faster:
            parts.append(
                f"at {len(faster)} of the {n_short} amplitudes chaotic at the shortest "
                f"period the exponent per unit time is larger there than at the longest"
            )
        nonmono = [A[i] for i in range(A.size) if ch[i, 0] == 0 and np.any(ch[i, 1:] == 1)]
        if nonmono:
            parts.append(
                "but at a = "
                + ", ".join(f"{a:g}" for a in nonmono)
                + " the shortest period is regular again (not monotone in T)"
            )
        verdict_T = (
            "supports the period part in part: " + "; ".join(parts) + "."
            if parts
            else "does not show chaos appearing as T shrinks in the grid."
        )
        claim_T = "in part" if emerge else "no"
    else:
        verdict_T = "cannot test the period part (one period only)."
        claim_T = "not tested"
    lines.append(f"Period: the map {verdict_T}")
    claim_p = "not tested"
    if "period_mode" in cmap:
        plines, claim_p = _return_periods_reading(cmap, units)
        lines.extend(plines)
    else:
        lines.append("The return-map periods were not measured.")
    lines.append("")
    lines.append(
        f"Theorem 1 against the data: periods growing with a before chaos: {claim_p}; "
        f"chaos at large a: {claim_a}; chaos appearing as T shrinks: {claim_T}."
    )
    if relax is not None:
        v = relax["relaxed_density"]
        dch = relax["density_change"]
        tr = relax["density_trend"]
        lines.append("")
        lines.append("## Density relaxation (generic column)")
        lines.append("")
        txt = (
            f"Relaxed mean linear density {v[0]:.7g} [{v[3]:.7g}, {v[4]:.7g}] "
            f"kg/{units['length']} over {v[5]} replicas; change from the start "
            f"{dch[0]:.3g} [{dch[3]:.3g}, {dch[4]:.3g}]; trend over the second half "
            f"{tr[0]:.3g} [{tr[3]:.3g}, {tr[4]:.3g}] per tap."
        )
        if "band_position" in relax:
            bp = relax["band_position"]
            txt += (
                f" The rest density can only move inside the stick band (contacts stuck "
                f"with forces in [K(1-e)c, K(1+e)c]); it sits at {bp[0]:.2f} of the band "
                f"(0 loosest, 1 densest): tapping does not compact this 1D column beyond "
                f"the hysteresis of its contacts."
            )
        lines.append(txt)
    lines.append("")
    lines.extend(continuum_note(comp, conv, units, sigma_widths))
    return "\n".join(lines) + "\n"


def _finest(conv: xr.Dataset, var: str, model: str, top: str):
    """Value of ``var`` at the finest refinement run for (model, top), and that h/dz."""
    ks = conv["refinement"].sel(model=model).values
    last = int(np.max(np.where(ks > 0)[0]))
    return float(conv[var].sel(model=model, top=top).values[last]), int(ks[last])


def finest_orders(conv: xr.Dataset, model: str, top: str) -> list[float]:
    """Observed orders of one model and top, coarsest pair first."""
    return [float(x) for x in str(conv.attrs[f"orders_{model}_{top}"]).split()]


def continuum_rows(
    comp: xr.Dataset, conv: xr.Dataset, length_unit: str, sigma_widths=()
) -> list[dict]:
    """Summary rows of the continuum comparison (docs/results.md, "Column").

    Per model and top treatment, at the finest refinement: RMS distances to the discrete
    column in units of h (positions, displacements from rest, displacements relative to
    the discrete column's RMS displacement) and the observed order of the finest pair;
    the collapse time of BSR as printed (units sqrt(m/K)); and what the printed Eq. (35)
    implies for the same column in cgs and in SI (its linear wave speed, units h sqrt(K/m));
    ``length_unit`` is the unit of length of the Fig. 2 column's config.
    """
    from ..analysis.summary import summary_row

    rows = []
    for model in CONTINUUM_MODELS:
        for top in TOP_TREATMENTS:
            tag = f"[model={model},top={top}]"
            for var, unit in (
                ("rms_positions", "h"),
                ("rms_displacements", "h"),
                ("relative_displacements", "1"),
            ):
                v, k = _finest(conv, var, model, top)
                rows.append(summary_row("column", f"continuum_{var}{tag}", v, unit))
            o = finest_orders(conv, model, top)
            rows.append(
                summary_row(
                    "column", f"continuum_observed_order_finest{tag}", o[-1] if o else np.nan, "1"
                )
            )
        rows.append(summary_row("column", f"continuum_finest_refinement[model={model}]", k, "h/dz"))
    rows += sigma_scan_rows(conv, sigma_widths)
    for top in TOP_TREATMENTS:
        rows.append(
            summary_row(
                "column",
                f"bsr_collapse_time[top={top}]",
                float(comp.attrs[f"bsr_collapse_time_{top}"]),
                "sqrt(m/K)",
            )
        )
    speeds = printed_longwave_speeds(float(comp.attrs["length_scale"]), length_unit)
    for system, speed in speeds.items():
        rows.append(
            summary_row("column", f"printed_eq35_wave_speed[units={system}]", speed, "h sqrt(K/m)")
        )
    return rows


def _sigma_scan(conv: xr.Dataset, sigma_widths=()):
    """(model, top, w_σ, relative distance) of the scan over w_σ: every scanned model and
    top at the widths of the convergence run and of ``sigma_widths``; NaN where the run
    has no value."""
    da = conv.get("sigma_scan_relative_displacements")
    have = {}
    if da is not None:
        have = {
            (str(m), str(t), float(w)): float(da.sel(scan_model=m, top=t, sigma_width=w))
            for m in da["scan_model"].values
            for t in da["top"].values
            for w in da["sigma_width"].values
        }
    widths = list(dict.fromkeys([w for _, _, w in have] + [float(w) for w in sigma_widths]))
    return [
        (m, t, w, have.get((m, t, w), math.nan))
        for m in SIGMA_SCAN_MODELS
        for t in TOP_TREATMENTS
        for w in widths
    ]


def _sigma_scan_name(m: str, t: str, w: float) -> str:
    return f"continuum_relative_displacements[model={m},top={t},sigma_width={w:g}]"


def sigma_scan_rows(conv: xr.Dataset, sigma_widths=()) -> list[dict]:
    """Summary rows of the scan over the width w_σ of the smooth sign (docs/results.md),
    one per model, top and width of :func:`_sigma_scan`."""
    return [
        summary_row("column", _sigma_scan_name(m, t, w), v, "1")
        for m, t, w, v in _sigma_scan(conv, sigma_widths)
    ]


def printed_longwave_speeds(h: float, length_unit: str) -> dict:
    """sqrt(C(1)) of the printed Eq. (35) for a column of spacing h given in cgs and in SI.

    C(1) = A₊/3 − hB/3 + 2rαh² with α = 1/h: 2.5/3 + 1/3 + h² in the unit of length used,
    a speed in units of h sqrt(K/m), in which the chain's own long-wave speed is 1.
    ``length_unit`` ("cm" or "m") is the unit h is given in.
    """
    to_cm = {"cm": 1.0, "m": 100.0}
    if length_unit not in to_cm:
        raise ValueError(f"length unit must be cm or m, got {length_unit!r}")
    h_cm = h * to_cm[length_unit]
    out = {}
    for system, hh in (("cgs", h_cm), ("SI", h_cm / 100.0)):
        p = ColumnParams(N=1, m=1.0, r=hh / 2, g=0.0, K=1.0, e=0.0, a=0.0, omega=1.0, T=1.0)
        out[system] = math.sqrt(cont.longwave_coefficients(p).C1)
    return out


def sigma_scan_note(conv: xr.Dataset, sigma_widths=()) -> list[str]:
    """Lines of the column note on the scan over w_σ; the rows without a value named."""
    scan = _sigma_scan(conv, sigma_widths)
    if not scan:
        return []
    k = conv.attrs.get("sigma_scan_refinement", "?")
    lines = [
        f"- Against the width w_σ of the smooth sign (L-W and derived BSR at h/{k}; the "
        "chain with the same smooth sign is what the smoothing alone costs):"
    ]
    for top in TOP_TREATMENTS:
        for m in SIGMA_SCAN_MODELS:
            vals = [f"{v:.3g} (w_σ = {w:g})" for mm, t, w, v in scan if mm == m and t == top]
            lines.append(f"  - {top} top, {MODEL_NAMES[m]}: " + ", ".join(vals))
    empty = [_sigma_scan_name(m, t, w) for m, t, w, v in scan if not math.isfinite(v)]
    if empty:
        lines.append(
            "  - empty (the convergence run has no value there: width not run, or no "
            "solution): " + ", ".join(empty)
        )
    return lines


def continuum_note(
    comp: xr.Dataset, conv: xr.Dataset, units: Mapping, sigma_widths=()
) -> list[str]:
    """Lines of the column note on the continuum models against the discrete column."""
    lines = ["## Continuum models against the discrete column (Fig. 2 problem)", ""]
    sc_t = float(comp.attrs["time_scale"])
    lines.append(
        f"Chain units: h = {comp.attrs['length_scale']:.4g} {units['fig2_length']}, "
        f"sqrt(m/K) = {sc_t:.4g} {units['fig2_time']}; tap {comp.attrs['tap_duration']:.4g} "
        f"(= {comp.attrs['tap_duration'] * sc_t:.3g} {units['fig2_time']}) of every period "
        f"{comp.attrs['period']:.4g}, amplitude {comp.attrs['tap_amplitude']:.3g} h, "
        f"G = mg/(Kh) = {comp.attrs['G']:.4g}. Distances at the finest grid, in h; "
        "'relative' divides the displacement distance by the discrete column's RMS "
        "displacement."
    )
    lines.append("")
    for model in CONTINUUM_MODELS:
        parts = []
        for top in TOP_TREATMENTS:
            pos, k = _finest(conv, "rms_positions", model, top)
            disp, _ = _finest(conv, "rms_displacements", model, top)
            rel, _ = _finest(conv, "relative_displacements", model, top)
            o = finest_orders(conv, model, top)
            parts.append(
                f"{top} top: positions {pos:.3g}, displacements {disp:.3g} (relative "
                f"{rel:.3g}), observed orders {' '.join(f'{x:.2f}' for x in o)} up to h/{k}"
            )
        lines.append(f"- {MODEL_NAMES[model]}: " + "; ".join(parts) + ".")
    for model in ("longwave", "bsr_derived"):
        rel_h, _ = _finest(conv, "relative_displacements", model, "hybrid")
        rel_f, _ = _finest(conv, "relative_displacements", model, "free")
        lines.append(
            f"- Imposed by the hybrid top ({MODEL_NAMES[model]}): the distance is "
            f"{rel_h:.3g} of the discrete motion with it and {rel_f:.3g} with a free top."
        )
    lines.extend(sigma_scan_note(conv, sigma_widths))
    for top in TOP_TREATMENTS:
        ct = float(comp.attrs[f"bsr_collapse_time_{top}"])
        lines.append(
            f"- BSR as printed, {top} top: collapses onto the floor at t = {ct:.3g} "
            f"sqrt(m/K) = {ct * sc_t:.3g} {units['fig2_time']}."
        )
    speeds = printed_longwave_speeds(float(comp.attrs["length_scale"]), units["fig2_length"])
    lines.append(
        "- Eq. (35) as printed for this column: linear wave speed "
        + ", ".join(f"{v:.3g} h sqrt(K/m) in {k}" for k, v in speeds.items())
        + " (the chain's: 1)."
    )
    return lines


# -------------------------------------------------------- the relaxation fit
def relaxation_fit(ens: xr.Dataset, n_boot: int = 1000, seed: int = 0, confidence=0.95):
    """What the taps do to the rest density, with Student-t intervals over replicas.

    * ``relaxed_density``: mean over the second half of the taps (per replica, then over
      replicas);
    * ``density_change``: that minus the replica's start (paired);
    * ``density_trend``: least-squares slope per tap over the second half (a drift left
      there means the run is still relaxing);
    * ``relaxation_taps``: taps until the replica-mean curve first enters the band
      relaxed ± 2 standard errors (NaN if it starts there);
    * ``band_position``: where the relaxed density sits in the stick band (0 = loosest,
      1 = densest rest state, see :func:`stick_band_densities`).

    Returns a dict quantity -> (value, unit, fit_error, ci_low, ci_high, n). ``n_boot`` and
    ``seed`` are kept for interface stability (the intervals are t-intervals).
    """
    rep = ens["density_replicas"].values
    taps = ens["tap"].values.astype(float)
    late = taps >= max(1.0, taps[-1] / 2)
    unit = "mass/length"
    per_rep = np.nanmean(rep[:, late], axis=1)
    m, lo, hi, n = t_interval(per_rep, confidence)
    dm, dlo, dhi, _ = t_interval(per_rep - rep[:, 0], confidence)
    slopes = np.array([np.polyfit(taps[late], r[late], 1)[0] for r in rep])
    sm, slo, shi, _ = t_interval(slopes, confidence)
    mean_curve = np.nanmean(rep, axis=0)
    sem = (hi - lo) / 2 if np.isfinite(hi) else 0.0
    inside = np.abs(mean_curve - m) <= 2 * sem
    tau = float(taps[np.argmax(inside)]) if inside.any() and not inside[0] else np.nan
    out = {
        "relaxed_density": (m, unit, np.nan, lo, hi, n),
        "density_change": (dm, unit, np.nan, dlo, dhi, n),
        "density_trend": (sm, unit + "/tap", np.nan, slo, shi, n),
        "relaxation_taps": (tau, "taps", np.nan, np.nan, np.nan, n),
    }
    a = ens.attrs
    if "density_band_low" in a:
        width = a["density_band_high"] - a["density_band_low"]
        out["band_position"] = (
            (m - a["density_band_low"]) / width,
            "1",
            np.nan,
            (lo - a["density_band_low"]) / width,
            (hi - a["density_band_low"]) / width,
            n,
        )
        out["equilibrium_density"] = (a["density_equilibrium"], unit, np.nan, np.nan, np.nan, 1)
    return out
