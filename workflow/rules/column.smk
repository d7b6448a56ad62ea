# column study (docs/column.md): runs -> ensemble -> fits -> figures (no init stage: the start is
# the closed-form equilibrium of Eq. 27, perturbed per replica inside the runs).
# Rules only call `granpipe column <stage>`; params carry the exact config subset each rule
# depends on (granpipe.column.layout.rule_params), so an edit reruns what it touches: a figure-1 column
# reruns its trajectory; relaxation physics/n_taps/batch_size/perturbation rerun the
# relaxation batches, n_replicas only adds batches; chaos physics and settings rerun the
# points, the grids add or drop points; confidence -> chaos map onwards; n_boot/units ->
# fits and figures.

from granpipe.column import layout as column_layout

COLUMN = config.get("column", {})
COLUMN_ON = enabled("column")
COLUMN_SETS = column_layout.figure_sets(COLUMN) if COLUMN_ON else []
COLUMN_BATCHES = column_layout.relaxation_batches(COLUMN) if COLUMN_ON else []
COLUMN_POINTS = column_layout.chaos_points(COLUMN) if COLUMN_ON else []
# The config subset of each rule, built in granpipe.column.layout.rule_params.
COLUMN_PARAMS = column_layout.rule_params(COLUMN) if COLUMN_ON else {}
COLUMN_RELAX = COLUMN_PARAMS.get("relaxation", {})
COLUMN_CHAOS = COLUMN_PARAMS.get("chaos", {})


wildcard_constraints:
    column_batch=r"\d{4}",
    column_set=r"[A-Za-z0-9_]+",
    column_a=r"[0-9.e+-]+",
    column_T=r"[0-9.e+-]+",


rule column_trajectories:
    """Fig. 1 data: y_i(t) of one figure-1 column over the configured taps."""
    output:
        out("column", "runs", "trajectories_{column_set}.nc"),
    params:
        json=lambda w: as_json(COLUMN_PARAMS["trajectories"][w.column_set]),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "runs", "trajectories_{column_set}.log"),
    threads: 1
    resources:
        runtime=5,
        mem_mb=1000,
    group:
        "column_small"
    shell:
        "granpipe column trajectories --params {params.json:q} --set {wildcards.column_set}"
        " --out {output:q} > {log:q} 2>&1"


rule column_relaxation:
    """Density relaxation: one batch of perturbed starts over many taps."""
    output:
        out("column", "runs", "relaxation", "batch_{column_batch}.nc"),
    params:
        json=lambda w: as_json(COLUMN_RELAX),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "runs", "relaxation_{column_batch}.log"),
    threads: 1
    resources:
        runtime=lambda w: int(5 + 0.01 * COLUMN_RELAX["n_taps"] * COLUMN_RELAX["batch_size"]),
        mem_mb=1000,
    shell:
        "granpipe column relaxation --params {params.json:q} --batch {wildcards.column_batch}"
        " --out {output:q} > {log:q} 2>&1"


rule column_chaos:
    """One (a, T) point of the chaos map: ensemble of largest Lyapunov exponents."""
    output:
        out("column", "runs", "chaos", "a={column_a},T={column_T}.nc"),
    params:
        json=lambda w: as_json(COLUMN_CHAOS),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "runs", "chaos_a={column_a},T={column_T}.log"),
    threads: 1
    resources:
        runtime=lambda w: int(5 + 0.05 * COLUMN_CHAOS["n_replicas"] * COLUMN_CHAOS["taps"]),
        mem_mb=1000,
    group:
        "column_chaos"
    shell:
        "granpipe column chaos --params {params.json:q} --a {wildcards.column_a}"
        " --T {wildcards.column_T} --out {output:q} > {log:q} 2>&1"


rule column_continuum:
    """Fig. 2 data: discrete column, long-wave and BSR solutions, their distances."""
    output:
        out("column", "runs", "continuum.nc"),
    params:
        json=lambda w: as_json(COLUMN_PARAMS["continuum"]),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "runs", "continuum.log"),
    threads: 1
    resources:
        runtime=10,
        mem_mb=2000,
    shell:
        "granpipe column continuum --params {params.json:q} --out {output:q} > {log:q} 2>&1"


rule column_convergence:
    """Both continuum solvers under grid refinement on the Fig. 2 problem."""
    output:
        out("column", "runs", "convergence.nc"),
    params:
        json=lambda w: as_json(COLUMN_PARAMS["convergence"]),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "runs", "convergence.log"),
    threads: 1
    resources:
        runtime=20,
        mem_mb=2000,
    shell:
        "granpipe column convergence --params {params.json:q} --out {output:q} > {log:q} 2>&1"


