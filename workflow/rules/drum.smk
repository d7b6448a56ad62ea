# drum study (docs/drum.md): per parameter point init -> runs -> ensemble -> fits, then
# one summary and the figures. Rules only call `granpipe drum <stage>`; params carry the
# exact config subset each stage depends on, built in granpipe.drum.layout.rule_params,
# so a config edit reruns exactly what it touches: a point's physics/settle/protocol or
# batch_size -> that point's simulations and everything after; exclude_flagged ->
# ensembles onwards; fits -> fits, summary and figures; figures -> figures. n_replicas
# only adds batches; a new period, start-up or friction law only adds its point.

import re

from granpipe.drum import layout as drum_layout
from granpipe.drum.layout import filled as drum_filled

DRUM = drum_filled(config.get("drum", {}))
DRUM_POINTS = drum_layout.point_sections(DRUM)
DRUM_PARAMS = drum_layout.rule_params(DRUM)
DRUM_REF = next(iter(DRUM_POINTS))
DRUM_BATCH_MIN = DRUM["ensemble"]["batch_size"] * DRUM["resources"]["replica_minutes"]


DRUM_RUNS = {p: [out("drum", f) for f in drum_layout.run_files(DRUM, p)] for p in DRUM_POINTS}
# A point's folder from four wildcards: a wildcard value holding "," or "=" would break
# the job specifications Snakemake passes to grouped cluster jobs.
DRUM_POINT = drum_layout.POINT_PATTERN


wildcard_constraints:
    drum_batch=r"\d{4}",
    drum_n=r"\d+",
    drum_period=r"[0-9.e+]+",
    drum_startup="|".join(re.escape(s) for s in drum_layout.STARTUPS),
    drum_friction=drum_layout.FRICTION_WILDCARD,


rule drum_init:
    """Random placement and start-up of the replicas of one batch of one point."""
    output:
        out("drum", "init", DRUM_POINT, "batch_{drum_batch}.nc"),
    params:
        json=lambda w: as_json(DRUM_PARAMS["sim"][drum_layout.point_of(w)]),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("drum", "init", DRUM_POINT, "batch_{drum_batch}.log"),
    threads: DRUM["ensemble"]["threads"]
    resources:
        runtime=lambda w, threads: int(10 + 0.3 * DRUM_BATCH_MIN / threads),
        mem_mb=DRUM["resources"]["mem_mb"],
    group:
        "drum_sim"
    shell:
        "granpipe drum init --params {params.json:q} --batch {wildcards.drum_batch}"
        " --threads {threads} --out {output:q} > {log:q} 2>&1"


rule drum_runs:
    """Onset window, continuous avalanche, decay window for one batch of one point."""
    input:
        init=rules.drum_init.output[0],
    output:
        out("drum", "runs", DRUM_POINT, "batch_{drum_batch}.nc"),
    params:
        json=lambda w: as_json(DRUM_PARAMS["sim"][drum_layout.point_of(w)]),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("drum", "runs", DRUM_POINT, "batch_{drum_batch}.log"),
    threads: DRUM["ensemble"]["threads"]
    resources:
        runtime=lambda w, threads: int(10 + 1.2 * DRUM_BATCH_MIN / threads),
        mem_mb=DRUM["resources"]["mem_mb"],
    group:
        "drum_sim"
    shell:
        "granpipe drum runs --params {params.json:q} --batch {wildcards.drum_batch}"
        " --threads {threads} --init {input.init:q} --out {output:q} > {log:q} 2>&1"


rule drum_ensemble:
    """Streaming reduction of every batch of one point to mean, standard error and count."""
    input:
        runs=lambda w: DRUM_RUNS[drum_layout.point_of(w)],
    output:
        out("drum", "ensemble", f"{DRUM_POINT}.nc"),
    params:
        json=lambda w: as_json(DRUM_PARAMS["ensemble"][drum_layout.point_of(w)]),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("drum", "ensemble", f"{DRUM_POINT}.log"),
    threads: 1
    resources:
        runtime=lambda w: 10 + len(DRUM_RUNS[drum_layout.point_of(w)]) // 50,
        mem_mb=2000,
    shell:
        "granpipe drum ensemble --params {params.json:q} --out {output:q} {input.runs:q}"
        " > {log:q} 2>&1"


rule drum_fits:
    """Onset time, sign changes and lags of one point with fit errors and bootstrap CIs."""
    input:
        ensemble=rules.drum_ensemble.output[0],
        runs=lambda w: DRUM_RUNS[drum_layout.point_of(w)],
    output:
        out("drum", "fits", f"{DRUM_POINT}.nc"),
    params:
        json=lambda w: as_json(DRUM_PARAMS["fits"][drum_layout.point_of(w)]),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("drum", "fits", f"{DRUM_POINT}.log"),
    threads: 1
    resources:
        runtime=lambda w: 15 + len(DRUM_RUNS[drum_layout.point_of(w)]) // 20,
        mem_mb=4000,
    shell:
        "granpipe drum fits --params {params.json:q} --ensemble {input.ensemble:q}"
        " --out {output:q} {input.runs:q} > {log:q} 2>&1"


