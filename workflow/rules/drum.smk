# drum study (SPEC.md §1): stages init -> runs -> ensemble -> fits -> figures.
# Rules only call `granpipe drum <stage>`; params carry the exact config subset each stage
# depends on (schema defaults filled), so a config edit reruns exactly what it touches:
# physics/settle/protocol/batch_size -> everything; exclude_flagged -> ensemble onwards;
# fits -> fits and figures; figures -> figures. n_replicas only adds batches.

from granpipe.drum import layout as drum_layout
from granpipe.drum.settings import PHYSICS_KEYS as DRUM_PHYSICS_KEYS
from granpipe.drum.settings import filled as drum_filled

DRUM = drum_filled(config.get("drum", {}))
DRUM_SIM = {
    **{k: DRUM[k] for k in DRUM_PHYSICS_KEYS},
    "ensemble": pick(DRUM["ensemble"], "batch_size"),
}
DRUM_ENSEMBLE = {"ensemble": pick(DRUM["ensemble"], "exclude_flagged")}
DRUM_FITS = {**DRUM_ENSEMBLE, "fits": DRUM["fits"]}
DRUM_RUNS = [out("drum", f) for f in drum_layout.run_files(DRUM)]
DRUM_BATCH_MIN = DRUM["ensemble"]["batch_size"] * DRUM["resources"]["replica_minutes"]


wildcard_constraints:
    drum_batch=r"\d{4}",


rule drum_init:
    """Random placement and settling of the replicas of one batch."""
    output:
        out("drum", "init", drum_layout.point_name(DRUM), "batch_{drum_batch}.nc"),
    params:
        json=lambda w: as_json(DRUM_SIM),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("drum", "init", "batch_{drum_batch}.log"),
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
    """Onset window, continuous avalanche, decay window for the replicas of one batch."""
    input:
        init=rules.drum_init.output[0],
    output:
        out("drum", "runs", drum_layout.point_name(DRUM), "batch_{drum_batch}.nc"),
    params:
        json=lambda w: as_json(DRUM_SIM),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("drum", "runs", "batch_{drum_batch}.log"),
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
    """Streaming reduction of every batch to mean, standard error and count."""
    input:
        runs=DRUM_RUNS,
    output:
        out("drum", drum_layout.ensemble_file(DRUM)),
    params:
        json=lambda w: as_json(DRUM_ENSEMBLE),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("drum", "ensemble.log"),
    threads: 1
    resources:
        runtime=lambda w: 10 + len(DRUM_RUNS) // 50,
        mem_mb=2000,
    shell:
        "granpipe drum ensemble --params {params.json:q} --out {output:q} {input.runs:q}"
        " > {log:q} 2>&1"


rule drum_fits:
    """Onset time, sign changes and lags with fit errors and bootstrap CIs; summary.csv."""
    input:
        ensemble=rules.drum_ensemble.output[0],
        runs=DRUM_RUNS,
    output:
        fits=out("drum", drum_layout.fits_file(DRUM)),
        summary=report(
            out("drum", drum_layout.summary_file()),
            category="drum",
            subcategory="summary",
            caption="../report/drum_summary.rst",
        ),
    params:
        json=lambda w: as_json(DRUM_FITS),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("drum", "fits.log"),
    threads: 1
    resources:
        runtime=lambda w: 15 + len(DRUM_RUNS) // 20,
        mem_mb=4000,
    shell:
        "granpipe drum fits --params {params.json:q} --ensemble {input.ensemble:q}"
        " --out {output.fits:q} --summary {output.summary:q} {input.runs:q} > {log:q} 2>&1"


rule drum_figures:
    """Figs. 2-5 of the paper (PNG for the report, PDF beside them)."""
    input:
        ensemble=rules.drum_ensemble.output[0],
        fits=rules.drum_fits.output.fits,
        snapshot=out("drum", drum_layout.run_file(DRUM, DRUM["figures"]["snapshot_batch"])),
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
        pdf=[out("drum", f) for f in drum_layout.figure_files(("pdf",))],
    params:
        json=lambda w: as_json({"figures": DRUM["figures"]}),
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
        "granpipe drum figures --params {params.json:q} --ensemble {input.ensemble:q}"
        " --fits {input.fits:q} --snapshot {input.snapshot:q} --outdir {params.outdir:q}"
        " > {log:q} 2>&1"


register_targets(
    "drum",
    lambda: [
        *rules.drum_figures.output,
        rules.drum_fits.output.summary,
    ],
)