rule column_ensemble_relaxation:
    """Relaxation batches -> per-tap mean, spread, standard error, count, stick band."""
    input:
        [out("column", "runs", "relaxation", f"batch_{b}.nc") for b in COLUMN_BATCHES],
    output:
        out("column", "ensemble", "relaxation.nc"),
    params:
        json=lambda w: as_json(COLUMN_PARAMS["ensemble_relaxation"]),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "ensemble", "relaxation.log"),
    threads: 1
    resources:
        runtime=5,
        mem_mb=2000,
    shell:
        "granpipe column ensemble --params {params.json:q} --kind relaxation"
        " --out {output:q} {input:q} > {log:q} 2>&1"


rule column_ensemble_chaos:
    """Chaos points -> the (a, T) map with t-intervals and the chaotic/regular flags."""
    input:
        [out("column", "runs", "chaos", f"{pt}.nc") for pt in COLUMN_POINTS],
    output:
        out("column", "ensemble", "chaos_map.nc"),
    params:
        json=lambda w: as_json(COLUMN_PARAMS["ensemble_chaos"]),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "ensemble", "chaos_map.log"),
    threads: 1
    resources:
        runtime=5,
        mem_mb=2000,
    shell:
        "granpipe column ensemble --params {params.json:q} --kind chaos"
        " --out {output:q} {input:q} > {log:q} 2>&1"


rule column_fits:
    """Relaxation statistics, chaos thresholds, the Theorem 1 note, continuum distances."""
    input:
        relaxation=rules.column_ensemble_relaxation.output[0],
        chaos=rules.column_ensemble_chaos.output[0],
        continuum=rules.column_continuum.output[0],
        convergence=rules.column_convergence.output[0],
    output:
        nc=out("column", "fits", "column_fits.nc"),
        summary=out("column", "fits", "summary.csv"),
        note=report(
            out("column", "fits", "theorem1_and_continuum.md"),
            category="column",
            caption="../report/column_note.rst",
        ),
    params:
        json=lambda w: as_json(COLUMN_PARAMS["fits"]),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "fits.log"),
    threads: 1
    resources:
        runtime=5,
        mem_mb=2000,
    shell:
        "granpipe column fits --params {params.json:q} --relaxation {input.relaxation:q}"
        " --chaos {input.chaos:q} --continuum {input.continuum:q}"
        " --convergence {input.convergence:q} --out-csv {output.summary:q}"
        " --out-nc {output.nc:q} --out-note {output.note:q} > {log:q} 2>&1"


rule column_figures:
    """Figures 1-6 (PNG for the report, PDF beside them)."""
    input:
        trajectories=[out("column", "runs", f"trajectories_{s}.nc") for s in COLUMN_SETS],
        continuum=rules.column_continuum.output[0],
        relaxation=rules.column_ensemble_relaxation.output[0],
        chaos=rules.column_ensemble_chaos.output[0],
        convergence=rules.column_convergence.output[0],
    output:
        png=[
            report(
                out("column", "figures", f"{name}.png"),
                category="column",
                caption=f"../report/column_{name.split('_')[0]}.rst",
            )
            for name in column_layout.FIGURES
        ],
        pdf=[out("column", "figures", f"{name}.pdf") for name in column_layout.FIGURES],
    params:
        json=lambda w: as_json(COLUMN_PARAMS["figures"]),
        outdir=lambda w, output: str(Path(output.png[0]).parent),
        traj=lambda w, input: [a for p in input.trajectories for a in ("--trajectories", p)],
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "figures.log"),
    threads: 1
    resources:
        runtime=10,
        mem_mb=2000,
    shell:
        "granpipe column figures --params {params.json:q} {params.traj:q}"
        " --continuum {input.continuum:q} --relaxation {input.relaxation:q}"
        " --chaos {input.chaos:q} --convergence {input.convergence:q}"
        " --outdir {params.outdir:q} > {log:q} 2>&1"


if COLUMN_ON:
    # run files are targets too: a plain rerun recomputes any that a killed job removed
    register_targets(
        "column",
        lambda: [
            *rules.column_figures.output,
            rules.column_fits.output.summary,
            rules.column_fits.output.note,
            *[out("column", f) for f in column_layout.run_files(COLUMN)],
        ],
    )
