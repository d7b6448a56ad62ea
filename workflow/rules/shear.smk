# shear study (docs/shear.md): per packing fraction runs -> fits, then one summary and the
# figures (no init or ensemble stage: the preparation is part of each replica's run, and
# the event-triggered averages read every replica's record). Rules only call
# `granpipe shear <stage>`; params carry the exact config subset each stage depends on
# (granpipe.shear.layout), so an edit reruns what it touches: physics, preparation,
# protocol, events.edge_cutoff or batch_size -> the runs; the detector's thresholds and
# fits -> fits onwards; figures -> figures. n_replicas only adds batches; a new phi only
# adds its point. A variant's points sit in a folder of its name ("wide/phi=0.82"): the
# group wildcard is that folder or empty (the base section). The phi wildcard holds the
# number alone (a value with "=" or "," would break the job specifications SLURM jobs
# carry).

from granpipe.shear import layout as shear_layout

SHEAR = config.get("shear", {})
SHEAR_ON = enabled("shear")
SHEAR_POINTS = shear_layout.points(SHEAR) if SHEAR_ON else []
SHEAR_DRUM = [out("drum", drum_layout.fits_file(DRUM_REF))] if SHEAR_ON and enabled("drum") else []


wildcard_constraints:
    shear_group=r"(|[A-Za-z][A-Za-z0-9_]*/)",
    shear_phi=r"[0-9.e+-]+",
    shear_batch=r"\d{4}",


rule shear_runs:
    """One batch of replicas at one packing fraction: preparation and record."""
    output:
        out("shear", "runs", "{shear_group}phi={shear_phi}", "batch_{shear_batch}.nc"),
    params:
        json=lambda w: as_json(shear_layout.runs_params(SHEAR, shear_layout.wildcards_point(w))),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("shear", "runs", "{shear_group}phi={shear_phi}", "batch_{shear_batch}.log"),
    threads: 1
    resources:
        runtime=lambda w: int(5 + SHEAR["ensemble"]["batch_size"] * SHEAR["resources"]["replica_minutes"]),
        mem_mb=lambda w: SHEAR["resources"]["mem_mb"],
    shell:
        "granpipe shear runs --params {params.json:q} --batch {wildcards.shear_batch}"
        " --out {output:q} > {log:q} 2>&1"


rule shear_fits:
    """A point's ⟨λ⟩, rearrangements, event-triggered λ̄ and lead time, correlations, the
    jamming measures, and the predictions of when and where the packing rearranges."""
    input:
        lambda w: [out("shear", shear_layout.run_file(shear_layout.wildcards_point(w), b))
                   for b in shear_layout.batches(SHEAR, shear_layout.wildcards_point(w))],
    output:
        out("shear", "fits", "{shear_group}phi={shear_phi}.nc"),
    params:
        json=lambda w: as_json(shear_layout.fits_params(SHEAR, shear_layout.wildcards_point(w))),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("shear", "fits", "{shear_group}phi={shear_phi}.log"),
    threads: 1
    resources:
        runtime=10,
        mem_mb=lambda w: SHEAR["resources"]["mem_mb"],
    shell:
        "granpipe shear fits --params {params.json:q} --out {output:q} {input:q} > {log:q} 2>&1"


rule shear_summary:
    """Every point's rows, and each variant's transition and jamming point across φ."""
    input:
        [out("shear", shear_layout.fits_file(p)) for p in SHEAR_POINTS],
    output:
        report(out("shear", "fits", "summary.csv"), category="shear", subcategory="summary",
               caption="../report/shear_summary.rst"),
    params:
        json=lambda w: as_json(shear_layout.summary_params(SHEAR)),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("shear", "summary.log"),
    threads: 1
    resources:
        runtime=10,
        mem_mb=1000,
    shell:
        "granpipe shear summary --params {params.json:q} --out {output:q} {input:q} > {log:q} 2>&1"


rule shear_figures:
    """Figs. 1-7; the contrast figure with the drum's aligned λ̄ when the scale runs the drum."""
    input:
        fits=[out("shear", shear_layout.fits_file(p)) for p in SHEAR_POINTS],
        drum=SHEAR_DRUM,
    output:
        png=[report(out("shear", "figures", f"{name}.png"), category="shear",
                    caption=f"../report/shear_{name.split('_')[0]}.rst")
             for name in shear_layout.FIGURES],
        pdf=[out("shear", "figures", f"{name}.pdf") for name in shear_layout.FIGURES],
    params:
        json=lambda w: as_json(shear_layout.figures_params(SHEAR)),
        outdir=lambda w, output: str(Path(output.png[0]).parent),
        drum=lambda w, input: [a for p in input.drum for a in ("--drum-fits", p)],
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("shear", "figures.log"),
    threads: 1
    resources:
        runtime=10,
        mem_mb=2000,
    shell:
        "granpipe shear figures --params {params.json:q} --out-dir {params.outdir:q}"
        " {params.drum:q} {input.fits:q} > {log:q} 2>&1"


rule shear_movie:
    """The report's movie: one replica replayed around an event (docs/watching.md)."""
    input:
        out("shear", shear_layout.movie_input(SHEAR)) if SHEAR_ON else [],
    output:
        report(out("shear", shear_layout.movie_file(SHEAR)) if SHEAR_ON else "shear.none",
               category="shear", subcategory="movie", caption="../report/shear_movie.rst"),
    params:
        json=lambda w: as_json(shear_layout.movie_params(SHEAR)),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("shear", "movie.log"),
    threads: 1
    resources:
        runtime=10,
        mem_mb=2000,
    shell:
        "granpipe shear movie --params {params.json:q} --out {output:q} {input:q} > {log:q} 2>&1"


if SHEAR_ON:
    register_targets(
        "shear",
        lambda: [
            *(rules.shear_movie.output if SHEAR["movie"]["enabled"] else []),
            *rules.shear_figures.output,
            *rules.shear_summary.output,
            *[out("shear", f) for f in shear_layout.run_files(SHEAR)],
        ],
    )
