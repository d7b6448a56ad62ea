"""``granpipe column <stage>``: the column study's workflow stages (docs/architecture.md).

Stage map (outputs under ``results/<scale>/column/``):

* runs:     ``trajectories`` (Fig. 1 columns), ``relaxation`` (one batch of replicas),
            ``chaos`` (one (a, T) point of the map: Lyapunov exponents and return-map
            periods), ``continuum`` (discrete vs L-W vs BSR),
            ``convergence`` (continuum solvers under refinement)
* ensemble: ``ensemble --kind relaxation|chaos`` (batches → means, spreads, intervals)
* fits:     ``fits`` (relaxation fit, chaos thresholds, return-map periods, continuum
            distances → summary.csv, fits netCDF and the Theorem 1 note)
* figures:  ``figures`` (fig1–fig6, PNG and PDF)

The column has no separate init stage: its start is the closed-form equilibrium (Eq. 27),
perturbed per replica inside the runs.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import click

from ..cli import params_option

cli = click.Group(
    "column", help="Tapped column of particles (docs/column.md): stages of the study."
)


def _log(msg):
    click.echo(f"[column {time.strftime('%H:%M:%S')}] {msg}", err=True)
    sys.stderr.flush()


def _write(ds, out, params, seeds=None, **attrs):
    from ..io import write_dataset

    write_dataset(ds, out, config_subset=params, seeds=seeds, study="column", **attrs)
    _log(f"wrote {out}")


def _inputs(paths, stage, kind):
    """Read column files and check that each is a ``stage`` file of ``kind``.

    Raises RunFileError naming the file: unreadable, from another study, stage or kind.
    """
    from ..io import expect_attrs, read_dataset

    out = []
    for p in paths:
        ds = read_dataset(p)
        expect_attrs(ds, p, study="column", stage=stage, kind=kind)
        out.append(ds)
    return out


def _same_physics(datasets, paths, ignore=()):
    """Refuse (naming the file) datasets whose config physics differ beyond ``ignore``."""
    from ..io import RunFileError, config_from_attrs

    ref = None
    for ds, p in zip(datasets, paths, strict=True):
        phys = {k: v for k, v in config_from_attrs(ds).get("physics", {}).items()}
        for k in ignore:
            phys.pop(k, None)
        if ref is None:
            ref = (phys, p)
        elif phys != ref[0]:
            raise RunFileError(
                f"{p} was computed for another column than {ref[1]}: physics {phys} "
                f"against {ref[0]}"
            )


def _reduced_inputs(relax_path, chaos_path, cont_path, conv_path):
    """The fits' and figures' inputs, each checked to be the file its option names, the
    continuum and convergence runs of one column (RunFileError names the file)."""
    (ens,) = _inputs([relax_path], "ensemble", "relaxation")
    (cmap,) = _inputs([chaos_path], "ensemble", "chaos")
    (comp,) = _inputs([cont_path], "runs", "continuum")
    (conv,) = _inputs([conv_path], "runs", "convergence")
    _same_physics([comp, conv], [cont_path, conv_path])
    return ens, cmap, comp, conv


def _check_chaos_points(datasets, paths):
    """Chaos points: one file per (a, T), its name (if a=..,T=..) matching its content,
    the same column otherwise, and no replica twice in a file (RunFileError names it)."""
    import re

    from ..io import RunFileError

    seen = {}
    for ds, p in zip(datasets, paths, strict=True):
        key = (float(ds.attrs["a"]), float(ds.attrs["T"]))
        m = re.fullmatch(r"a=([0-9.e+-]+),T=([0-9.e+-]+)", Path(p).stem)
        if m and (float(m.group(1)), float(m.group(2))) != key:
            raise RunFileError(f"{p} holds the point a={key[0]:g}, T={key[1]:g}, not its name's")
        if key in seen:
            raise RunFileError(
                f"the point a={key[0]:g}, T={key[1]:g} appears twice: {seen[key]}, {p}"
            )
        seen[key] = p
        reps = ds["replica"].values
        if len(set(reps.tolist())) != reps.size:
            raise RunFileError(f"{p}: a replica appears twice in the point")
    _same_physics(datasets, paths, ignore=("a", "T"))


@cli.command("trajectories")
@params_option
@click.option("--set", "set_name", required=True, help="Name of the column in params['sets'].")
@click.option("--out", required=True, type=click.Path(dir_okay=False))
def trajectories_cmd(params, set_name, out):
    """Fig. 1: y_i(t) of one column over the configured taps from the equilibrium start."""
    from .study import trajectories

    t0 = time.time()
    ds = trajectories(
        params["sets"][set_name],
        int(params["n_taps"]),
        float(params["record_dt"]),
        float(params["step_factor"]),
    )
    ds.attrs["set"] = set_name
    _write(ds, out, params, stage="runs", kind="trajectories", wall_time_s=time.time() - t0)


@cli.command("relaxation")
@params_option
@click.option("--batch", required=True, type=int, help="Batch index (fixed replica range).")
@click.option("--out", required=True, type=click.Path(dir_okay=False))
def relaxation_cmd(params, batch, out):
    """Density relaxation: one batch of perturbed starts over many taps."""
    from ..seeds import batch_replicas
    from .study import relaxation_batch

    t0 = time.time()
    # a batch is always full, so that n_replicas only adds batches (docs/architecture.md,
    # "Seeds, batches, growing ensembles")
    reps = list(batch_replicas(batch, int(params["batch_size"])))
    _log(f"relaxation batch {batch}: replicas {reps}, {params['n_taps']} taps")
    ds, seeds = relaxation_batch(
        params["physics"],
        reps,
        int(params["n_taps"]),
        float(params["perturbation"]),
        float(params["step_factor"]),
    )
    _write(
        ds,
        out,
        params,
        seeds=seeds,
        stage="runs",
        kind="relaxation",
        batch=batch,
        wall_time_s=time.time() - t0,
    )


@cli.command("chaos")
@params_option
@click.option("--a", "amplitude", required=True, type=float, help="Tap amplitude a.")
@click.option("--T", "period", required=True, type=float, help="Tap period T.")
@click.option("--out", required=True, type=click.Path(dir_okay=False))
def chaos_cmd(params, amplitude, period, out):
    """One point of the chaos map: largest Lyapunov exponents and return-map periods."""
    from .study import lyapunov_point

    t0 = time.time()
    phys = {**params["physics"], "a": amplitude, "T": period}
    ds, seeds = lyapunov_point(
        phys,
        range(int(params["n_replicas"])),
        int(params["transient_taps"]),
        int(params["taps"]),
        float(params["perturbation"]),
        float(params["twin_epsilon"]),
        bool(params["plain"]),
        float(params["step_factor"]),
        int(params.get("return_max_period", 6)),
        int(params.get("return_taps", 12)),
        float(params.get("return_tolerance", 1e-6)),
    )
    _log(
        f"a={amplitude:g} T={period:g}: lambda/tap = {ds['lambda_tap'].values.round(3).tolist()}"
        f" twin {ds['lambda_twin'].values.round(3).tolist()}"
        f" return-map periods {ds['return_period'].values.tolist()}"
    )
    _write(
        ds,
        out,
        {**params, "physics": phys},
        seeds=seeds,
        stage="runs",
        kind="chaos",
        wall_time_s=time.time() - t0,
    )


@cli.command("continuum")
@params_option
@click.option("--out", required=True, type=click.Path(dir_okay=False))
def continuum_cmd(params, out):
    """Fig. 2 data: discrete column, L-W and BSR solutions and their distances."""
    from .study import continuum_comparison

    t0 = time.time()
    ds, dist = continuum_comparison(
        params["physics"],
        int(params["n_taps"]),
        int(params["lw_refinement"]),
        int(params["bsr_refinement"]),
        float(params["record_dt"]),
        float(params["sigma_width"]),
        float(params["step_factor"]),
        int(params["bsr_derived_refinement"]),
    )
    _log(f"distances to the discrete column [h] (positions, displacements, relative): {dist}")
    _write(ds, out, params, stage="runs", kind="continuum", wall_time_s=time.time() - t0)


@cli.command("convergence")
@params_option
@click.option("--out", required=True, type=click.Path(dir_okay=False))
def convergence_cmd(params, out):
    """Both continuum solvers under grid refinement on the Fig. 2 problem."""
    from .study import continuum_convergence

    t0 = time.time()
    c = params["convergence"]
    ds = continuum_convergence(
        params["physics"],
        float(c["t_end"]),
        c["lw_refinements"],
        c["bsr_refinements"],
        float(c["bsr_t_end"]),
        float(params["sigma_width"]),
        float(params["step_factor"]),
        c["bsr_derived_refinements"],
    )
    _log("observed orders: " + ", ".join(f"{k}: {v}" for k, v in ds.attrs.items() if "orders" in k))
    _write(ds, out, params, stage="runs", kind="convergence", wall_time_s=time.time() - t0)


@cli.command("ensemble")
@params_option
@click.option("--kind", required=True, type=click.Choice(["relaxation", "chaos"]))
@click.option("--out", required=True, type=click.Path(dir_okay=False))
@click.argument("inputs", nargs=-1, required=True, type=click.Path(exists=True))
def ensemble_cmd(params, kind, out, inputs):
    """Reduce run files: relaxation batches → per-tap statistics; chaos points → the map."""
    from ..io import check_run_files
    from .study import chaos_map, relaxation_ensemble

    if kind == "relaxation":
        # one column, batches named as they hold, no replica twice
        check_run_files(inputs, study="column")
    datasets = _inputs(inputs, "runs", kind)
    if kind == "relaxation":
        ds = relaxation_ensemble(datasets)
    else:
        _check_chaos_points(datasets, inputs)
        ds = chaos_map(datasets, float(params.get("confidence", 0.95)))
    _write(ds, out, params, stage="ensemble", kind=kind)


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
    import numpy as np

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


def _theorem1_note(cmap, dist, conv, units, relax=None):
    """Plain-text reading of the chaos map against Theorem 1, and the continuum distances."""
    import numpy as np

    from .study import continuum_note

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
    lines.extend(continuum_note(dist, conv, units))
    return "\n".join(lines) + "\n"


@cli.command("fits")
@params_option
@click.option("--relaxation", "relax_path", required=True, type=click.Path(exists=True))
@click.option("--chaos", "chaos_path", required=True, type=click.Path(exists=True))
@click.option("--continuum", "cont_path", required=True, type=click.Path(exists=True))
@click.option("--convergence", "conv_path", required=True, type=click.Path(exists=True))
@click.option("--out-csv", required=True, type=click.Path(dir_okay=False))
@click.option("--out-nc", required=True, type=click.Path(dir_okay=False))
@click.option("--out-note", required=True, type=click.Path(dir_okay=False))
def fits_cmd(params, relax_path, chaos_path, cont_path, conv_path, out_csv, out_nc, out_note):
    """Relaxation fit, chaos thresholds, continuum distances: summary.csv rows and a note."""
    import numpy as np
    import xarray as xr

    from ..analysis.summary import summary_row, write_summary
    from ..io import write_text
    from .study import continuum_rows, relaxation_fit

    ens, cmap, comp, conv = _reduced_inputs(relax_path, chaos_path, cont_path, conv_path)
    units = params.get("units", {"length": "m", "time": "s", "fig2_length": "cm", "fig2_time": "s"})
    rows = []

    def row(q, v, unit, err=None, lo=None, hi=None, n=None):
        rows.append(summary_row("column", q, v, unit, err, lo, hi, n))

    fit = relaxation_fit(ens, int(params.get("n_boot", 1000)))
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
    rows.extend(continuum_rows(comp, conv, units["fig2_length"]))
    # the column's own file: rewritten whole (merge=False), so a dropped grid point leaves
    write_summary(rows, out_csv, merge=False)
    _log(f"wrote {out_csv} ({len(rows)} rows)")
    fds = xr.Dataset(
        {
            "chaos_onset_amplitude": (
                "T",
                thresholds,
                {
                    "units": units["length"],
                    "long_name": "smallest amplitude with a chaotic point (NaN: none)",
                },
            )
        },
        coords={"T": ("T", T, {"units": units["time"], "long_name": "tap period"})},
        attrs={f"relaxation_{k}": float(v[0]) for k, v in fit.items()},
    )
    _write(fds, out_nc, params, stage="fits")
    note = _theorem1_note(cmap, comp, conv, units, fit)
    write_text(note, out_note)
    click.echo(note)


@cli.command("figures")
@params_option
@click.option("--trajectories", "traj", required=True, multiple=True, type=click.Path(exists=True))
@click.option("--continuum", "cont_path", required=True, type=click.Path(exists=True))
@click.option("--relaxation", "relax_path", required=True, type=click.Path(exists=True))
@click.option("--chaos", "chaos_path", required=True, type=click.Path(exists=True))
@click.option("--convergence", "conv_path", required=True, type=click.Path(exists=True))
@click.option("--outdir", required=True, type=click.Path(file_okay=False))
def figures_cmd(params, traj, cont_path, relax_path, chaos_path, conv_path, outdir):
    """Figures 1–6 as PNG and PDF: fig<k>_<name>.{png,pdf}."""
    from ..figures import column as F
    from .study import relaxation_fit

    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    units = params.get("units", {"length": "m", "time": "s", "fig2_length": "cm", "fig2_time": "s"})
    ens, cmap, comp, conv = _reduced_inputs(relax_path, chaos_path, cont_path, conv_path)
    made = []
    made += F.save(
        F.fig1_trajectories(_inputs(traj, "runs", "trajectories"), units["fig2_length"]),
        out / "fig1_trajectories",
    )
    made += F.save(F.fig2_continuum(comp), out / "fig2_continuum")
    made += F.save(
        F.fig3_density_relaxation(ens, relaxation_fit(ens, 200), f"kg/{units['length']}"),
        out / "fig3_density_relaxation",
    )
    made += F.save(F.fig4_chaos_map(cmap, units["length"], units["time"]), out / "fig4_chaos_map")
    made += F.save(
        F.fig5_continuum_convergence(conv),
        out / "fig5_continuum_convergence",
    )
    made += F.save(F.fig6_lyapunov_estimates(cmap), out / "fig6_lyapunov_estimates")
    for m in made:
        _log(f"wrote {m}")
