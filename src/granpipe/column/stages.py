"""The column study's stages as file-to-file functions (the CLI calls these; rules call
the CLI; docs/architecture.md, "Stages").

Stage map (outputs under ``results/<scale>/column/``):

* runs:     :func:`trajectories_stage` (Fig. 1 columns), :func:`relaxation_stage` (one
            batch of replicas), :func:`chaos_stage` (one (a, T) point of the map: Lyapunov
            exponents and return-map periods), :func:`continuum_stage` (discrete vs L-W
            vs BSR), :func:`convergence_stage` (continuum solvers under refinement)
* ensemble: :func:`ensemble_stage` (relaxation batches or chaos points → means, spreads,
            intervals)
* fits:     :func:`fits_stage` (relaxation fit, chaos thresholds, return-map periods,
            continuum distances → summary.csv, fits netCDF and the Theorem 1 note)
* figures:  :func:`figures_stage` (fig1–fig6, PNG and PDF)

Each takes ``params``, the exact config subset its rule depends on (stored as the
output's ``config_subset``); progress goes to stderr. Input files are checked to be the
study's, stage's and kind's they should be (RunFileError names the file).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path


def _log(msg):
    print(f"[column {time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def _write(ds, out, params, seeds=None, **attrs):
    from ..io import write_dataset

    write_dataset(ds, out, config_subset=params, seeds=seeds, study="column", **attrs)
    _log(f"wrote {out}")


def _inputs(paths, stage, kind, hashes):
    """Read column files and check that each is a ``stage`` file of ``kind`` computed from
    the config subset whose hash the stage was asked for: ``hashes`` is one hash for
    every file, or a mapping from the file's name attribute (``set``, or the chaos point
    ``a=..,T=..``) to its hash.

    Raises RunFileError naming the file: unreadable, from another study, stage, kind or
    configuration.
    """
    from ..io import RunFileError, expect_input, read_dataset

    out = []
    for p in paths:
        ds = read_dataset(p)
        expect_input(ds, p, study="column", stage=stage, kind=kind)
        if isinstance(hashes, str):
            want = hashes
        else:
            name = _name(ds)
            if name not in hashes:
                raise RunFileError(
                    f"{p} holds the {kind} {name!r}, which this stage was not asked for "
                    f"(expected one of: {', '.join(hashes)})"
                )
            want = hashes[name]
        expect_input(ds, p, study="column", stage=stage, kind=kind, config_hash=want)
        out.append(ds)
    return out


def _name(ds):
    """A trajectories file's set, or a chaos point's name ``a=<a>,T=<T>``."""
    if ds.attrs.get("kind") == "chaos":
        return f"a={float(ds.attrs['a']):g},T={float(ds.attrs['T']):g}"
    return str(ds.attrs.get("set"))


def _reduced_inputs(params, relax_path, chaos_path, cont_path, conv_path):
    """The fits' and figures' inputs, each checked to be the file its option names, computed
    from the config whose hash ``params["inputs"]`` holds (RunFileError names the file)."""
    want = params["inputs"]
    (ens,) = _inputs([relax_path], "ensemble", "relaxation", want["relaxation"])
    (cmap,) = _inputs([chaos_path], "ensemble", "chaos", want["chaos"])
    (comp,) = _inputs([cont_path], "runs", "continuum", want["continuum"])
    (conv,) = _inputs([conv_path], "runs", "convergence", want["convergence"])
    return ens, cmap, comp, conv


def _check_chaos_points(datasets, paths, points):
    """Chaos points: every point of the grid (``points``) once, its file's name (if
    a=..,T=..) matching its content, no replica twice in a file (RunFileError names it)."""
    import re

    from ..io import RunFileError

    seen = {}
    for ds, p in zip(datasets, paths, strict=True):
        key = _name(ds)
        m = re.fullmatch(r"a=([0-9.e+-]+),T=([0-9.e+-]+)", Path(p).stem)
        if m and (float(m.group(1)), float(m.group(2))) != (ds.attrs["a"], ds.attrs["T"]):
            raise RunFileError(f"{p} holds the point {key}, not its name's")
        if key in seen:
            raise RunFileError(f"the point {key} appears twice: {seen[key]}, {p}")
        seen[key] = p
        reps = ds["replica"].values
        if len(set(reps.tolist())) != reps.size:
            raise RunFileError(f"{p}: a replica appears twice in the point")
    missing = [pt for pt in points if pt not in seen]
    if missing:
        raise RunFileError(f"no file of the chaos point(s) {', '.join(missing)}")


def trajectories_stage(params, set_name, out):
    """Fig. 1: y_i(t) of one column over the configured taps from the equilibrium start."""
    from .protocol import trajectories

    t0 = time.time()
    ds = trajectories(
        params["sets"][set_name],
        int(params["n_taps"]),
        float(params["record_dt"]),
        float(params["step_factor"]),
    )
    ds.attrs["set"] = set_name
    _write(ds, out, params, stage="runs", kind="trajectories", wall_time_s=time.time() - t0)


def relaxation_stage(params, batch, out):
    """Density relaxation: one batch of perturbed starts over many taps."""
    from ..seeds import batch_replicas
    from .protocol import relaxation_batch

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


def chaos_stage(params, amplitude, period, out):
    """One point of the chaos map: largest Lyapunov exponents and return-map periods."""
    from .protocol import lyapunov_point

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


def continuum_stage(params, out):
    """Fig. 2 data: discrete column, L-W and BSR solutions and their distances."""
    from .protocol import continuum_comparison

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
        float(params["bsr_kernel_width"]),
    )
    _log(f"distances to the discrete column [h] (positions, displacements, relative): {dist}")
    _write(ds, out, params, stage="runs", kind="continuum", wall_time_s=time.time() - t0)


def convergence_stage(params, out):
    """Both continuum solvers under grid refinement on the Fig. 2 problem."""
    from .protocol import continuum_convergence

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
        float(params["bsr_kernel_width"]),
        [float(w) for w in c["sigma_widths"]],
        int(c["sigma_scan_refinement"]),
    )
    _log("observed orders: " + ", ".join(f"{k}: {v}" for k, v in ds.attrs.items() if "orders" in k))
    _write(ds, out, params, stage="runs", kind="convergence", wall_time_s=time.time() - t0)


def ensemble_stage(params, kind, out, inputs):
    """Reduce run files: relaxation batches → per-tap statistics; chaos points → the map."""
    from ..io import check_run_files
    from .measures import chaos_map, relaxation_ensemble

    if kind == "relaxation":
        # the batches of the column asked for, named as they hold, no replica twice
        want = params["runs_config_hash"]
        check_run_files(inputs, study="column", config_hash=want, kind=kind)
        # streamed: one batch file in memory at a time
        ds = relaxation_ensemble(_inputs([p], "runs", kind, want)[0] for p in inputs)
    else:
        datasets = _inputs(inputs, "runs", kind, params["points"])
        _check_chaos_points(datasets, inputs, params["points"])
        ds = chaos_map(datasets, float(params.get("confidence", 0.95)))
    _write(ds, out, params, stage="ensemble", kind=kind)


def fits_stage(params, relax_path, chaos_path, cont_path, conv_path, out_csv, out_nc, out_note):
    """Relaxation fit, chaos thresholds, continuum distances: summary.csv rows and a note."""
    import xarray as xr

    from ..analysis.summary import write_summary
    from ..io import write_text
    from .fits import relaxation_fit, summary_rows, theorem1_note

    ens, cmap, comp, conv = _reduced_inputs(params, relax_path, chaos_path, cont_path, conv_path)
    units = params.get("units", {"length": "m", "time": "s", "fig2_length": "cm", "fig2_time": "s"})
    fit = relaxation_fit(ens, int(params.get("n_boot", 1000)))
    widths = params.get("convergence", {}).get("sigma_widths", ())
    rows, thresholds = summary_rows(fit, cmap, comp, conv, units, widths)
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
        coords={"T": ("T", cmap["T"].values, {"units": units["time"], "long_name": "tap period"})},
        attrs={f"relaxation_{k}": float(v[0]) for k, v in fit.items()},
    )
    _write(fds, out_nc, params, stage="fits")
    note = theorem1_note(cmap, comp, conv, units, fit, widths)
    write_text(note, out_note)
    print(note)


def figures_stage(params, traj, cont_path, relax_path, chaos_path, conv_path, outdir):
    """Figures 1–6 as PNG and PDF: fig<k>_<name>.{png,pdf}."""
    from ..figures import column as F
    from ..figures import save_figure
    from .fits import relaxation_fit

    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    units = params.get("units", {"length": "m", "time": "s", "fig2_length": "cm", "fig2_time": "s"})
    ens, cmap, comp, conv = _reduced_inputs(params, relax_path, chaos_path, cont_path, conv_path)
    made = []
    made += save_figure(
        F.fig1_trajectories(
            _inputs(traj, "runs", "trajectories", params["inputs"]["trajectories"]),
            units["fig2_length"],
        ),
        out / "fig1_trajectories",
    )
    made += save_figure(F.fig2_continuum(comp), out / "fig2_continuum")
    made += save_figure(
        F.fig3_density_relaxation(ens, relaxation_fit(ens, 200), f"kg/{units['length']}"),
        out / "fig3_density_relaxation",
    )
    made += save_figure(
        F.fig4_chaos_map(cmap, units["length"], units["time"]), out / "fig4_chaos_map"
    )
    made += save_figure(
        F.fig5_continuum_convergence(conv),
        out / "fig5_continuum_convergence",
    )
    made += save_figure(F.fig6_lyapunov_estimates(cmap), out / "fig6_lyapunov_estimates")
    for m in made:
        _log(f"wrote {m}")