rule drum_summary:
    """Every point's fitted numbers in summary.csv, the paper's beside the reference's."""
    input:
        fits=[out("drum", drum_layout.fits_file(p)) for p in DRUM_POINTS],
    output:
        report(
            out("drum", drum_layout.summary_file()),
            category="drum",
            subcategory="summary",
            caption="../report/drum_summary.rst",
        ),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("drum", "summary.log"),
    threads: 1
    resources:
        runtime=10,
        mem_mb=1000,
    shell:
        "granpipe drum summary --out {output:q} {input.fits:q} > {log:q} 2>&1"


rule drum_figures:
    """Figs. 2-5 of the paper and Fig. 9 (aligned on each pile's avalanche) for the
    reference point, and Figs. 6-8 across points."""
    input:
        ensembles=[out("drum", drum_layout.ensemble_file(p)) for p in DRUM_POINTS],
        fits=[out("drum", drum_layout.fits_file(p)) for p in DRUM_POINTS],
        snapshot=out(
            "drum", drum_layout.run_file(DRUM_POINTS[DRUM_REF], DRUM["figures"]["snapshot_batch"])
        ),
    output:
        fig2=report(
            out("drum", "figures", "fig2_snapshot.png"),
            category="drum",
            caption="../report/drum_fig2.rst",
        ),
        fig3=report(
            out("drum", "figures", "fig3_onset.png"),
            category="drum",
            caption="../report/drum_fig3.rst",
        ),
        fig4=report(
            out("drum", "figures", "fig4_decay.png"),
            category="drum",
            caption="../report/drum_fig4.rst",
        ),
        fig5=report(
            out("drum", "figures", "fig5_lambda_vs_speed.png"),
            category="drum",
            caption="../report/drum_fig5.rst",
        ),
        fig6=report(
            out("drum", "figures", "fig6_startup.png"),
            category="drum",
            caption="../report/drum_fig6.rst",
        ),
        fig7=report(
            out("drum", "figures", "fig7_lag_vs_rotation.png"),
            category="drum",
            caption="../report/drum_fig7.rst",
        ),
        fig8=report(
            out("drum", "figures", "fig8_friction.png"),
            category="drum",
            caption="../report/drum_fig8.rst",
        ),
        fig9=report(
            out("drum", "figures", "fig9_aligned.png"),
            category="drum",
            caption="../report/drum_fig9.rst",
        ),
        pdf=[out("drum", f) for f in drum_layout.figure_files(("pdf",))],
    params:
        json=lambda w: as_json(DRUM_PARAMS["figures"]),
        # option lists, each path quoted by Snakemake ({params.ensembles:q})
        ensembles=lambda w, input: [a for e in input.ensembles for a in ("--ensemble", e)],
        fits=lambda w, input: [a for f in input.fits for a in ("--fits", f)],
        outdir=lambda w, output: str(Path(output.fig2).parent),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("drum", "figures.log"),
    threads: 1
    resources:
        runtime=10,
        mem_mb=2000,
    shell:
        "granpipe drum figures --params {params.json:q} {params.ensembles:q}"
        " {params.fits:q} --snapshot {input.snapshot:q} --outdir {params.outdir:q}"
        " > {log:q} 2>&1"


# The run files are targets too: after a killed job (or a killed --forcerun, which removes
# them first) a plain rerun recomputes the missing ones, and everything after them.
rule drum_movie:
    """The report's movies: one replica of the reference point replayed around its pile's
    flow onset and stop (docs/watching.md); after the reference fits, which check the
    run files first."""
    input:
        runs=out("drum", drum_layout.movie_input(DRUM)),
        fits=out("drum", drum_layout.fits_file(DRUM_REF)),
    output:
        report(out("drum", "movie", f"{DRUM_REF}_{{drum_window}}.{DRUM['movie']['format']}"),
               category="drum", subcategory="movie", caption="../report/drum_movie.rst"),
    wildcard_constraints:
        drum_window="onset|decay",
    params:
        json=lambda w: as_json(drum_layout.movie_params(DRUM)),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("drum", "movie_{drum_window}.log"),
    threads: 1
    resources:
        runtime=lambda w: int(10 + DRUM["resources"]["replica_minutes"]),
        mem_mb=2000,
    shell:
        "granpipe drum movie --params {params.json:q} --part {wildcards.drum_window}"
        " --out {output:q} {input.runs:q} > {log:q} 2>&1"


register_targets(
    "drum",
    lambda: [
        *[out("drum", drum_layout.movie_file(DRUM, w)) for w in DRUM["movie"]["windows"]
          if DRUM["movie"]["enabled"]],
        *rules.drum_figures.output,
        rules.drum_summary.output[0],
        *[f for files in DRUM_RUNS.values() for f in files],
    ],
)
